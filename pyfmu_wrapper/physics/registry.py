"""The parameter registry: every model parameter declared once.

Each :class:`Parameter` gives the name used in Python and in scenario files, the paper's symbol,
the SI unit, the default, the bounds, a description, the subsystem it belongs to, its FMU variable
(name and value reference in that subsystem's FMU), its Modelica name, and the inerter models it
applies to. Everything else is derived from this table:

* the parameter classes :class:`~pyfmu_wrapper.physics.params.BaseParams` and
  :class:`~pyfmu_wrapper.physics.params.TMDParams` (fields, defaults, validation);
* the packed float array of the compiled kernels (:data:`PACK_INDEX`, the ``P_*`` indices);
* the parameter variables of the FMUs (the FMUs' variable tables, :mod:`pyfmu_wrapper.models.base_tmd.fmus.variables`) and the values a
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


@dataclass(frozen=True, kw_only=True)
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


#: The registry, in the order of the kernels' packed parameter array (never reorder: append).
PARAMETERS: tuple[Parameter, ...] = (
    Parameter(
        name="mass",
        symbol="M",
        subsystem="base",
        unit="kg",
        default=100.0,
        minimum=0.0,
        strict=True,
        description="base mass",
        fmu_name="M",
        fmu_vr=0,
        modelica_name="M",
        modelica_type="Mass",
    ),
    Parameter(
        name="stiffness",
        symbol="K",
        subsystem="base",
        unit="N/m",
        default=4.0e4,
        minimum=0.0,
        strict=False,
        description="base stiffness",
        fmu_name="K",
        fmu_vr=1,
        modelica_name="K",
        modelica_type="TranslationalSpringConstant",
    ),
    Parameter(
        name="damping",
        symbol="C",
        subsystem="base",
        unit="N.s/m",
        default=100.0,
        minimum=0.0,
        strict=False,
        description="base viscous damping",
        fmu_name="C",
        fmu_vr=2,
        modelica_name="C",
        modelica_type="TranslationalDampingConstant",
    ),
    Parameter(
        name="force_amplitude",
        symbol="F",
        subsystem="base",
        unit="N",
        default=200.0,
        minimum=None,
        strict=False,
        description="amplitude F of the excitation F cos(w t)",
        fmu_name="F",
        fmu_vr=3,
        modelica_name="F",
        modelica_type="Force",
    ),
    Parameter(
        name="omega",
        symbol="w",
        subsystem="base",
        unit="rad/s",
        default=20.0,
        minimum=0.0,
        strict=True,
        description="excitation angular frequency (the paper's 'Hz' are rad/s); passed to the solvers, not a field",
        fmu_name="w",
        fmu_vr=4,
        modelica_name="w",
        modelica_type="AngularFrequency",
        field=False,
        mappable=False,
    ),
    Parameter(
        name="mass",
        symbol="m",
        subsystem="tmd",
        unit="kg",
        default=9.0,
        minimum=0.0,
        strict=False,
        description="TMD mass",
        fmu_name="m",
        fmu_vr=0,
        modelica_name="m",
        modelica_type="Mass",
    ),
    Parameter(
        name="stiffness",
        symbol="k",
        subsystem="tmd",
        unit="N/m",
        default=4.0e3,
        minimum=0.0,
        strict=False,
        description="linear stiffness of the TMD spring",
        fmu_name="k",
        fmu_vr=1,
        modelica_name="k",
        modelica_type="TranslationalSpringConstant",
    ),
    Parameter(
        name="damping",
        symbol="c",
        subsystem="tmd",
        unit="N.s/m",
        default=0.0,
        minimum=0.0,
        strict=False,
        description="viscous damping of the TMD link",
        fmu_name="c",
        fmu_vr=2,
        modelica_name="c",
        modelica_type="TranslationalDampingConstant",
    ),
    Parameter(
        name="friction_force",
        symbol="df",
        subsystem="tmd",
        unit="N",
        default=0.0,
        minimum=0.0,
        strict=False,
        description="dry friction force amplitude, df (2/pi) atan(s (xd - yd))",
        fmu_name="df",
        fmu_vr=3,
        modelica_name="df",
        modelica_type="Force",
    ),
    Parameter(
        name="friction_slope",
        symbol="s",
        subsystem="tmd",
        unit="s/m",
        default=1.0e6,
        minimum=0.0,
        strict=True,
        description="regularisation slope of the friction law (1e6 in the paper)",
        fmu_name="s",
        fmu_vr=4,
        modelica_name="slope",
        modelica_type="InverseVelocity",
    ),
    Parameter(
        name="inertance",
        symbol="I",
        subsystem="tmd",
        unit="kg",
        default=1.0,
        minimum=0.0,
        strict=False,
        description="inertance of the inerter (0 without inerter)",
        fmu_name="I",
        fmu_vr=5,
        modelica_name="I",
        modelica_type="Inertance",
        models=(IDEAL, PLAY),
    ),
    Parameter(
        name="mesh_stiffness",
        symbol="ki",
        subsystem="tmd",
        unit="N/m",
        default=2.0e7,
        minimum=0.0,
        strict=True,
        description="gear mesh stiffness of the play chain",
        fmu_name="ki",
        fmu_vr=6,
        modelica_name="ki",
        modelica_type="TranslationalSpringConstant",
        models=(PLAY,),
    ),
    Parameter(
        name="mesh_damping",
        symbol="ci",
        subsystem="tmd",
        unit="N.s/m",
        default=0.01,
        minimum=0.0,
        strict=False,
        description="gear mesh damping of the play chain",
        fmu_name="ci",
        fmu_vr=7,
        modelica_name="ci",
        modelica_type="TranslationalDampingConstant",
        models=(PLAY,),
    ),
    Parameter(
        name="play_gap",
        symbol="eps",
        subsystem="tmd",
        unit="m",
        default=0.0,
        minimum=0.0,
        strict=False,
        description="half the backlash of the gear (free while |r - y| < eps)",
        fmu_name="eps",
        fmu_vr=8,
        modelica_name="eps",
        modelica_type="Position",
        models=(PLAY,),
    ),
    Parameter(
        name="inerter",
        symbol="-",
        subsystem="tmd",
        unit="1",
        default=IDEAL,
        minimum=NONE,
        strict=False,
        description="inerter model: 0 none (I must be 0), 1 ideal, 2 with play",
        fmu_name="inerter",
        fmu_vr=9,
        modelica_name=None,
        modelica_type=None,
        kind="enum",
        mappable=False,
        maximum=PLAY,
    ),
    Parameter(
        name="cubic_stiffness",
        symbol="k3",
        subsystem="tmd",
        unit="N/m3",
        default=0.0,
        minimum=None,
        strict=False,
        description="cubic term of the TMD spring, k3 (x - y)^3 (> 0 hardening, < 0 softening)",
        fmu_name="k3",
        fmu_vr=10,
        modelica_name="k3",
        modelica_type="CubicSpringConstant",
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


def declared() -> tuple[str, ...]:
    """The subsystems the model units declared (beyond base and tmd), in declaration order."""
    return tuple(_DECLARED)


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
        fmu = f"`{p.fmu_name}` ({p.fmu_vr})" if p.fmu_name else "- (no FMU)"
        rows.append(
            f"| `{name}` | {p.symbol} | {p.unit} | {p.default:g} | {bound} | {fmu} "
            f"| {p.modelica_name or '-'} | {applies} | {p.description.replace('|', chr(92) + '|')} |"
        )
    return "\n".join(rows) + "\n"


# -- a model's own structure, declared by rows: its checks and the Modelica types of its units ----------

#: the Modelica type (``TMDInerter.Units``) of each SI unit a model's own rows use
MODELICA_TYPES = {
    "kg": "Mass",
    "N/m": "TranslationalSpringConstant",
    "N.s/m": "TranslationalDampingConstant",
    "N": "Force",
    "m": "Length",
    "N.m.s/rad": "RotationalDampingConstant",
}


def structure_row(
    subsystem: str,
    name: str,
    symbol: str,
    unit: str,
    default: float,
    minimum: float | None,
    strict: bool,
    description: str,
    fmu_vr: int = -1,
    fmu_name: str | None = None,
) -> Parameter:
    """A declared row of a model's own structure: its scenario key and dataclass field ``name``, its symbol
    (also its Modelica parameter and, with ``fmu_vr`` >= 0, its FMU parameter unless ``fmu_name`` names
    another), its SI unit (Modelica type from :data:`MODELICA_TYPES`), its default, bound and description;
    never mapped."""
    return Parameter(
        name=name,
        symbol=symbol,
        subsystem=subsystem,
        unit=unit,
        default=default,
        minimum=minimum,
        strict=strict,
        description=description,
        fmu_name=(symbol if fmu_name is None else fmu_name) if fmu_vr >= 0 else "",
        fmu_vr=fmu_vr,
        modelica_name=symbol,
        modelica_type=MODELICA_TYPES[unit],
        mappable=False,
    )
