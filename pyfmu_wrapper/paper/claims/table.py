"""The claims table's machinery: a check (:class:`Check`), a row (:class:`Claim`) with its verdict computed
from its checks, what the claim functions read (:class:`Context`), the ordered table :data:`CLAIMS` filled
by the :func:`claim` decorator in the section modules, and :func:`evaluate`.
"""

from __future__ import annotations

import math
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from .. import claim_data as cd

CASES = (1, 2, 3)
_OPS = {"<=": lambda a, b: a <= b, "<": lambda a, b: a < b, ">=": lambda a, b: a >= b, ">": lambda a, b: a > b}


def fmt(x: float | None, nd: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, str):
        return x
    ax = abs(x)
    if ax != 0 and (ax < 1e-2 or ax >= 1e4):
        return f"{x:.{nd - 1}e}"
    return f"{x:.{nd}g}"


@dataclass(frozen=True)
class Check:
    """One comparison: ``value op threshold`` (NaN never passes)."""

    quantity: str  #: what is compared
    value: float
    op: str  #: '<=', '<', '>=' or '>'
    threshold: float
    unit: str = ""

    def __post_init__(self) -> None:
        if self.op not in _OPS:
            raise ValueError(f"op must be one of {list(_OPS)}, got {self.op!r}")

    @property
    def passed(self) -> bool:
        v = float(self.value)
        return math.isfinite(v) and bool(_OPS[self.op](v, float(self.threshold)))

    def text(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        mark = "yes" if self.passed else "NO"
        return f"{self.quantity} = {fmt(float(self.value))}{u} {self.op} {fmt(float(self.threshold))}{u}: {mark}"


@dataclass
class Claim:
    """A row of the claims table; ``verdict`` is computed from ``checks``."""

    section: str
    claim: str
    paper: str  #: the reference value as the paper states it
    project: str = ""  #: the computed numbers, in words
    checks: tuple = ()
    note: str = ""
    status: str = "ok"  #: 'ok', 'not computed' (scenario not run), 'error' (the computation failed)
    detail: str = ""  #: why not computed / the error

    @property
    def verdict(self) -> str:
        if self.status != "ok":
            return self.status
        if not self.checks:
            raise ValueError(f"claim {self.claim!r} has no check: a verdict must come from a comparison")
        n = sum(c.passed for c in self.checks)
        return "agrees" if n == len(self.checks) else ("disagrees" if n == 0 else "partly")

    def as_row(self) -> dict:
        return dict(
            section=self.section,
            claim=self.claim,
            paper=self.paper,
            project=self.project,
            checks=[
                dict(
                    quantity=c.quantity,
                    value=float(c.value),
                    op=c.op,
                    threshold=float(c.threshold),
                    unit=c.unit,
                    passed=c.passed,
                )
                for c in self.checks
            ],
            verdict=self.verdict,
            note=self.note,
            detail=self.detail,
        )


@dataclass
class Context:
    """What the claim functions read: the runs (name -> reproduce.Run), quick mode, shared results."""

    runs: dict[str, Any]
    quick: bool = False
    shared: dict[str, Any] = field(default_factory=dict)

    def data(self, name: str, study: str) -> Any:
        return self.runs[name].datas[study]

    def fits(self) -> dict:
        """Simplified-model errors per Case of the Fig. 6 runs (computed once)."""
        if "fits" not in self.shared:
            self.shared["fits"] = {
                c: cd.simplified_fits(self.runs[f"fig6_case{c}"], c) for c in CASES if f"fig6_case{c}" in self.runs
            }
        return self.shared["fits"]


#: what a claim function returns: (the project's numbers in words, its checks, a note)
ClaimResult = tuple[str, Sequence[Check], str]


@dataclass(frozen=True)
class Entry:
    section: str
    claim: str
    paper: str
    needs: tuple[str, ...]
    compute: Callable[[Context], ClaimResult]  #: callable(Context) -> (project text, checks, note)


CLAIMS: list[Entry] = []


def claim(
    section: str, text: str, paper: str, needs: Iterable[str]
) -> Callable[[Callable[[Context], ClaimResult]], Callable[[Context], ClaimResult]]:
    def deco(fn: Callable[[Context], ClaimResult]) -> Callable[[Context], ClaimResult]:
        CLAIMS.append(Entry(section, text, paper, tuple(needs), fn))
        return fn

    return deco


def not_run(ctx: Context, prefix: str) -> str:
    """'; Case k: not run' for the Cases whose scenario ``prefix``k is missing."""
    miss = [c for c in CASES if f"{prefix}{c}" not in ctx.runs]
    return "".join(f"; Case {c}: scenario {prefix}{c} not run" for c in miss)


def nc_note(n: int) -> str:
    """The note a claim carries when n steady states of its data did not converge."""
    return f" [{n} steady states of the data not converged]" if n else ""


FIG3 = [f"fig3_case{c}" for c in CASES]
FIG4 = [f"fig4_case{c}" for c in CASES]
FIG6 = [f"fig6_case{c}" for c in CASES]
FIG5 = [f"fig5_case{c}" for c in CASES]


# --- the table --------------------------------------------------------------------------------------


def evaluate(ctx: Context, only: Iterable[str] | None = None) -> list[Claim]:
    """Every claim of :data:`CLAIMS` in order (``only``: those whose text starts with one of these
    strings): computed, not computed (scenario missing) or error."""
    rows = []
    for e in CLAIMS:
        if only is not None and not e.claim.startswith(tuple(only)):
            continue
        missing = [n for n in e.needs if n not in ctx.runs]
        if missing:
            rows.append(
                Claim(
                    e.section,
                    e.claim,
                    e.paper,
                    status="not computed",
                    detail=f"scenarios not run: {', '.join(missing)}",
                )
            )
            continue
        try:
            project, checks, note = e.compute(ctx)
            rows.append(Claim(e.section, e.claim, e.paper, project, tuple(checks), note))
            rows[-1].verdict  # noqa: B018 - a claim without checks is an error
        except Exception as exc:  # noqa: BLE001 - a flagged row, and a failing exit code
            rows.append(
                Claim(
                    e.section,
                    e.claim,
                    e.paper,
                    status="error",
                    detail=f"{type(exc).__name__}: {exc}",
                    note=traceback.format_exc(limit=2).splitlines()[-1],
                )
            )
    return rows
