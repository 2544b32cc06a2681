"""Compiled kernels: the single statement of the equations of motion.

Brzeski & Perlikowski (2017), Eqs. (1)-(2) with the physical (passive) sign convention of the
physics notes. Every solver, the FMU slaves and the analysis call these functions; nothing else
in the project writes an equation of motion.

State of the coupled system (6 entries)::

    z = [x, xd, y, yd, d, dd]      d = r - y (play chain, Scheibe & Smith 2009; unused otherwise)

Link forces act on the base in -x and on the TMD in +y:

    Fs = k (x - y) + k3 (x - y)^3 + c (xd - yd) + df (2/pi) atan(s (xd - yd))   spring, damper, friction
    P  = I (xdd - ydd)                                                  ideal inerter
    P  = I (xdd - rdd) = ki (r - u) + ci (rd - ud)                      inerter with play

    M xdd + C xd + K x + Fs + P = F cos(w t)
    m ydd - Fs - P = 0

The TMD side is written as an affine function of the base acceleration,
``f_link = f0 + a * xdd``, ``ydd = ydd0 + ya * xdd``, ``ddd = ddd0 + da * xdd``. ``a`` is the
direct feed-through of the base acceleration into the link force (nonzero only for the ideal
inerter: a = m I / (m + I)); it is what closes the algebraic loop in the monolithic system and what
the TMD FMU reports as its directional derivative.

The kernels are written so that they also accept complex arguments, for the complex-step
derivatives of :mod:`.jacobians` (exact to rounding). The hot paths (the coupled system of the
monolithic solver, the TMD subsystem) use hand-derived Jacobians, also in :mod:`.jacobians`: a
second statement of the derivatives of these equations, held against the complex-step ones by the
tests.
"""

from __future__ import annotations

import math
from typing import Any, cast

from numpy.typing import NDArray

from .._jit import njit, on_load
from .params import P_C, P_F, P_I, P_K, P_M, P_MODEL, P_W, P_c, P_ci, P_df, P_eps, P_k, P_k3, P_ki, P_m, P_s
from .registry import InerterModel

#: a value of the equations: real, or complex in the complex-step derivatives
Num = float | complex
#: an array of the equations (state, parameters, inputs, outputs; float64, or complex128 for the complex step)
Vec = NDArray[Any]

#: the inerter model codes as plain ints for the compiled code (registry.InerterModel)
MODEL_NONE, MODEL_IDEAL, MODEL_PLAY = (int(m) for m in InerterModel)
NSTATE = 6
TWO_OVER_PI = 2.0 / math.pi


@njit(cache=True, inline="always")
def _re(v: Num) -> float:
    return v.real


def _atan(v: Num) -> Num:  # real arctangent, or its complex-step extension, dispatched at compile time
    return math.atan(cast(float, v))  # the Python body runs for real v only; compiled code uses the overload


def _atan_overload(v):  # type: ignore[no-untyped-def]  # numba compares this signature, annotations included, with the lambda's
    from numba import types

    if isinstance(v, types.Complex):
        # complex-step use only (imaginary part ~1e-30): first order in Im is exact to rounding
        return lambda v: complex(math.atan(v.real), v.imag / (1.0 + v.real * v.real))
    return lambda v: math.atan(v)


def _cos(v: Num) -> Num:  # real cosine, or its complex-step extension, dispatched at compile time
    return math.cos(cast(float, v))  # the Python body runs for real v only; compiled code uses the overload


def _cos_overload(v):  # type: ignore[no-untyped-def]  # numba compares this signature, annotations included, with the lambda's
    from numba import types

    if isinstance(v, types.Complex):
        # complex-step use only (imaginary part ~1e-30): first order in Im is exact to rounding
        return lambda v: complex(math.cos(v.real), -v.imag * math.sin(v.real))
    return lambda v: math.cos(v)


def _register_overloads() -> None:
    """The compiled versions of _atan and _cos (registered when numba is loaded, pyfmu_wrapper/_jit.py)."""
    from numba.extending import overload

    overload(_atan)(_atan_overload)
    overload(_cos)(_cos_overload)


on_load(_register_overloads)


@njit(cache=True)
def friction_force(v: Num, df: float, s: float) -> Num:
    """Regularised Coulomb friction df (2/pi) atan(s v) [N] at relative velocity v = xd - yd [m/s]."""
    if df == 0.0:
        return 0.0 * v
    return df * TWO_OVER_PI * _atan(s * v)


@njit(cache=True)
def spring_force(u: Num, p: Vec) -> Num:
    """TMD spring k u + k3 u^3 [N] at relative displacement u = x - y [m] (k3 = 0 adds exactly 0)."""
    return p[P_k] * u + p[P_k3] * (u * u * u)


@njit(cache=True)
def static_link_force(x: Num, xd: Num, y: Num, yd: Num, p: Vec) -> Num:
    """Fs = spring + viscous damper + dry friction [N], positive on the TMD in +y."""
    v = xd - yd
    return spring_force(x - y, p) + p[P_c] * v + friction_force(v, p[P_df], p[P_s])


@njit(cache=True)
def chain_force(d: Num, dd: Num, p: Vec) -> Num:
    """Force P [N] carried by the inerter-with-play chain, for d = r - y and its rate dd.

    Engaged in compression (d > eps): P = max(0, ki (d - eps) + ci dd); in extension (d < -eps):
    P = min(0, ki (d + eps) + ci dd); free otherwise. With eps = 0 the gap is closed on both sides
    and the chain is the linear inerter-in-series-with-spring P = ki d + ci dd.
    """
    ki, ci, eps = p[P_ki], p[P_ci], p[P_eps]
    if eps == 0.0:
        return ki * d + ci * dd
    if _re(d) > eps:
        f = ki * (d - eps) + ci * dd
        return f if _re(f) > 0.0 else 0.0 * f
    if _re(d) < -eps:
        f = ki * (d + eps) + ci * dd
        return f if _re(f) < 0.0 else 0.0 * f
    return 0.0 * d


@njit(cache=True)
def link_nonlinear(u: Num, v: Num, d: Num, dd: Num, p: Vec) -> tuple[Num, Num]:
    """The link forces' parts that are not linear in the state: (the spring's cubic term plus the dry
    friction [N], entering as :func:`static_link_force` does; the play chain's force P [N], 0 for the
    other models), at u = x - y, v = xd - yd and the chain's d, dd. Whatever is left of
    :func:`rhs_fext` with these two forces removed (k3 = df = 0, ki = ci = eps = 0) is linear in the
    state and the applied force: the split the transient simulation's affine RK4 step is built on."""
    fs = p[P_k3] * (u * u * u) + friction_force(v, p[P_df], p[P_s])
    if int(p[P_MODEL]) == MODEL_PLAY:
        return fs, chain_force(d, dd, p)
    return fs, 0.0 * d


@njit(cache=True)
def tmd_link(x: Num, xd: Num, y: Num, yd: Num, d: Num, dd: Num, p: Vec) -> tuple[Num, Num, Num, Num, Num, Num, Num]:
    """TMD side as affine functions of the base acceleration xdd.

    Returns (f0, a, ydd0, ya, ddd0, da, P0) with f_link = f0 + a xdd (force of the links on the
    base, acting in -x), ydd = ydd0 + ya xdd, ddd = ddd0 + da xdd and the inerter force
    P = P0 + (a - ...) (reported for diagnostics; for the ideal inerter P depends on xdd too and
    P0 here is its value at xdd = 0 -- use :func:`inerter_force` for the actual value).
    """
    model = int(p[P_MODEL])
    m, I = p[P_m], p[P_I]
    Fs = static_link_force(x, xd, y, yd, p)
    if model == MODEL_IDEAL:
        mi = m + I
        # m ydd = Fs + I (xdd - ydd)  ->  ydd = (Fs + I xdd) / (m + I)
        ydd0 = Fs / mi
        ya = I / mi
        # f = Fs + I (xdd - ydd) = m (Fs + I xdd) / (m + I)
        return m * Fs / mi, m * I / mi, ydd0, ya, 0.0 * dd, 0.0, -I * ydd0
    if model == MODEL_PLAY:
        P = chain_force(d, dd, p)
        ydd0 = (Fs + P) / m
        # rdd = xdd - P / I ; ddd = rdd - ydd
        return Fs + P, 0.0, ydd0, 0.0, -P / I - ydd0, 1.0, P
    ydd0 = Fs / m
    return Fs, 0.0, ydd0, 0.0, 0.0 * dd, 0.0, 0.0 * Fs


@njit(cache=True)
def base_acceleration(x: Num, xd: Num, f_link: Num, a: Num, fext: Num, p: Vec) -> Num:
    """Base: (M + a) xdd = fext - C xd - K x - f_link0, with the link's direct feed-through a."""
    return (fext - p[P_C] * xd - p[P_K] * x - f_link) / (p[P_M] + a)


@njit(cache=True)
def excitation(t: Num, p: Vec) -> Num:
    """F cos(w t) [N], w in rad/s."""
    return p[P_F] * _cos(p[P_W] * t)


@njit(cache=True)
def rhs_fext(z: Vec, fext: Num, p: Vec, out: Vec) -> None:
    """Time derivative of the coupled state for a given applied force fext [N]."""
    x, xd, y, yd, d, dd = z[0], z[1], z[2], z[3], z[4], z[5]
    f0, a, ydd0, ya, ddd0, da, _ = tmd_link(x, xd, y, yd, d, dd, p)
    xdd = base_acceleration(x, xd, f0, a, fext, p)
    out[0] = xd
    out[1] = xdd
    out[2] = yd
    out[3] = ydd0 + ya * xdd
    out[4] = dd
    out[5] = ddd0 + da * xdd


@njit(cache=True)
def rhs(t: float, z: Vec, p: Vec, out: Vec) -> None:
    """dz/dt of the coupled system under F cos(w t)."""
    rhs_fext(z, excitation(t, p), p, out)


# --- subsystems, as the FMUs integrate them ----------------------------------------------------
# Inputs of a subsystem over a communication step are Taylor polynomials in tau = t - u[0]:
# input k has value u[1 + 3k], first derivative u[2 + 3k], second derivative u[3 + 3k].
# The TMD subsystem's u carries one more entry after its three input polynomials (x, xd, xdd):
# u[U_KAPPA] = the compliance kappa = 1/M [1/kg] of the body it is mounted on (0: off). With
# kappa > 0 the xdd input is that body's acceleration *without* this TMD's link force, and the TMD
# adds the body's instantaneous reaction to its own force (:func:`mounted_acceleration`).
SYS_COUPLED, SYS_BASE, SYS_TMD = 0, 1, 2
U_KAPPA = 10


@njit(cache=True, inline="always")
def input_value(u: Vec, k: int, t: Num) -> Num:
    tau = t - u[0]
    return u[1 + 3 * k] + tau * (u[2 + 3 * k] + 0.5 * tau * u[3 + 3 * k])


@njit(cache=True)
def base_rhs(t: float, z: Vec, p: Vec, f_link: Num, out: Vec) -> None:
    """Base alone: z = [x, xd]; f_link [N] is the force of the TMD links on the base (in -x)."""
    out[0] = z[1]
    out[1] = base_acceleration(z[0], z[1], f_link, 0.0, excitation(t, p), p)


@njit(cache=True, inline="always")
def tmd_kappa(u: Vec) -> float:
    """The mounting compliance kappa carried in a TMD input vector u (0 when u has no slot)."""
    return u[U_KAPPA] if u.shape[0] > U_KAPPA else 0.0


@njit(cache=True, inline="always")
def mounted_acceleration(xdd_in: Num, kappa: float, f0: Num, a: Num) -> Num:
    """Acceleration of the body the TMD is mounted on, seen by the TMD within a step.

    kappa = 0: the input itself. kappa = 1/M > 0 (interface Jacobian d xdd / d f_link = -1/M):
    the input is the body's acceleration without the link force, xdd_free, and the body's
    reaction to the TMD's own force f = f0 + a xdd is added at every instant:
    xdd = xdd_free - kappa (f0 + a xdd)  ->  xdd = (xdd_free - kappa f0) / (1 + kappa a).
    This is the base's own equation of motion, so the fast gear-mesh dynamics see the base react
    without the delay of a communication step.
    """
    if kappa == 0.0:
        return xdd_in
    return (xdd_in - kappa * f0) / (1.0 + kappa * a)


@njit(cache=True)
def tmd_rhs(z: Vec, x: Num, xd: Num, xdd: Num, kappa: float, p: Vec, out: Vec) -> None:
    """TMD subsystem alone: z = [y, yd, d, dd] driven by the base motion x, xd, xdd
    (xdd: the base's acceleration without the TMD's force when kappa > 0, see
    :func:`mounted_acceleration`)."""
    f0, a, ydd0, ya, ddd0, da, _ = tmd_link(x, xd, z[0], z[1], z[2], z[3], p)
    xdd = mounted_acceleration(xdd, kappa, f0, a)
    out[0] = z[1]
    out[1] = ydd0 + ya * xdd
    out[2] = z[3]
    out[3] = ddd0 + da * xdd


@njit(cache=True)
def tmd_outputs(z: Vec, x: Num, xd: Num, xdd: Num, kappa: float, p: Vec) -> tuple[Num, Num, int]:
    """(force on the base [N], inerter chain force [N], gear contact state) of the TMD subsystem
    (kappa, xdd: see :func:`tmd_rhs`)."""
    f0, a, ydd0, ya, ddd0, da, P0 = tmd_link(x, xd, z[0], z[1], z[2], z[3], p)
    xdd = mounted_acceleration(xdd, kappa, f0, a)
    P = P0
    if int(p[P_MODEL]) == MODEL_IDEAL:
        P = p[P_I] * (xdd - (ydd0 + ya * xdd))
    return f0 + a * xdd, P, contact_state(z[2], p)


@njit(cache=True)
def system_rhs(system: int, t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """Right-hand side of the coupled system (u unused) or of one subsystem driven by inputs u."""
    if system == SYS_COUPLED:
        rhs_fext(z, excitation(t, p), p, out)
    elif system == SYS_BASE:
        base_rhs(t, z, p, input_value(u, 0, t), out)
    else:
        tmd_rhs(z, input_value(u, 0, t), input_value(u, 1, t), input_value(u, 2, t), tmd_kappa(u), p, out)


@njit(cache=True)
def inerter_force(z: Vec, xdd: Num, p: Vec) -> Num:
    """The force P [N] carried by the inerter link (0 without inerter)."""
    f0, a, ydd0, ya, ddd0, da, P0 = tmd_link(z[0], z[1], z[2], z[3], z[4], z[5], p)
    model = int(p[P_MODEL])
    if model == MODEL_IDEAL:
        return p[P_I] * (xdd - (ydd0 + ya * xdd))
    return P0


@njit(cache=True)
def contact_state(d: Num, p: Vec) -> int:
    """Gear contact of the play chain: +1 engaged in compression, -1 in extension, 0 free."""
    if int(p[P_MODEL]) != MODEL_PLAY:
        return 0
    eps = p[P_eps]
    if d > eps:
        return 1
    if d < -eps:
        return -1
    return 0


@njit(cache=True)
def system_switching(system: int, z: Vec, p: Vec, g: Vec) -> None:
    """Switching functions of a system in its own state layout (see switching_functions)."""
    if system == SYS_COUPLED:
        switching_functions(z, p, g)
    elif system == SYS_BASE:
        g[0] = 1.0
        g[1] = 1.0
        g[2] = 1.0
    else:
        g[0] = 1.0  # the base velocity is an input: reversals are not the TMD's to land on
        if int(p[P_MODEL]) == MODEL_PLAY and p[P_eps] > 0.0:
            g[1] = z[2] - p[P_eps]
            g[2] = z[2] + p[P_eps]
        else:
            g[1] = 1.0
            g[2] = 1.0


@njit(cache=True)
def switching_functions(z: Vec, p: Vec, g: Vec) -> None:
    """Functions whose sign changes mark non-smooth points that steps should land on.

    g[0] = xd - yd (friction reversal, only with friction), g[1] = d - eps, g[2] = d + eps (gear
    contact, only with a gap). Inactive entries are set to 1.
    """
    g[0] = z[1] - z[3] if p[P_df] > 0.0 else 1.0
    if int(p[P_MODEL]) == MODEL_PLAY and p[P_eps] > 0.0:
        g[1] = z[4] - p[P_eps]
        g[2] = z[4] + p[P_eps]
    else:
        g[1] = 1.0
        g[2] = 1.0


@njit(cache=True)
def energy(z: Vec, p: Vec) -> float:
    """Mechanical energy [J] stored in the coupled system (physics notes).

    E = M xd^2/2 + m yd^2/2 + K x^2/2 + k (x-y)^2/2 + k3 (x-y)^4/4 + I (xd - rd)^2/2
        + ki ((|d| - eps)+)^2/2.
    For the ideal inerter the inerter term is I (xd - yd)^2 / 2.
    """
    x, xd, y, yd, d, dd = z[0], z[1], z[2], z[3], z[4], z[5]
    u = x - y
    E = (
        0.5 * p[P_M] * xd * xd
        + 0.5 * p[P_m] * yd * yd
        + 0.5 * p[P_K] * x * x
        + 0.5 * p[P_k] * u * u
        + 0.25 * p[P_k3] * u**4
    )
    model = int(p[P_MODEL])
    if model == MODEL_IDEAL:
        E += 0.5 * p[P_I] * (xd - yd) ** 2
    elif model == MODEL_PLAY:
        rd = dd + yd
        E += 0.5 * p[P_I] * (xd - rd) ** 2
        pen = abs(d) - p[P_eps]
        if pen > 0.0:
            E += 0.5 * p[P_ki] * pen * pen
    return E


@njit(cache=True)
def power_balance(t: float, z: Vec, p: Vec) -> tuple[float, float]:
    """(input power, dissipated power) [W] at state z: dE/dt = input - dissipated.

    Dissipation: C xd^2 + c v^2 + Ffric v + ci dd_rel^2 in the engaged chain (v = xd - yd).
    """
    xd, yd, d, dd = z[1], z[3], z[4], z[5]
    v = xd - yd
    pin = excitation(t, p) * xd
    pd = p[P_C] * xd * xd + p[P_c] * v * v + friction_force(v, p[P_df], p[P_s]) * v
    if int(p[P_MODEL]) == MODEL_PLAY:
        if p[P_eps] == 0.0:
            pd += p[P_ci] * dd * dd
        else:
            P = chain_force(d, dd, p)
            if P != 0.0:
                pd += p[P_ci] * dd * dd
    return pin, pd
