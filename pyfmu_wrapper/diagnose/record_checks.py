"""Consistency checks of a measured record against itself and its declaration in dataset.yaml
(used by :mod:`.records`): a header that names a column twice, a declared drive frequency the
record's sampling cannot hold or its data contradict."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .harmonic import estimate_omega

if TYPE_CHECKING:
    from pathlib import Path

    from numpy import ndarray


def header_names(file: Path) -> list[str]:
    """The column names as written on the header line (the first line that is neither blank nor a
    '#' comment), before pandas renames duplicates ('force', 'force.1')."""
    with open(file, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            s = line.strip()
            if s and not s.startswith("#"):
                return [c.strip().strip('"') for c in s.split(",")]
    return []


#: a declared drive frequency may differ from the one found in the data by at most this share
OMEGA_TOLERANCE = 0.05


def declared_omega_problem(t: ndarray, s: ndarray, omega: float) -> tuple[str, str | None] | None:
    """(message, column) refusing a declared drive frequency that the record cannot hold (above the Nyquist frequency
    of its sampling) or that the data contradict: the dominant frequency of the drive channel
    ``s`` (displacement of a link record, force of a system time record) differs by more than
    OMEGA_TOLERANCE. A record with no dominant frequency (transient, random) is not checked (None)."""
    dt = float(t[-1] - t[0]) / max(len(t) - 1, 1)
    nyq = math.pi / dt
    if omega >= nyq:
        return (
            f"the declared drive frequency w = {omega:.6g} rad/s is above the Nyquist frequency pi/dt = "
            f"{nyq:.6g} rad/s of the record (sample spacing dt = {dt:.6g} s; t must be in seconds, "
            "not milliseconds)",
            "t",
        )
    est = estimate_omega(t, s)
    if est is None or abs(est / omega - 1.0) <= OMEGA_TOLERANCE:
        return None
    ratio = omega / est
    hint = " (is t in milliseconds? t must be in seconds)" if 500 < ratio < 2000 else ""
    return (
        f"the declared drive frequency w = {omega:.6g} rad/s ({omega / (2 * math.pi):.6g} Hz) disagrees with "
        f"the record: its dominant frequency is {est:.6g} rad/s ({est / (2 * math.pi):.6g} Hz), "
        f"the declared value is {ratio:.3g} times it{hint}; correct omega / frequency_hz in dataset.yaml or leave it out "
        "(it is then estimated from the data)",
        None,
    )
