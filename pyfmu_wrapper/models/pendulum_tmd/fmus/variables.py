"""The variable table of the PendulumTMD FMU: the pendulum (a mass m on a massless rod of length L, pivot
damper c_p) on a pivot that moves with the body it hangs on, as one FMU.

Mirrors the paper's TMDInerter (``base_tmd/fmus/variables.py``), so that it couples to a BaseOscillator as the
TMDInerter does: inputs ``x``, ``xd``, ``xdd`` (the pivot body's motion; with ``base_compliance`` = 1/M,
``xdd`` is its acceleration without the rod's force, BaseOscillator.xdd_free: the interface Jacobian), output
``force`` (the rod's force on the body, positive in -x: m ydd, y = x + L sin th the bob's horizontal position;
= BaseOscillator.f_link) and the bob's ``y``, ``yd`` (the momentum coupling's source: ``force`` is m d(yd)/dt).
Parameters: the model's declared rows of the pendulum (:data:`~pyfmu_wrapper.models.pendulum_tmd.params.OWN`:
their FMU names and value references), the start angle and rate, the compliance, the integrator's tolerances.
Its slave is :mod:`.slave`; the FMU is declared by :mod:`.pendulum_tmd_fmu`.
"""

from __future__ import annotations

from ....fmi.varspec import INTEGER, REAL, FmuSpec, Variable, parameter
from ..params import OWN, PARAMETERS

#: the pendulum's declared rows, in the order of the FMU's parameters
ROWS = tuple(p for p in PARAMETERS if p.name in OWN)
_PARS = tuple(p.fmu_name for p in ROWS)


def _input(name: str, vr: int, unit: str, doc: str) -> Variable:
    return Variable(
        name=name, vr=vr, type=REAL, causality="input", variability="continuous", description=doc, unit=unit, start=0.0
    )


def _output(name: str, vr: int, unit: str, doc: str, initial: tuple[str, ...], feedthrough: bool = False) -> Variable:
    return Variable(
        name=name,
        vr=vr,
        type=REAL,
        causality="output",
        variability="continuous",
        description=doc,
        unit=unit,
        initial="calculated",
        depends_on=("xdd",) if feedthrough else (),
        dependencies_kind=("dependent",) if feedthrough else (),
        initial_depends_on=initial,
    )


PENDULUM_TMD_FMU = FmuSpec(
    model_name="PendulumTMD",
    model_identifier="PendulumTMD",
    description="Pendulum TMD (mass m on a massless rod of length L, pivot damper c_p) on a pivot driven by the "
    "motion of the body it hangs on; returns the rod's force on that body",
    variables=(
        *(
            parameter(
                p.fmu_name,
                p.fmu_vr,
                float(p.default),
                p.unit,
                f"{p.symbol}: {p.description}",
                min=p.minimum,
                min_exclusive=p.strict and p.minimum is not None,
            )
            for p in ROWS
        ),
        parameter("th0", 11, 0.0, "rad", "initial pendulum angle from the hanging position"),
        parameter("thd0", 12, 0.0, "rad/s", "initial pendulum angular velocity"),
        parameter(
            "base_compliance",
            15,
            0.0,
            "1/kg",
            "interface Jacobian -d xdd/d force = 1/M of the body the pendulum hangs on. 0 (default): xdd is the "
            "pivot's acceleration. > 0: xdd is the body's acceleration without the rod's force "
            "(BaseOscillator.xdd_free) and the pendulum adds the body's reaction -force/M at every instant of a step",
            min=0.0,
        ),
        _input("x", 30, "m", "displacement of the body the pendulum hangs on (the pivot) at the start of a step"),
        _input("xd", 31, "m/s", "velocity of that body (the pivot) at the start of a step"),
        _input("xdd", 32, "m/s2", "acceleration of that body (without the rod's force when base_compliance > 0)"),
        _output(
            "force",
            40,
            "N",
            "force of the rod on the body it hangs on, positive in -x on the body: m ydd, the bob's mass times its "
            "horizontal acceleration (= BaseOscillator.f_link)",
            _PARS + ("th0", "thd0", "base_compliance", "xdd"),
            feedthrough=True,
        ),
        _output(
            "y",
            41,
            "m",
            "horizontal position of the bob, x + L sin th (the pivot as the pendulum integrated it over the last "
            "step, from x at its start)",
            ("L", "th0", "x"),
        ),
        _output("yd", 42, "m/s", "horizontal velocity of the bob, xd + L cos th thd", ("L", "th0", "thd0", "xd")),
        _output("th", 43, "rad", "pendulum angle from the hanging position", ("th0",)),
        _output("thd", 44, "rad/s", "pendulum angular velocity", ("thd0",)),
        parameter(
            "rtol",
            90,
            1e-8,
            None,
            "relative tolerance of the RODAS4 integrator inside doStep (> 0, <= 1)",
            min=0.0,
            max=1.0,
            min_exclusive=True,
        ),
        parameter(
            "atol",
            91,
            1e-10,
            None,
            "absolute tolerance of the integrator: of the pivot's displacement and velocity (SI units), of the "
            "angle and its rate atol / L (the bob's swing; > 0)",
            min=0.0,
            min_exclusive=True,
        ),
        Variable(
            name="debug_raise",
            vr=99,
            type=INTEGER,
            causality="parameter",
            variability="tunable",
            description="testing aid: 1 makes the next doStep raise a Python exception, 2 raise inside the compiled "
            "step (both reported as fmi2Error)",
            unit=None,
            start=0,
            initial="exact",
            min=0,
            max=2,
        ),
    ),
)
