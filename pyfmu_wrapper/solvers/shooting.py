"""Newton shooting for a periodic steady state, shared by both engines.

The unknown is the state z at the start of a forcing period (phase w t = 0 mod 2 pi); the
residual is g(z) = P(z) - z with P the period map (one forcing period of the monolithic
integrator, or of the co-simulated FMUs re-initialised from z). Its Jacobian is D - I with D the
monodromy matrix, taken from the previous frequency of a sweep when given, else by finite
differences (one period per state), and refreshed by Broyden updates; a fresh finite-difference
Jacobian is computed when the iteration stops contracting.

Converged when the last Newton correction is below ``tol`` and the residual below 10 ``tol``,
both relative to max(|z_i|, scale_i) per state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike


class ShootingResult(NamedTuple):
    z: np.ndarray  #: the converged start state
    zT: np.ndarray  #: the state one period later (= z to the tolerance)
    amplitude: float  #: max |x| over the period from z, as the period map reported it
    periods: int  #: periods integrated (Newton iterations and finite differences)
    change: float  #: max(last relative correction, relative residual)
    jacobian: np.ndarray | None  #: the last Jacobian D - I (for the next frequency; None if never formed)


def shoot(
    period_map: Callable[[np.ndarray], tuple[np.ndarray, float]],
    z0: ArrayLike,
    scale: ArrayLike,
    tol: float,
    max_newton: int = 8,
    jacobian: np.ndarray | None = None,
) -> ShootingResult | None:
    """Newton shooting on ``period_map(z) -> (z(T), max |x| over the period)``; None when it does
    not converge (after ``3 max_newton`` iterations, or ``max_newton`` iterations with a fresh
    Jacobian still correcting by more than 1e3 ``tol``, or a singular / non-finite step).

    z0, scale: start state and per-state scales (same length as the period map's state).
    jacobian: a starting D - I (e.g. from the previous frequency), or None.
    """
    z = np.array(z0, dtype=float)
    scale = np.asarray(scale, dtype=float)
    n = z.size
    J = jacobian if jacobian is not None and np.shape(jacobian) == (n, n) else None
    periods = 0
    fresh = False
    last_change = np.inf
    g_old = s_old = None
    res_old = np.inf
    for it in range(3 * max_newton):
        zT, amp = period_map(z)
        periods += 1
        g = zT - z
        zmag = np.maximum(np.abs(z), scale)
        res = float(np.max(np.abs(g) / zmag))
        if last_change <= tol and res <= 10 * tol:
            return ShootingResult(z, zT, float(amp), periods, max(last_change, res), J)
        if J is not None and g_old is not None and s_old is not None:
            if res > 0.5 * res_old and not fresh:
                J = None  # stalled: refresh the Jacobian below
            else:
                J = J + np.outer(g - g_old - J @ s_old, s_old) / float(s_old @ s_old)
        if J is None:
            J = np.empty((n, n))
            for j in range(n):
                dz = np.zeros(n)
                dz[j] = 1e-6 * zmag[j]
                zpT, _ = period_map(z + dz)
                J[:, j] = (zpT - (z + dz) - g) / dz[j]
            periods += n
            fresh = True
        else:
            fresh = False
        try:
            delta = -np.linalg.solve(J, g)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(delta)):
            return None
        z = z + delta
        g_old, s_old, res_old = g, delta, res
        last_change = float(np.max(np.abs(delta) / zmag))
        if it >= max_newton and fresh and last_change > 1e3 * tol:
            return None
    return None
