"""The variable table of the ShearFrame FMU: a shear frame of 1 to 20 storeys (the number of storeys
``storeys`` is a structural parameter; the per-storey parameters and start states are declared for 20
storeys, those above ``storeys`` are not used), driven by the TMDInerter FMU's forces.

Inputs: ``f_link``, the TMD's total force on the structure (TMDInerter.force), and ``f_inerter``, its
inerter's share (TMDInerter.inerter_force): f_link - f_inerter acts on the TMD's storey, f_inerter on
the inerter's terminal (nothing when it is the ground). Outputs: the top storey's motion (the reported
amplitude), the TMD storey's motion and the terminal's acceleration (the TMDInerter's inputs).
The frame's physics is :mod:`pyfmu_wrapper.models.frame_model`; its step is exact (:mod:`.step`); the FMU is declared by :mod:`.shear_frame`.
"""

from __future__ import annotations

from typing import Any

from ....fmi.varspec import REAL, FmuSpec, Variable, parameter
from ..params import MAX_STOREYS

#: value references: per-storey blocks of 20 from these bases (storey i at base + i - 1)
VR_MASS, VR_STIFFNESS, VR_DAMPING, VR_X0, VR_XD0 = 200, 300, 400, 500, 600
#: value references of the per-storey state outputs x_i, xd_i (storey i at base + i - 1)
VR_X, VR_XD = 700, 800


def _per_storey(prefix: str, base: int, start: float, unit: str, doc: str, **kw: Any) -> tuple[Variable, ...]:
    return tuple(
        parameter(f"{prefix}{i}", base + i - 1, start, unit, f"{doc} of storey {i}", **kw)
        for i in range(1, MAX_STOREYS + 1)
    )


_PARS = ("storeys", "F", "w", "force_storey", "tmd_storey", "inerter_to")
_ALL_PARS = (
    _PARS
    + tuple(f"m{i}" for i in range(1, 21))
    + tuple(f"k{i}" for i in range(1, 21))
    + tuple(f"c{i}" for i in range(1, 21))
)
_STARTS = tuple(f"x0_{i}" for i in range(1, 21)) + tuple(f"xd0_{i}" for i in range(1, 21))


def _out(name: str, vr: int, unit: str, doc: str, feedthrough: bool) -> Variable:
    return Variable(
        name=name,
        vr=vr,
        type=REAL,
        causality="output",
        variability="continuous",
        description=doc,
        unit=unit,
        initial="calculated",
        depends_on=("f_link", "f_inerter") if feedthrough else (),
        dependencies_kind=("fixed", "fixed") if feedthrough else (),
        initial_depends_on=_ALL_PARS + _STARTS + (("f_link", "f_inerter") if feedthrough else ()),
    )


SHEAR_FRAME = FmuSpec(
    model_name="ShearFrame",
    model_identifier="ShearFrame",
    description="Shear frame of 1-20 storeys under F cos(w t) on one storey, driven by a TMD's forces on two storeys",
    variables=(
        parameter("storeys", 0, 1, None, "number of storeys n (structural)", min=1, max=MAX_STOREYS),
        parameter("F", 1, 200.0, "N", "F: amplitude of the excitation F cos(w t)"),
        parameter("w", 2, 20.0, "rad/s", "w: excitation angular frequency", min=0.0, min_exclusive=True),
        parameter("force_storey", 3, 0, None, "the storey the force acts on (0: the top)", min=0, max=MAX_STOREYS),
        parameter("tmd_storey", 4, 0, None, "the storey the TMD hangs on (0: the top)", min=0, max=MAX_STOREYS),
        parameter(
            "inerter_to",
            5,
            -1,
            None,
            "the inerter's second terminal: a storey, 0 the ground, -1 the TMD's storey",
            min=-1,
            max=MAX_STOREYS,
        ),
        *_per_storey("m", VR_MASS, 100.0, "kg", "mass", min=0.0, min_exclusive=True),
        *_per_storey("k", VR_STIFFNESS, 4.0e4, "N/m", "stiffness to the storey below", min=0.0, min_exclusive=True),
        *_per_storey("c", VR_DAMPING, 100.0, "N.s/m", "viscous damping to the storey below", min=0.0),
        *_per_storey("x0_", VR_X0, 0.0, "m", "initial displacement"),
        *_per_storey("xd0_", VR_XD0, 0.0, "m/s", "initial velocity"),
        Variable(
            name="f_link",
            vr=10,
            type=REAL,
            causality="input",
            variability="continuous",
            description="the TMD's total force on the structure (TMDInerter.force)",
            unit="N",
            start=0.0,
        ),
        Variable(
            name="f_inerter",
            vr=11,
            type=REAL,
            causality="input",
            variability="continuous",
            description="the inerter's share of it (TMDInerter.inerter_force)",
            unit="N",
            start=0.0,
        ),
        _out("x_top", 20, "m", "displacement of the top storey", False),
        _out("xd_top", 21, "m/s", "velocity of the top storey", False),
        _out("x", 22, "m", "displacement of the TMD's storey (TMDInerter.x)", False),
        _out("xd", 23, "m/s", "velocity of the TMD's storey (TMDInerter.xd)", False),
        _out("xdd", 24, "m/s2", "acceleration of the inerter's terminal, 0 for the ground (TMDInerter.xdd)", True),
        _out(
            "xdd_free",
            25,
            "m/s2",
            "acceleration of the inerter's terminal without the TMD's forces: the input of a TMDInerter with "
            "base_compliance = 1/M of that storey (when the terminal is the TMD's storey)",
            False,
        ),
        *(
            _out(f"x_{i}", VR_X + i - 1, "m", f"displacement of storey {i} (0 above the top)", False)
            for i in range(1, MAX_STOREYS + 1)
        ),
        *(
            _out(f"xd_{i}", VR_XD + i - 1, "m/s", f"velocity of storey {i} (0 above the top)", False)
            for i in range(1, MAX_STOREYS + 1)
        ),
        parameter(
            "rtol",
            90,
            1e-8,
            None,
            "relative tolerance of an integrator inside doStep (not used: ShearFrame steps exactly, by the matrix "
            "exponential of the linear frame with its drives)",
            min=0.0,
            max=1.0,
            min_exclusive=True,
        ),
        parameter(
            "atol",
            91,
            1e-10,
            None,
            "absolute tolerance of an integrator (all states, SI units; not used: ShearFrame steps exactly)",
            min=0.0,
            min_exclusive=True,
        ),
    ),
)
