"""Equations of the base oscillator with a plain linear TMD, numba-compiled with the integrator's
signatures (:mod:`pyfmu_wrapper.physics.models`).

State z = [x, xd, y, yd] (main mass, absorber; z[0] is the displacement the curves report):

    M xdd = F cos(w t) - K x - C xd + k (y - x) + c (yd - xd)
    m ydd = -k (y - x) - c (yd - xd)

Packed parameters: the paper's array's length (:data:`~pyfmu_wrapper.physics.params.N_PARAMS`) with
only F and w set at their ``P_F``, ``P_W`` indices (the excitation
:func:`~pyfmu_wrapper.physics.kernels.excitation` reads them there, and ``ModelUnit.linear_system``
sets them), then M, K, C, m, k, c from :data:`L_AT` on.
"""

from __future__ import annotations

from ..._jit import njit
from ...physics.jacobians import complex_step_jacobian
from ...physics.kernels import Vec, excitation
from ...physics.params import N_PARAMS

#: index of the model's own part of the packed array: M, K, C, m, k, c
L_AT = N_PARAMS
L_M, L_K, L_C, L_m, L_k, L_c = L_AT, L_AT + 1, L_AT + 2, L_AT + 3, L_AT + 4, L_AT + 5
N_PACKED = L_AT + 6


@njit(cache=True)
def linear_tmd_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt (module doc); z and t real or complex."""
    link = p[L_k] * (z[2] - z[0]) + p[L_c] * (z[3] - z[1])  # the absorber's pull on the main mass
    out[0] = z[1]
    out[1] = (excitation(t, p) - p[L_K] * z[0] - p[L_C] * z[1] + link) / p[L_M]
    out[2] = z[3]
    out[3] = -link / p[L_m]


#: J = d rhs / dz and ft = d rhs / dt of :func:`linear_tmd_rhs` by the complex step (exact to rounding)
linear_tmd_jacobian = complex_step_jacobian(linear_tmd_rhs, "linear_tmd")
