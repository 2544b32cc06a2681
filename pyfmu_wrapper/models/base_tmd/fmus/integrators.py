"""The integrators of the two FMU subsystems, as the Python slaves and the native step use them.

* The TMD (``y, yd, d, dd``: nonlinear, with friction and the gear's play) is integrated by the
  RODAS4 integrator built from its model by the generic factory
  (:func:`pyfmu_wrapper.solvers.rodas.make_integrator`). Compiling only this one keeps the FMU's
  first-load compile time small (the coupled system's integrator is not needed here).
* The base oscillator (``x, xd``) is linear: it is stepped **exactly** by :func:`advance_base`, the
  flow exp(A h) of the base with its harmonic force and the link force's input polynomial
  (:mod:`pyfmu_wrapper.physics.linear`). No tolerance, no step-size control; exp(A h) is computed
  once per step length and kept in the slave's input array (its cache, :data:`U_BASE_CACHE`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...._jit import njit
from ....fmi.contract import NATIVE_MAX_STEP
from ....physics import kernels as kn
from ....physics import models
from ....physics.linear import N_AUG, base_augmented_matrix, base_augmented_state
from ....physics.params import P_C, P_I, P_K, P_M, P_MODEL, P_W, P_ki
from ....solvers.expm import expm
from ....solvers.rodas import STAT_STEPS, make_integrator

#: the model, for messages (:func:`~pyfmu_wrapper.solvers.rodas.failure_message`)
TMD_MODEL = models.TMD
integrate_tmd = make_integrator(models.TMD)


@njit(cache=True)
def fill_atol(system: int, a: float, p: NDArray[np.float64], atol: NDArray[np.float64]) -> None:
    """The integrator's absolute tolerance per state from the FMU parameter ``atol`` = a.

    Every state gets a, except the gear chain's rate dd of the play model, which gets
    a sqrt(ki/I) (at least a): the rate of a chain ringing at the mesh frequency sqrt(ki/I) is
    sqrt(ki/I) times its deflection d, so this asks the same of dd as of d (the monolithic
    solver's scaling). Held to a alone, dd would be resolved 4472 times finer than d (Case 1) and
    the rattling chain would cost the TMD FMU 2.7x the integrator steps per period
    (docs/cosimulation.md). Both step paths (native and Python) call this, so they stay
    bit-identical; without the play model every tolerance is a."""
    for i in range(atol.shape[0]):
        atol[i] = a
    if system == kn.SYS_TMD and int(p[P_MODEL]) == kn.MODEL_PLAY and p[P_ki] > 0.0 and p[P_I] > 0.0:
        atol[3] = a * max(1.0, math.sqrt(p[P_ki] / p[P_I]))


#: the base's input array u: [t0, f_link, d f_link/dt, d2 f_link/dt2] (:func:`~pyfmu_wrapper.physics.kernels.input_value`),
#: then the exact step's cache from this index: [h, M, C, K, w] (the key) and the first two rows of exp(A h)
U_BASE_CACHE = 4
_KEY = 5
BASE_U_SIZE = U_BASE_CACHE + _KEY + 2 * N_AUG
#: a step longer than this [s] is taken in equal pieces (the native step's longest step), so that
#: exp(A h) needs few squarings (accurate to a few units in the last place)
PIECE = NATIVE_MAX_STEP


@njit(cache=True)
def advance_base(
    z: NDArray[np.float64], t: float, h: float, p: NDArray[np.float64], u: NDArray[np.float64], stats: NDArray[np.int64]
) -> int:
    """z = [x, xd] at t -> at t + h, exactly, under F cos(w t) and the link force of the polynomial
    u[:4]; u[U_BASE_CACHE:] holds exp(A h) for the last (h, M, C, K, w). Returns 0, or 1 when the
    state is not finite afterwards (z is then left at the start of the step)."""
    n = 1 if h <= PIECE else int(math.ceil(h / PIECE))
    hh = h / n
    c = U_BASE_CACHE
    if not (u[c] == hh and u[c + 1] == p[P_M] and u[c + 2] == p[P_C] and u[c + 3] == p[P_K] and u[c + 4] == p[P_W]):
        a = np.empty((N_AUG, N_AUG))
        base_augmented_matrix(p, a)
        for i in range(N_AUG):
            for j in range(N_AUG):
                a[i, j] *= hh
        e = np.empty((N_AUG, N_AUG))
        expm(a, e)
        for j in range(N_AUG):
            u[c + _KEY + j] = e[0, j]
            u[c + _KEY + N_AUG + j] = e[1, j]
        u[c], u[c + 1], u[c + 2], u[c + 3], u[c + 4] = hh, p[P_M], p[P_C], p[P_K], p[P_W]
    w = np.empty(N_AUG)
    x, xd = z[0], z[1]
    for k in range(n):
        base_augmented_state(x, xd, t + k * hh, p, u, w)
        x1 = 0.0
        v1 = 0.0
        for j in range(N_AUG):
            x1 += u[c + _KEY + j] * w[j]
            v1 += u[c + _KEY + N_AUG + j] * w[j]
        x, xd = x1, v1
    stats[STAT_STEPS] += n
    if not (math.isfinite(x) and math.isfinite(xd)):
        return 1
    z[0] = x
    z[1] = xd
    return 0
