"""The parameter registry: every model parameter declared once.

Each :class:`Parameter` gives the name used in Python and in scenario files, the paper's symbol,
the SI unit, the default, the bounds, a description, the subsystem it belongs to, its FMU variable
(name and value reference in that subsystem's FMU), its Modelica name, and the inerter models it
applies to. Everything else is derived from this table:

* the parameter classes :class:`~pyfmu_wrapper.physics.params.BaseParams` and
  :class:`~pyfmu_wrapper.physics.params.TMDParams` (fields, defaults, validation);
* the packed float array of the compiled kernels (:data:`PACK_INDEX`, the ``P_*`` indices);
* the parameter variables of the FMUs (:mod:`pyfmu_wrapper.fmi.variables`) and the values a
  master sets on them (:func:`fmu_start_values`);
* the parameters a scenario map may sweep (``scenario.schema.MAP_PARAMETERS``);
* the Modelica defaults and parameter declarations (:mod:`pyfmu_wrapper.generate.modelica`);
* the parameter tables of the documentation (``docs/parameters.md``, :func:`markdown_table`).

The tests hold every derived artefact against this table. To add a parameter, see
``docs/adding-a-parameter.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Any


class InerterModel(IntEnum):
    """How the inerter link between base and TMD is modelled (paper Table 1): the one definition of
    the codes, which the parameter classes, the compiled kernels (``kernels.MODEL_*``) and the FMUs'
    ``inerter`` variable use."""

    NONE = 0  #: no inerter (I must be 0)
    IDEAL = 1  #: ideal inerter, force I (xdd - ydd)
    PLAY = 2  #: Scheibe-Smith chain: inerter I - mesh spring ki || damper ci - gap +-eps
    # eps = 0 with finite ki is the linear inerter-in-series-with-spring (no clamping); the
    # kernels treat it through the same PLAY chain with a zero gap.


#: inerter models, as the table below lists which apply to a parameter
NONE, IDEAL, PLAY = InerterModel.NONE, InerterModel.IDEAL, InerterModel.PLAY
ALL_MODELS = tuple(InerterModel)


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    name: Python field and scenario key (``stiffness``); symbol: the paper's symbol (``k``);
    subsystem: ``base`` or ``tmd`` (the FMU it belongs to); unit: SI unit in FMI notation;
    default: default value; minimum: lower bound (None: any finite value); strict: the bound
    is exclusive; description: one line; fmu_name / fmu_vr: the FMU parameter variable and its
    value reference; modelica_name: the Modelica parameter (None: not a Modelica parameter);
    modelica_type: its ``TMDInerter.Units`` type; models: the inerter models it applies to;
    field: it is a field of the subsystem's parameter class (False for the excitation
    frequency, which the solvers take separately); kind: ``real`` or ``enum``;
    mappable: a scenario map may sweep it; maximum: upper bound, inclusive (None: none).
    The bounds are declared as min/max in the FMUs' modelDescription.xml and enforced by
    fmi2SetReal/fmi2SetInteger (an exclusive minimum m is declared as the next double above m).
    """

    name: str
    symbol: str
    subsystem: str
    unit: str
    default: float
    minimum: float | None
    strict: bool
    description: str
    fmu_name: str
    fmu_vr: int
    modelica_name: str | None
    modelica_type: str | None
    models: tuple[int, ...] = ALL_MODELS
    field: bool = True
    kind: str = "real"
    mappable: bool = True
    maximum: float | None = None

    @property
    def label(self) -> str:
        """``name (symbol)``, as used in error messages."""
        return f"{self.name} ({self.symbol})"


_P = Parameter
#: The registry, in the order of the kernels' packed parameter array (never reorder: append).
PARAMETERS: tuple[Parameter, ...] = (
    _P("mass", "M", "base", "kg", 100.0, 0.0, True, "base mass", "M", 0, "M", "Mass"),
    _P(
        "stiffness", "K", "base", "N/m", 4.0e4, 0.0, False, "base stiffness", "K", 1, "K", "TranslationalSpringConstant"
    ),
    _P(
        "damping",
        "C",
        "base",
        "N.s/m",
        100.0,
        0.0,
        False,
        "base viscous damping",
        "C",
        2,
        "C",
        "TranslationalDampingConstant",
    ),
    _P(
        "force_amplitude",
        "F",
        "base",
        "N",
        200.0,
        None,
        False,
        "amplitude F of the excitation F cos(w t)",
        "F",
        3,
        "F",
        "Force",
    ),
    _P(
        "omega",
        "w",
        "base",
        "rad/s",
        20.0,
        0.0,
        True,
        "excitation angular frequency (the paper's 'Hz' are rad/s); passed to the solvers, not a field",
        "w",
        4,
        "w",
        "AngularFrequency",
        field=False,
        mappable=False,
    ),
    _P("mass", "m", "tmd", "kg", 9.0, 0.0, False, "TMD mass", "m", 0, "m", "Mass"),
    _P(
        "stiffness",
        "k",
        "tmd",
        "N/m",
        4.0e3,
        0.0,
        False,
        "linear stiffness of the TMD spring",
        "k",
        1,
        "k",
        "TranslationalSpringConstant",
    ),
    _P(
        "damping",
        "c",
        "tmd",
        "N.s/m",
        0.0,
        0.0,
        False,
        "viscous damping of the TMD link",
        "c",
        2,
        "c",
        "TranslationalDampingConstant",
    ),
    _P(
        "friction_force",
        "df",
        "tmd",
        "N",
        0.0,
        0.0,
        False,
        "dry friction force amplitude, df (2/pi) atan(s (xd - yd))",
        "df",
        3,
        "df",
        "Force",
    ),
    _P(
        "friction_slope",
        "s",
        "tmd",
        "s/m",
        1.0e6,
        0.0,
        True,
        "regularisation slope of the friction law (1e6 in the paper)",
        "s",
        4,
        "slope",
        "InverseVelocity",
    ),
    _P(
        "inertance",
        "I",
        "tmd",
        "kg",
        1.0,
        0.0,
        False,
        "inertance of the inerter (0 without inerter)",
        "I",
        5,
        "I",
        "Inertance",
        models=(IDEAL, PLAY),
    ),
    _P(
        "mesh_stiffness",
        "ki",
        "tmd",
        "N/m",
        2.0e7,
        0.0,
        True,
        "gear mesh stiffness of the play chain",
        "ki",
        6,
        "ki",
        "TranslationalSpringConstant",
        models=(PLAY,),
    ),
    _P(
        "mesh_damping",
        "ci",
        "tmd",
        "N.s/m",
        0.01,
        0.0,
        False,
        "gear mesh damping of the play chain",
        "ci",
        7,
        "ci",
        "TranslationalDampingConstant",
        models=(PLAY,),
    ),
    _P(
        "play_gap",
        "eps",
        "tmd",
        "m",
        0.0,
        0.0,
        False,
        "half the backlash of the gear (free while |r - y| < eps)",
        "eps",
        8,
        "eps",
        "Position",
        models=(PLAY,),
    ),
    _P(
        "inerter",
        "-",
        "tmd",
        "1",
        IDEAL,
        NONE,
        False,
        "inerter model: 0 none (I must be 0), 1 ideal, 2 with play",
        "inerter",
        9,
        None,
        None,
        kind="enum",
        mappable=False,
        maximum=PLAY,
    ),
    _P(
        "cubic_stiffness",
        "k3",
        "tmd",
        "N/m3",
        0.0,
        None,
        False,
        "cubic term of the TMD spring, k3 (x - y)^3 (> 0 hardening, < 0 softening)",
        "k3",
        10,
        "k3",
        "CubicSpringConstant",
    ),
)

#: index of each parameter in the kernels' packed array, by ``"subsystem.name"``
PACK_INDEX: dict[str, int] = {f"{p.subsystem}.{p.name}": i for i, p in enumerate(PARAMETERS)}
N_PARAMS = len(PARAMETERS)


#: the parameters of the subsystems declared by model units (:func:`declare`), beside base and tmd
_DECLARED: dict[str, tuple[Parameter, ...]] = {}


def declare(subsystem: str, parameters: tuple[Parameter, ...]) -> tuple[Parameter, ...]:
    """Declare the parameters of a model unit's own subsystem (a frame, ...): they are not packed
    with the paper's array (:data:`PARAMETERS`), their unit packs them itself."""
    if subsystem in ("base", "tmd") or subsystem in _DECLARED:
        raise ValueError(f"subsystem {subsystem!r} is declared already")
    if any(p.subsystem != subsystem for p in parameters):
        raise ValueError(f"every parameter declared for {subsystem!r} must name that subsystem")
    _DECLARED[subsystem] = tuple(parameters)
    return _DECLARED[subsystem]


def of(subsystem: str) -> tuple[Parameter, ...]:
    """The parameters of one subsystem (``base``, ``tmd`` or one a unit declared), in registry order."""
    if subsystem in _DECLARED:
        return _DECLARED[subsystem]
    if subsystem not in ("base", "tmd"):
        known = ", ".join(("base", "tmd", *_DECLARED))
        raise ValueError(f"subsystem must be one of {known}, got {subsystem!r}")
    return tuple(p for p in PARAMETERS if p.subsystem == subsystem)


def get(subsystem: str, name: str) -> Parameter:
    """The parameter ``name`` of a subsystem (KeyError naming the known ones otherwise)."""
    for p in of(subsystem):
        if p.name == name:
            return p
    raise KeyError(f"no {subsystem} parameter {name!r}; known: {[p.name for p in of(subsystem)]}")


def fields(subsystem: str) -> tuple[Parameter, ...]:
    """The parameters that are fields of the subsystem's parameter class."""
    return tuple(p for p in of(subsystem) if p.field)


def fmu_start_values(base: Any, tmd: Any, omega: float) -> dict[str, float | int]:
    """``"base.<fmu name>"`` / ``"tmd.<fmu name>"`` -> value, for every registry parameter."""
    out: dict[str, float | int] = {}
    for p in PARAMETERS:
        if p.subsystem == "base":
            v = float(omega) if p.name == "omega" else getattr(base, p.name)
        elif p.subsystem == "tmd":
            v = getattr(tmd, p.name)
        else:  # pragma: no cover - PARAMETERS holds base and tmd only (others are declared)
            raise ValueError(f"parameter {p.subsystem}.{p.name} is not packed with the paper's array")
        out[f"{p.subsystem}.{p.fmu_name}"] = int(v) if p.kind == "enum" else float(v)
    return out


def markdown_table(subsystem: str) -> str:
    """The documentation table of one subsystem's parameters."""
    rows = [
        "| name | symbol | unit | default | bounds | FMU variable (vr) | Modelica | applies to | description |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for p in of(subsystem):
        bound = "any" if p.minimum is None else (f"> {p.minimum:g}" if p.strict else f">= {p.minimum:g}")
        if p.maximum is not None:
            bound = f"<= {p.maximum:g}" if p.minimum is None else f"{bound}, <= {p.maximum:g}"
        if p.kind == "enum":
            bound = ", ".join(str(int(m)) for m in InerterModel)
        applies = "all" if p.models == ALL_MODELS else ", ".join(InerterModel(m).name.lower() for m in p.models)
        name = p.name if p.field else f"{p.name} (not a field)"
        rows.append(
            f"| `{name}` | {p.symbol} | {p.unit} | {p.default:g} | {bound} | `{p.fmu_name}` ({p.fmu_vr}) "
            f"| {p.modelica_name or '-'} | {applies} | {p.description.replace('|', chr(92) + '|')} |"
        )
    return "\n".join(rows) + "\n"
