"""The variable table of the LinearTMD FMU: the main mass with its plain linear absorber, as one FMU.

Parameters: the model's declared rows (:data:`~pyfmu_wrapper.models.linear_tmd.params.PARAMETERS`: their
FMU names and value references), the excitation's angular frequency ``w`` and the start state. Input:
``f_ext``, a force on the main mass besides F cos(w t) (to couple the model to another structure).
Outputs: the state and the main mass's acceleration, which feeds through from ``f_ext``. Its slave is
:mod:`.slave`; the FMU is declared by :mod:`.linear_tmd_fmu`.
"""

from __future__ import annotations

from ....fmi.varspec import REAL, FmuSpec, Variable, parameter
from ..params import PARAMETERS

_PARS = tuple(p.fmu_name for p in PARAMETERS) + ("w",)
_STARTS = ("x0", "xd0", "y0", "yd0")


def _out(name: str, vr: int, unit: str, doc: str, start: str, feedthrough: bool = False) -> Variable:
    return Variable(
        name=name,
        vr=vr,
        type=REAL,
        causality="output",
        variability="continuous",
        description=doc,
        unit=unit,
        initial="calculated",
        depends_on=("f_ext",) if feedthrough else (),
        dependencies_kind=("fixed",) if feedthrough else (),
        initial_depends_on=(_PARS + _STARTS + ("f_ext",)) if feedthrough else (start,),
    )


LINEAR_TMD_FMU = FmuSpec(
    model_name="LinearTMD",
    model_identifier="LinearTMD",
    description="Main mass on K and C under F cos(w t) + f_ext, with a plain linear TMD (m, k, c; no inerter)",
    variables=(
        *(
            parameter(
                p.fmu_name,
                p.fmu_vr,
                float(p.default),
                None if p.unit == "1" else p.unit,
                f"{p.symbol}: {p.description}",
                min=p.minimum,
                min_exclusive=p.strict and p.minimum is not None,
            )
            for p in PARAMETERS
        ),
        parameter("w", 7, 20.0, "rad/s", "w: excitation angular frequency", min=0.0),
        parameter("x0", 8, 0.0, "m", "initial displacement of the main mass"),
        parameter("xd0", 9, 0.0, "m/s", "initial velocity of the main mass"),
        parameter("y0", 10, 0.0, "m", "initial displacement of the absorber"),
        parameter("yd0", 11, 0.0, "m/s", "initial velocity of the absorber"),
        Variable(
            name="f_ext",
            vr=20,
            type=REAL,
            causality="input",
            variability="continuous",
            description="force on the main mass besides F cos(w t), positive in +x",
            unit="N",
            start=0.0,
        ),
        _out("x", 30, "m", "displacement of the main mass", "x0"),
        _out("xd", 31, "m/s", "velocity of the main mass", "xd0"),
        _out("xdd", 32, "m/s2", "acceleration of the main mass (with f_ext)", "", feedthrough=True),
        _out("y", 33, "m", "displacement of the absorber", "y0"),
        _out("yd", 34, "m/s", "velocity of the absorber", "yd0"),
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
            "absolute tolerance of the integrator (all states, SI units; > 0)",
            min=0.0,
            min_exclusive=True,
        ),
    ),
)
