"""The matrix exponential of a small dense matrix, compiled (numba), with no LAPACK.

Used for the exact step of a linear time-invariant system (the base oscillator's FMU,
:mod:`pyfmu_wrapper.fmi.integrators`): over a step h, z(t + h) = exp(A h) z(t) for z' = A z. It knows
no model; it runs inside an FMU's bundled copy, which has numpy and numba but no scipy, so it uses
no ``np.linalg`` (numba's needs scipy's LAPACK) and no division by a matrix.

Method: scaling and squaring with a Taylor polynomial (Moler & Van Loan 2003, "Nineteen dubious
ways", method 3 with scaling and squaring). A is scaled by 2^-s so that its 1-norm is at most
1/2; the Taylor series of exp(A / 2^s) is summed until a term no longer changes the sum in double
precision (at most :data:`MAX_TERMS` terms: the truncation error after n terms is below
0.5^(n+1) / (n+1)!, under 1e-22 for n = 18); the result is squared s times. For the matrices met
here (a damped oscillator with its harmonic and polynomial generators, |A h| ~ 1) that is accurate
to a few units in the last place; the tests compare it with scipy.linalg.expm and with the exact
forced response of the oscillator.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .._jit import njit

#: at most this many Taylor terms (the series has converged to double precision long before)
MAX_TERMS = 30
#: the scaled matrix's 1-norm is at most this
SCALED_NORM = 0.5


@njit(cache=True)
def norm1(a: NDArray[np.float64]) -> float:
    """The 1-norm (largest absolute column sum) of a square matrix."""
    n = a.shape[0]
    best = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(a[i, j])
        best = max(best, s)
    return best


@njit(cache=True)
def _matmul(a: NDArray[np.float64], b: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """out = a b. Each entry is the sum over k in ascending order, from 0 (the rounding of a plain dot product);
    the loops run i, k, j so that the innermost runs along rows of b and out (vectorised by the compiler, the same
    additions in the same order per entry)."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.0
        for k in range(n):
            aik = a[i, k]
            for j in range(n):
                out[i, j] += aik * b[k, j]


@njit(cache=True)
def expm(a: NDArray[np.float64], out: NDArray[np.float64]) -> int:
    """out = exp(a) for a square float64 matrix a (n x n, out of the same shape, not a itself).

    Returns the number of squarings s (>= 0), or -1 when a is not finite (out is then filled with
    NaN)."""
    n = a.shape[0]
    nrm = norm1(a)
    if not math.isfinite(nrm):
        for i in range(n):
            for j in range(n):
                out[i, j] = np.nan
        return -1
    s = 0
    if nrm > SCALED_NORM:
        s = int(math.ceil(math.log2(nrm / SCALED_NORM)))
    scale = 0.5**s
    x = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            x[i, j] = a[i, j] * scale
    # Taylor: out = I + x + x^2/2! + ...; term_k = term_{k-1} x / k
    term = np.zeros((n, n))
    nxt = np.empty((n, n))
    for i in range(n):
        term[i, i] = 1.0
    for i in range(n):
        for j in range(n):
            out[i, j] = term[i, j]
    for k in range(1, MAX_TERMS + 1):
        _matmul(term, x, nxt)
        changed = False
        for i in range(n):
            for j in range(n):
                t = nxt[i, j] / k
                term[i, j] = t
                new = out[i, j] + t
                if new != out[i, j]:
                    changed = True
                out[i, j] = new
        if not changed:
            break
    for _ in range(s):
        _matmul(out, out, nxt)
        for i in range(n):
            for j in range(n):
                out[i, j] = nxt[i, j]
    return s
