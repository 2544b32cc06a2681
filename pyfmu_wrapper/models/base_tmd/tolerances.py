"""The absolute tolerance per state of the paper's model (z = [x, xd, y, yd, d, dd]), as one compiled function
of the packed parameters: the unit's ``atol`` (the monolithic engine), the TMDSystem FMU's integrator and the
nominal values of its states in Model Exchange all call it.

With xs = |F| / K the static deflection (1e-3 m when F = 0) and wn = max(w, sqrt(K/M), 1) [rad/s]: the
displacements get scale xs, the rates scale xs wn; the play chain with a gap gets the chain's own tolerance
(:func:`~pyfmu_wrapper.physics.tmd.chain_tolerance`: the gear penetration F / ki
resolved) for d, and that times the mesh frequency sqrt(ki / I) for dd (:func:`~pyfmu_wrapper.physics.tmd.packed_tmd_atol`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..._jit import njit
from ...physics.params import P_F, P_K, P_M, P_W
from ...physics.tmd import packed_tmd_atol


@njit(cache=True)
def coupled_atol(p: NDArray[np.float64], scale: float, atol: NDArray[np.float64]) -> None:
    """atol[:6] for the packed parameters p and the relative scale (module doc)."""
    force = abs(p[P_F])
    xs = force / max(p[P_K], 1e-300)
    xs = xs if xs > 0 else 1e-3
    wn = max(p[P_W], math.sqrt(p[P_K] / p[P_M]), 1.0)
    a = scale * xs
    for i in range(3):
        atol[2 * i] = a
        atol[2 * i + 1] = a * wn
    packed_tmd_atol(p, atol)
