"""The variable tables of the paper's two FMUs, BaseOscillator and TMDInerter: their one declaration.

Every variable is declared once here with an explicit value reference, type, causality, variability,
unit, start value and description; the model parameters come from the parameter registry
(:mod:`pyfmu_wrapper.physics.registry`). ``modelDescription.xml`` is generated from these tables
(:mod:`pyfmu_wrapper.fmubuild.model_description`), the C stub reads the type/causality table written
from them into ``resources/variables.tsv``, and the Python slaves (:mod:`.slaves`) address the shared
value buffers through :meth:`~pyfmu_wrapper.fmi.varspec.FmuSpec.vr`. What a declaration holds is
:mod:`pyfmu_wrapper.fmi.varspec`; the FMUs are declared by :mod:`.base_oscillator` and :mod:`.tmd_inerter`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ....fmi.varspec import INTEGER, REAL, FmuSpec, Variable, parameter
from ....physics import registry


def _registry_parameters(subsystem: str) -> tuple[Variable, ...]:
    """The model parameters of one FMU, from the parameter registry (name, vr, unit, default, bounds)."""
    out = []
    for p in registry.of(subsystem):
        if p.kind == "enum":
            out.append(
                parameter(
                    p.fmu_name,
                    p.fmu_vr,
                    int(p.default),
                    None,
                    p.description,
                    min=None if p.minimum is None else int(p.minimum),
                    max=None if p.maximum is None else int(p.maximum),
                )
            )
        else:
            unit = None if p.unit == "1" else p.unit
            out.append(
                parameter(
                    p.fmu_name,
                    p.fmu_vr,
                    float(p.default),
                    unit,
                    f"{p.symbol}: {p.description}",
                    min=p.minimum,
                    max=p.maximum,
                    min_exclusive=p.strict and p.minimum is not None,
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
        parameter(
            "rtol",
            90,
            1e-8,
            None,
            "relative tolerance of the RODAS4 integrator inside doStep (> 0, <= 1)" + unused,
            min=0.0,
            max=1.0,
            min_exclusive=True,
        ),
        parameter(
            "atol",
            91,
            1e-10,
            None,
            "absolute tolerance of the integrator (all states, SI units; the play chain's rate dd: atol x sqrt(ki/I); > 0)"
            + unused,
            min=0.0,
            min_exclusive=True,
        ),
        Variable(
            name="debug_raise",
            vr=99,
            type=INTEGER,
            causality="parameter",
            variability="tunable",
            description="testing aid: 1 makes the next doStep raise a Python exception, 2 raise inside the compiled step "
            "(both reported as fmi2Error)",
            unit=None,
            start=0,
            initial="exact",
            min=0,
            max=2,
        ),
    )


BASE_OSCILLATOR = FmuSpec(
    model_name="BaseOscillator",
    model_identifier="BaseOscillator",
    description="Base oscillator of Brzeski & Perlikowski (2017): M xdd + C xd + K x = F cos(w t) - f_link",
    variables=(
        *_registry_parameters("base"),
        parameter("x0", 5, 0.0, "m", "initial base displacement"),
        parameter("xd0", 6, 0.0, "m/s", "initial base velocity"),
        Variable(
            name="f_link",
            vr=10,
            type=REAL,
            causality="input",
            variability="continuous",
            description="force of the TMD links on the base, positive when it pushes the base in -x (= TMDInerter.force)",
            unit="N",
            start=0.0,
        ),
        Variable(
            name="x",
            vr=20,
            type=REAL,
            causality="output",
            variability="continuous",
            description="base displacement",
            unit="m",
            initial="calculated",
            initial_depends_on=("x0",),
        ),
        Variable(
            name="xd",
            vr=21,
            type=REAL,
            causality="output",
            variability="continuous",
            description="base velocity",
            unit="m/s",
            initial="calculated",
            initial_depends_on=("xd0",),
        ),
        Variable(
            name="xdd",
            vr=22,
            type=REAL,
            causality="output",
            variability="continuous",
            description="base acceleration",
            unit="m/s2",
            initial="calculated",
            depends_on=("f_link",),
            dependencies_kind=("fixed",),
            initial_depends_on=_BASE_PARS + ("x0", "xd0", "f_link"),
        ),
        Variable(
            name="f_exc",
            vr=23,
            type=REAL,
            causality="output",
            variability="continuous",
            description="excitation force F cos(w t)",
            unit="N",
            initial="calculated",
            initial_depends_on=("F", "w"),
        ),
        Variable(
            name="xdd_free",
            vr=24,
            type=REAL,
            causality="output",
            variability="continuous",
            description="base acceleration without the link force, (F cos(w t) - C xd - K x)/M: the input of a "
            "TMDInerter with base_compliance = 1/M",
            unit="m/s2",
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
    variables=(
        *_registry_parameters("tmd"),
        parameter("y0", 11, 0.0, "m", "initial TMD displacement"),
        parameter("yd0", 12, 0.0, "m/s", "initial TMD velocity"),
        parameter("d0", 13, 0.0, "m", "initial play-chain deflection d = r - y (play model)"),
        parameter("dd0", 14, 0.0, "m/s", "initial play-chain deflection rate (play model)"),
        parameter(
            "base_compliance",
            15,
            0.0,
            "1/kg",
            "interface Jacobian -d xdd/d force = 1/M of the body the TMD is mounted on. 0 (default): "
            "xdd is the base acceleration. > 0: xdd is the base acceleration without this TMD's force "
            "(BaseOscillator.xdd_free) and the TMD adds the base's reaction -force/M within each step",
            min=0.0,
        ),
        Variable(
            name="x",
            vr=30,
            type=REAL,
            causality="input",
            variability="continuous",
            description="base displacement",
            unit="m",
            start=0.0,
        ),
        Variable(
            name="xd",
            vr=31,
            type=REAL,
            causality="input",
            variability="continuous",
            description="base velocity",
            unit="m/s",
            start=0.0,
        ),
        Variable(
            name="xdd",
            vr=32,
            type=REAL,
            causality="input",
            variability="continuous",
            description="base acceleration (without this TMD's force when base_compliance > 0)",
            unit="m/s2",
            start=0.0,
        ),
        Variable(
            name="force",
            vr=40,
            type=REAL,
            causality="output",
            variability="continuous",
            description="force of the TMD links on the base, positive in -x on the base (+y on the TMD)",
            unit="N",
            initial="calculated",
            depends_on=("x", "xd", "xdd"),
            dependencies_kind=("fixed", "dependent", "fixed"),
            initial_depends_on=_TMD_PARS + ("y0", "yd0", "d0", "dd0", "base_compliance", "x", "xd", "xdd"),
        ),
        Variable(
            name="y",
            vr=41,
            type=REAL,
            causality="output",
            variability="continuous",
            description="TMD displacement",
            unit="m",
            initial="calculated",
            initial_depends_on=("y0",),
        ),
        Variable(
            name="yd",
            vr=42,
            type=REAL,
            causality="output",
            variability="continuous",
            description="TMD velocity",
            unit="m/s",
            initial="calculated",
            initial_depends_on=("yd0",),
        ),
        Variable(
            name="inerter_force",
            vr=43,
            type=REAL,
            causality="output",
            variability="continuous",
            description="force P carried by the inerter chain (diagnostic)",
            unit="N",
            initial="calculated",
            depends_on=("x", "xd", "xdd"),
            dependencies_kind=("fixed", "dependent", "fixed"),
            initial_depends_on=_TMD_PARS + ("y0", "yd0", "d0", "dd0", "base_compliance", "x", "xd", "xdd"),
        ),
        Variable(
            name="contact",
            vr=44,
            type=INTEGER,
            causality="output",
            variability="discrete",
            description="gear contact of the play chain: +1 compression, -1 extension, 0 free",
            unit=None,
            initial="calculated",
            initial_depends_on=("eps", "inerter", "d0"),
        ),
    )
    + _integrator(exact=False),
)


# --- TMDSystem: the base with its TMD-inerter in one FMU (co-simulation and Model Exchange) ----------------

#: the TMD's registry parameters sit at these value references in TMDSystem (its own are the base's)
SYSTEM_TMD_VR = 100


def _system_variables() -> tuple[Variable, ...]:
    """TMDSystem's table: BaseOscillator's and TMDInerter's parameters, start values and outputs under their
    names (the TMD's parameters moved to value references from :data:`SYSTEM_TMD_VR`, the base's outputs x,
    xd, xdd where both have one), the chain's states d, dd, the states' derivatives and the event indicators
    (Model Exchange), the coupled integrator's tolerances."""
    base = {v.name: v for v in BASE_OSCILLATOR.variables}
    tmd = {v.name: v for v in TMD_INERTER.variables}

    def out(v: Variable) -> Variable:  # an output of the system: no inputs, computed from the state
        return replace(v, depends_on=(), dependencies_kind=(), initial_depends_on=None)

    def local(name: str, vr: int, unit: str | None, doc: str, **kw: Any) -> Variable:
        return Variable(
            name=name, vr=vr, type=REAL, causality="local", variability="continuous", description=doc, unit=unit,
            initial="calculated", **kw,
        )  # fmt: skip

    states = (("x", "m"), ("xd", "m/s"), ("y", "m"), ("yd", "m/s"), ("d", "m"), ("dd", "m/s"))
    rate = {"m": "m/s", "m/s": "m/s2"}
    return (
        *(base[p.fmu_name] for p in registry.of("base")),
        *(replace(tmd[p.fmu_name], vr=SYSTEM_TMD_VR + p.fmu_vr) for p in registry.of("tmd")),
        base["x0"],
        base["xd0"],
        *(tmd[n] for n in ("y0", "yd0", "d0", "dd0")),
        *(out(base[n]) for n in ("x", "xd", "xdd", "f_exc", "xdd_free")),
        *(out(tmd[n]) for n in ("force", "y", "yd", "inerter_force", "contact")),
        local("d", 45, "m", "play-chain deflection d = r - y (a state; 0 unless the inerter has play)"),
        local("dd", 46, "m/s", "play-chain deflection rate (a state; 0 unless the inerter has play)"),
        *(
            local(f"der({n})", 50 + i, rate[u], f"time derivative of the state {n}", derivative_of=n)
            for i, (n, u) in enumerate(states)
        ),
        local(
            "g_friction", 60, "m/s", "event indicator: the friction's relative velocity xd - yd (1 without friction)",
            event_indicator=True,
        ),
        local(
            "g_compression", 61, "m", "event indicator: d - eps, the gear's contact in compression (1 without a gap)",
            event_indicator=True,
        ),
        local(
            "g_extension", 62, "m", "event indicator: d + eps, the gear's contact in extension (1 without a gap)",
            event_indicator=True,
        ),
        parameter(
            "rtol", 90, 1e-8, None, "relative tolerance of the coupled RODAS4 integrator inside doStep (> 0, <= 1; "
            "co-simulation only: in Model Exchange the host integrates)", min=0.0, max=1.0, min_exclusive=True,
        ),
        parameter(
            "atol", 91, 1e-7, None, "absolute tolerance of that integrator as a fraction of the static deflection "
            "F/K (rates scaled by the natural frequency; the monolithic solver's atol_scale; > 0)",
            min=0.0, min_exclusive=True,
        ),
    )  # fmt: skip


TMD_SYSTEM = FmuSpec(
    model_name="TMDSystem",
    model_identifier="TMDSystem",
    description="Base oscillator of Brzeski & Perlikowski (2017) with its TMD-inerter (none/ideal/with play, "
    "friction, cubic spring) as one FMU: co-simulation and Model Exchange",
    variables=_system_variables(),
)
