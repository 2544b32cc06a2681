"""The base oscillator as a linear time-invariant system, for its exact step (the BaseOscillator FMU).

The base alone (paper Sect. 2; the equation of :func:`.kernels.base_acceleration` with the link's
feed-through a = 0) is linear:

    M x'' + C x' + K x = F cos(w t) - f_link(t),

driven by the harmonic force and by the link force, which the master hands over as a polynomial in
tau = t - t0 of degree <= 2 (the FMU's input and its two input derivatives, :func:`.kernels.input_value`).
Both drives are outputs of autonomous linear generators, so the base and its drives form one linear
system w' = A w of 7 states,

    w = [x, xd, F cos(w t), F sin(w t), f(tau), f'(tau), f''(tau)],

    x'   = xd
    xd'  = (-K x - C xd + F cos(w t) - f) / M
    (F cos)' = -w F sin,   (F sin)' = w F cos
    f' = f',   (f')' = f'',   (f'')' = 0,

whose flow over a step h is exp(A h) exactly: x and xd at t + h are the first two rows of
exp(A h) applied to w(t). No step-size control, no tolerance: the only errors are the rounding of
exp(A h) (:mod:`pyfmu_wrapper.solvers.expm`) and of the products. A depends on M, C, K and w only,
not on F, which enters through w's harmonic states.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .._jit import njit
from .params import P_C, P_F, P_K, P_M, P_W

#: size of the augmented state w
N_AUG = 7


@njit(cache=True)
def base_augmented_matrix(p: NDArray[np.float64], a: NDArray[np.float64]) -> None:
    """a (7 x 7) = the matrix A of the base with its drives (module doc), for packed parameters p."""
    m, c, k, w = p[P_M], p[P_C], p[P_K], p[P_W]
    for i in range(N_AUG):
        for j in range(N_AUG):
            a[i, j] = 0.0
    a[0, 1] = 1.0
    a[1, 0] = -k / m
    a[1, 1] = -c / m
    a[1, 2] = 1.0 / m
    a[1, 4] = -1.0 / m
    a[2, 3] = -w
    a[3, 2] = w
    a[4, 5] = 1.0
    a[5, 6] = 1.0


@njit(cache=True)
def base_augmented_state(
    x: float, xd: float, t: float, p: NDArray[np.float64], u: NDArray[np.float64], w: NDArray[np.float64]
) -> None:
    """w = the augmented state (module doc) at time t, for the base state (x, xd) and the link force's
    polynomial u = [t0, f(t0), f'(t0), f''(t0)] (:func:`.kernels.input_value`'s layout)."""
    tau = t - u[0]
    w[0] = x
    w[1] = xd
    w[2] = p[P_F] * math.cos(p[P_W] * t)
    w[3] = p[P_F] * math.sin(p[P_W] * t)
    w[4] = u[1] + tau * (u[2] + 0.5 * tau * u[3])
    w[5] = u[2] + tau * u[3]
    w[6] = u[3]
