"""The absolute tolerance per state of the frame with its TMD (the layout of :mod:`.equations`), as one compiled
function of the packed parameters: the unit's ``atol`` (the monolithic engine), the FrameSystem FMU's integrator
and the nominal values of its states in Model Exchange all call it.

xs = |F| / K (K = 1 / sum(1 / K_i), the top's static deflection bound; 1e-3 m when F = 0) and
wn = max(w, max_i sqrt(K_i / M_i), 1) [rad/s]: displacements get scale xs, rates scale xs wn; the play chain
its own (:func:`~pyfmu_wrapper.physics.tmd.packed_tmd_atol`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..._jit import njit
from ...physics.params import P_F, P_W
from ...physics.tmd import packed_tmd_atol
from .equations import F_N, F_VALUES


@njit(cache=True)
def frame_atol(p: NDArray[np.float64], scale: float, atol: NDArray[np.float64]) -> None:
    """atol[:2 n + 4] for the packed parameters p and the relative scale (module doc)."""
    n = int(p[F_N])
    m0, k0 = F_VALUES, F_VALUES + n
    if n == 1:
        stiffness = p[k0]
    else:
        s = 0.0
        for i in range(n):
            s += 1.0 / p[k0 + i]
        stiffness = 1.0 / s
    nf = math.sqrt(p[k0] / p[m0])
    for i in range(1, n):
        nf = max(nf, math.sqrt(p[k0 + i] / p[m0 + i]))
    xs = abs(p[P_F]) / stiffness
    xs = xs if xs > 0 else 1e-3
    wn = max(p[P_W], nf, 1.0)
    a = scale * xs
    for i in range(n + 2):
        atol[2 * i] = a
        atol[2 * i + 1] = a * wn
    packed_tmd_atol(p, atol)
