"""Declarative variable tables of the FMUs: the single source of truth for the interfaces.

Every variable is declared once here with an explicit value reference, type, causality,
variability, unit, start value and description. ``modelDescription.xml`` is generated from these
tables (:mod:`.model_description`), the C stub reads the type/causality table written from them
into ``resources/variables.tsv``, and the Python slaves (:mod:`.slaves`) address the shared value
buffers through :meth:`FmuSpec.vr`.

Value references are unique across all types of one FMU (the C stub keeps one buffer per type
indexed by value reference).

Dependencies in the ModelStructure (FMI 2.0, Sect. 2.2.8): ``depends_on`` lists the *inputs* an
output depends on directly (algebraic feed-through within one communication point), with the
matching ``dependencies_kind``; ``initial_depends_on`` lists the knowns (inputs and exact
parameters) an initial unknown depends on during initialisation.

Ranges: ``min`` / ``max`` (inclusive; ``min_exclusive``: the minimum itself is refused) come from
the parameter registry for the model parameters and are declared here for the others. They go
into ``modelDescription.xml`` (an exclusive minimum m as the next double above m: FMI's min is
inclusive) and into the stub's table, which refuses an out-of-range value in fmi2SetReal /
fmi2SetInteger with a message naming the variable, the value and the range.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..physics import registry

REAL, INTEGER, BOOLEAN = "Real", "Integer", "Boolean"


@dataclass(frozen=True)
class Variable:
    """One FMI scalar variable."""

    name: str
    vr: int
    type: str
    causality: str  #: parameter | input | output | local | independent
    variability: str  #: fixed | tunable | continuous | discrete | constant
    description: str
    unit: str | None = None
    start: float | int | bool | None = None
    initial: str | None = None  #: exact | approx | calculated (None: FMI default)
    depends_on: tuple[str, ...] = ()
    dependencies_kind: tuple[str, ...] = ()
    initial_depends_on: tuple[str, ...] | None = None
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False

    def __post_init__(self) -> None:
        if self.type not in (REAL, INTEGER, BOOLEAN):
            raise ValueError(f"{self.name}: unsupported type {self.type!r}")
        if self.causality in ("parameter", "input") and self.start is None:
            raise ValueError(f"{self.name}: a {self.causality} needs a start value")
        if self.causality == "output" and self.start is not None and self.initial != "approx":
            raise ValueError(f"{self.name}: a calculated output takes no start value")
        if len(self.depends_on) != len(self.dependencies_kind):
            raise ValueError(f"{self.name}: depends_on and dependencies_kind differ in length")
        if (self.min is not None or self.max is not None) and self.type == BOOLEAN:
            raise ValueError(f"{self.name}: a Boolean has no range")
        if self.start is not None and not self.in_range(self.start):
            raise ValueError(f"{self.name}: start value {self.start!r} is outside its range {self.range_text()}")

    def in_range(self, value: float | int | bool) -> bool:
        """Whether value lies within min/max (what the stub accepts)."""
        if self.min is not None and (value <= self.min if self.min_exclusive else value < self.min):
            return False
        return self.max is None or value <= self.max

    def range_text(self) -> str:
        """The range as people read it: ``> 0``, ``>= 0``, ``0 ... 2``, ``any``."""
        lo = None if self.min is None else f"{'>' if self.min_exclusive else '>='} {self.min:g}"
        if self.max is None:
            return lo or "any"
        if lo is None:
            return f"<= {self.max:g}"
        return f"{self.min:g} ... {self.max:g}" if not self.min_exclusive else f"{lo} and <= {self.max:g}"


@dataclass(frozen=True)
class FmuSpec:
    """Everything needed to generate, build and run one FMU."""

    model_name: str
    model_identifier: str
    description: str
    slave: str  #: "module:Class" of the Python slave
    variables: tuple[Variable, ...]
    can_interpolate_inputs: bool = True
    max_output_derivative_order: int = 0
    provides_directional_derivative: bool = True
    default_step: float = 1e-3
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        names = [v.name for v in self.variables]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.model_name}: duplicate variable names")
        vrs = [v.vr for v in self.variables]
        if len(set(vrs)) != len(vrs):
            raise ValueError(f"{self.model_name}: duplicate value references")
        for v in self.variables:
            for d in v.depends_on:
                if self.by_name(d).causality != "input":
                    raise ValueError(f"{v.name}: dependency {d} is not an input")

    def by_name(self, name: str) -> Variable:
        for v in self.variables:
            if v.name == name:
                return v
        raise KeyError(f"{self.model_name} has no variable {name!r}")

    def vr(self, name: str) -> int:
        return self.by_name(name).vr

    def of(self, causality: str) -> list[Variable]:
        return [v for v in self.variables if v.causality == causality]

    def index(self, name: str) -> int:
        """1-based index in ModelVariables (as ModelStructure refers to it)."""
        return [v.name for v in self.variables].index(name) + 1


def _par(
    name: str,
    vr: int,
    start: float | int,
    unit: str | None,
    description: str,
    type_: str = REAL,
    lo: float | None = None,
    hi: float | None = None,
    exclusive: bool = False,
) -> Variable:
    return Variable(
        name,
        vr,
        type_,
        "parameter",
        "fixed",
        description,
        unit,
        start,
        "exact",
        min=lo,
        max=hi,
        min_exclusive=exclusive,
    )


def _registry_parameters(subsystem: str) -> tuple[Variable, ...]:
    """The model parameters of one FMU, from the parameter registry (name, vr, unit, default, bounds)."""
    out = []
    for p in registry.of(subsystem):
        if p.kind == "enum":
            out.append(
                _par(
                    p.fmu_name,
                    p.fmu_vr,
                    int(p.default),
                    None,
                    p.description,
                    INTEGER,
                    None if p.minimum is None else int(p.minimum),
                    None if p.maximum is None else int(p.maximum),
                )
            )
        else:
            unit = None if p.unit == "1" else p.unit
            out.append(
                _par(
                    p.fmu_name,
                    p.fmu_vr,
                    float(p.default),
                    unit,
                    f"{p.symbol}: {p.description}",
                    lo=p.minimum,
                    hi=p.maximum,
                    exclusive=p.strict and p.minimum is not None,
                )
            )
    return tuple(out)


#: FMU names of the model parameters (every output of a subsystem depends on them initially)
_BASE_PARS = tuple(p.fmu_name for p in registry.of("base"))
_TMD_PARS = tuple(p.fmu_name for p in registry.of("tmd"))


def _integrator(exact: bool) -> tuple[Variable, ...]:
    """The integrator's parameters (and the testing aid); exact: the subsystem is stepped exactly
    (the linear base: its tolerances are accepted and range-checked, and not used)."""
    unused = " (not used: BaseOscillator steps exactly, by the matrix exponential of the linear base)" if exact else ""
    return (
        _par(
            "rtol",
            90,
            1e-8,
            None,
            "relative tolerance of the RODAS4 integrator inside doStep (> 0, <= 1)" + unused,
            lo=0.0,
            hi=1.0,
            exclusive=True,
        ),
        _par(
            "atol",
            91,
            1e-10,
            None,
            "absolute tolerance of the integrator (all states, SI units; the play chain's rate dd: atol x sqrt(ki/I); > 0)"
            + unused,
            lo=0.0,
            exclusive=True,
        ),
        Variable(
            "debug_raise",
            99,
            INTEGER,
            "parameter",
            "tunable",
            "testing aid: 1 makes the next doStep raise a Python exception, 2 raise inside the compiled step "
            "(both reported as fmi2Error)",
            None,
            0,
            "exact",
            min=0,
            max=2,
        ),
    )


BASE_OSCILLATOR = FmuSpec(
    model_name="BaseOscillator",
    model_identifier="BaseOscillator",
    description="Base oscillator of Brzeski & Perlikowski (2017): M xdd + C xd + K x = F cos(w t) - f_link",
    slave="pyfmu_wrapper.fmi.slaves:BaseOscillatorSlave",
    variables=(
        *_registry_parameters("base"),
        _par("x0", 5, 0.0, "m", "initial base displacement"),
        _par("xd0", 6, 0.0, "m/s", "initial base velocity"),
        Variable(
            "f_link",
            10,
            REAL,
            "input",
            "continuous",
            "force of the TMD links on the base, positive when it pushes the base in -x (= TMDInerter.force)",
            "N",
            0.0,
        ),
        Variable(
            "x",
            20,
            REAL,
            "output",
            "continuous",
            "base displacement",
            "m",
            initial="calculated",
            initial_depends_on=("x0",),
        ),
        Variable(
            "xd",
            21,
            REAL,
            "output",
            "continuous",
            "base velocity",
            "m/s",
            initial="calculated",
            initial_depends_on=("xd0",),
        ),
        Variable(
            "xdd",
            22,
            REAL,
            "output",
            "continuous",
            "base acceleration",
            "m/s2",
            initial="calculated",
            depends_on=("f_link",),
            dependencies_kind=("fixed",),
            initial_depends_on=_BASE_PARS + ("x0", "xd0", "f_link"),
        ),
        Variable(
            "f_exc",
            23,
            REAL,
            "output",
            "continuous",
            "excitation force F cos(w t)",
            "N",
            initial="calculated",
            initial_depends_on=("F", "w"),
        ),
        Variable(
            "xdd_free",
            24,
            REAL,
            "output",
            "continuous",
            "base acceleration without the link force, (F cos(w t) - C xd - K x)/M: the input of a "
            "TMDInerter with base_compliance = 1/M",
            "m/s2",
            initial="calculated",
            initial_depends_on=_BASE_PARS + ("x0", "xd0"),
        ),
    )
    + _integrator(exact=True),
)

TMD_INERTER = FmuSpec(
    model_name="TMDInerter",
    model_identifier="TMDInerter",
    description="TMD with spring, damper, dry friction and an inerter (none/ideal/with play) driven by the base motion",
    slave="pyfmu_wrapper.fmi.slaves:TMDInerterSlave",
    variables=(
        *_registry_parameters("tmd"),
        _par("y0", 11, 0.0, "m", "initial TMD displacement"),
        _par("yd0", 12, 0.0, "m/s", "initial TMD velocity"),
        _par("d0", 13, 0.0, "m", "initial play-chain deflection d = r - y (play model)"),
        _par("dd0", 14, 0.0, "m/s", "initial play-chain deflection rate (play model)"),
        _par(
            "base_compliance",
            15,
            0.0,
            "1/kg",
            "interface Jacobian -d xdd/d force = 1/M of the body the TMD is mounted on. 0 (default): "
            "xdd is the base acceleration. > 0: xdd is the base acceleration without this TMD's force "
            "(BaseOscillator.xdd_free) and the TMD adds the base's reaction -force/M within each step",
            lo=0.0,
        ),
        Variable("x", 30, REAL, "input", "continuous", "base displacement", "m", 0.0),
        Variable("xd", 31, REAL, "input", "continuous", "base velocity", "m/s", 0.0),
        Variable(
            "xdd",
            32,
            REAL,
            "input",
            "continuous",
            "base acceleration (without this TMD's force when base_compliance > 0)",
            "m/s2",
            0.0,
        ),
        Variable(
            "force",
            40,
            REAL,
            "output",
            "continuous",
            "force of the TMD links on the base, positive in -x on the base (+y on the TMD)",
            "N",
            initial="calculated",
            depends_on=("x", "xd", "xdd"),
            dependencies_kind=("fixed", "dependent", "fixed"),
            initial_depends_on=_TMD_PARS + ("y0", "yd0", "d0", "dd0", "base_compliance", "x", "xd", "xdd"),
        ),
        Variable(
            "y",
            41,
            REAL,
            "output",
            "continuous",
            "TMD displacement",
            "m",
            initial="calculated",
            initial_depends_on=("y0",),
        ),
        Variable(
            "yd",
            42,
            REAL,
            "output",
            "continuous",
            "TMD velocity",
            "m/s",
            initial="calculated",
            initial_depends_on=("yd0",),
        ),
        Variable(
            "inerter_force",
            43,
            REAL,
            "output",
            "continuous",
            "force P carried by the inerter chain (diagnostic)",
            "N",
            initial="calculated",
            depends_on=("x", "xd", "xdd"),
            dependencies_kind=("fixed", "dependent", "fixed"),
            initial_depends_on=_TMD_PARS + ("y0", "yd0", "d0", "dd0", "base_compliance", "x", "xd", "xdd"),
        ),
        Variable(
            "contact",
            44,
            INTEGER,
            "output",
            "discrete",
            "gear contact of the play chain: +1 compression, -1 extension, 0 free",
            None,
            initial="calculated",
            initial_depends_on=("eps", "inerter", "d0"),
        ),
    )
    + _integrator(exact=False),
)

# A do-nothing model used only to measure the per-call overhead of the stub (benchmarks).
TRIVIAL = FmuSpec(
    model_name="Trivial",
    model_identifier="Trivial",
    description="y = gain * u; doStep only advances time (stub overhead benchmark)",
    slave="pyfmu_wrapper.fmi.slaves:TrivialSlave",
    variables=(
        _par("gain", 0, 2.0, None, "gain"),
        Variable("u", 1, REAL, "input", "continuous", "input", None, 0.0),
        Variable(
            "y",
            2,
            REAL,
            "output",
            "continuous",
            "gain * u",
            None,
            initial="calculated",
            depends_on=("u",),
            dependencies_kind=("fixed",),
            initial_depends_on=("gain", "u"),
        ),
    ),
    provides_directional_derivative=True,
)

SPECS = {s.model_identifier: s for s in (BASE_OSCILLATOR, TMD_INERTER, TRIVIAL)}
#: The FMUs of the project (the trivial one is built only on request).
PROJECT_FMUS = ("BaseOscillator", "TMDInerter")
