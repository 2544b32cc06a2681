"""The multi-storey shear frame with the paper's TMD-inerter attached to any storey (TMDI included),
as one model unit: parameters (:mod:`.params`), equations (:mod:`.equations`), their packing
(:mod:`.packing`), and here the unit (state layout, tolerances, its FMU). Registered in
:mod:`pyfmu_wrapper.models`.

With one storey and the inerter on that storey it is the paper's base oscillator with the
TMD-inerter, in the paper's state layout (tests/test_frame_model.py holds the two to 1e-12).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ...physics.kernels import inerter_force
from ...physics.params import TMDParams
from ...physics.tmd import active_states
from ...physics.unit import ModelUnit
from .effects import VOCABULARY
from .equations import (
    F_N,
    F_TMD,
    F_TO,
    frame_rhs,
    storey_index,
)
from .modelica import MODELICA
from .ode import FRAME
from .packing import frame_pack
from .params import PARAMETERS, FrameParams
from .scenario import read_frame
from .tolerances import frame_atol

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel

__all__ = ["UNIT", "FrameParams", "frame_pack", "storey_index"]


def fmus() -> tuple[FmuModel, ...]:
    """The frame's FMUs, ShearFrame (its TMD's FMU is the paper's TMDInerter, which ``base_tmd`` declares) and
    FrameSystem (the frame with its TMD-inerter in one FMU, co-simulation and Model Exchange), imported on the
    first call: importing the unit stays cheap."""
    from .fmus.frame_system import FMU as FRAME_SYSTEM
    from .fmus.shear_frame import FMU

    return (FMU, FRAME_SYSTEM)


def _n_state(frame: FrameParams) -> int:
    return 2 * frame.n + 4


def _atol(frame: FrameParams, tmd: TMDParams, omega: float, atol_scale: float) -> NDArray[np.float64]:
    """The paper's rule per storey: atol_scale times the static deflection bound F / K (rates: times
    the larger of w and the fastest storey's sqrt(K_i / M_i)); the play chain's as the paper's
    (:func:`.tolerances.frame_atol`)."""
    atol = np.empty(_n_state(frame))
    frame_atol(frame_pack(frame, tmd, omega), atol_scale, atol)
    return atol


def _inerter_force(z: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    """P = I (xdd_j - ydd) through the kernels' :func:`~pyfmu_wrapper.physics.kernels.inerter_force`
    at the TMD's storey, with the terminal's acceleration."""
    n, s, j = int(p[F_N]), int(p[F_TMD]), int(p[F_TO])
    f = np.empty(z.shape[0])
    frame_rhs(0.0, z, p, np.zeros(1), f)
    sx = storey_index(s, n)
    zt = np.array([z[sx], z[sx + 1], z[2], z[3], z[4], z[5]])
    return float(inerter_force(zt, f[storey_index(j, n) + 1] if j > 0 else 0.0, p))


def _active(frame: FrameParams, tmd: TMDParams) -> list[int]:
    return active_states(tmd, _n_state(frame))


def _example() -> FrameParams:
    return FrameParams.uniform(3, 100.0, 1.2e5, 100.0, tmd_storey=3, inerter_to=2)


@functools.cache
def _cosim() -> Any:
    """The frame's co-simulation (imported when asked: the FMUs and the master load only for a co-simulation)."""
    from .cosim import engine

    return engine(UNIT)


UNIT = ModelUnit(
    name="frame",
    ode=FRAME,
    structure=FrameParams,
    parameters=PARAMETERS,
    pack=frame_pack,
    n_state=_n_state,
    atol=_atol,
    active=_active,
    inerter_force=_inerter_force,
    cosim=_cosim,
    fmus=fmus,
    modelica=MODELICA,
    scenario_reader=read_frame,
    example=_example,
    description="a shear frame of 1-20 storeys with the TMD-inerter on any storey (TMDI: inerter to another storey or the ground)",
    home=__name__,
    effects=VOCABULARY,
)
