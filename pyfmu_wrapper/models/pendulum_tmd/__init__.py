"""The base oscillator with a pendulum TMD (a mass on a massless rod pivoted on the main mass, with a
pivot damper) as one model unit: parameters (:mod:`.params`), equations (:mod:`.equations`), Modelica
source (:mod:`.modelica`), its FMU PendulumTMD (:mod:`.fmus`), its co-simulation with the paper's
BaseOscillator (:mod:`.cosim`), and here the unit (packing, state layout, tolerances, start). Registered in
:mod:`pyfmu_wrapper.models`.

The absorber is part of the structure (:class:`~.params.PendulumTMDParams`), so the model takes no paper
TMD (``takes_tmd=False``: its scenario files have a ``pendulum_tmd:`` block and no ``tmd:`` block). It is
nonlinear in its own way and has no linear configuration nearby: its periodic solutions start from the
linearisation about rest and are continued in the force (:class:`~pyfmu_wrapper.physics.unit.SmallForcing`).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ...physics.models import smooth_model
from ...physics.params import TMDParams
from ...physics.unit import ModelUnit, SmallForcing
from .equations import pendulum_tmd_jacobian, pendulum_tmd_rhs
from .modelica import MODELICA
from .packing import pendulum_tmd_pack
from .params import PARAMETERS, SUBSYSTEM, PendulumTMDParams

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel

__all__ = ["PENDULUM_TMD", "UNIT", "PendulumTMDParams", "pendulum_tmd_pack"]


def fmus() -> tuple[FmuModel, ...]:
    """The model's FMU, PendulumTMD (its co-simulation couples it to the paper's BaseOscillator, which
    ``base_tmd`` gives), imported on the first call: importing the unit stays cheap."""
    from .fmus.pendulum_tmd_fmu import FMU

    return (FMU,)


@functools.cache
def _cosim() -> Any:
    """The co-simulation (imported when asked: the FMUs and the master load only for a co-simulation; built
    once per process)."""
    from .cosim import engine

    return engine(UNIT)


def _atol(s: PendulumTMDParams, tmd: TMDParams, omega: float, atol_scale: float) -> NDArray[np.float64]:
    """The paper's rule: atol_scale times the static deflection F / K for x and F / (K L) for the angle
    (the bob's swing of the same size), times the larger of w and the fastest own frequency for rates."""
    xs = abs(s.force_amplitude) / s.stiffness
    xs = xs if xs > 0 else 1e-3
    a = atol_scale * xs
    b = a / s.length
    wn = max(omega, s.natural_frequency, 1.0)
    return np.array([a, a * wn, b, b * wn])


def _inerter_force(z: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    """No inerter: 0."""
    return 0.0


def _n_state(s: PendulumTMDParams) -> int:
    return 4


def _active(s: PendulumTMDParams, tmd: TMDParams) -> list[int]:
    """Every state: the damped pendulum has no floating mode."""
    return [0, 1, 2, 3]


def _is_linear(s: PendulumTMDParams, tmd: TMDParams) -> bool:
    """The angle enters through sin and cos: never linear."""
    return False


PENDULUM_TMD = smooth_model("pendulum_tmd", pendulum_tmd_rhs, pendulum_tmd_jacobian, ("x", "xd", "th", "thd"))

UNIT = ModelUnit(
    name=SUBSYSTEM,
    ode=PENDULUM_TMD,
    structure=PendulumTMDParams,
    parameters=PARAMETERS,
    pack=pendulum_tmd_pack,
    n_state=_n_state,
    atol=_atol,
    active=_active,
    inerter_force=_inerter_force,
    example=PendulumTMDParams,
    description="a base oscillator with a pendulum TMD (a mass on a massless rod, pivot damper)",
    takes_tmd=False,
    modelica=MODELICA,
    is_linear=_is_linear,
    start=SmallForcing(),
    cosim=_cosim,
    fmus=fmus,
    home=__name__,
)
