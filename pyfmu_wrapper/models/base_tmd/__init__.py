"""The paper's model as a unit: the base oscillator with the TMD-inerter (Brzeski & Perlikowski 2017).

State z = [x, xd, y, yd, d, dd] (:mod:`~pyfmu_wrapper.physics.kernels`), parameters
:class:`~pyfmu_wrapper.physics.params.BaseParams` and :class:`~pyfmu_wrapper.physics.params.TMDParams`,
equations :data:`~pyfmu_wrapper.physics.models.COUPLED`, Modelica source and the paper's cases in
:mod:`.modelica`. Registered in :mod:`pyfmu_wrapper.models`.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ...physics import registry
from ...physics.kernels import NSTATE, inerter_force, rhs
from ...physics.models import COUPLED
from ...physics.params import BaseParams, TMDParams, pack
from ...physics.tmd import active_states
from ...physics.unit import ModelUnit
from .effects import VOCABULARY
from .modelica import MODELICA
from .scenario import read_base
from .tolerances import coupled_atol

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel


def fmus() -> tuple[FmuModel, ...]:
    """The pair's FMUs, BaseOscillator and TMDInerter (the paper's co-simulation; the frame's uses the
    TMDInerter too), and TMDSystem (the two in one FMU, co-simulation and Model Exchange), imported on the first
    call: importing the unit stays cheap."""
    from .fmus.base_oscillator import FMU as BASE_OSCILLATOR
    from .fmus.tmd_inerter import FMU as TMD_INERTER
    from .fmus.tmd_system import FMU as TMD_SYSTEM

    return (BASE_OSCILLATOR, TMD_INERTER, TMD_SYSTEM)


def _atol(base: BaseParams, tmd: TMDParams, omega: float, atol_scale: float) -> NDArray[np.float64]:
    atol = np.empty(NSTATE)
    coupled_atol(pack(base, tmd, omega), atol_scale, atol)
    return atol


def _inerter_force(z: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    f = np.empty(NSTATE)
    rhs(0.0, z, p, f)
    return float(inerter_force(z, f[1], p))


def _n_state(base: BaseParams) -> int:
    return NSTATE


def _active(base: BaseParams, tmd: TMDParams) -> list[int]:
    return active_states(tmd, NSTATE)


@functools.cache
def _cosim() -> Any:
    """The pair's co-simulation (imported when asked: the FMUs and the master load only for a co-simulation)."""
    from .cosim import engine

    return engine(UNIT)


UNIT = ModelUnit(
    name="base_tmd",
    ode=COUPLED,
    structure=BaseParams,
    parameters=registry.of("base"),
    pack=pack,
    n_state=_n_state,
    atol=_atol,
    active=_active,
    inerter_force=_inerter_force,
    description="the paper's base oscillator with the TMD-inerter (one storey, one TMD)",
    cosim=_cosim,
    fmus=fmus,
    example=BaseParams,
    modelica=MODELICA,
    scenario_block="base",
    scenario_reader=read_base,
    home=__name__,
    effects=VOCABULARY,
)
