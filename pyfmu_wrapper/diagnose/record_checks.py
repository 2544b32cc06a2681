"""Consistency checks of a measured record against itself and its declaration in dataset.yaml
(used by :mod:`.records`): a header that names a column twice, a declared drive frequency the
record's sampling cannot hold or its data contradict."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..solvers.harmonic import estimate_omega
from .errors import DataError

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


#: the largest record file read (bytes); ``diagnose --max-record-size MB`` raises it (:func:`set_max_record_size`)
MAX_RECORD_BYTES = 2**30
#: the longest line (on average) of a CSV record of numbers, in bytes
MAX_LINE_BYTES = 4096


def set_max_record_size(megabytes: float | None) -> None:
    """Raise or lower :data:`MAX_RECORD_BYTES` (``--max-record-size MB``)."""
    global MAX_RECORD_BYTES
    if megabytes is None:
        return
    if not 0 < megabytes < 1e7:
        raise DataError(f"--max-record-size {megabytes}: must be a size in MB, > 0")
    MAX_RECORD_BYTES = int(megabytes * 2**20)


def check_record_size(file: Path) -> int:
    """The size of a record file in bytes, refused (DataError) above :data:`MAX_RECORD_BYTES` before a
    byte of it is read."""
    size = file.stat().st_size
    if size > MAX_RECORD_BYTES:
        raise DataError(
            f"{file}: the record is {size / 2**20:,.0f} MB, more than the limit of {MAX_RECORD_BYTES / 2**20:,.0f} MB "
            "for one record (600 s at 12.8 kHz with six channels is about 700 MB); if it really is that large, raise "
            "the limit with --max-record-size MB"
        )
    return size


def check_line_length(file: Path, size: int, n_rows: int) -> None:
    """Refuse a file whose lines are far too long for a CSV record of numbers (a binary file)."""
    if size > MAX_LINE_BYTES * (n_rows + 2):
        raise DataError(
            f"{file}: {size:,} bytes in {n_rows + 1:,} lines: lines of {size // (n_rows + 1):,} bytes on average are "
            "not a CSV record of numbers (a binary file, or a file of NUL bytes?)"
        )
