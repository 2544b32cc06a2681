"""Measured datasets for ``diagnose``: a folder with ``dataset.yaml`` and CSV files (SI units).

Record kinds (told apart by their columns):

* ``link``   -- ``t, displacement, force`` (optional ``velocity``, ``acceleration``): relative motion
  across one device and the force through it (damper test rig).
* ``time``   -- system level: ``t, force`` and the displacements ``x, y`` or the accelerations
  ``xdd, ydd`` (or both; optional ``xd, yd``): base plus TMD under the harmonic force ``force``.
* ``frc``    -- system level stepped sine: ``omega, force_amplitude, x_max`` (optional ``direction``).

Every problem is raised as :class:`DataError` naming the file, and where it applies the row
(1-based data row, not counting the header or '#' comment lines) and the column.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from .errors import DataError

REQUIRED = {
    "link": ["t", "displacement", "force"],
    "time": ["t", "force"],
    "frc": ["omega", "force_amplitude", "x_max"],
}
OPTIONAL = {
    "link": ["velocity", "acceleration"],
    "time": ["x", "y", "xd", "yd", "xdd", "ydd"],
    "frc": ["direction"],
}
LINK_NOMINAL = ("stiffness", "damping", "friction_force", "friction_slope", "inertance")



@dataclass
class Record:
    name: str  #: file name
    kind: str  #: link | time | frc
    columns: dict  #: column name -> float array (direction: array of str)
    omega: float | None = None  #: forcing / drive frequency [rad/s]
    amplitude: float | None = None  #: force amplitude [N] (system) or displacement amplitude [m] (link)
    role: str | None = None  #: train | test | None (automatic)
    meta: dict = field(default_factory=dict)

    def __getitem__(self, k):
        return self.columns[k]

    def has(self, k):
        return k in self.columns


@dataclass
class Dataset:
    path: Path
    level: str  #: link | system
    nominal: dict  #: link: force-law parameters; system: {"base": {...}, "tmd": {...}}
    records: list
    description: str = ""
    raw: dict = field(default_factory=dict)
    acquisition: dict = field(default_factory=dict)  #: channel -> acquisition.Chain (dataset.yaml 'acquisition')


def _err(file, msg, row=None, column=None, line=None):
    where = str(file) if line is None else f"{file}:{line}"
    if row is not None:
        where += f", row {row}"
    if column is not None:
        where += f", column '{column}'"
    return DataError(f"{where}: {msg}")


def _kind_of(cols, level, file):
    if "omega" in cols or "x_max" in cols:
        return "frc"
    if level == "link" or "displacement" in cols:
        return "link"
    return "time"


#: keys allowed in dataset.yaml (top level) and in each entry of ``records``; anything else is
#: refused with this list (a typo such as ``rol: test`` must not be ignored silently).
ALLOWED_KEYS = {
    "dataset": ("level", "description", "nominal", "records", "x_max_noise", "acquisition"),
    "record": ("file", "kind", "omega", "frequency_hz", "force_amplitude", "amplitude", "role", "source_file",
               "description"),
}
#: channels that must move in a record of each kind: constant means a dead sensor
LIVE_CHANNELS = {"link": ("displacement", "force"), "time": ("force", "x", "y", "xdd", "ydd")}
MAX_SAMPLES = 100_000  #: samples kept per record; a longer record is block-averaged down to at most this
CHUNK_ROWS = 500_000  #: rows parsed at a time from a long CSV (bounded memory)


def _stderr(msg):
    import sys

    print(msg, file=sys.stderr, flush=True)


def _plainf(x) -> str:
    return repr(float(x))


def _columns(df, file, kind, row0=0, t_prev=None):
    """Validated numeric columns of (a block of) a record; rows counted from row0."""
    cols = {}
    for c in REQUIRED[kind] + OPTIONAL[kind]:
        if c not in df.columns:
            continue
        if c == "direction":
            vals = df[c].astype(str).str.strip().str.lower().to_numpy()
            bad = np.nonzero(~np.isin(vals, ["up", "down"]))[0]
            if bad.size:
                raise _err(file, f"direction must be 'up' or 'down', got {df[c].iloc[bad[0]]!r}",
                           row=row0 + int(bad[0]) + 1, column=c)
            cols[c] = vals
            continue
        num = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.nonzero(~np.isfinite(num))[0]
        if bad.size:
            raw = df[c].iloc[bad[0]]
            raw = raw.item() if hasattr(raw, "item") else raw
            raise _err(file, f"value {raw!r} is not a finite number ({bad.size} bad value(s) in this column"
                             + (")" if row0 == 0 and t_prev is None else " in this block of rows)"),
                       row=row0 + int(bad[0]) + 1, column=c)
        cols[c] = num
    if "t" in cols:
        t = cols["t"] if t_prev is None else np.concatenate([[t_prev], cols["t"]])
        bad = np.nonzero(np.diff(t) <= 0)[0]
        if bad.size:
            i = int(bad[0])
            raise _err(file, f"time must be strictly increasing: t = {_plainf(t[i + 1])} after {_plainf(t[i])}",
                       row=row0 + i + (2 if t_prev is None else 1), column="t")
    if kind == "frc":
        bad = np.nonzero(cols["omega"] <= 0)[0]
        if bad.size:
            raise _err(file, "omega must be > 0 rad/s", row=row0 + int(bad[0]) + 1, column="omega")
    return cols


def _check_header(df, file, level, entry):
    df.columns = [str(c).strip() for c in df.columns]
    kind = entry.get("kind") or _kind_of(df.columns, level, file)
    if kind not in REQUIRED:
        raise _err(file, f"unknown record kind {kind!r} (link, time or frc)")
    if level == "link" and kind != "link":
        raise _err(file, f"a link-level dataset needs columns {REQUIRED['link']}, got {list(df.columns)}")
    missing = [c for c in REQUIRED[kind] if c not in df.columns]
    if missing:
        raise _err(file, f"missing column(s) {missing} for a {kind} record (needs {REQUIRED[kind]}, "
                         f"optional {OPTIONAL[kind]}); found {list(df.columns)}", column=missing[0])
    if kind == "time":  # displacements or accelerations of both bodies (acceleration-only records)
        opts = [[c for c in pair if c not in df.columns] for pair in (("x", "y"), ("xdd", "ydd"))]
        if all(opts):
            miss = min(opts, key=len)
            raise _err(file, f"missing column(s) {miss} for a time record (needs {REQUIRED[kind]} and the "
                             f"displacements ['x', 'y'] or the accelerations ['xdd', 'ydd'], or both); "
                             f"found {list(df.columns)}", column=miss[0])
    return kind


def _read_csv(file, **kw):
    try:
        return pd.read_csv(file, comment="#", skipinitialspace=True, **kw)
    except UnicodeDecodeError as e:  # pragma: no cover - caught by the byte scan first
        raise _err(file, f"not UTF-8 text: {e}") from None
    except Exception as e:  # pandas parser errors (message names the line)
        raise _err(file, f"cannot be read as CSV: {' '.join(str(e).split())}") from None


def _read_long(file, level, entry, n_rows, log):
    """A record with more than MAX_SAMPLES rows, read in blocks of CHUNK_ROWS rows (bounded memory):
    every q consecutive samples are averaged (a boxcar anti-alias filter, then one sample per block),
    q = ceil(rows / MAX_SAMPLES). For a linear model the averaged record obeys the same equations as
    the raw one (averaging commutes with derivatives and linear force laws); the drive-frequency
    amplitude is scaled by sinc(pi / samples per period after averaging), equally in every channel."""
    import time as _time

    q = max(1, math.ceil(n_rows / MAX_SAMPLES))
    chunk = q * max(1, CHUNK_ROWS // q)
    log(f"{file.name}: {n_rows:,} lines after the header, more than {MAX_SAMPLES:,}: reading {chunk:,} rows at a time and averaging "
        f"every {q} consecutive samples (boxcar anti-alias filter) -> about {n_rows // q:,} samples")
    parts, lo, hi = {}, {}, {}
    kind, t_prev, row0, dropped = None, None, 0, 0
    t0 = last = _time.monotonic()
    try:
        reader = _read_csv(file, chunksize=chunk)
        for df in reader:
            if kind is None:
                kind = _check_header(df, file, level, entry)
                if kind == "frc":
                    raise _err(file, f"an FRC record (one line per frequency) with {n_rows:,} rows: at most "
                                     f"{MAX_SAMPLES:,} are read")
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
                log(f"{file.name}: read {row0:,} of about {n_rows:,} rows ({100 * row0 / n_rows:.0f} %, "
                    f"{last - t0:.0f} s)")
    except DataError:
        raise
    except Exception as e:  # pandas parser errors in a later block
        raise _err(file, f"cannot be read as CSV: {' '.join(str(e).split())}") from None
    if kind is None:
        raise _err(file, "has no data rows")
    cols = {c: np.concatenate(v) for c, v in parts.items()}
    info = {"rows": row0, "block": q, "samples": int(len(cols["t"])), "dropped_rows": dropped,
            "method": f"boxcar average of {q} consecutive samples, one sample kept per block"}
    log(f"{file.name}: {row0:,} rows read in {_time.monotonic() - t0:.0f} s -> {info['samples']:,} samples "
        f"(averages of {q})" + (f"; the last {dropped} rows (less than one block) are not used" if dropped else ""))
    return kind, cols, (lo, hi), info


def read_record(file: Path, level: str, entry: dict | None = None, log=_stderr) -> Record:
    """Read and validate one CSV record (records longer than MAX_SAMPLES rows: see :func:`_read_long`)."""
    from ..cli.errors import scan_utf8_lines

    entry = entry or {}
    file = Path(file)
    if not file.is_file():
        raise _err(file, "file not found")
    n_rows = max(scan_utf8_lines(file, error=DataError) - 1, 0)  # header excluded (comments counted)
    reduced = None
    if n_rows <= MAX_SAMPLES:
        df = _read_csv(file)
        kind = _check_header(df, file, level, entry)
        if len(df) < 3:
            raise _err(file, f"needs at least 3 data rows, has {len(df)}")
        cols = _columns(df, file, kind)
        span = ({c: float(np.min(v)) for c, v in cols.items() if c != "direction"},
                {c: float(np.max(v)) for c, v in cols.items() if c != "direction"})
    else:
        kind, cols, span, reduced = _read_long(file, level, entry, n_rows, log)
        if len(cols["t"]) < 3:
            raise _err(file, f"needs at least 3 data rows, has {len(cols['t'])}")
    for c in LIVE_CHANNELS.get(kind, ()):
        if c in cols and span[0][c] == span[1][c]:
            raise _err(file, f"the channel is constant (every value = {span[0][c]:g}): a dead channel (sensor not "
                             "connected or not recorded?); the diagnosis needs it measured", column=c)
    omega = entry.get("omega")
    if omega is None and entry.get("frequency_hz") is not None:
        omega = 2 * math.pi * float(entry["frequency_hz"])
    amp = entry.get("force_amplitude", entry.get("amplitude"))
    rec = Record(name=file.name, kind=kind, columns=cols, omega=None if omega is None else float(omega),
                 amplitude=None if amp is None else float(amp), role=entry.get("role"),
                 meta={k: v for k, v in entry.items() if k not in ("file",)})
    if reduced is not None:
        rec.meta["reduced"] = reduced
    if kind in ("link", "time") and rec.omega is None:
        rec.omega = estimate_omega(cols["t"], cols["displacement"] if kind == "link" else cols["force"])
        rec.meta["omega_estimated"] = True
        if rec.omega is None:
            rec.meta["periodic"] = False
    if rec.omega is not None and not rec.omega > 0:
        raise _err(file, f"omega must be > 0 rad/s, got {_plainf(rec.omega)}")
    if kind == "time" and rec.omega is not None:
        span_s, period = float(cols["t"][-1] - cols["t"][0]), 2 * math.pi / rec.omega
        if span_s < period:
            raise _err(file, f"the record spans {span_s:.4g} s, less than one period of w = {rec.omega:.4g} rad/s "
                             f"({period:.4g} s): the harmonic analysis of a system time record needs whole periods "
                             "(at least 2)")
    if kind == "link" and rec.amplitude is None:
        d = cols["displacement"]
        rec.amplitude = 0.5 * float(np.percentile(d, 99.5) - np.percentile(d, 0.5))
    return rec


def estimate_omega(t, d) -> float | None:
    """Dominant angular frequency [rad/s] > 0 of a sampled signal, or None when it is not periodic
    (see :func:`harmonic.estimate_omega`)."""
    from .harmonic import estimate_omega as _est

    return _est(t, d)


def _line(node, key):
    f = getattr(node, "line_of", None)
    return f(key) if f is not None else None


def _number(v, file, key, line=None, minimum=None, strict=False, unit=""):
    try:
        if isinstance(v, bool):
            raise TypeError
        x = float(v)
    except (TypeError, ValueError):
        raise _err(file, f"'{key}' must be a number, got {v!r}", line=line) from None
    if not math.isfinite(x):
        raise _err(file, f"'{key}' must be finite, got {v!r}", line=line)
    if minimum is not None and (x <= minimum if strict else x < minimum):
        raise _err(file, f"'{key}' must be {'>' if strict else '>='} {minimum:g}{' ' + unit if unit else ''} "
                         f"(a physical value), got {v!r}", line=line)
    return x


def _unknown_keys(node, allowed, file, where):
    unknown = [k for k in node if k not in allowed]
    if unknown:
        k = unknown[0]
        raise _err(file, f"{where}: unknown key(s) {[str(u) for u in unknown]}; allowed keys: {list(allowed)}",
                   line=_line(node, k))


def _plain_data(x):
    """MarkedDict/MarkedList (with line numbers) -> plain dict/list."""
    if isinstance(x, dict):
        return {k: _plain_data(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_plain_data(v) for v in x]
    return x


def load_dataset(path, model_override: dict | None = None, log=_stderr, model_source=None) -> Dataset:
    """Load and validate ``path/dataset.yaml`` and its records (``model_override``: a nominal model
    read from the file ``model_source``). Progress of long records goes to ``log``."""
    from ..cli.errors import read_utf8
    from ..scenario.yamlio import load_marked

    path = Path(path)
    yml = path if path.suffix in (".yaml", ".yml") else path / "dataset.yaml"
    path = yml.parent
    if not yml.is_file():
        raise _err(yml, "file not found (a dataset is a folder with dataset.yaml and CSV files)")
    text = read_utf8(yml, error=DataError)
    try:
        raw = load_marked(text, name=str(yml))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        raise _err(yml, f"invalid YAML: {' '.join(str(e).split())}",
                   line=None if mark is None else mark.line + 1) from None
    raw = {} if raw is None else raw
    if not isinstance(raw, dict):
        raise _err(yml, "must be a mapping with keys level, nominal, records")
    _unknown_keys(raw, ALLOWED_KEYS["dataset"], yml, "dataset.yaml")
    level = raw.get("level", "system")
    if level not in ("link", "system"):
        raise _err(yml, f"'level' must be 'link' or 'system', got {level!r}", line=_line(raw, "level"))
    if "x_max_noise" in raw:
        raw["x_max_noise"] = _number(raw["x_max_noise"], yml, "x_max_noise", _line(raw, "x_max_noise"), 0.0,
                                     unit="m")
    nominal = model_override if model_override is not None else raw.get("nominal")
    if not isinstance(nominal, dict):
        raise _err(yml, "'nominal' (the model parameters) is missing or not a mapping", line=_line(raw, "nominal"))
    nominal = normalise_nominal(nominal, level, yml if model_override is None else (model_source or "--model"))
    entries = raw.get("records")
    if not isinstance(entries, list) or not entries:
        raise _err(yml, "'records' must be a non-empty list of {file: ..., ...}", line=_line(raw, "records"))
    records = []
    for i, entry in enumerate(entries):
        ln = _line(entries, i)
        if isinstance(entry, str):
            entry = {"file": entry}
        if not isinstance(entry, dict) or "file" not in entry:
            raise _err(yml, f"records[{i}] needs a 'file' key (a CSV file name)", line=ln)
        _unknown_keys(entry, ALLOWED_KEYS["record"], yml, f"records[{i}] ({entry.get('file')})")
        if not isinstance(entry["file"], str) or not entry["file"].strip():
            raise _err(yml, f"records[{i}].file must be a file name, got {entry['file']!r}", line=_line(entry, "file") or ln)
        for key in ("omega", "force_amplitude", "amplitude", "frequency_hz"):
            if key in entry:
                entry[key] = _number(entry[key], yml, f"records[{i}].{key}", _line(entry, key) or ln, 0.0, strict=True,
                                 unit={"omega": "rad/s", "frequency_hz": "Hz"}.get(key, ""))
        if entry.get("role") not in (None, "train", "test"):
            raise _err(yml, f"records[{i}].role must be 'train' or 'test', got {entry['role']!r}", line=_line(entry, "role") or ln)
        if entry.get("kind") not in (None, *REQUIRED):
            raise _err(yml, f"records[{i}].kind must be one of {list(REQUIRED)}, got {entry['kind']!r}",
                       line=_line(entry, "kind") or ln)
        records.append(read_record(path / entry["file"], level, _plain_data(entry), log=log))
    roles = [r.role for r in records if r.kind != "frc"]
    if any(roles) and "test" not in roles:
        raise _err(yml, "every record has role 'train': mark at least one record 'role: test' (held out), or give "
                        "no roles (records are then held out automatically)", line=_line(raw, "records"))
    if roles and all(r == "test" for r in roles):
        raise _err(yml, "every record has role 'test': at least one record must be for training",
                   line=_line(raw, "records"))
    from .acquisition import check_records, correct_frc, parse_acquisition

    acq = parse_acquisition(raw.get("acquisition"), yml, level)
    check_records(acq, records, yml)
    correct_frc(records, acq)
    return Dataset(path=path, level=level, nominal=nominal, records=records,
                   description=str(raw.get("description", "")), raw=_plain_data(raw), acquisition=acq)


def normalise_nominal(nom: dict, level: str, file) -> dict:
    """Link: {stiffness, damping, friction_force, friction_slope, inertance} (missing = 0, slope 1e3),
    each within the physics registry's bounds (k, c, df, I >= 0; s > 0).
    System: {"base": BaseParams kwargs, "tmd": TMDParams kwargs} (validated by the physics classes)."""
    from ..physics import registry
    from ..physics.params import BaseParams, ParameterError, TMDParams, field_names

    if "nominal" in nom and isinstance(nom["nominal"], dict):
        nom = nom["nominal"]
    ln = lambda node, k: _line(node, k) or _line(nom, k)  # noqa: E731
    if level == "link":
        if "link" in nom and set(nom) - {"link", "base", "tmd"}:
            extra = sorted(map(str, set(nom) - {"link", "base", "tmd"}))
            raise _err(file, f"nominal: unknown key(s) {extra} beside 'link'; allowed keys: ['link'] (or the link "
                             f"parameters {list(LINK_NOMINAL)} directly)", line=_line(nom, extra[0]))
        src = nom.get("link", nom)
        if "tmd" in nom and "link" not in nom:  # a scenario: its TMD link is the device
            try:
                t = TMDParams(**nom["tmd"], source=str(file))
            except (ParameterError, TypeError) as e:
                raise _err(file, f"nominal model: {e}", line=_line(nom, "tmd")) from None
            src = {"stiffness": t.stiffness, "damping": t.damping, "friction_force": t.friction_force,
                   "friction_slope": t.friction_slope, "inertance": t.inertance}
        if not isinstance(src, dict):
            raise _err(file, "nominal.link must be a mapping of the link parameters", line=_line(nom, "link"))
        unknown = set(src) - set(LINK_NOMINAL)
        if unknown:
            raise _err(file, f"unknown nominal link parameter(s) {sorted(map(str, unknown))}; known: {list(LINK_NOMINAL)}",
                       line=ln(src, sorted(map(str, unknown))[0]))
        out = {}
        for k in LINK_NOMINAL:
            par = registry.get("tmd", k)
            out[k] = _number(src.get(k, 1e3 if k == "friction_slope" else 0.0), file, f"nominal.{k}", ln(src, k),
                             par.minimum, par.strict, par.unit)
        return out
    extra = [k for k in nom if k not in ("base", "tmd")]
    if "base" not in nom or "tmd" not in nom:
        raise _err(file, "a system-level nominal model needs 'base' and 'tmd' mappings", line=_line(nom, "base"))
    if extra:
        raise _err(file, f"nominal: unknown key(s) {[str(k) for k in extra]}; allowed keys: ['base', 'tmd']",
                   line=_line(nom, extra[0]))
    for part, cls in (("base", BaseParams), ("tmd", TMDParams)):
        node = nom[part]
        if not isinstance(node, dict):
            raise _err(file, f"nominal.{part} must be a mapping, got {node!r}", line=_line(nom, part))
        allowed = [f for f in field_names(cls) if f != "source"]
        bad = [k for k in node if k not in allowed]
        if bad:
            raise _err(file, f"nominal.{part}: unknown key(s) {[str(k) for k in bad]}; allowed keys: {allowed}",
                       line=ln(node, bad[0]))
        try:
            cls(**node, source=str(file))
        except (ParameterError, TypeError) as e:
            msg = str(e).replace(f" (from {file})", "")
            raise _err(file, f"nominal model: {part}: {msg}", line=_line(nom, part)) from None
    return {"base": _plain_data(nom["base"]), "tmd": _plain_data(nom["tmd"])}


def write_record(file: Path, columns: dict, header_comment: str | None = None, fmt="%.9g"):
    """Write a record as CSV (the format read_record accepts)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[c], dtype=float) for c in names])
    with open(file, "w") as f:
        if header_comment:
            for line in header_comment.splitlines():
                f.write(f"# {line}\n")
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt=fmt)
