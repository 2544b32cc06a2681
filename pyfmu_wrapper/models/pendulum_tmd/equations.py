"""Equations of the base oscillator with a pendulum TMD, numba-compiled with the integrator's signatures
(:mod:`pyfmu_wrapper.physics.models`).

State z = [x, xd, th, thd] (main mass displacement [m] and velocity, pendulum angle from the hanging
position [rad] and its rate; z[0] is the displacement the curves report):

    (M + m) xdd + m L (thdd cos th - thd^2 sin th) + C xd + K x = F cos(w t)
    m L^2 thdd + m L xdd cos th + c_p thd + m g L sin th = 0

The 2x2 mass matrix [[M + m, m L cos th], [m L cos th, m L^2]] is solved explicitly (its determinant
m L^2 (M + m sin^2 th) never vanishes).

Packed parameters: the paper's array's length (:data:`~pyfmu_wrapper.physics.params.N_PARAMS`) with
only F and w set at their ``P_F``, ``P_W`` indices (the excitation
:func:`~pyfmu_wrapper.physics.kernels.excitation` reads them there, and ``ModelUnit.linear_system``
sets them), then M, K, C, m, L, c_p from :data:`Q_AT` on.
"""

from __future__ import annotations

import numpy as np

from ..._jit import njit
from ...physics.jacobians import complex_step_jacobian
from ...physics.kernels import Num, Vec, excitation
from ...physics.params import N_PARAMS
from .params import GRAVITY

#: index of the model's own part of the packed array: M, K, C, m, L, c_p
Q_AT = N_PARAMS
Q_M, Q_K, Q_C, Q_m, Q_L, Q_cp = Q_AT, Q_AT + 1, Q_AT + 2, Q_AT + 3, Q_AT + 4, Q_AT + 5
N_PACKED = Q_AT + 6


@njit(cache=True)
def pendulum_accelerations(g1: float, g2: Num, r: Num, th: Num, thd: Num, p: Vec) -> tuple[Num, Num]:
    """(xdd, thdd): the pivot's acceleration and the angle's, from the pendulum's equation

        m L^2 thdd + m L xdd cos th + c_p thd + m g L sin th = 0

    and the pivot body's, written as g1 xdd = r - g2 f with f = m (xdd + L (thdd cos th - thd^2 sin th))
    the force of the rod on that body (in -x; ``m ydd``, y = x + L sin th the bob's horizontal position):

        (g1 + g2 m) xdd + g2 m L cos th thdd = r + g2 m L thd^2 sin th

    The monolithic model is g1 = M, g2 = 1, r = F cos(w t) - K x - C xd (:func:`pendulum_tmd_rhs`); the
    FMU is g1 = 1, g2 = kappa (the pivot body's compliance 1/M: the interface Jacobian; 0: a prescribed
    pivot), r = its acceleration without the rod's force (``fmus/step.py``). The 2x2 mass matrix is solved
    explicitly (determinant m L^2 (g1 + g2 m sin^2 th) > 0). Real or complex arguments (the complex step)."""
    m, L, cp = p[Q_m], p[Q_L], p[Q_cp]
    s, c = np.sin(th), np.cos(th)
    r1 = r + g2 * m * L * thd * thd * s
    r2 = -cp * thd - m * GRAVITY * L * s
    det = m * L * L * (g1 + g2 * m * s * s)
    xdd = (m * L * L * r1 - g2 * m * L * c * r2) / det
    thdd = ((g1 + g2 * m) * r2 - m * L * c * r1) / det
    return xdd, thdd


@njit(cache=True)
def pendulum_tmd_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt (module doc); z and t real or complex (np.sin, np.cos take either)."""
    r = excitation(t, p) - p[Q_K] * z[0] - p[Q_C] * z[1]
    xdd, thdd = pendulum_accelerations(p[Q_M], 1.0, r, z[2], z[3], p)
    out[0] = z[1]
    out[1] = xdd
    out[2] = z[3]
    out[3] = thdd


#: J = d rhs / dz and ft = d rhs / dt of :func:`pendulum_tmd_rhs` by the complex step (exact to rounding)
pendulum_tmd_jacobian = complex_step_jacobian(pendulum_tmd_rhs, "pendulum_tmd")
