"""Cubic Hermite interpolation between integrator steps (or communication points): the largest
|x| over a step from the end values and slopes, and the dense state at a fraction of a step. Used
by the integrator (:mod:`.rodas`: event and sample output) and by the co-simulation's steady state
(the one Hermite maximum of both engines)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .._jit import njit


@njit(cache=True)
def hermite_absmax(x0: float, v0: float, x1: float, v1: float, h: float) -> float:
    """max |p(s)| over s in [0, h] of the cubic Hermite p with p(0)=x0, p'(0)=v0, p(h)=x1, p'(h)=v1."""
    m = max(abs(x0), abs(x1))
    # p(theta) = h00 x0 + h10 h v0 + h01 x1 + h11 h v1; derivative in theta is quadratic.
    a0, b0, a1, b1 = x0, h * v0, x1, h * v1
    # p(th) = c0 + c1 th + c2 th^2 + c3 th^3
    c0 = a0
    c1 = b0
    c2 = -3.0 * a0 - 2.0 * b0 + 3.0 * a1 - b1
    c3 = 2.0 * a0 + b0 - 2.0 * a1 + b1
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    if qa == 0.0:
        if qb != 0.0:
            th = -qc / qb
            if 0.0 < th < 1.0:
                m = max(m, abs(c0 + th * (c1 + th * (c2 + th * c3))))
        return m
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0:
        return m
    sq = math.sqrt(disc)
    for th in ((-qb + sq) / (2.0 * qa), (-qb - sq) / (2.0 * qa)):
        if 0.0 < th < 1.0:
            m = max(m, abs(c0 + th * (c1 + th * (c2 + th * c3))))
    return m


@njit(cache=True)
def hermite_absmax_series(x: NDArray[np.float64], v: NDArray[np.float64], h: float) -> float:
    """max |p| over all intervals of the cubic Hermite interpolant of samples x, v = dx/dt at
    spacing h (the one Hermite maximum of both engines: the monolithic solver applies
    :func:`hermite_absmax` step by step, the co-simulation to its communication points)."""
    m = 0.0
    for i in range(x.shape[0] - 1):
        m = max(m, hermite_absmax(x[i], v[i], x[i + 1], v[i + 1], h))
    if x.shape[0] == 1:
        m = abs(x[0])
    return m


@njit(cache=True)
def hermite_state(
    z0: NDArray[np.float64],
    f0: NDArray[np.float64],
    z1: NDArray[np.float64],
    f1: NDArray[np.float64],
    h: float,
    theta: float,
    out: NDArray[np.float64],
) -> None:
    h00 = (1.0 + 2.0 * theta) * (1.0 - theta) ** 2
    h10 = theta * (1.0 - theta) ** 2
    h01 = theta * theta * (3.0 - 2.0 * theta)
    h11 = theta * theta * (theta - 1.0)
    for i in range(z0.shape[0]):
        out[i] = h00 * z0[i] + h10 * h * f0[i] + h01 * z1[i] + h11 * h * f1[i]
