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


class DataError(ValueError):
    """Bad measured data; the message names the file, row and column."""


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


def _err(file, msg, row=None, column=None):
    where = str(file)
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


def read_record(file: Path, level: str, entry: dict | None = None) -> Record:
    """Read and validate one CSV record."""
    entry = entry or {}
    file = Path(file)
    if not file.is_file():
        raise _err(file, "file not found")
    try:
        df = pd.read_csv(file, comment="#", skipinitialspace=True)
    except Exception as e:  # pragma: no cover - pandas parser errors
        raise _err(file, f"cannot be read as CSV: {e}") from None
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
    if len(df) < 3:
        raise _err(file, f"needs at least 3 data rows, has {len(df)}")
    cols = {}
    for c in REQUIRED[kind] + OPTIONAL[kind]:
        if c not in df.columns:
            continue
        if c == "direction":
            vals = df[c].astype(str).str.strip().str.lower().to_numpy()
            bad = np.nonzero(~np.isin(vals, ["up", "down"]))[0]
            if bad.size:
                raise _err(file, f"direction must be 'up' or 'down', got {df[c].iloc[bad[0]]!r}",
                           row=int(bad[0]) + 1, column=c)
            cols[c] = vals
            continue
        num = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.nonzero(~np.isfinite(num))[0]
        if bad.size:
            raw = df[c].iloc[bad[0]]
            raise _err(file, f"value {raw!r} is not a finite number ({bad.size} bad value(s) in this column)",
                       row=int(bad[0]) + 1, column=c)
        cols[c] = num
    if "t" in cols:
        dt = np.diff(cols["t"])
        bad = np.nonzero(dt <= 0)[0]
        if bad.size:
            r = int(bad[0]) + 2
            raise _err(file, f"time must be strictly increasing: t = {cols['t'][r - 1]!r} after "
                             f"{cols['t'][r - 2]!r}", row=r, column="t")
    if kind == "frc":
        bad = np.nonzero(cols["omega"] <= 0)[0]
        if bad.size:
            raise _err(file, "omega must be > 0 rad/s", row=int(bad[0]) + 1, column="omega")
    omega = entry.get("omega")
    if omega is None and entry.get("frequency_hz") is not None:
        omega = 2 * math.pi * float(entry["frequency_hz"])
    amp = entry.get("force_amplitude", entry.get("amplitude"))
    rec = Record(name=file.name, kind=kind, columns=cols, omega=None if omega is None else float(omega),
                 amplitude=None if amp is None else float(amp), role=entry.get("role"),
                 meta={k: v for k, v in entry.items() if k not in ("file",)})
    if kind in ("link", "time") and rec.omega is None:
        rec.omega = estimate_omega(cols["t"], cols["displacement"] if kind == "link" else cols["force"])
        rec.meta["omega_estimated"] = True
        if rec.omega is None:
            rec.meta["periodic"] = False
    if rec.omega is not None and not rec.omega > 0:
        raise _err(file, f"omega must be > 0 rad/s, got {rec.omega!r}")
    if kind == "link" and rec.amplitude is None:
        d = cols["displacement"]
        rec.amplitude = 0.5 * float(np.percentile(d, 99.5) - np.percentile(d, 0.5))
    return rec


def estimate_omega(t, d) -> float | None:
    """Dominant angular frequency [rad/s] > 0 of a sampled signal, or None when it is not periodic
    (see :func:`harmonic.estimate_omega`)."""
    from .harmonic import estimate_omega as _est

    return _est(t, d)


def _number(v, file, key):
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise _err(file, f"'{key}' must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise _err(file, f"'{key}' must be finite, got {v!r}")
    return x


def load_dataset(path, model_override: dict | None = None) -> Dataset:
    """Load and validate ``path/dataset.yaml`` and its records."""
    path = Path(path)
    yml = path if path.suffix in (".yaml", ".yml") else path / "dataset.yaml"
    path = yml.parent
    if not yml.is_file():
        raise _err(yml, "file not found (a dataset is a folder with dataset.yaml and CSV files)")
    try:
        raw = yaml.safe_load(yml.read_text()) or {}
    except yaml.YAMLError as e:
        raise _err(yml, f"invalid YAML: {e}") from None
    if not isinstance(raw, dict):
        raise _err(yml, "must be a mapping with keys level, nominal, records")
    level = raw.get("level", "system")
    if level not in ("link", "system"):
        raise _err(yml, f"'level' must be 'link' or 'system', got {level!r}")
    nominal = model_override if model_override is not None else raw.get("nominal")
    if not isinstance(nominal, dict):
        raise _err(yml, "'nominal' (the model parameters) is missing or not a mapping")
    nominal = normalise_nominal(nominal, level, yml)
    entries = raw.get("records")
    if not isinstance(entries, list) or not entries:
        raise _err(yml, "'records' must be a non-empty list of {file: ..., ...}")
    records = []
    for i, e in enumerate(entries):
        if isinstance(e, str):
            e = {"file": e}
        if not isinstance(e, dict) or "file" not in e:
            raise _err(yml, f"records[{i}] needs a 'file' key")
        for key in ("omega", "force_amplitude", "amplitude", "frequency_hz"):
            if key in e:
                e[key] = _number(e[key], yml, f"records[{i}].{key}")
        if e.get("role") not in (None, "train", "test"):
            raise _err(yml, f"records[{i}].role must be 'train' or 'test', got {e['role']!r}")
        records.append(read_record(path / e["file"], level, e))
    from .acquisition import check_records, correct_frc, parse_acquisition

    acq = parse_acquisition(raw.get("acquisition"), yml, level)
    check_records(acq, records, yml)
    correct_frc(records, acq)
    return Dataset(path=path, level=level, nominal=nominal, records=records,
                   description=str(raw.get("description", "")), raw=raw, acquisition=acq)


def normalise_nominal(nom: dict, level: str, file) -> dict:
    """Link: {stiffness, damping, friction_force, friction_slope, inertance} (missing = 0, slope 1e3).
    System: {"base": BaseParams kwargs, "tmd": TMDParams kwargs} (validated by the physics classes)."""
    from ..physics.params import BaseParams, ParameterError, TMDParams

    if "nominal" in nom and isinstance(nom["nominal"], dict):
        nom = nom["nominal"]
    if level == "link":
        src = nom.get("link", nom)
        if "tmd" in nom and "link" not in nom:  # a scenario: its TMD link is the device
            try:
                t = TMDParams(**nom["tmd"], source=str(file))
            except (ParameterError, TypeError) as e:
                raise _err(file, f"nominal model: {e}") from None
            src = {"stiffness": t.stiffness, "damping": t.damping, "friction_force": t.friction_force,
                   "friction_slope": t.friction_slope, "inertance": t.inertance}
        out = {}
        for k in LINK_NOMINAL:
            out[k] = _number(src.get(k, 1e3 if k == "friction_slope" else 0.0), file, f"nominal.{k}")
        unknown = set(src) - set(LINK_NOMINAL)
        if unknown:
            raise _err(file, f"unknown nominal link parameter(s) {sorted(unknown)}; known: {list(LINK_NOMINAL)}")
        return out
    nom = {"base": nom.get("base"), "tmd": nom.get("tmd")} if "base" in nom and "tmd" in nom else nom
    if "base" not in nom or "tmd" not in nom:
        raise _err(file, "a system-level nominal model needs 'base' and 'tmd' mappings")
    try:
        BaseParams(**nom["base"], source=str(file))
        TMDParams(**nom["tmd"], source=str(file))
    except (ParameterError, TypeError) as e:
        raise _err(file, f"nominal model: {e}") from None
    return {"base": dict(nom["base"]), "tmd": dict(nom["tmd"])}


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
