"""The variable table of the FrameSystem FMU: the shear frame of 1 to 20 storeys with its TMD-inerter (TMD or
TMDI) as one FMU, co-simulation and Model Exchange.

Its parameters are ShearFrame's (``storeys`` structural, the per-storey values declared for 20 storeys, those
above ``storeys`` not used; the same value references) and TMDInerter's (moved to value references from
:data:`~pyfmu_wrapper.models.base_tmd.fmus.variables.SYSTEM_TMD_VR`, as in TMDSystem), its outputs ShearFrame's
(the frame's, where both have one) and TMDInerter's. Where a name is both a storey's and the TMD's, the
storey's wins: the TMD's cubic stiffness ``k3`` is ``k_cubic`` here (``k3`` is storey 3's stiffness). The continuous states are declared for the largest frame,
in the frame model's layout for 20 storeys (the top storey first, the TMD's four, the storeys down:
``x_20, xd_20, y, yd, d, dd, x_19, ..., xd_1``, one value per storey by its number); a frame of fewer
storeys leaves the states of the storeys above its top at their start values (0), with derivative 0.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ....fmi.varspec import REAL, FmuSpec, Variable, parameter
from ....physics import registry
from ...base_tmd.fmus.variables import SYSTEM_TMD_VR, TMD_INERTER
from ..params import MAX_STOREYS
from .variables import SHEAR_FRAME

#: value references of the storeys' states x_i, xd_i and of the derivatives of every state
VR_XS, VR_XDS, VR_DER = 700, 720, 740


def state_names() -> list[str]:
    """The continuous states in the order of the state vector (the frame model's layout for 20 storeys)."""
    names = ["x_20", "xd_20", "y", "yd", "d", "dd"]
    for i in range(MAX_STOREYS - 1, 0, -1):
        names += [f"x_{i}", f"xd_{i}"]
    return names


#: TMDInerter's parameters whose names a storey's parameter has (the frame's wins): their names here
RENAMED = {"k3": "k_cubic"}


def tmd_name(name: str) -> str:
    """FrameSystem's name of a TMDInerter parameter (the TMD's cubic stiffness k3 is ``k_cubic``: ``k3`` is storey
    3's stiffness)."""
    return RENAMED.get(name, name)


def _variables() -> tuple[Variable, ...]:
    frame = {v.name: v for v in SHEAR_FRAME.variables}
    tmd = {v.name: v for v in TMD_INERTER.variables}

    def out(v: Variable) -> Variable:  # an output of the system: no inputs, computed from the state
        return replace(v, depends_on=(), dependencies_kind=(), initial_depends_on=None)

    def local(name: str, vr: int, unit: str | None, doc: str, **kw: Any) -> Variable:
        return Variable(
            name=name, vr=vr, type=REAL, causality="local", variability="continuous", description=doc, unit=unit,
            initial="calculated", **kw,
        )  # fmt: skip

    frame_pars = [v for v in SHEAR_FRAME.variables if v.causality == "parameter" and v.name not in ("rtol", "atol")]
    storeys = []
    for i in range(1, MAX_STOREYS + 1):
        storeys.append(local(f"x_{i}", VR_XS + i - 1, "m", f"displacement of storey {i} (a state; not used above "
                             "the top storey)"))  # fmt: skip
        storeys.append(local(f"xd_{i}", VR_XDS + i - 1, "m/s", f"velocity of storey {i} (a state)"))
    unit = {"x": "m/s", "xd": "m/s2", "y": "m/s", "yd": "m/s2", "d": "m/s", "dd": "m/s2"}
    ders = [
        local(f"der({n})", VR_DER + k, unit[n.split("_")[0]], f"time derivative of the state {n}", derivative_of=n)
        for k, n in enumerate(state_names())
    ]
    return (
        *frame_pars,
        *(
            replace(tmd[p.fmu_name], vr=SYSTEM_TMD_VR + p.fmu_vr, name=tmd_name(p.fmu_name))
            for p in registry.of("tmd")
        ),
        *(tmd[n] for n in ("y0", "yd0", "d0", "dd0")),
        *(out(frame[n]) for n in ("x_top", "xd_top", "x", "xd", "xdd")),
        *(out(tmd[n]) for n in ("force", "y", "yd", "inerter_force", "contact")),
        local("d", 45, "m", "play-chain deflection d = r - y (a state; 0 unless the inerter has play)"),
        local("dd", 46, "m/s", "play-chain deflection rate (a state; 0 unless the inerter has play)"),
        *storeys,
        *ders,
        local("g_friction", 60, "m/s", "event indicator: the friction's relative velocity (TMD storey's xd - yd; 1 "
              "without friction)", event_indicator=True),  # fmt: skip
        local("g_compression", 61, "m", "event indicator: d - eps, the gear's contact in compression (1 without a "
              "gap)", event_indicator=True),  # fmt: skip
        local("g_extension", 62, "m", "event indicator: d + eps, the gear's contact in extension (1 without a gap)",
              event_indicator=True),  # fmt: skip
        parameter(
            "rtol", 90, 1e-8, None, "relative tolerance of the frame's RODAS4 integrator inside doStep (> 0, <= 1; "
            "co-simulation only: in Model Exchange the host integrates)", min=0.0, max=1.0, min_exclusive=True,
        ),
        parameter(
            "atol", 91, 1e-7, None, "absolute tolerance of that integrator as a fraction of the static deflection "
            "bound F/K (rates scaled by the fastest storey's frequency; the monolithic solver's atol_scale; > 0)",
            min=0.0, min_exclusive=True,
        ),
    )  # fmt: skip


FRAME_SYSTEM = FmuSpec(
    model_name="FrameSystem",
    model_identifier="FrameSystem",
    description="Shear frame of 1-20 storeys with the TMD-inerter (TMD or TMDI; none/ideal/with play, friction, "
    "cubic spring) as one FMU: co-simulation and Model Exchange",
    variables=_variables(),
)
