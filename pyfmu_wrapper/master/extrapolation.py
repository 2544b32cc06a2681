"""Input polynomials from the history of the source outputs (extrapolation and interpolation).

Every FMU gets its inputs at the communication point t_n as a Taylor polynomial of degree
``order`` (value, first and second derivative), the derivatives at t_n of the Lagrange polynomial
through the last ``order + 1`` communication points of the source output. :class:`History` keeps
those points; :func:`lagrange_weights` gives the derivative weights of any set of points.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy import ndarray


def lagrange_weights(s: np.ndarray) -> tuple[ndarray, ndarray]:
    """Weights (d1, d2): first and second derivative at s = 0 of the polynomial through s (1 to 3 points)."""
    n = len(s)
    d1 = np.zeros(n)
    d2 = np.zeros(n)
    if n == 1:
        return d1, d2
    for i in range(n):
        others = [s[j] for j in range(n) if j != i]
        den = np.prod([s[i] - o for o in others])
        if n == 2:
            d1[i] = 1.0 / den
        else:  # n == 3
            d1[i] = (-others[0] - others[1]) / den
            d2[i] = 2.0 / den
    return d1, d2


def combine(w: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """sum_i w[i] rows[i], summed left to right with separate multiplies and adds.

    Not ``w @ rows``: numpy hands that to BLAS (gemv), whose summation order and use of fused
    multiply-adds depend on the vector length and the CPU, so its last bit cannot be
    reproduced elsewhere; the compiled loop (:mod:`.cloop`) does exactly these operations, so the
    two paths agree bit for bit (and a result no longer depends on the BLAS kernel)."""
    acc = w[0] * rows[0]
    for i in range(1, len(w)):
        acc = acc + w[i] * rows[i]
    return acc


class History:
    """Source values at the last three communication points, oldest first.

    ``y[3 - k:]`` / ``t[3 - k:]`` are the last k points (k <= ``n``). The derivative weights
    depend only on the spacing of the points relative to the current time and are cached (a
    fixed step reuses one set)."""

    def __init__(self, nsig: int) -> None:
        self.y = np.zeros((3, nsig))
        self.t = np.zeros(3)
        self.n = 0
        self._cache: dict = {}
        self.generation = 0  #: bumped whenever the weight cache is emptied (the compiled loop mirrors it)

    def clear(self) -> None:
        self.n = 0

    def push(self, t: float, y: np.ndarray) -> None:
        self.y[:-1] = self.y[1:]
        self.t[:-1] = self.t[1:]
        self.y[-1] = y
        self.t[-1] = t
        self.n = min(self.n + 1, 3)

    def weights(self, k: int, t: float) -> tuple[ndarray, ndarray]:
        """Cached derivative weights at t of the polynomial through the last k points."""
        ht = self.t
        key: tuple[float, ...]  # (k, the node offsets rounded): nodes at the same offsets share weights
        if k == 3:
            key = (3, round(float(ht[0]) - t, 13), round(float(ht[1]) - t, 13))
        elif k == 2:
            key = (2, round(float(ht[1]) - t, 13))
        else:
            key = (k,)
        w = self._cache.get(key)
        if w is None:
            w = lagrange_weights(ht[3 - k :] - t)
            if len(self._cache) > 64:
                self._cache.clear()
                self.generation += 1
            self._cache[key] = w
        return w

    def clear_cache(self) -> None:
        self._cache.clear()
        self.generation += 1

    def snapshot(self) -> tuple[ndarray, ndarray, int]:
        return self.y.copy(), self.t.copy(), self.n

    def restore(self, snap: tuple[ndarray, ndarray, int]) -> None:
        y, t, self.n = snap
        self.y[:], self.t[:] = y, t
