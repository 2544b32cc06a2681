"""The numerical building blocks of the RODAS4 step of :mod:`pyfmu_wrapper.solvers.rodas`: the
method's coefficients (Hairer & Wanner, Solving ODEs II, Sect. IV.7, as in their ``rodas.f``) and the
small dense LU factorisation with partial pivoting that solves each stage's linear system
``G K_i = ...`` (no LAPACK: the integrator runs in an FMU's bare runtime). It knows no model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._jit import njit

FloatArray = NDArray[np.float64]

# RODAS4 coefficients (Hairer & Wanner 1996), lower-triangular A and C stored as full matrices.
GAMMA = 0.25
ALPHA = np.array([0.0, 0.386, 0.21, 0.63, 1.0, 1.0])
GAMMAI = np.array([0.25, -0.1043, 0.1035, -0.3620000000000023e-01, 0.0, 0.0])
COEF_A = np.zeros((6, 6))
COEF_C = np.zeros((6, 6))
_a = [
    0.1544000000000000e01,
    0.9466785280815826,
    0.2557011698983284,
    0.3314825187068521e01,
    0.2896124015972201e01,
    0.9986419139977817,
    0.1221224509226641e01,
    0.6019134481288629e01,
    0.1253708332932087e02,
    -0.6878860361058950,
    0.1221224509226641e01,
    0.6019134481288629e01,
    0.1253708332932087e02,
    -0.6878860361058950,
    1.0,
]
_c = [
    -0.5668800000000000e01,
    -0.2430093356833875e01,
    -0.2063599157091915,
    -0.1073529058151375,
    -0.9594562251023355e01,
    -0.2047028614809616e02,
    0.7496443313967647e01,
    -0.1024680431464352e02,
    -0.3399990352819905e02,
    0.1170890893206160e02,
    0.8083246795921522e01,
    -0.7981132988064893e01,
    -0.3152159432874371e02,
    0.1631930543123136e02,
    -0.6058818238834054e01,
]
_k = 0
for _i in range(1, 6):
    for _j in range(_i):
        COEF_A[_i, _j] = _a[_k]
        COEF_C[_i, _j] = _c[_k]
        _k += 1
COEF_M = np.array([_a[6], _a[7], _a[8], _a[9], 1.0, 1.0])
COEF_E = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])


@njit(cache=True)
def lu_factor(a: FloatArray, piv: NDArray[np.int64]) -> bool:
    n = a.shape[0]
    for k in range(n):
        imax = k
        vmax = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > vmax:
                vmax = abs(a[i, k])
                imax = i
        piv[k] = imax
        if imax != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[imax, j]
                a[imax, j] = tmp
        if a[k, k] == 0.0:
            return False
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            f = a[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
    return True


@njit(cache=True)
def lu_solve(a: FloatArray, piv: NDArray[np.int64], b: FloatArray) -> None:
    n = a.shape[0]
    for k in range(n):
        if piv[k] != k:
            tmp = b[k]
            b[k] = b[piv[k]]
            b[piv[k]] = tmp
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= a[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= a[i, j] * b[j]
        b[i] = s / a[i, i]
