"""The ShearFrame FMU's step and outputs as compiled functions, called by both step paths: the Python
slave (:mod:`.slave`) and the native step (:mod:`.native`), so the two are bit-identical.

The frame alone (the storeys of :mod:`pyfmu_wrapper.models.frame_model`, driven by F cos(w t) and by
the TMD's two forces as input polynomials) is linear and time-invariant once its drives are states,
as the paper's base is (:mod:`pyfmu_wrapper.physics.linear`): with s = 2 n + 4 the frame model's
state length (the TMD's four slots at rest),

    w = [z (s), F cos(w t), F sin(w t), f(tau), f'(tau), f''(tau), P(tau), P'(tau), P''(tau)],

f the links' total force (input ``f_link``) and P its inerter's share (input ``f_inerter``), each a
polynomial in tau = t - t0 of degree <= 2 (:func:`~pyfmu_wrapper.physics.kernels.input_value`). The
matrix A of w' = A w is read off the frame model's own :func:`storeys_rhs` (its columns are the rhs
of unit states and unit drives: the rhs is linear, so that is exact to rounding) and the drives'
generators; a step of h is exp(A h) (:func:`~pyfmu_wrapper.solvers.expm.expm`), computed once per
step length and parameter set and kept in the slave's input array (its cache). No tolerance and no
step-size control: the step is exact to rounding, which no integrator tolerance matches at the cost of
one matrix-vector product of at most 44 x 52 per step.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...._jit import njit
from ....fmi.contract import NATIVE_MAX_STEP
from ....fmi.outputs import output_layout
from ....physics.params import N_PARAMS, P_F, P_W
from ....solvers.expm import expm
from ....solvers.rodas import STAT_STEPS
from ..equations import F_N, F_TMD, F_TO, storey_index, storey_rates, storeys_rhs
from ..params import MAX_STOREYS
from .variables import SHEAR_FRAME

#: the longest state (20 storeys and the TMD's slots) and the drives' states
NS_MAX = 2 * MAX_STOREYS + 4
N_DRIVE = 8
NA_MAX = NS_MAX + N_DRIVE
#: the packed parameters of the largest frame (:func:`~pyfmu_wrapper.models.frame_model.frame_pack`)
NP_FRAME = N_PARAMS + 4 + 3 * MAX_STOREYS
#: the input polynomials [t0, f, f', f'', P, P', P''], then the cache: the step length, the packed
#: parameters it was computed for, and the first s rows of exp(A h) (row-major, NA_MAX columns)
U_IN = 7
U_CACHE = U_IN
_KEY = 1 + NP_FRAME
FRAME_U_SIZE = U_CACHE + _KEY + NS_MAX * NA_MAX
#: the outputs :func:`frame_outputs` writes, in the order of the variable table (checked on import)
FRAME_OUTPUTS = (
    ("x_top", "xd_top", "x", "xd", "xdd", "xdd_free")
    + tuple(f"x_{i}" for i in range(1, MAX_STOREYS + 1))
    + tuple(f"xd_{i}" for i in range(1, MAX_STOREYS + 1))
)
#: where the per-storey outputs x_i, xd_i start in ``out``
OUT_X, OUT_XD = 6, 6 + MAX_STOREYS
FRAME_OUT_VR, FRAME_OUT_INT = output_layout(SHEAR_FRAME, FRAME_OUTPUTS)
#: a step longer than this [s] is taken in equal pieces (few squarings in exp(A h))
PIECE = NATIVE_MAX_STEP


@njit(cache=True)
def frame_augmented_matrix(p: NDArray[np.float64], ns: int, a: NDArray[np.float64]) -> None:
    """a[:ns + 8, :ns + 8] = A of the frame with its drives (module doc) for packed parameters p,
    read off :func:`storeys_rhs`."""
    na = ns + N_DRIVE
    for i in range(na):
        for j in range(na):
            a[i, j] = 0.0
    q = p.copy()
    q[P_F] = 0.0
    e = np.zeros(ns)
    out = np.empty(ns)
    u = np.zeros(U_IN)
    for j in range(ns):
        e[j] = 1.0
        storeys_rhs(0.0, e, q, u, out)
        e[j] = 0.0
        for i in range(ns):
            a[i, j] = out[i]
    q[P_F] = 1.0  # the unit harmonic force at t = 0: the column of F cos(w t)
    storeys_rhs(0.0, e, q, u, out)
    for i in range(ns):
        a[i, ns] = out[i]
    q[P_F] = 0.0
    for col, k in ((ns + 2, 1), (ns + 5, 4)):  # unit f, unit P
        u[k] = 1.0
        storeys_rhs(0.0, e, q, u, out)
        u[k] = 0.0
        for i in range(ns):
            a[i, col] = out[i]
    w = p[P_W]
    a[ns, ns + 1] = -w
    a[ns + 1, ns] = w
    a[ns + 2, ns + 3] = 1.0
    a[ns + 3, ns + 4] = 1.0
    a[ns + 5, ns + 6] = 1.0
    a[ns + 6, ns + 7] = 1.0


@njit(cache=True)
def advance_frame(
    z: NDArray[np.float64], t: float, h: float, p: NDArray[np.float64], u: NDArray[np.float64], stats: NDArray[np.int64]
) -> int:
    """z (the frame model's layout) at t -> at t + h exactly, under F cos(w t) and the input
    polynomials u[:7]; u[U_CACHE:] holds exp(A h) for the last step length and parameters. Returns 0,
    or 1 when the state is not finite afterwards (z is then left at the start of the step)."""
    ns = 2 * int(p[F_N]) + 4
    na = ns + N_DRIVE
    n = 1 if h <= PIECE else int(math.ceil(h / PIECE))
    hh = h / n
    c = U_CACHE
    np_ = p.shape[0]
    fresh = u[c] == hh
    if fresh:
        for i in range(np_):
            if u[c + 1 + i] != p[i]:
                fresh = False
                break
    e0 = c + _KEY
    if not fresh:
        a = np.empty((na, na))
        frame_augmented_matrix(p, ns, a)
        for i in range(na):
            for j in range(na):
                a[i, j] *= hh
        ex = np.empty((na, na))
        expm(a, ex)
        for i in range(ns):
            for j in range(na):
                u[e0 + i * NA_MAX + j] = ex[i, j]
        u[c] = hh
        for i in range(np_):
            u[c + 1 + i] = p[i]
    w = np.empty(na)
    x = np.empty(ns)
    for i in range(ns):
        x[i] = z[i]
    for k in range(n):
        tk = t + k * hh
        tau = tk - u[0]
        for i in range(ns):
            w[i] = x[i]
        w[ns] = p[P_F] * math.cos(p[P_W] * tk)
        w[ns + 1] = p[P_F] * math.sin(p[P_W] * tk)
        for d in range(2):
            b = 1 + 3 * d
            w[ns + 2 + 3 * d] = u[b] + tau * (u[b + 1] + 0.5 * tau * u[b + 2])
            w[ns + 3 + 3 * d] = u[b + 1] + tau * u[b + 2]
            w[ns + 4 + 3 * d] = u[b + 2]
        for i in range(ns):
            if 2 <= i < 6:  # the TMD's slots stay at rest
                continue
            s = 0.0
            row = e0 + i * NA_MAX
            for j in range(na):
                s += u[row + j] * w[j]
            x[i] = s
    stats[STAT_STEPS] += n
    for i in range(ns):
        if not math.isfinite(x[i]):
            return 1
    for i in range(ns):
        z[i] = x[i]
    return 0


@njit(cache=True)
def frame_outputs(
    z: NDArray[np.float64], t: float, f: complex, P: complex, p: NDArray[np.float64], out: NDArray
) -> None:
    """ShearFrame: the top storey's x and xd, the TMD storey's x and xd, the inerter terminal's
    acceleration under the TMD's forces f (total) and P (the inerter's share) and without them (both 0
    for the ground), at time t; then every storey's x and xd (0 above the top); f and P real or complex
    (directional derivatives by complex step)."""
    n = int(p[F_N])
    m = 2 * n + 4
    zc = np.empty(m, dtype=out.dtype)
    for i in range(m):
        zc[i] = z[i]
    rates = np.empty(m, dtype=out.dtype)
    xdd = storey_rates(t, zc, p, f, f - P, 0.0, rates)
    free = storey_rates(t, zc, p, 0.0 * f, 0.0 * f, 0.0, rates)
    sx = storey_index(int(p[F_TMD]), n)
    ground = int(p[F_TO]) <= 0
    out[0] = zc[0]
    out[1] = zc[1]
    out[2] = zc[sx]
    out[3] = zc[sx + 1]
    out[4] = 0.0 * xdd if ground else xdd
    out[5] = 0.0 * free if ground else free
    for i in range(1, MAX_STOREYS + 1):
        if i <= n:
            ix = storey_index(i, n)
            out[OUT_X + i - 1] = zc[ix]
            out[OUT_XD + i - 1] = zc[ix + 1]
        else:
            out[OUT_X + i - 1] = 0.0 * zc[0]
            out[OUT_XD + i - 1] = 0.0 * zc[0]
