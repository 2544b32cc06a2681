"""Jacobians of the equations of :mod:`.kernels`: the derivatives the implicit integrator needs.

Two kinds, both of the *same* right-hand sides (and :func:`complex_step_jacobian`, the complex-step Jacobian
of any model's right-hand side, the one helper every model with its own equations uses):

* **complex-step** (:func:`system_jacobian`, :func:`system_dfdt`, :func:`jacobian`): the right-hand
  side of :mod:`.kernels` evaluated at a complex state (the kernels accept complex arguments), so
  d rhs / dz is exact to rounding and no equation is restated. The base subsystem and the time
  derivatives of the subsystems use these.
* **hand-derived** (:func:`coupled_jacobian` of the coupled system, the monolithic solver's hot path;
  :func:`tmd_jacobian` of the TMD subsystem): the chain rule written out over the same structure
  (f_link = f0 + a xdd, ydd = ydd0 + ya xdd, ddd = ddd0 + da xdd) with the slopes of the force laws
  (:func:`spring_stiffness`, :func:`friction_slope_at`, :func:`chain_force_gradient`). This is a
  second, hand-derived statement of the derivatives: the tests (tests/test_physics.py,
  tests/test_registry.py) hold each one against the complex-step Jacobian to rounding, so an edit of an
  equation in :mod:`.kernels` that is not carried here fails them.
"""

from __future__ import annotations

import math
import types
from typing import TYPE_CHECKING, Any

import numpy as np

from .._jit import njit
from .kernels import (
    MODEL_IDEAL,
    MODEL_NONE,
    MODEL_PLAY,
    SYS_COUPLED,
    TWO_OVER_PI,
    Num,
    Vec,
    input_value,
    system_rhs,
    tmd_kappa,
)
from .params import P_C, P_F, P_I, P_K, P_M, P_MODEL, P_W, P_c, P_ci, P_df, P_eps, P_k, P_k3, P_ki, P_m, P_s

#: the complex step of every complex-step derivative (Jacobians here, the FMUs' directional derivatives)
CSTEP = 1e-30


@njit(cache=True)
def spring_stiffness(u: Num, p: Vec) -> Num:
    """d/du of :func:`spring_force`: k + 3 k3 u^2 [N/m]."""
    return p[P_k] + 3.0 * p[P_k3] * (u * u)


@njit(cache=True)
def friction_slope_at(v: Num, df: float, s: float) -> Num:
    """d/dv of :func:`friction_force`: df (2/pi) s / (1 + (s v)^2) [N s/m]."""
    if df == 0.0:
        return 0.0
    sv = s * v
    return df * TWO_OVER_PI * s / (1.0 + sv * sv)


@njit(cache=True)
def chain_force_gradient(d: Num, dd: Num, p: Vec) -> tuple[Num, Num]:
    """(dP/dd, dP/ddd) of :func:`chain_force` (0 where the chain is free or clamped)."""
    ki, ci, eps = p[P_ki], p[P_ci], p[P_eps]
    if eps == 0.0:
        return ki, ci
    # the two engagement sides, each with its own force test (kept nested: with the tests merged, a
    # failing first test would fall through to the second side)
    if d > eps:  # noqa: SIM102
        if ki * (d - eps) + ci * dd > 0.0:
            return ki, ci
    elif d < -eps:  # noqa: SIM102
        if ki * (d + eps) + ci * dd < 0.0:
            return ki, ci
    return 0.0, 0.0


@njit(cache=True)
def coupled_jacobian(t: float, z: Vec, p: Vec, J: Vec, ft: Vec) -> None:
    """Analytic d(rhs)/dz and d(rhs)/dt of the coupled system (the hot path of the monolithic solver).

    Differentiates the same structure as :func:`rhs_fext` (f_link = f0 + a xdd, ydd = ydd0 + ya xdd,
    ddd = ddd0 + da xdd) using the slopes of the force laws; the tests hold it against the
    complex-step Jacobian of :func:`rhs_fext`.
    """
    x, xd, y, yd, d, dd = z[0], z[1], z[2], z[3], z[4], z[5]
    model = int(p[P_MODEL])
    m, I, M = p[P_m], p[P_I], p[P_M]
    kv = p[P_c] + friction_slope_at(xd - yd, p[P_df], p[P_s])
    ks = spring_stiffness(x - y, p)
    # gradient of Fs over [x, xd, y, yd, d, dd]
    gF = (ks, kv, -ks, -kv, 0.0, 0.0)
    a, ya, da = 0.0, 0.0, 0.0
    Pd, Pdd = 0.0, 0.0
    if model == MODEL_IDEAL:
        mi = m + I
        cf, cy = m / mi, 1.0 / mi
        a, ya = m * I / mi, I / mi
    elif model == MODEL_PLAY:
        Pd, Pdd = chain_force_gradient(d, dd, p)
        cf, cy = 1.0, 1.0 / m
        da = 1.0
    else:
        cf, cy = 1.0, 1.0 / m
    inv = 1.0 / (M + a)
    for j in range(6):
        gP = Pd if j == 4 else (Pdd if j == 5 else 0.0)
        gf0 = cf * (gF[j] + gP) if model == MODEL_PLAY else cf * gF[j]
        gy0 = cy * (gF[j] + gP)
        gxdd = -gf0 * inv
        if j == 0:
            gxdd -= p[P_K] * inv
        elif j == 1:
            gxdd -= p[P_C] * inv
        J[0, j] = 1.0 if j == 1 else 0.0
        J[1, j] = gxdd
        J[2, j] = 1.0 if j == 3 else 0.0
        J[3, j] = gy0 + ya * gxdd
        J[4, j] = 1.0 if j == 5 else 0.0
        J[5, j] = (-gP / I - gy0 + da * gxdd) if model == MODEL_PLAY else 0.0
    dx = -p[P_F] * p[P_W] * math.sin(p[P_W] * t) * inv
    ft[0] = 0.0
    ft[1] = dx
    ft[2] = 0.0
    ft[3] = ya * dx
    ft[4] = 0.0
    ft[5] = da * dx


@njit(cache=True)
def tmd_jacobian(t: float, z: Vec, p: Vec, u: Vec, J: Vec) -> None:
    """Analytic d(rhs)/dz of the TMD subsystem (SYS_TMD, z = [y, yd, d, dd]) driven by the inputs u;
    held against the complex-step Jacobian in the tests."""
    x = input_value(u, 0, t)
    xd = input_value(u, 1, t)
    y, yd, d, dd = z[0], z[1], z[2], z[3]
    model = int(p[P_MODEL])
    m, I = p[P_m], p[P_I]
    kv = p[P_c] + friction_slope_at(xd - yd, p[P_df], p[P_s])
    # gradient of Fs over [y, yd, d, dd]
    gF0, gF1 = -spring_stiffness(x - y, p), -kv
    Pd, Pdd = 0.0, 0.0
    if model == MODEL_IDEAL:
        cy = 1.0 / (m + I)
    else:
        cy = 1.0 / m
        if model == MODEL_PLAY:
            Pd, Pdd = chain_force_gradient(d, dd, p)
    for i in range(4):
        for j in range(4):
            J[i, j] = 0.0
    J[0, 1] = 1.0
    J[2, 3] = 1.0
    J[1, 0] = cy * gF0
    J[1, 1] = cy * gF1
    J[1, 2] = cy * Pd
    J[1, 3] = cy * Pdd
    if model == MODEL_PLAY:
        # ddd = xdd - P / I - ydd
        for j in range(4):
            J[3, j] = -J[1, j]
        J[3, 2] -= Pd / I
        J[3, 3] -= Pdd / I
    kappa = tmd_kappa(u)
    if kappa != 0.0 and model != MODEL_NONE:
        # mounted_acceleration: d xdd / dz = -kappa / (1 + kappa a) * d f0 / dz
        if model == MODEL_PLAY:  # f0 = Fs + P, a = 0, xdd enters ddd with weight 1
            J[3, 0] -= kappa * gF0
            J[3, 1] -= kappa * gF1
            J[3, 2] -= kappa * Pd
            J[3, 3] -= kappa * Pdd
        else:  # ideal: f0 = m Fs / (m + I), a = m I / (m + I), xdd enters ydd with weight I / (m + I)
            w = -kappa / (1.0 + kappa * m * I / (m + I)) * (m / (m + I)) * (I / (m + I))
            J[1, 0] += w * gF0
            J[1, 1] += w * gF1


@njit(cache=True)
def system_jacobian(system: int, t: float, z: Vec, p: Vec, u: Vec, J: Vec) -> None:
    """d(rhs)/dz by the complex-step derivative (exact to rounding, no hand-derived copy)."""
    n = z.shape[0]
    zc = np.empty(n, dtype=np.complex128)
    oc = np.empty(n, dtype=np.complex128)
    system_jacobian_work(system, t, z, p, u, J, zc, oc)


@njit(cache=True)
def system_jacobian_work(system: int, t: float, z: Vec, p: Vec, u: Vec, J: Vec, zc: Vec, oc: Vec) -> None:
    """:func:`system_jacobian` with caller-provided complex work arrays zc, oc (no allocation)."""
    n = z.shape[0]
    for j in range(n):
        for i in range(n):
            zc[i] = z[i]
        zc[j] = z[j] + 1j * CSTEP
        system_rhs(system, t, zc, p, u, oc)
        for i in range(n):
            J[i, j] = oc[i].imag / CSTEP


@njit(cache=True)
def system_dfdt(system: int, t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """Partial derivative of the rhs with respect to t, by the complex step in t."""
    n = z.shape[0]
    zc = np.empty(n, dtype=np.complex128)
    oc = np.empty(n, dtype=np.complex128)
    system_dfdt_work(system, t, z, p, u, out, zc, oc)


@njit(cache=True)
def system_dfdt_work(system: int, t: float, z: Vec, p: Vec, u: Vec, out: Vec, zc: Vec, oc: Vec) -> None:
    """:func:`system_dfdt` with caller-provided complex work arrays."""
    n = z.shape[0]
    for i in range(n):
        zc[i] = z[i]
    system_rhs(system, t + 1j * CSTEP, zc, p, u, oc)
    for i in range(n):
        out[i] = oc[i].imag / CSTEP


@njit(cache=True)
def jacobian(t: float, z: Vec, p: Vec, J: Vec) -> None:
    """d(rhs)/dz of the coupled system."""
    system_jacobian(SYS_COUPLED, t, z, p, np.zeros(1), J)


# -- the complex-step Jacobian of any right-hand side ------------------------------------------------


def _complex_step_template(t: float, z: Vec, p: Vec, u: Vec, J: Vec, ft: Vec, zc: Vec, oc: Vec) -> None:
    """J = d rhs / dz and ft = d rhs / dt by the complex step (exact to rounding) of the right-hand side
    bound as ``_cs_rhs`` (see :func:`complex_step_jacobian`); zc, oc: complex work arrays."""
    n = z.shape[0]
    for j in range(n):
        for i in range(n):
            zc[i] = z[i]
        zc[j] = z[j] + 1j * CSTEP
        _cs_rhs(t, zc, p, u, oc)  # noqa: F821 - bound per right-hand side by complex_step_jacobian
        for i in range(n):
            J[i, j] = oc[i].imag / CSTEP
    for i in range(n):
        zc[i] = z[i]
    _cs_rhs(t + 1j * CSTEP, zc, p, u, oc)  # noqa: F821
    for i in range(n):
        ft[i] = oc[i].imag / CSTEP


if TYPE_CHECKING:  # bound per right-hand side by complex_step_jacobian
    _cs_rhs: Any


def complex_step_jacobian(rhs: Any, name: str) -> Any:
    """The Jacobian function of the integrator's signature, ``jacobian(t, z, p, u, J, ft, zc, oc)``, of a
    right-hand side ``rhs(t, z, p, u, out)`` that accepts a complex state and time: the complex-step
    derivative in z and t, exact to rounding (no second statement of the equations). One template for
    every model: its code with ``rhs`` as its global and a name of its own (``jacobian_<name>``, a Python
    identifier), so numba compiles ``rhs`` inline and caches each Jacobian in a file of its own (as
    :func:`~pyfmu_wrapper.solvers.rodas.make_integrator` does for the integrator)."""
    if not name.isidentifier():
        raise ValueError(f"complex_step_jacobian: name {name!r} is not a Python identifier")
    g = dict(globals())
    g["_cs_rhs"] = rhs
    tpl = _complex_step_template
    fn = types.FunctionType(tpl.__code__, g, f"jacobian_{name}", tpl.__defaults__)
    fn.__qualname__ = f"jacobian_{name}"
    fn.__doc__ = f"J = d rhs / dz and ft = d rhs / dt of {getattr(rhs, '__name__', name)} by the complex step."
    fn.__module__ = tpl.__module__
    return njit(cache=True)(fn)
