"""Read and validate scenario YAML files (schema version 1, documented in docs/scenarios.md).

Every problem raises :class:`ScenarioError` whose message names the file, the line (where known),
the key path (``tmd.friction_force``, ``studies[2].values[3]``) and the offending value. Physical
checks are left to the parameter dataclasses of :mod:`pyfmu_wrapper.physics.params`, which are
given ``source="file.yaml:LINE key.path"``.
"""
from __future__ import annotations

import math
import os
import re
from typing import Any

import numpy as np
import yaml

from ..physics.params import CASES, BaseParams, InerterModel, ParameterError, TMDParams, field_names
from ..solvers import settings_table as _settings
from ..solvers.steady import SettingsError
from .schema import (
    COSIM_KEYS,
    DIRECTIONS,
    LINEAR_METHODS,
    MAP_PARAMETERS,
    READ_VERSIONS,
    SCHEMA_VERSION,
    STUDY_KINDS,
    CosimConfig,
    Curve,
    FRCStudy,
    MapStudy,
    PhasePortraitStudy,
    Scenario,
    ScenarioError,
    SolverConfig,
    SweepConfig,
)
from .yamlio import MarkedDict, MarkedList, load_marked

TMD_FIELDS = tuple(field_names(TMDParams))
TMD_KEYS = ("case", "inertance_ratio") + TMD_FIELDS
BASE_FIELDS = tuple(field_names(BaseParams))
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
MAX_GRID = 100_000


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


class _Reader:
    """Validation context: the file name and helpers that raise located errors."""

    def __init__(self, file: str):
        self.file = file

    # -- errors ---------------------------------------------------------------------------------
    def fail(self, path: str, line, reason: str, value=None, *, show_value=True):
        where = f"{self.file}:{line}" if line else self.file
        got = f" (got {value!r})" if show_value else ""
        raise ScenarioError(f"{where}: {path or '<top level>'}: {reason}{got}",
                            file=self.file, line=line, path=path, value=value)

    def parameter_error(self, exc: ParameterError, path: str, line, value):
        """Re-raise a ParameterError built with ``source=self.source(path, line)`` as a ScenarioError."""
        text = str(exc).replace(f" (from {self.source(path, line)})", "")
        where = f"{self.file}:{line}" if line else self.file
        raise ScenarioError(f"{where}: {path}: {text}", file=self.file, line=line, path=path, value=value) from None

    def source(self, path: str, line) -> str:
        return f"{self.file}:{line} {path}" if line else f"{self.file} {path}"

    # -- structure ------------------------------------------------------------------------------
    def mapping(self, node, path, line, *, required=(), optional=(), hints=None):
        """Check a mapping's keys; ``hints``: key -> where it belongs instead (a clearer refusal)."""
        if not isinstance(node, dict):
            self.fail(path, line, f"must be a mapping with keys {list(required) + list(optional)}", node)
        allowed = set(required) | set(optional)
        for key in node:
            if key not in allowed:
                hint = (hints or {}).get(key)
                reason = (f"does not apply here: {hint}" if hint else
                          f"unknown key {key!r}; allowed keys: {sorted(map(str, allowed))}")
                self.fail(_join(path, key), _line(node, key), reason, node[key])
        for key in required:
            if key not in node:
                self.fail(_join(path, key), _line(node), "missing required key", show_value=False)
        return node

    def sequence(self, node, path, line, *, nonempty=True):
        if not isinstance(node, list):
            self.fail(path, line, "must be a list", node)
        if nonempty and not node:
            self.fail(path, line, "must not be empty", node)
        return node

    # -- scalars ------------------------------------------------------------------------------
    def number(self, node, key, path, *, minimum=None, strict=False, maximum=None, default=None):
        p = _join(path, key)
        if key not in node:
            return default
        v, line = node[key], _line(node, key)
        return self.check_number(v, p, line, minimum=minimum, strict=strict, maximum=maximum)

    def check_number(self, v, p, line, *, minimum=None, strict=False, maximum=None):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(p, line, "must be a number", v)
        if not math.isfinite(v):
            self.fail(p, line, "must be finite", v)
        if minimum is not None and (v <= minimum if strict else v < minimum):
            self.fail(p, line, f"must be {'>' if strict else '>='} {minimum:g}", v)
        if maximum is not None and v > maximum:
            self.fail(p, line, f"must be <= {maximum:g}", v)
        return float(v)

    def integer(self, node, key, path, *, minimum=None, maximum=None, default=None, allow_null=False):
        p = _join(path, key)
        if key not in node:
            return default
        v, line = node[key], _line(node, key)
        if v is None and allow_null:
            return None
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(p, line, "must be an integer" + (" or null" if allow_null else ""), v)
        if minimum is not None and v < minimum:
            self.fail(p, line, f"must be >= {minimum}", v)
        if maximum is not None and v > maximum:
            self.fail(p, line, f"must be <= {maximum}", v)
        return int(v)

    def string(self, node, key, path, *, default=None, choices=None, pattern=None):
        p = _join(path, key)
        if key not in node:
            return default
        v, line = node[key], _line(node, key)
        if not isinstance(v, str):
            self.fail(p, line, "must be a string", v)
        if choices is not None and v not in choices:
            self.fail(p, line, f"must be one of {list(choices)}", v)
        if pattern is not None and not pattern.match(v):
            self.fail(p, line, "must be a simple name (letters, digits, '_', '-', '.')", v)
        return v

    def boolean(self, node, key, path, *, default=False):
        if key not in node:
            return default
        v = node[key]
        if not isinstance(v, bool):
            self.fail(_join(path, key), _line(node, key), "must be true or false", v)
        return v

    # -- grids ----------------------------------------------------------------------------------
    def grid(self, node, path, line, *, positive=False):
        """{start, stop, count} (evenly spaced, both ends included) or an explicit list of numbers."""
        minimum = 0.0 if positive else None
        if isinstance(node, list):
            self.sequence(node, path, line)
            vals = [self.check_number(v, _join(path, i), _line(node, i), minimum=minimum, strict=positive)
                    for i, v in enumerate(node)]
            return np.array(vals)
        self.mapping(node, path, line, required=("start", "stop", "count"))
        start = self.number(node, "start", path, minimum=minimum, strict=positive)
        stop = self.number(node, "stop", path, minimum=minimum, strict=positive)
        count = self.integer(node, "count", path, minimum=1, maximum=MAX_GRID)
        if stop < start:
            self.fail(_join(path, "stop"), _line(node, "stop"), f"must be >= start = {start:g}", stop)
        if count == 1 and stop != start:
            self.fail(_join(path, "count"), _line(node, "count"), "must be >= 2 when stop != start", count)
        return np.linspace(start, stop, count)


def _line(node, key=None):
    if key is not None and isinstance(node, (MarkedDict, MarkedList)):
        return node.line_of(key)
    return getattr(node, "line", None)


# --- TMD specifications ------------------------------------------------------------------------

class _TMDSpec:
    """A TMD block merged over its parent (scenario tmd <- study tmd <- curve tmd <- map value),
    remembering for every key where it was set (key path, line)."""

    def __init__(self, values=None, origin=None):
        self.values = dict(values or {})
        self.origin = dict(origin or {})

    def over(self, rd: _Reader, node, path, line) -> _TMDSpec:
        rd.mapping(node, path, line, optional=TMD_KEYS)
        new = _TMDSpec(self.values, self.origin)
        # a new case / ratio / explicit inertia split replaces the inherited one
        if "case" in node or "inertance_ratio" in node:
            for k in ("mass", "inertance", "case", "inertance_ratio"):
                new.values.pop(k, None)
            if "inerter" not in node and str(new.values.get("inerter", "")).lower() == "none":
                new.values.pop("inerter")  # a paper case has an inerter: back to the default, ideal
        if "mass" in node or "inertance" in node:
            new.values.pop("inertance_ratio", None)
        for key, v in node.items():
            p, ln = _join(path, key), _line(node, key)
            new.set(rd, key, v, p, ln)
        return new

    def set(self, rd: _Reader, key, v, p, line):
        if key == "case":
            if isinstance(v, bool) or v not in CASES:
                rd.fail(p, line, f"must be one of {sorted(CASES)} (the paper's Cases)", v)
        elif key == "inerter":
            if not isinstance(v, str) or v.upper() not in InerterModel.__members__:
                rd.fail(p, line, f"must be one of {[m.name.lower() for m in InerterModel]}", v)
        elif key == "inertance_ratio":
            rd.check_number(v, p, line, minimum=0.0, maximum=1.0)
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                rd.fail(p, line, "must be a number", v)
        self.values[key] = v
        self.origin[key] = (p, line)

    def build(self, rd: _Reader, path, line) -> TMDParams:
        """Resolve into TMDParams: defaults <- case <- explicit fields <- inertance_ratio."""
        v = self.values
        kw: dict[str, Any] = {}
        if "case" in v:
            kw.update(CASES[v["case"]])
        kw.update({k: v[k] for k in TMD_FIELDS if k in v})
        if "inertance_ratio" in v:
            r = float(v["inertance_ratio"])
            total = kw.get("mass", TMDParams.mass) + kw.get("inertance", TMDParams.inertance)
            kw["inertance"] = r * total
            kw["mass"] = total - kw["inertance"]
            if str(kw.get("inerter", "ideal")).lower() in ("none", "ideal"):
                kw["inerter"] = "none" if r == 0.0 else "ideal"  # Iratio = 0: there is no inerter
        try:
            return TMDParams(**kw)
        except ParameterError as exc:
            key = _blamed_key(str(exc), self.origin)
            p, ln = self.origin.get(key, (path, line))
            try:
                TMDParams(**kw, source=rd.source(p, ln))
            except ParameterError as located:
                rd.parameter_error(located, p, ln, v.get(key))
            raise  # pragma: no cover - the same values cannot pass the second time


def _blamed_key(message: str, origin: dict):
    """The scenario key to blame for a ParameterError (its message starts with the field name)."""
    first = message.split()[0] if message else ""
    if first in origin:
        return first
    if first in ("mass", "inertance", "inerter"):
        for key in ("inertance_ratio", "case", "inertance", "mass", "inerter"):
            if key in origin:
                return key
    return first


def _detached(tmd: TMDParams) -> TMDParams:
    """The TMD detached from the base (no links): the base responds alone."""
    return TMDParams(mass=tmd.mass if tmd.mass > 0 else 1.0, stiffness=0.0, damping=0.0, friction_force=0.0,
                     inertance=0.0, inerter="none", play_gap=0.0)


# --- the document ------------------------------------------------------------------------------

def load_scenario(path) -> Scenario:
    """Read, validate and resolve a scenario file. Raises ScenarioError on any problem."""
    path = os.fspath(path)
    file = path
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise ScenarioError(f"{file}: cannot read scenario file: {exc.strerror or exc}", file=file) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:  # name the line and byte, not a traceback
        from ..cli.errors import bad_bytes_message

        raise ScenarioError(bad_bytes_message(file, data, exc), file=file,
                            line=data.count(b"\n", 0, exc.start) + 1) from None
    return parse_scenario(text, file)


def parse_scenario(text: str, file: str = "<string>") -> Scenario:
    rd = _Reader(file)
    try:
        doc = load_marked(text, name=file)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        line = mark.line + 1 if mark is not None else None
        where = f"{file}:{line}" if line else file
        msg = " ".join(str(exc).split())
        raise ScenarioError(f"{where}: not valid YAML for a scenario (safe loader): {msg}", file=file,
                            line=line) from None
    if doc is None:
        rd.fail("", None, "the file is empty", show_value=False)
    rd.mapping(doc, "", 1, required=("schema_version", "name", "base", "tmd", "frequencies", "studies"),
               optional=("description", "sweep", "solver", "cosim"))
    version = doc["schema_version"]
    if isinstance(version, bool) or version not in READ_VERSIONS:
        rd.fail("schema_version", _line(doc, "schema_version"), f"unsupported schema version; this "
                f"program reads schema_version {SCHEMA_VERSION}", version)
    if version != SCHEMA_VERSION:
        for key in ("solver", "sweep", "cosim"):  # schema 1 had one solver block read by both engines
            if key in doc:
                rd.fail(key, _line(doc, key), f"a schema_version {version} file cannot have a {key!r} block: in "
                        f"schema 1 'solver:' meant different things to the two engines; write schema_version "
                        f"{SCHEMA_VERSION} with 'sweep:' (direction, continuation), 'solver:' (monolithic engine) "
                        "and 'cosim:' (co-simulation engine), see docs/scenarios.md", doc[key])
    name = rd.string(doc, "name", "", pattern=_NAME_RE)
    description = rd.string(doc, "description", "", default="")

    b = rd.mapping(doc["base"], "base", _line(doc, "base"), required=BASE_FIELDS)
    for key in BASE_FIELDS:
        rd.number(b, key, "base")
    try:
        base = BaseParams(**{k: b[k] for k in BASE_FIELDS})
    except ParameterError:
        key = next(k for k in BASE_FIELDS if _base_fails(b, k))
        p, ln = f"base.{key}", _line(b, key)
        try:
            BaseParams(**{k: b[k] for k in BASE_FIELDS}, source=rd.source(p, ln))
        except ParameterError as exc:
            rd.parameter_error(exc, p, ln, b[key])

    top = _TMDSpec().over(rd, doc["tmd"], "tmd", _line(doc, "tmd"))
    tmd = top.build(rd, "tmd", _line(doc, "tmd"))
    omegas = rd.grid(doc["frequencies"], "frequencies", _line(doc, "frequencies"), positive=True)
    sweep = _sweep(rd, doc.get("sweep", {}), _line(doc, "sweep"))
    solver = _solver(rd, doc.get("solver", {}), _line(doc, "solver"))
    cosim = _cosim(rd, doc.get("cosim", {}), _line(doc, "cosim"))

    studies_node = rd.sequence(doc["studies"], "studies", _line(doc, "studies"))
    studies, names = [], set()
    for i, st in enumerate(studies_node):
        s = _study(rd, st, f"studies[{i}]", _line(studies_node, i), top, omegas)
        if s.name in names:
            rd.fail(f"studies[{i}].name", _line(st, "name"), "duplicate study name", s.name)
        names.add(s.name)
        studies.append(s)
    return Scenario(path=file, name=name, description=description, schema_version=version, base=base, tmd=tmd,
                    frequencies=omegas, solver=solver, studies=tuple(studies), sweep=sweep, cosim=cosim,
                    raw=_plain(doc))


def _base_fails(b, key) -> bool:
    try:
        BaseParams(**{key: b[key]})
        return False
    except ParameterError:
        return True


_SWEEP_KEYS = ("direction", "continuation")
#: the solver: block's settings (rows of solvers/settings_table.py read by the monolithic engine's block)
_SOLVER_SETTINGS = tuple(s.name for s in _settings.SETTINGS if _settings.MONO in s.blocks)
_SOLVER_KEYS = _SOLVER_SETTINGS + ("linear",)
_TO_SWEEP = {k: f"shared by both engines: write it as sweep.{k}" for k in _SWEEP_KEYS}
_TO_COSIM = {k: f"a co-simulation setting: write it under cosim: (cosim.{k})"
             for k in COSIM_KEYS if k not in _SOLVER_KEYS}
_TO_SOLVER = {k: f"a monolithic-engine setting: write it under solver: (solver.{k})"
              for k in _SOLVER_KEYS if k not in COSIM_KEYS}


def _sweep(rd: _Reader, node, line) -> SweepConfig:
    rd.mapping(node, "sweep", line, optional=_SWEEP_KEYS,
               hints={**_TO_COSIM, **_TO_SOLVER})
    d = SweepConfig()
    return SweepConfig(direction=rd.string(node, "direction", "sweep", choices=DIRECTIONS, default=d.direction),
                       continuation=rd.boolean(node, "continuation", "sweep", default=d.continuation))


def _solver(rd: _Reader, node, line) -> SolverConfig:
    rd.mapping(node, "solver", line, optional=_SOLVER_KEYS, hints={**_TO_SWEEP, **_TO_COSIM})
    d = SolverConfig()
    values = {k: _setting(rd, node, k, "solver") if k in node else getattr(d, k) for k in _SOLVER_SETTINGS}
    cfg = SolverConfig(**values, linear=rd.string(node, "linear", "solver", choices=LINEAR_METHODS, default=d.linear))
    _check_settings(rd, "solver", node, line, cfg.settings)
    return cfg


def _cosim(rd: _Reader, node, line) -> CosimConfig:
    rd.mapping(node, "cosim", line, optional=COSIM_KEYS, hints={**_TO_SWEEP, **_TO_SOLVER})
    overrides = tuple((k, _setting(rd, node, k, "cosim")) for k in node)
    cfg = CosimConfig(overrides)
    _check_settings(rd, "cosim", node, line, cfg.settings)
    return cfg


def _setting(rd: _Reader, node, key: str, block: str):
    """The value of setting ``key`` of a solver: / cosim: block, checked against its one rule (its
    row of :data:`pyfmu_wrapper.solvers.settings_table.SETTINGS`, which the engines' settings
    classes apply too); a float for a number, an int for an integer."""
    s = _settings.BY_NAME[key]
    v = node[key]
    why = s.problem(v)
    if why is not None:
        rd.fail(_join(block, key), _line(node, key), why, v)
    if v is None:
        return None
    return float(v) if s.kind == "number" else int(v) if s.kind == "integer" else v


def _check_settings(rd: _Reader, block: str, node, line, make):
    """Build the engine's settings of a block: a value the settings refuse (their validation,
    :class:`~pyfmu_wrapper.solvers.steady.SteadySettings`, the one place of the range rules)
    becomes a ScenarioError naming ``block.field`` and its line."""
    try:
        make()
    except SettingsError as exc:
        rd.fail(f"{block}.{exc.field}", _line(node, exc.field) or line, exc.reason, exc.value)


_COMMON = ("kind", "name", "title", "tmd", "frequencies")
_KIND_KEYS = {
    "frc": (("curves",), ()),
    "map": (("parameter", "values"), ()),
    "phase_portrait": (("omegas", "curves"), ("n_periods", "samples_per_period")),
}


def _study(rd: _Reader, node, path, line, top: _TMDSpec, omegas):
    if not isinstance(node, dict):
        rd.fail(path, line, "must be a mapping (a study)", node)
    if "kind" not in node:
        rd.fail(_join(path, "kind"), _line(node), f"missing required key (one of {list(STUDY_KINDS)})",
                show_value=False)
    kind = rd.string(node, "kind", path, choices=STUDY_KINDS)
    req, opt = _KIND_KEYS[kind]
    rd.mapping(node, path, line, required=("kind", "name") + req, optional=_COMMON[2:] + opt)
    name = rd.string(node, "name", path, pattern=_NAME_RE)
    title = rd.string(node, "title", path, default=name)
    spec = top.over(rd, node["tmd"], _join(path, "tmd"), _line(node, "tmd")) if "tmd" in node else top
    if "frequencies" in node:
        omegas = rd.grid(node["frequencies"], _join(path, "frequencies"), _line(node, "frequencies"), positive=True)
    if kind == "frc":
        curves = _curves(rd, node["curves"], _join(path, "curves"), _line(node, "curves"), spec)
        return FRCStudy(name=name, title=title, omegas=omegas, curves=curves)
    if kind == "phase_portrait":
        wp = _join(path, "omegas")
        w = rd.grid(node["omegas"], wp, _line(node, "omegas"), positive=True)
        curves = _curves(rd, node["curves"], _join(path, "curves"), _line(node, "curves"), spec)
        n = rd.integer(node, "n_periods", path, minimum=1, maximum=1000, default=1)
        sp = rd.integer(node, "samples_per_period", path, minimum=8, maximum=100_000, default=400)
        return PhasePortraitStudy(name=name, title=title, omegas=tuple(float(x) for x in w), curves=curves,
                                  n_periods=n, samples_per_period=sp)
    # map
    param = rd.string(node, "parameter", path, choices=MAP_PARAMETERS)
    vnode, vpath, vline = node["values"], _join(path, "values"), _line(node, "values")
    values = rd.grid(vnode, vpath, vline)
    tmds = []
    for j, val in enumerate(values):
        if isinstance(vnode, list):
            p, ln = _join(vpath, j), _line(vnode, j)
        else:
            p, ln = f"{vpath}[{j}]", vline
        s = _TMDSpec(spec.values, spec.origin)
        if param == "inertance_ratio":
            for k in ("mass", "inertance", "case", "inertance_ratio"):
                s.values.pop(k, None)
            total = spec.build(rd, vpath, vline).inertia
            s.set(rd, "mass", total, p, ln)
            s.set(rd, "inertance", 0.0, p, ln)
        s.set(rd, param, float(val), p, ln)
        tmds.append(s.build(rd, p, ln))
    return MapStudy(name=name, title=title, parameter=param, values=values, omegas=omegas, tmds=tuple(tmds))


def _curves(rd: _Reader, node, path, line, spec: _TMDSpec) -> tuple[Curve, ...]:
    rd.sequence(node, path, line)
    out, labels = [], set()
    for i, c in enumerate(node):
        p, ln = _join(path, i), _line(node, i)
        rd.mapping(c, p, ln, required=("label",), optional=("tmd", "without_tmd"))
        label = rd.string(c, "label", p)
        if label in labels:
            rd.fail(_join(p, "label"), _line(c, "label"), "duplicate curve label", label)
        labels.add(label)
        without = rd.boolean(c, "without_tmd", p)
        if without and "tmd" in c:
            rd.fail(_join(p, "tmd"), _line(c, "tmd"), "a curve with without_tmd: true takes no tmd block", c["tmd"])
        s = spec.over(rd, c["tmd"], _join(p, "tmd"), _line(c, "tmd")) if "tmd" in c else spec
        tmd = s.build(rd, p, ln)
        out.append(Curve(label=label, tmd=_detached(tmd) if without else tmd, without_tmd=without))
    return tuple(out)


def _plain(obj):
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj
