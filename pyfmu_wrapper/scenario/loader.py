"""Read and validate scenario YAML files (schema version 2, :data:`~.schema.SCHEMA_VERSION`; version 1 files are
still read, see :data:`~.schema.READ_VERSIONS`; documented in docs/scenarios.md).

Every problem raises :class:`ScenarioError` whose message names the file, the line (where known),
the key path (``tmd.friction_force``, ``studies[2].values[3]``) and the offending value. Physical
checks are left to the parameter dataclasses of :mod:`pyfmu_wrapper.physics.params`, which are
given ``source="file.yaml:LINE key.path"``. The located checks are :class:`~.reader.Reader`'s, the TMD
blocks' merging :class:`~.tmdspec.TMDSpec`'s; this module reads the document: base, sweep, solver and
co-simulation settings, studies.
"""

from __future__ import annotations

import os
import re
from typing import TYPE_CHECKING, Any

import yaml

from ..inputs.reader import Reader, key_path, line_of
from ..inputs.yamlio import load_marked
from ..physics.params import TMDParams
from ..physics.unit import ModelUnit
from ..solvers import settings_table as _settings
from ..solvers.steady import SettingsError
from .framespec import attached
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
from .structspec import block_units, over_block, read_structure
from .tmdspec import TMDSpec, detached_tmd

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

    from numpy import ndarray

    from ..inputs.yamlio import MarkedDict, MarkedList
    from .schema import FRCStudy, MapStudy, PhasePortraitStudy

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


# --- the document ------------------------------------------------------------------------------


def load_scenario(path: str | Path) -> Scenario:
    """Read, validate and resolve a scenario file. Raises ScenarioError on any problem."""
    path = os.fspath(path)
    file = path
    from ..errors import read_bytes_limited

    try:
        data = read_bytes_limited(path, ScenarioError, what="scenario file")
    except OSError as exc:
        raise ScenarioError(f"{file}: cannot read scenario file: {exc.strerror or exc}", file=file) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:  # name the line and byte, not a traceback
        from ..errors import bad_bytes_message

        raise ScenarioError(
            bad_bytes_message(file, data, exc), file=file, line=data.count(b"\n", 0, exc.start) + 1
        ) from None
    return parse_scenario(text, file)


def parse_scenario(text: str, file: str = "<string>") -> Scenario:
    rd = Reader(file)
    try:
        doc = load_marked(text, name=file)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        line = mark.line + 1 if mark is not None else None
        where = f"{file}:{line}" if line else file
        msg = " ".join(str(exc).split())
        raise ScenarioError(
            f"{where}: not valid YAML for a scenario (safe loader): {msg}", file=file, line=line
        ) from None
    if doc is None:
        rd.fail("", None, "the file is empty", show_value=False)
    rd.mapping(
        doc,
        "",
        1,
        required=("schema_version", "name", "frequencies", "studies"),
        optional=("description", "sweep", "solver", "cosim", "plot", "tmd", *block_units()),
    )
    blocks = [k for k in block_units() if k in doc]
    if len(blocks) != 1:
        rd.fail(
            "",
            1,
            "needs exactly one primary structure, the block of a registered model: "
            + ", ".join(f"{k}: ({u.description})" for k, u in block_units().items()),
            show_value=False,
        )
    block = blocks[0]
    unit = block_units()[block]
    version = doc["schema_version"]
    if isinstance(version, bool) or version not in READ_VERSIONS:
        rd.fail(
            "schema_version",
            line_of(doc, "schema_version"),
            f"unsupported schema version; this program reads schema_version {SCHEMA_VERSION}",
            version,
        )
    if version != SCHEMA_VERSION:
        for key in ("solver", "sweep", "cosim"):  # schema 1 had one solver block read by both engines
            if key in doc:
                rd.fail(
                    key,
                    line_of(doc, key),
                    f"a schema_version {version} file cannot have a {key!r} block: in "
                    f"schema 1 'solver:' meant different things to the two engines; write schema_version "
                    f"{SCHEMA_VERSION} with 'sweep:' (direction, continuation), 'solver:' (monolithic engine) "
                    "and 'cosim:' (co-simulation engine), see docs/scenarios.md",
                    doc[key],
                )
    name = rd.string(doc, "name", "", pattern=_NAME_RE)
    description = rd.string(doc, "description", "", default="")

    base: Any = read_structure(rd, unit, doc[block], block, line_of(doc, block))
    _check_tmd_block(rd, doc, "", 1, unit, block, top_level=True)
    top = TMDSpec().over(rd, doc["tmd"], "tmd", line_of(doc, "tmd")) if unit.takes_tmd else TMDSpec()
    tmd = top.build(rd, "tmd", line_of(doc, "tmd")) if unit.takes_tmd else detached_tmd(TMDParams())
    base = attached(rd, base, top, "tmd", line_of(doc, "tmd"))
    omegas = rd.grid(doc["frequencies"], "frequencies", line_of(doc, "frequencies"), positive=True)
    sweep = _sweep(rd, doc.get("sweep", {}), line_of(doc, "sweep"))
    solver = _solver(rd, doc.get("solver", {}), line_of(doc, "solver"))
    cosim = _cosim(rd, doc.get("cosim", {}), line_of(doc, "cosim"))
    yscale = _plot(rd, doc.get("plot", {}), "plot", line_of(doc, "plot"), "linear")

    studies_node = rd.sequence(doc["studies"], "studies", line_of(doc, "studies"))
    studies, names = [], set()
    for i, st in enumerate(studies_node):
        s = _study(rd, st, f"studies[{i}]", line_of(studies_node, i), top, omegas, base, (block, unit), yscale)
        if s.name in names:
            rd.fail(f"studies[{i}].name", line_of(st, "name"), "duplicate study name", s.name)
        names.add(s.name)
        studies.append(s)
    return Scenario(
        path=file,
        name=name,
        description=description,
        schema_version=version,
        base=base,
        tmd=tmd,
        frequencies=omegas,
        solver=solver,
        studies=tuple(studies),
        sweep=sweep,
        cosim=cosim,
        raw=plain_data(doc),
    )


def _check_tmd_block(
    rd: Reader, node: MarkedDict, path: str, line: int | None, unit: ModelUnit, block: str, top_level: bool = False
) -> None:
    """A model that takes the paper's TMD needs the scenario's tmd: block; one that carries its own
    absorber (``takes_tmd=False``) refuses tmd: anywhere (it would be ignored)."""
    if unit.takes_tmd:
        if top_level and "tmd" not in node:
            rd.fail("tmd", line, f"missing required key (the TMD of model {unit.name!r})", show_value=False)
    elif "tmd" in node:
        rd.fail(
            key_path(path, "tmd"),
            line_of(node, "tmd"),
            f"model {unit.name!r} carries its own absorber and takes no tmd: block; set its parameters in a "
            f"{block}: block",
            node["tmd"],
        )


_SWEEP_KEYS = ("direction", "continuation")
#: the solver: block's settings (rows of solvers/settings_table.py read by the monolithic engine's block)
_SOLVER_SETTINGS = tuple(s.name for s in _settings.SETTINGS if _settings.MONO in s.blocks)
_SOLVER_KEYS = _SOLVER_SETTINGS + ("linear",)
_TO_SWEEP = {k: f"shared by both engines: write it as sweep.{k}" for k in _SWEEP_KEYS}
_TO_COSIM = {
    k: f"a co-simulation setting: write it under cosim: (cosim.{k})" for k in COSIM_KEYS if k not in _SOLVER_KEYS
}
_TO_SOLVER = {
    k: f"a monolithic-engine setting: write it under solver: (solver.{k})" for k in _SOLVER_KEYS if k not in COSIM_KEYS
}


#: the plot: block (top level, or in an FRC study over it): how the FRC plots draw the amplitude
PLOT_KEYS = ("yscale",)
YSCALES = ("linear", "log")


def _plot(rd: Reader, node: MarkedDict, path: str, line: int | None, default: str) -> str:
    """The amplitude axis of the FRC plots: ``plot: {yscale: linear | log}`` (log shows the higher
    modes of a frame beside its first)."""
    rd.mapping(node, path, line, optional=PLOT_KEYS)
    return rd.string(node, "yscale", path, choices=YSCALES, default=default)


def _sweep(rd: Reader, node: MarkedDict, line: int | None) -> SweepConfig:
    rd.mapping(node, "sweep", line, optional=_SWEEP_KEYS, hints={**_TO_COSIM, **_TO_SOLVER})
    d = SweepConfig()
    return SweepConfig(
        direction=rd.string(node, "direction", "sweep", choices=DIRECTIONS, default=d.direction),
        continuation=rd.boolean(node, "continuation", "sweep", default=d.continuation),
    )


def _solver(rd: Reader, node: MarkedDict, line: int | None) -> SolverConfig:
    rd.mapping(node, "solver", line, optional=_SOLVER_KEYS, hints={**_TO_SWEEP, **_TO_COSIM})
    d = SolverConfig()
    values = {k: _setting(rd, node, k, "solver") if k in node else getattr(d, k) for k in _SOLVER_SETTINGS}
    cfg = SolverConfig(**values, linear=rd.string(node, "linear", "solver", choices=LINEAR_METHODS, default=d.linear))
    _check_settings(rd, "solver", node, line, cfg.settings)
    return cfg


def _cosim(rd: Reader, node: MarkedDict, line: int | None) -> CosimConfig:
    rd.mapping(node, "cosim", line, optional=COSIM_KEYS, hints={**_TO_SWEEP, **_TO_SOLVER})
    overrides = tuple((k, _setting(rd, node, k, "cosim")) for k in node)
    cfg = CosimConfig(overrides)
    _check_settings(rd, "cosim", node, line, cfg.settings)
    return cfg


def _setting(rd: Reader, node: MarkedDict, key: str, block: str) -> Any:
    """The value of setting ``key`` of a solver: / cosim: block, checked against its one rule (its
    row of :data:`pyfmu_wrapper.solvers.settings_table.SETTINGS`, which the engines' settings
    classes apply too); a float for a number, an int for an integer."""
    s = _settings.BY_NAME[key]
    v = node[key]
    why = s.problem(v)
    if why is not None:
        rd.fail(key_path(block, key), line_of(node, key), why, v)
    if v is None:
        return None
    return float(v) if s.kind == "number" else int(v) if s.kind == "integer" else v


def _check_settings(rd: Reader, block: str, node: MarkedDict, line: int | None, make: Callable[..., Any]) -> None:
    """Build the engine's settings of a block: a value the settings refuse (their validation,
    :class:`~pyfmu_wrapper.solvers.steady.SteadySettings`, the one place of the range rules)
    becomes a ScenarioError naming ``block.field`` and its line."""
    try:
        make()
    except SettingsError as exc:
        rd.fail(f"{block}.{exc.field}", line_of(node, exc.field) or line, exc.reason, exc.value)


_COMMON = ("kind", "name", "title", "tmd", "frequencies")
_KIND_KEYS = {
    "frc": (("curves",), ("plot",)),
    "map": (("parameter", "values"), ()),
    "phase_portrait": (("omegas", "curves"), ("n_periods", "samples_per_period")),
}


def _study(
    rd: Reader,
    node: MarkedDict,
    path: str,
    line: int | None,
    top: TMDSpec,
    omegas: ndarray,
    base: Any,
    model: tuple[str, ModelUnit],
    yscale: str = "linear",
) -> FRCStudy | PhasePortraitStudy | MapStudy:
    if not isinstance(node, dict):
        rd.fail(path, line, "must be a mapping (a study)", node)
    if "kind" not in node:
        rd.fail(
            key_path(path, "kind"),
            line_of(node),
            f"missing required key (one of {list(STUDY_KINDS)})",
            show_value=False,
        )
    kind = rd.string(node, "kind", path, choices=STUDY_KINDS)
    req, opt = _KIND_KEYS[kind]
    rd.mapping(node, path, line, required=("kind", "name") + req, optional=_COMMON[2:] + opt)
    name = rd.string(node, "name", path, pattern=_NAME_RE)
    title = rd.string(node, "title", path, default=name)
    _check_tmd_block(rd, node, path, line, model[1], model[0])
    spec = top.over(rd, node["tmd"], key_path(path, "tmd"), line_of(node, "tmd")) if "tmd" in node else top
    if "frequencies" in node:
        omegas = rd.grid(
            node["frequencies"], key_path(path, "frequencies"), line_of(node, "frequencies"), positive=True
        )
    if kind == "frc":
        curves = _curves(rd, node["curves"], key_path(path, "curves"), line_of(node, "curves"), spec, base, model)
        if "plot" in node:
            yscale = _plot(rd, node["plot"], key_path(path, "plot"), line_of(node, "plot"), yscale)
        return FRCStudy(name=name, title=title, omegas=omegas, curves=curves, yscale=yscale)
    if kind == "phase_portrait":
        wp = key_path(path, "omegas")
        w = rd.grid(node["omegas"], wp, line_of(node, "omegas"), positive=True)
        curves = _curves(rd, node["curves"], key_path(path, "curves"), line_of(node, "curves"), spec, base, model)
        n = rd.integer(node, "n_periods", path, minimum=1, maximum=1000, default=1)
        sp = rd.integer(node, "samples_per_period", path, minimum=8, maximum=100_000, default=400)
        return PhasePortraitStudy(
            name=name, title=title, omegas=tuple(float(x) for x in w), curves=curves, n_periods=n, samples_per_period=sp
        )
    # map
    if not model[1].takes_tmd:
        rd.fail(
            key_path(path, "kind"),
            line_of(node, "kind"),
            f"a map sweeps a TMD parameter; model {model[1].name!r} takes no TMD",
            kind,
        )
    if attached(rd, base, spec, path, line) != base:
        rd.fail(key_path(path, "tmd"), line_of(node, "tmd"), "a map study keeps the scenario's attachment of the TMD")
    param = rd.string(node, "parameter", path, choices=MAP_PARAMETERS)
    vnode, vpath, vline = node["values"], key_path(path, "values"), line_of(node, "values")
    values = rd.grid(vnode, vpath, vline)
    tmds = []
    for j, val in enumerate(values):
        if isinstance(vnode, list):
            p, ln = key_path(vpath, j), line_of(vnode, j)
        else:
            p, ln = f"{vpath}[{j}]", vline
        s = TMDSpec(spec.values, spec.origin)
        if param == "inertance_ratio":
            for k in ("mass", "inertance", "case", "inertance_ratio"):
                s.values.pop(k, None)
            total = spec.build(rd, vpath, vline).inertia
            s.set(rd, "mass", total, p, ln)
            s.set(rd, "inertance", 0.0, p, ln)
        s.set(rd, param, float(val), p, ln)
        tmds.append(s.build(rd, p, ln))
    return MapStudy(name=name, title=title, parameter=param, values=values, omegas=omegas, tmds=tuple(tmds))


def _curves(
    rd: Reader, node: MarkedList, path: str, line: int | None, spec: TMDSpec, base: Any, model: tuple[str, ModelUnit]
) -> tuple[Curve, ...]:
    rd.sequence(node, path, line)
    out, labels = [], set()
    block, unit = model
    for i, c in enumerate(node):
        p, ln = key_path(path, i), line_of(node, i)
        if not unit.takes_tmd:  # the curve varies the structure's own block (its absorber)
            _check_tmd_block(rd, c, p, ln, unit, block)
            rd.mapping(
                c,
                p,
                ln,
                required=("label",),
                optional=(block,),
                hints={
                    "without_tmd": f"model {unit.name!r} carries its own absorber: detach it in the curve's {block}: block"
                },
            )
            label = rd.string(c, "label", p)
            if label in labels:
                rd.fail(key_path(p, "label"), line_of(c, "label"), "duplicate curve label", label)
            labels.add(label)
            structure = (
                over_block(rd, unit, base, c[block], key_path(p, block), line_of(c, block)) if block in c else base
            )
            tmd = detached_tmd(TMDParams())  # not read by the unit
            out.append(Curve(label=label, tmd=tmd, structure=None if structure == base else structure))
            continue
        rd.mapping(c, p, ln, required=("label",), optional=("tmd", "without_tmd"))
        label = rd.string(c, "label", p)
        if label in labels:
            rd.fail(key_path(p, "label"), line_of(c, "label"), "duplicate curve label", label)
        labels.add(label)
        without = rd.boolean(c, "without_tmd", p)
        if without and "tmd" in c:
            rd.fail(
                key_path(p, "tmd"), line_of(c, "tmd"), "a curve with without_tmd: true takes no tmd block", c["tmd"]
            )
        s = spec.over(rd, c["tmd"], key_path(p, "tmd"), line_of(c, "tmd")) if "tmd" in c else spec
        tmd = s.build(rd, p, ln)
        structure = attached(rd, base, s, p, ln)
        out.append(
            Curve(
                label=label,
                tmd=detached_tmd(tmd) if without else tmd,
                without_tmd=without,
                structure=None if structure == base else structure,
            )
        )
    return tuple(out)


def plain_data(obj: Any) -> Any:
    """The YAML document as plain dicts and lists (the line-marked containers dropped)."""
    if isinstance(obj, dict):
        return {k: plain_data(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [plain_data(v) for v in obj]
    return obj
