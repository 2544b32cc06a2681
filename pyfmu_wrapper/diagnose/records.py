"""Measured records for ``diagnose``: the CSV files of a dataset (SI units), read with located
errors (file, row, column), long records block-averaged in bounded memory, and written back
(:func:`write_record`). The dataset description (``dataset.yaml``) is :mod:`.data`.

Record kinds (told apart by their columns):

* ``link``   -- ``t, displacement, force`` (optional ``velocity``, ``acceleration``): relative motion
  across one device and the force through it (damper test rig).
* ``time``   -- system level: ``t, force`` and the displacements ``x, y`` or the accelerations
  ``xdd, ydd`` (or both; optional ``xd, yd``): base plus TMD under the harmonic force ``force``.
* ``frc``    -- system level stepped sine: ``omega, force_amplitude, x_max`` (optional ``direction``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import DataError

# pandas is imported when a record's rows are read (_read_csv): the headers of every record are
# checked first (check_header), so a dataset with a missing column costs no pandas import

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any

    from numpy import float64, ndarray
    from pandas import DataFrame, Index

REQUIRED = {
    "link": ["t", "displacement", "force"],
    "time": ["t", "force"],
    "frc": ["omega", "force_amplitude", "x_max"],
    "transient": ["t"],
}


OPTIONAL = {
    "link": ["velocity", "acceleration"],
    "time": ["x", "y", "xd", "yd", "xdd", "ydd"],
    "frc": ["direction"],
    "transient": ["force", "x", "y", "xdd", "ydd"],
}

#: a frame's storey channels in a transient record: ``x<i>`` [m] and ``x<i>dd`` [m/s^2] of storey i (1 = lowest)
STOREY_COLUMN = re.compile(r"^x([1-9][0-9]?)(dd)?$")


def storey_columns(cols: Any) -> list[str]:
    """The storey channels (``x1``, ``x2dd``, ...) among the column names ``cols``, in their order."""
    return [str(c) for c in cols if STOREY_COLUMN.match(str(c))]


@dataclass
class Record:
    name: str  #: file name
    kind: str  #: link | time | frc
    columns: dict  #: column name -> float array (direction: array of str)
    omega: float | None = None  #: forcing / drive frequency [rad/s]
    amplitude: float | None = None  #: force amplitude [N] (system) or displacement amplitude [m] (link)
    role: str | None = None  #: train | test | None (automatic)
    meta: dict = field(default_factory=dict)

    def __getitem__(self, k: str) -> ndarray:
        return self.columns[k]

    def has(self, k: str) -> bool:
        return k in self.columns


def data_error(
    file: str | Path, msg: str, row: int | None = None, column: str | None = None, line: int | None = None
) -> DataError:
    where = str(file) if line is None else f"{file}:{line}"
    if row is not None:
        where += f", row {row}"
    if column is not None:
        where += f", column '{column}'"
    return DataError(f"{where}: {msg}")


def _kind_of(cols: Index | list[str], level: str, file: Path) -> str:
    if "omega" in cols or "x_max" in cols:
        return "frc"
    if level == "link" or "displacement" in cols:
        return "link"
    return "time"


#: channels that must move in a record of each kind: constant means a dead sensor
LIVE_CHANNELS = {
    "link": ("displacement", "force"),
    "time": ("force", "x", "y", "xdd", "ydd"),
    "transient": ("x", "y", "xdd", "ydd"),  # force may be absent or zero (a free decay)
}


MAX_SAMPLES = 100_000  #: samples kept per record; a longer record is block-averaged down to at most this


CHUNK_ROWS = 500_000  #: rows parsed at a time from a long CSV (bounded memory)


def say(msg: str) -> None:
    import sys

    print(msg, file=sys.stderr, flush=True)


def _plainf(x: float) -> str:
    return repr(float(x))


def _columns(df: DataFrame, file: Path, kind: str, row0: int = 0, t_prev: float64 | None = None) -> dict[str, ndarray]:
    """Validated numeric columns of (a block of) a record; rows counted from row0."""
    cols = {}
    extra = storey_columns(df.columns) if kind == "transient" else []
    for c in REQUIRED[kind] + OPTIONAL[kind] + extra:
        if c not in df.columns:
            continue
        if c == "direction":
            vals = df[c].astype(str).str.strip().str.lower().to_numpy()
            bad = np.nonzero(~np.isin(vals, ["up", "down"]))[0]
            if bad.size:
                raise data_error(
                    file,
                    f"direction must be 'up' or 'down', got {df[c].iloc[bad[0]]!r}",
                    row=row0 + int(bad[0]) + 1,
                    column=c,
                )
            cols[c] = vals
            continue
        import pandas as pd

        num = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.nonzero(~np.isfinite(num))[0]
        if bad.size:
            raw = df[c].iloc[bad[0]]
            raw = raw.item() if hasattr(raw, "item") else raw
            raise data_error(
                file,
                f"value {raw!r} is not a finite number ({bad.size} bad value(s) in this column"
                + (")" if row0 == 0 and t_prev is None else " in this block of rows)"),
                row=row0 + int(bad[0]) + 1,
                column=c,
            )
        cols[c] = num
    if "t" in cols:
        t = cols["t"] if t_prev is None else np.concatenate([[t_prev], cols["t"]])
        bad = np.nonzero(np.diff(t) <= 0)[0]
        if bad.size:
            i = int(bad[0])
            raise data_error(
                file,
                f"time must be strictly increasing: t = {_plainf(t[i + 1])} after {_plainf(t[i])}",
                row=row0 + i + (2 if t_prev is None else 1),
                column="t",
            )
    if kind == "frc":
        bad = np.nonzero(cols["omega"] <= 0)[0]
        if bad.size:
            raise data_error(file, "omega must be > 0 rad/s", row=row0 + int(bad[0]) + 1, column="omega")
    return cols


def _check_header(df: DataFrame, file: Path, level: str, entry: dict[str, Any]) -> str:
    df.columns = [str(c).strip() for c in df.columns]
    return check_header(file, level, entry)


def check_header(file: Path, level: str, entry: dict[str, Any]) -> str:
    """The record's kind from its header line and its declaration (dataset.yaml ``kind``,
    ``free_decay``), or :class:`DataError` naming the file and the column: a name written twice, a
    required column missing, a transient record without ``force`` that is not declared a free
    decay. Reads the header line only (no pandas): every record of a dataset is checked so before
    any is read."""
    from .record_checks import header_names

    names = header_names(file)
    if any("\ufffd" in c for c in names):  # bytes that are not UTF-8: read_record names them (line, offset)
        return str(entry.get("kind") or "")
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise data_error(
            file,
            f"column(s) {dup} appear more than once in the header {names}: which one is the measured "
            "channel is ambiguous; keep one (rename or drop the other)",
            column=dup[0],
        )
    cols = [c for c in names if c]
    kind = entry.get("kind") or _kind_of(cols, level, file)
    if kind not in REQUIRED:
        raise data_error(file, f"unknown record kind {kind!r} (link, time, frc or transient)")
    if level == "link" and kind == "transient":  # a link record without a drive frequency
        kind = "link"
    if level == "link" and kind != "link":
        raise data_error(file, f"a link-level dataset needs columns {REQUIRED['link']}, got {cols}")
    missing = [c for c in REQUIRED[kind] if c not in cols]
    if missing:
        raise data_error(
            file,
            f"missing column(s) {missing} for a {kind} record (needs {REQUIRED[kind]}, "
            f"optional {OPTIONAL[kind]}); found {cols}",
            column=missing[0],
        )
    if kind == "transient" and not any(c in cols for c in ("x", "y", "xdd", "ydd", *storey_columns(cols))):
        raise data_error(
            file,
            "a transient record needs at least one response channel of x, y, xdd, ydd (a frame's: x<i>, "
            "x<i>dd of storey i, y, ydd) (and 'force', "
            f"unless it is a free decay); found {cols}",
            column="x",
        )
    if kind == "transient":  # a record without force is a free decay only when dataset.yaml says so
        declared = bool(entry.get("free_decay"))
        if "force" not in cols and not declared:
            raise data_error(
                file,
                "no 'force' column: a forced record needs the measured force (the model's input); if no force "
                "acted (a free decay from a displaced start), say so in dataset.yaml: kind: decay (or "
                f"free_decay: true); found columns {cols}",
                column="force",
            )
        if declared and "force" in cols:
            raise data_error(
                file,
                "dataset.yaml calls this record a free decay (kind: decay / free_decay: true) but it has a "
                "'force' column: drop the column, or the declaration if a force acted",
                column="force",
            )
    if kind == "time":  # displacements or accelerations of both bodies (acceleration-only records)
        opts = [[c for c in pair if c not in cols] for pair in (("x", "y"), ("xdd", "ydd"))]
        if all(opts):
            miss = min(opts, key=len)
            raise data_error(
                file,
                f"missing column(s) {miss} for a time record (needs {REQUIRED[kind]} and the "
                f"displacements ['x', 'y'] or the accelerations ['xdd', 'ydd'], or both); "
                f"found {cols}",
                column=miss[0],
            )
    return kind


def _read_csv(file: Path, **kw: Any) -> Any:
    import pandas as pd

    try:
        return pd.read_csv(file, comment="#", skipinitialspace=True, **kw)
    except UnicodeDecodeError as e:  # pragma: no cover - caught by the byte scan first
        raise data_error(file, f"not UTF-8 text: {e}") from None
    except Exception as e:  # pandas parser errors (message names the line)
        raise data_error(file, f"cannot be read as CSV: {' '.join(str(e).split())}") from None


def _read_long(
    file: Path, level: str, entry: dict[str, Any], n_rows: int, log: Callable
) -> tuple[str, dict[str, ndarray], tuple[dict[str, float], dict[str, float]], dict[str, Any]]:
    """A record with more than MAX_SAMPLES rows, read in blocks of CHUNK_ROWS rows (bounded memory):
    every q consecutive samples are averaged (a boxcar anti-alias filter, then one sample per block),
    q = ceil(rows / MAX_SAMPLES). For a linear model the averaged record obeys the same equations as
    the raw one (averaging commutes with derivatives and linear force laws); the drive-frequency
    amplitude is scaled by sinc(pi / samples per period after averaging), equally in every channel."""
    import time as _time

    q = max(1, math.ceil(n_rows / MAX_SAMPLES))
    chunk = q * max(1, CHUNK_ROWS // q)
    log(
        f"{file.name}: {n_rows:,} lines after the header, more than {MAX_SAMPLES:,}: reading {chunk:,} rows at a time and averaging "
        f"every {q} consecutive samples (boxcar anti-alias filter) -> about {n_rows // q:,} samples"
    )
    parts: dict[Any, Any] = {}
    lo: dict[Any, Any] = {}
    hi: dict[Any, Any] = {}
    kind, t_prev, row0, dropped = None, None, 0, 0
    t0 = last = _time.monotonic()
    try:
        reader = _read_csv(file, chunksize=chunk)
        for df in reader:
            if kind is None:
                kind = _check_header(df, file, level, entry)
                if kind == "frc":
                    raise data_error(
                        file,
                        f"an FRC record (one line per frequency) with {n_rows:,} rows: at most "
                        f"{MAX_SAMPLES:,} are read",
                    )
            else:
                df.columns = [str(c).strip() for c in df.columns]
            cols = _columns(df, file, kind, row0, t_prev)
            if "t" in cols and len(cols["t"]):
                t_prev = cols["t"][-1]
            m = len(df) // q * q
            dropped += len(df) - m
            for c, v in cols.items():
                parts.setdefault(c, []).append(v[:m].reshape(-1, q).mean(axis=1))
                if len(v):
                    lo[c] = min(lo.get(c, np.inf), float(v.min()))
                    hi[c] = max(hi.get(c, -np.inf), float(v.max()))
            row0 += len(df)
            if _time.monotonic() - last >= 2.0:
                last = _time.monotonic()
                log(
                    f"{file.name}: read {row0:,} of about {n_rows:,} rows ({100 * row0 / n_rows:.0f} %, "
                    f"{last - t0:.0f} s)"
                )
    except DataError:
        raise
    except Exception as e:  # pandas parser errors in a later block
        raise data_error(file, f"cannot be read as CSV: {' '.join(str(e).split())}") from None
    if kind is None:
        raise data_error(file, "has no data rows")
    cols = {c: np.concatenate(v) for c, v in parts.items()}
    info = {
        "rows": row0,
        "block": q,
        "samples": int(len(cols["t"])),
        "dropped_rows": dropped,
        "method": f"boxcar average of {q} consecutive samples, one sample kept per block",
    }
    log(
        f"{file.name}: {row0:,} rows read in {_time.monotonic() - t0:.0f} s -> {info['samples']:,} samples "
        f"(averages of {q})" + (f"; the last {dropped} rows (less than one block) are not used" if dropped else "")
    )
    return kind, cols, (lo, hi), info


def read_record(file: Path, level: str, entry: dict | None = None, log: Callable = say) -> Record:
    """Read and validate one CSV record (records longer than MAX_SAMPLES rows: see :func:`_read_long`)."""
    from ..errors import scan_utf8_lines
    from .record_checks import check_line_length, check_record_size

    entry = entry or {}
    file = Path(file)
    if not file.is_file():
        raise data_error(file, "file not found")
    size = check_record_size(file)
    n_rows = max(scan_utf8_lines(file, error=DataError) - 1, 0)  # header excluded (comments counted)
    check_line_length(file, size, n_rows)
    reduced = None
    if n_rows <= MAX_SAMPLES:
        df = _read_csv(file)
        kind = _check_header(df, file, level, entry)
        if len(df) < 3:
            raise data_error(file, f"needs at least 3 data rows, has {len(df)}")
        cols = _columns(df, file, kind)
        span = (
            {c: float(np.min(v)) for c, v in cols.items() if c != "direction"},
            {c: float(np.max(v)) for c, v in cols.items() if c != "direction"},
        )
    else:
        kind, cols, span, reduced = _read_long(file, level, entry, n_rows, log)
        if len(cols["t"]) < 3:
            raise data_error(file, f"needs at least 3 data rows, has {len(cols['t'])}")
    for c in (*LIVE_CHANNELS.get(kind, ()), *(storey_columns(cols) if kind == "transient" else ())):
        if c in cols and span[0][c] == span[1][c]:
            raise data_error(
                file,
                f"the channel is constant (every value = {span[0][c]:g}): a dead channel (sensor not "
                "connected or not recorded?); the diagnosis needs it measured",
                column=c,
            )
    omega = entry.get("omega")
    if omega is None and entry.get("frequency_hz") is not None:
        omega = 2 * math.pi * float(entry["frequency_hz"])
    elif omega is not None and entry.get("frequency_hz") is not None:
        w_hz = 2 * math.pi * float(entry["frequency_hz"])
        if abs(w_hz - float(omega)) > 1e-6 * max(abs(w_hz), abs(float(omega))):
            raise data_error(
                file,
                f"dataset.yaml gives omega = {_plainf(float(omega))} rad/s and frequency_hz = "
                f"{_plainf(float(entry['frequency_hz']))} Hz (= {w_hz:.6g} rad/s): they disagree; give one of them",
            )
    amp = entry.get("force_amplitude", entry.get("amplitude"))
    rec = Record(
        name=file.name,
        kind=kind,
        columns=cols,
        omega=None if omega is None else float(omega),
        amplitude=None if amp is None else float(amp),
        role=entry.get("role"),
        meta={k: v for k, v in entry.items() if k not in ("file",)},
    )
    if reduced is not None:
        rec.meta["reduced"] = reduced
    if entry.get("kind") == "transient":  # no steady state, no drive frequency
        if rec.omega is not None:
            raise data_error(
                file,
                "a transient record has no drive frequency: leave omega / frequency_hz out (or give kind: time)",
            )
        rec.meta["transient"] = True
    elif kind in ("link", "time") and rec.omega is None:
        rec.omega = estimate_omega(cols["t"], cols["displacement"] if kind == "link" else cols["force"])
        rec.meta["omega_estimated"] = True
        if rec.omega is None:
            rec.meta["periodic"] = False
    if rec.omega is not None and not rec.omega > 0:
        raise data_error(file, f"omega must be > 0 rad/s, got {_plainf(rec.omega)}")
    if kind == "time" and rec.omega is not None:
        span_s, period = float(cols["t"][-1] - cols["t"][0]), 2 * math.pi / rec.omega
        if span_s < period:
            raise data_error(
                file,
                f"the record spans {span_s:.4g} s, less than one period of w = {rec.omega:.4g} rad/s "
                f"({period:.4g} s): the harmonic analysis of a system time record needs whole periods "
                "(at least 2)",
            )
    if kind in ("link", "time") and rec.omega is not None and not rec.meta.get("omega_estimated"):
        from .record_checks import declared_omega_problem

        bad = declared_omega_problem(cols["t"], cols["displacement"] if kind == "link" else cols["force"], rec.omega)
        if bad:
            raise data_error(file, bad[0], column=bad[1])
    if kind == "link" and rec.amplitude is None:
        d = cols["displacement"]
        rec.amplitude = 0.5 * float(np.percentile(d, 99.5) - np.percentile(d, 0.5))
    return rec


def estimate_omega(t: ndarray, d: ndarray) -> float | None:
    """Dominant angular frequency [rad/s] > 0 of a sampled signal, or None when it is not periodic
    (see :func:`harmonic.estimate_omega`)."""
    from ..solvers.harmonic import estimate_omega as _est

    return _est(t, d)


def write_record(file: Path, columns: dict, header_comment: str | None = None, fmt: str = "%.9g") -> None:
    """Write a record as CSV (the format read_record accepts)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[c], dtype=float) for c in names])
    with open(file, "w") as f:
        if header_comment:
            for line in header_comment.splitlines():
                f.write(f"# {line}\n")
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt=fmt)
