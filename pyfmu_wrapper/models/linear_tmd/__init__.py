"""The base oscillator with a plain linear TMD (mass, spring, viscous damper; no inerter) as one model
unit: parameters (:mod:`.params`), equations (:mod:`.equations`), their packing (:mod:`.packing`), and
here the unit (state layout, tolerances, its FMU). Registered in :mod:`pyfmu_wrapper.models`.

The absorber is part of the structure (:class:`~.params.LinearTMDParams`), so the model takes no
paper TMD (``takes_tmd=False``: its scenario files have a ``linear_tmd:`` block and no ``tmd:`` block).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ...physics.models import smooth_model
from ...physics.params import TMDParams
from ...physics.unit import LinearCompanion, ModelUnit, same_configuration
from .equations import linear_tmd_jacobian, linear_tmd_rhs
from .modelica import MODELICA
from .packing import linear_tmd_pack
from .params import PARAMETERS, SUBSYSTEM, LinearTMDParams

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel

__all__ = ["LINEAR_TMD", "UNIT", "LinearTMDParams", "linear_tmd_pack"]


def fmus() -> tuple[FmuModel, ...]:
    """The model's FMU, LinearTMD, imported on the first call: importing the unit stays cheap."""
    from .fmus.linear_tmd_fmu import FMU

    return (FMU,)


def _atol(s: LinearTMDParams, tmd: TMDParams, omega: float, atol_scale: float) -> NDArray[np.float64]:
    """The paper's rule: atol_scale times the static deflection F / K for displacements, times the
    larger of w and the fastest own frequency for velocities."""
    xs = abs(s.force_amplitude) / s.stiffness
    xs = xs if xs > 0 else 1e-3
    a = atol_scale * xs
    wn = max(omega, s.natural_frequency, 1.0)
    return np.array([a, a * wn, a, a * wn])


def _inerter_force(z: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    """No inerter: 0."""
    return 0.0


def _n_state(s: LinearTMDParams) -> int:
    return 4


def _active(s: LinearTMDParams, tmd: TMDParams) -> list[int]:
    """A detached absorber floats (its period map has the eigenvalue 1): shoot on the main mass only."""
    return [0, 1] if s.detached else [0, 1, 2, 3]


def _is_linear(s: LinearTMDParams, tmd: TMDParams) -> bool:
    """Every parameter enters linearly."""
    return True


LINEAR_TMD = smooth_model("linear_tmd", linear_tmd_rhs, linear_tmd_jacobian, ("x", "xd", "y", "yd"))

UNIT = ModelUnit(
    name=SUBSYSTEM,
    ode=LINEAR_TMD,
    structure=LinearTMDParams,
    parameters=PARAMETERS,
    pack=linear_tmd_pack,
    n_state=_n_state,
    atol=_atol,
    active=_active,
    inerter_force=_inerter_force,
    example=LinearTMDParams,
    description="a base oscillator with a plain linear TMD (mass, spring, viscous damper; no inerter)",
    takes_tmd=False,
    modelica=MODELICA,
    is_linear=_is_linear,
    start=LinearCompanion(same_configuration),
    home=__name__,
    fmus=fmus,
)
