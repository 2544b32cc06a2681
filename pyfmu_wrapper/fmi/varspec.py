"""What an FMU variable declaration is: :class:`Variable` (value reference, type, causality,
variability, unit, start, range, dependencies) and :class:`FmuSpec` (one FMU's interface). The
declarations themselves are the variable tables in the models' FMU folders; the slave and native
functions that implement one are its :class:`~.fmumodel.FmuModel`.

Units are unit strings of FMI's unit grammar (:mod:`.units`), checked when the spec is declared: a
malformed string or an unknown symbol is refused with the FMU, the variable and the string named.

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

import sys
from dataclasses import dataclass, field
from typing import Any

from .units import base_unit

REAL, INTEGER, BOOLEAN = "Real", "Integer", "Boolean"


#: what FMI 2.0 allows (the FMI 3.0 writer maps them): checked when a variable is declared
CAUSALITIES = ("parameter", "calculatedParameter", "input", "output", "local", "independent")
VARIABILITIES = ("constant", "fixed", "tunable", "discrete", "continuous")
INITIALS = ("exact", "approx", "calculated")
DEPENDENCY_KINDS = ("dependent", "constant", "fixed", "tunable", "discrete")


@dataclass(frozen=True, kw_only=True)
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
    #: Model Exchange: this variable is the time derivative of the continuous state named here (the
    #: states are the variables some derivative names, in the order of their derivatives)
    derivative_of: str | None = None
    #: Model Exchange: this (local, continuous Real) variable is an event indicator (its zero crossings
    #: are the model's events), numbered in the order of the table
    event_indicator: bool = False

    def __post_init__(self) -> None:
        if self.type not in (REAL, INTEGER, BOOLEAN):
            raise ValueError(f"{self.name}: unsupported type {self.type!r}")
        for field_, value, allowed in (
            ("causality", self.causality, CAUSALITIES),
            ("variability", self.variability, VARIABILITIES),
            ("initial", self.initial, (None, *INITIALS)),
        ):
            if value not in allowed:
                raise ValueError(f"{self.name}: {field_} must be one of {list(allowed)}, got {value!r}")
        for kind in self.dependencies_kind:
            if kind not in DEPENDENCY_KINDS:
                raise ValueError(
                    f"{self.name}: a dependency kind must be one of {list(DEPENDENCY_KINDS)}, got {kind!r}"
                )
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
        if (self.derivative_of is not None or self.event_indicator) and not (
            self.type == REAL and self.causality == "local" and self.variability == "continuous"
        ):
            raise ValueError(f"{self.name}: a state derivative or event indicator is a local continuous Real")

    def in_range(self, value: float | int | bool) -> bool:
        """Whether value lies within min/max (what the stub accepts: an exclusive minimum m as
        declared, the next value above m, the smallest normal double for m = 0.0)."""
        if self.min is not None and (value <= self.min if self.min_exclusive else value < self.min):
            return False
        if self.min_exclusive and self.min == 0.0 and self.type == REAL and value < sys.float_info.min:
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
    """One FMU's interface: what its model descriptions, variable table and documentation are generated
    from (the slave and the native functions that implement it: :class:`~.fmumodel.FmuModel`)."""

    model_name: str
    model_identifier: str
    description: str
    variables: tuple[Variable, ...]
    can_interpolate_inputs: bool = True
    max_output_derivative_order: int = 0
    provides_directional_derivative: bool = True
    default_step: float = 1e-3
    extra: dict[str, Any] = field(default_factory=dict)
    #: the highest value reference of the binary's value space when it is above every declared one (a native
    #: FMU's table without its test hook: the compiled code still addresses the hook's value reference, so
    #: the FMI 3.0 ``time`` and input-derivative value references come after it); None: the highest declared
    vr_top: int | None = None

    def __post_init__(self) -> None:
        names = [v.name for v in self.variables]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.model_name}: duplicate variable names")
        vrs = [v.vr for v in self.variables]
        if len(set(vrs)) != len(vrs):
            raise ValueError(f"{self.model_name}: duplicate value references")
        for v in self.variables:
            if v.unit is not None:
                base_unit(v.unit, where=f"FMU {self.model_name}, variable {v.name!r}")
            for d in v.depends_on:
                if self.by_name(d).causality != "input":
                    raise ValueError(f"{v.name}: dependency {d} is not an input")
            if v.derivative_of is not None:
                x = self.by_name(v.derivative_of)
                if x.type != REAL or x.variability != "continuous" or x.causality not in ("output", "local"):
                    raise ValueError(f"{v.name}: the state {x.name} is not a continuous Real output or local")
        states = [d.derivative_of for d in self.derivatives()]
        if len(set(states)) != len(states):
            raise ValueError(f"{self.model_name}: a state has two derivatives")

    def derivatives(self) -> list[Variable]:
        """Model Exchange: the state derivatives, in the order of the states (empty: co-simulation only)."""
        return [v for v in self.variables if v.derivative_of is not None]

    def states(self) -> list[Variable]:
        """Model Exchange: the continuous states, in the order of their derivatives (the model's state z)."""
        return [self.by_name(str(d.derivative_of)) for d in self.derivatives()]

    def event_indicators(self) -> list[Variable]:
        """Model Exchange: the event indicators, in the order of the table."""
        return [v for v in self.variables if v.event_indicator]

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


def parameter(
    name: str,
    vr: int,
    start: float | int,
    unit: str | None,
    description: str,
    *,
    min: float | None = None,  # noqa: A002 - FMI's attribute name, as in Variable
    max: float | None = None,  # noqa: A002
    min_exclusive: bool = False,
) -> Variable:
    """A fixed parameter with an exact start value: Integer when ``start`` is an int, else Real."""
    return Variable(
        name=name,
        vr=vr,
        type=INTEGER if isinstance(start, int) and not isinstance(start, bool) else REAL,
        causality="parameter",
        variability="fixed",
        description=description,
        unit=unit,
        start=start,
        initial="exact",
        min=min,
        max=max,
        min_exclusive=min_exclusive,
    )
