"""What the benchmark generators share (``make-benchmark``): each suite's default size and class shares,
declared once here and read by the generators and the command line, the class counts they give, and
the manifest written after every dataset (a run stopped early leaves a scorable part)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pathlib import Path


@dataclass(frozen=True)
class Shares:
    """A suite's default number of datasets and the shares of its clean, two-effect and
    out-of-vocabulary classes (the rest are single effects)."""

    n: int
    clean: float
    pair: float
    oov: float


SUITES: dict[str, Shares] = {
    "system": Shares(52, 0.19, 0.15, 0.23),
    "transient": Shares(60, 0.17, 0.13, 0.25),
    "frame": Shares(40, 0.2, 0.2, 0.2),
    "link": Shares(40, 0.25, 0.2, 0.0),  # no out-of-vocabulary class
}


def counts(
    suite: str, n: int | None = None, n_clean: int | None = None, n_pair: int | None = None, n_oov: int | None = None
) -> tuple[int, int, int, int]:
    """(clean, single, pair, oov) counts of ``n`` datasets (default: the suite's), each class count not
    given from the suite's share; ValueError when the given ones leave fewer than 0 singles."""
    d = SUITES[suite]
    n = d.n if n is None else int(n)
    nc = int(round(d.clean * n)) if n_clean is None else int(n_clean)
    npair = int(round(d.pair * n)) if n_pair is None else int(n_pair)
    no = int(round(d.oov * n)) if n_oov is None else int(n_oov)
    if nc + npair + no > n:
        raise ValueError(f"n = {n} is smaller than clean + pairs + OOV = {nc + npair + no}")
    return nc, n - nc - npair - no, npair, no


def counts_from_fractions(
    suite: str, n: int | None, clean: float | None = None, pair: float | None = None, oov: float | None = None
) -> tuple[int, int, int, int]:
    """:func:`counts` from the command line's shares (None: the suite's share); the pair count is cut
    to what the clean ones leave, the OOV count to what both leave."""
    d = SUITES[suite]
    n = d.n if n is None else int(n)
    nc = min(int(round((d.clean if clean is None else clean) * n)), n)
    npair = min(int(round((d.pair if pair is None else pair) * n)), n - nc)
    no = min(int(round((d.oov if oov is None else oov) * n)), n - nc - npair)
    return counts(suite, n, nc, npair, no)


def defaults_help(share: str) -> str:
    """``system 0.19, transient 0.17, ...`` of one share (``clean``, ``pair``, ``oov``) or of ``n``,
    for the command line's help."""
    return ", ".join(f"{s} {getattr(d, share):g}" for s, d in SUITES.items() if share != "oov" or d.oov)


def write_manifest(out: Path, doc: dict[str, Any]) -> None:
    """``out/manifest.json`` replaced as a whole (written beside it, then renamed: a reader never sees
    half a file)."""
    tmp = out / ".manifest.json.partial"
    tmp.write_text(json.dumps(doc, indent=1))
    tmp.replace(out / "manifest.json")


__all__ = ["SUITES", "Shares", "counts", "counts_from_fractions", "defaults_help", "write_manifest"]
