"""Transient records (system level, ``kind: transient``): the coupled model simulated with the
**measured force as its input**, sampled the way the record was.

A transient record (swept sine, random or burst force, free decay, hammer impulse) has no steady
state, so nothing periodic is assumed: the kernels' right-hand side (:func:`physics.kernels.rhs_fext`,
the one statement of the equations of motion) is integrated by classical RK4 on a grid ``r`` times
finer than the record's samples, the force linearly interpolated between its samples. The record is
reduced for the fit by averaging every ``q`` consecutive samples: FIT_RATE fit samples per period of
the highest frequency that matters (the nominal's highest mode, or the frequency below which 99 % of
the force's power lies, at most 4 times that mode), and FIT_MAX fit samples at most;
the simulation is averaged over **the same sample instants**, so the reduction is matched exactly
(no anti-alias approximation). The declared analog low-pass of each channel runs **on the
integration grid, before the block means** (its state space stepped exactly for an input linear
between grid points): it acts on the continuous signal, as on the rig, so content above the fit rate
(stick-slip, impulses) is filtered before the averaging folds it down, not after. The pure delay is
applied at the fit rate as ``exp(-i w delay)`` in the frequency domain (linear and time invariant,
so it commutes with the averaging); the fit skips the first ``settle`` seconds where
the chain's own start-up (and the wrap of the discrete transform) lives: ``10 order / (2 pi
cutoff) + delay``, at least one fit sample (the stated start rule).

Start state: the record may start anywhere (a decay from an initial displacement, a rig already
moving). Its start state (x, xd, y, yd) is a nuisance: the residual's projection on the responses
to a unit start state (of the nominal linear model, through the same chain) is removed (variable
projection), and the estimate is fed back as the simulation's start state for the next pass, so a
nonlinear candidate is simulated from the estimated start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..._jit import njit
from ...physics.kernels import friction_force, link_nonlinear, rhs_fext
from ...physics.params import P_df, P_s
from ..acquisition import Chain

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy import ndarray

    from ..records import Record

CHANNELS = ("x", "y", "xdd", "ydd")  #: response channels, in this order in every array
FIT_MAX = 20000  #: fit samples per record at most (every q consecutive samples averaged)
#: integration grid points per record and simulation at most: a candidate whose parameters would need a
#: finer grid (a fitted mass near 0 makes its mode's rate, and the grid, unbounded) is not simulated
#: (:func:`simulate` answers None, as for a blow-up); 4e6 points keep one grid force at 32 MB, and
#: allow 200 intervals per fit block at FIT_MAX blocks, 10x the finest grid a nominal model needs
MAX_GRID = 4_000_000
FIT_RATE = 12.0  #: fit samples per period of the highest frequency that matters (see :func:`make_view`)
STEP_OMEGA = 0.25  #: RK4 step: h * (fastest rate of the model) at most this
#: RK4 steps per period of the force's 99 % frequency: a 4 ms hammer impulse on a clean record left
#: chi2/n = 1.14 in x (nominal z 7.8) with 8, 1.04 (z 0.6) with 32, converged (1.05 with 128)
STEPS_FORCE = 32.0


@njit(cache=True, nogil=True)
def _integrate(
    p: ndarray,
    f: ndarray,
    h: float,
    n_sub: int,
    n_out: int,
    z0: ndarray,
    out: ndarray,
    cx: float,
    cy: float,
    nord: ndarray,
    phi: ndarray,
    g1: ndarray,
    g2: ndarray,
    cc: ndarray,
    dd: ndarray,
    ee: ndarray,
    lin: ndarray,
) -> bool:
    """RK4 on the grid t_j = j h (force f[2 j] at every grid point, f[2 j + 1] at its midpoint); out[i] = the Simpson mean over
    grid points i n_sub .. (i + 1) n_sub of the channels u = (x, y, xdd - cx f, ydd - cy f) -- the positions and the
    accelerations without the force's direct feed-through (cx, cy: :func:`feedthrough`) -- each run first through its
    analog filter on the same grid (channel k of order nord[k] > 0, :func:`filter_grid`: s_{j+1} = phi s_j + g1 u_j +
    g2 u_{j+1}, the exact first-order-hold step; output cc . s + dd u; started at rest for u_0, s_0 = ee u_0).
    A linear model's RK4 step comes as matrices, ``lin`` (8, 10) of :func:`rk4_affine` (rows 0-5: z_{j+1} =
    lin[:6, :6] z_j + lin[:6, 6:9] (f_j, f_mid, f_j+1); rows 6-7: xdd, ydd = lin[6:, :6] z + lin[6:, 9] f),
    the same step as the four right-hand sides; an empty ``lin``: the right-hand side itself.
    Returns False when the state blows up (a candidate far outside its stable range)."""
    z = z0.copy()
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    zt = np.empty(6)
    u = np.empty(4)
    u_prev = np.empty(4)
    yv = np.empty(4)
    nmax = phi.shape[1]
    sf = np.zeros((4, nmax))
    st = np.empty(nmax)
    out[:, :] = 0.0
    n_grid = n_out * n_sub
    inv = 1.0 / n_sub
    linear = lin.shape[0] == 8
    for j in range(n_grid + 1):
        f0 = f[2 * j]
        if linear:
            a1 = lin[6, 9] * f0
            a3 = lin[7, 9] * f0
            for s in range(6):
                a1 += lin[6, s] * z[s]
                a3 += lin[7, s] * z[s]
            k1[1] = a1
            k1[3] = a3
        else:
            rhs_fext(z, f0, p, k1)
        i = j // n_sub
        kk = j % n_sub
        u[0] = z[0]
        u[1] = z[2]
        u[2] = k1[1] - cx * f0
        u[3] = k1[3] - cy * f0
        for c in range(4):
            n = nord[c]
            if n == 0:
                yv[c] = u[c]
                continue
            if j == 0:
                for a in range(n):
                    sf[c, a] = ee[c, a] * u[c]
            else:
                for a in range(n):
                    acc = g1[c, a] * u_prev[c] + g2[c, a] * u[c]
                    for b in range(n):
                        acc += phi[c, a, b] * sf[c, b]
                    st[a] = acc
                for a in range(n):
                    sf[c, a] = st[a]
            acc = dd[c] * u[c]
            for a in range(n):
                acc += cc[c, a] * sf[c, a]
            yv[c] = acc
        for c in range(4):
            u_prev[c] = u[c]
        w = (1.0 if kk == 0 else (4.0 if kk % 2 else 2.0)) * inv / 3.0  # Simpson (n_sub even)
        if i < n_out:
            for c in range(4):
                out[i, c] += w * yv[c]
        if kk == 0 and i > 0:  # the block's closing end point
            w = inv / 3.0
            for c in range(4):
                out[i - 1, c] += w * yv[c]
        if j == n_grid:
            break
        f1 = f[2 * j + 2]
        fm = f[2 * j + 1]
        if linear:
            for a in range(6):
                acc = lin[a, 6] * f0 + lin[a, 7] * fm + lin[a, 8] * f1
                for b in range(6):
                    acc += lin[a, b] * z[b]
                zt[a] = acc
            for a in range(6):
                z[a] = zt[a]
            if not (abs(z[0]) < 1e6 and abs(z[2]) < 1e6):
                return False
            continue
        for s in range(6):
            zt[s] = z[s] + 0.5 * h * k1[s]
        rhs_fext(zt, fm, p, k2)
        for s in range(6):
            zt[s] = z[s] + 0.5 * h * k2[s]
        rhs_fext(zt, fm, p, k3)
        for s in range(6):
            zt[s] = z[s] + h * k3[s]
        rhs_fext(zt, f1, p, k4)
        for s in range(6):
            z[s] += h / 6.0 * (k1[s] + 2.0 * k2[s] + 2.0 * k3[s] + k4[s])
        if not (abs(z[0]) < 1e6 and abs(z[2]) < 1e6):
            return False
    return True


def _rk4_step(z: ndarray, f0: float, fm: float, f1: float, p: ndarray, h: float) -> ndarray:
    """One classical RK4 step of the kernels' right-hand side (the one of :func:`_integrate`)."""
    k = [np.empty(6) for _ in range(4)]
    rhs_fext(z, f0, p, k[0])
    rhs_fext(z + 0.5 * h * k[0], fm, p, k[1])
    rhs_fext(z + 0.5 * h * k[1], fm, p, k[2])
    rhs_fext(z + h * k[2], f1, p, k[3])
    return z + h / 6.0 * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])


def rk4_affine(p: ndarray, h: float) -> ndarray:
    """The RK4 step of step h of the model p as matrices when p is linear (no friction, play or cubic
    stiffness: the right-hand side is linear in the state and the force, so the step is too): (8, 10)
    rows 0-5 [step of the unit states | of a unit force at the step's start, midpoint, end], rows 6-7
    the accelerations xdd, ydd [per unit state | per unit force]; built from the right-hand side itself
    (the step of each unit vector) and checked on a random state; (0, 10) when p is not linear."""
    from ...physics.params import P_k3

    out = np.zeros((0, 10))
    if not smooth(p) or p[P_k3] != 0.0:
        return out
    lin = np.zeros((8, 10))
    eye = np.eye(6)
    zero = np.zeros(6)
    acc = np.empty(6)
    for c in range(6):
        lin[:6, c] = _rk4_step(eye[c], 0.0, 0.0, 0.0, p, h)
        rhs_fext(eye[c], 0.0, p, acc)
        lin[6:, c] = acc[[1, 3]]
    for c in range(3):
        fs = [0.0, 0.0, 0.0]
        fs[c] = 1.0
        lin[:6, 6 + c] = _rk4_step(zero, fs[0], fs[1], fs[2], p, h)
    rhs_fext(zero, 1.0, p, acc)
    lin[6:, 9] = acc[[1, 3]]
    z = np.random.default_rng(0).normal(size=6)
    got = _rk4_step(z, 0.3, -0.7, 1.1, p, h)
    want = lin[:6, :6] @ z + lin[:6, 6:9] @ np.array([0.3, -0.7, 1.1])
    if not np.allclose(got, want, rtol=1e-9, atol=1e-12 * np.max(np.abs(got))):
        return out
    return lin


#: the state's projections the nonlinear link forces read (:func:`physics.kernels.link_nonlinear`):
#: u = x - y, v = xd - yd (spring's cubic term, dry friction), the play chain's d and dd
_PROJ = np.array([[1.0, 0, -1, 0, 0, 0], [0, 1, 0, -1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]])


def linear_split(p: ndarray) -> tuple[ndarray, ndarray, ndarray]:
    """The kernels' right-hand side as ``rhs_fext(z, f, p) = A z + b f + E g`` with g the nonlinear
    link forces of :func:`physics.kernels.link_nonlinear` (g[0]: cubic spring + dry friction, g[1]: the
    play chain's force): A (6, 6), b (6,) of the model with both removed (k3 = df = 0; for play
    ki = ci = eps = 0, the chain free), E (6, 2) the right-hand side's answer to a unit of each force
    (a unit more viscous damping at a unit relative velocity; a unit chain stiffness at a unit d),
    all read off :func:`rhs_fext` itself."""
    from ...physics.params import P_MODEL, P_c, P_ci, P_df, P_eps, P_k3, P_ki

    def rhs(z: ndarray, fx: float, q: ndarray) -> ndarray:
        o = np.empty(6)
        rhs_fext(z, fx, q, o)
        return o

    pl = p.copy()
    pl[P_df] = 0.0
    pl[P_k3] = 0.0
    play = int(p[P_MODEL]) == 2
    if play:
        pl[P_ki] = pl[P_ci] = pl[P_eps] = 0.0
    eye = np.eye(6)
    A = np.stack([rhs(eye[c], 0.0, pl) for c in range(6)], axis=1)
    b = rhs(np.zeros(6), 1.0, pl)
    E = np.zeros((6, 2))
    pc = pl.copy()
    pc[P_c] += 1.0
    E[:, 0] = rhs(eye[1], 0.0, pc) - A[:, 1]
    if play:
        pk = pl.copy()
        pk[P_ki] = 1.0
        E[:, 1] = rhs(eye[4], 0.0, pk) - A[:, 4]
    return A, b, E


def step_tables(p: ndarray, h: float) -> tuple[ndarray, ndarray, ndarray, int, int] | None:
    """The RK4 step of :func:`_integrate` as tables for :func:`_integrate_tables`, from
    :func:`linear_split`: RK4 is affine in the state, the force and the nonlinear forces g_i of its four
    stages taken as inputs, x = (z[:ns], f_j, f_mid, f_j+1, g_1, .., g_4) (ns = 6 with play, else 4:
    the play chain's d, dd act on nothing else; ng = 0, 1 or 2 forces per stage: linear, cubic and / or
    friction, play). Returns (stp (ns, nx): z_{j+1} = stp x; prj (4, nq, nx): the projections
    (u, v[, d, dd]) of stage i's state (column block of g_k, k >= i, zero); acc (2, ns + 1 + ng): xdd,
    ydd at the grid point from (z, f_j, g_1); nq; ng). None when the split does not give the
    right-hand side on a random state to 1e-12 (then :func:`_integrate` steps the right-hand side)."""
    from ...physics.params import P_MODEL, P_df, P_k3

    A, b, E = linear_split(p)
    play = int(p[P_MODEL]) == 2
    ng = 2 if play else (1 if (p[P_df] > 0 or p[P_k3] != 0.0) else 0)
    ns = 6 if play else 4
    nq = (4 if play else 2) if ng else 0
    z = np.random.default_rng(1).normal(size=6) * np.array([1e-3, 1e-2, 1e-3, 1e-2, 1e-4, 1e-2])
    want = np.empty(6)
    rhs_fext(z, 0.7, p, want)
    g = np.array(link_nonlinear(*(_PROJ @ z), p), float)
    got = A @ z + b * 0.7 + E @ g
    if not np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.max(np.abs(want))) or np.any(A[:ns, ns:] != 0.0):
        return None
    A, b, E, Q = A[:ns, :ns], b[:ns], E[:ns, :ng], _PROJ[:nq, :ns]
    nx = ns + 3 + 4 * ng
    X = np.eye(nx)
    z0, fs = X[:ns], X[ns : ns + 3]
    gs = [X[ns + 3 + i * ng : ns + 3 + (i + 1) * ng] for i in range(4)]

    def k(zs: ndarray, fx: ndarray, gx: ndarray) -> ndarray:
        return A @ zs + np.outer(b, fx) + E @ gx

    k1 = k(z0, fs[0], gs[0])
    z2 = z0 + 0.5 * h * k1
    k2 = k(z2, fs[1], gs[1])
    z3 = z0 + 0.5 * h * k2
    k3 = k(z3, fs[1], gs[2])
    z4 = z0 + h * k3
    k4 = k(z4, fs[2], gs[3])
    stp = z0 + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    prj = np.stack([Q @ zi for zi in (z0, z2, z3, z4)])
    cols = [*range(ns + 1), *range(ns + 3, ns + 3 + ng)]
    acc = k1[[1, 3]][:, cols]
    return stp, prj, acc, nq, ng


def filter_blocks(filt: tuple[ndarray, ...], n_sub: int) -> tuple[ndarray, ...]:
    """The grid filters of :func:`filter_grid` over one fit block of n_sub intervals, for
    :func:`_integrate_tables`: the block's Simpson mean of channel c's output is r[c] . s + sum_l rho[c, l]
    u_l and its end state Phi[c] s + sum_l M[c, l] u_l (s: the state at the block's start, u_l: the
    input at its grid points l = 0 .. n_sub); an unfiltered channel has rho = the Simpson weights.
    Returns (nord, Phi (4, nmax, nmax), M (4, n_sub + 1, nmax), r (4, nmax), rho (4, n_sub + 1), ee).

    The grid step is s_k = P s_(k-1) + G1 u_(k-1) + G2 u_k, the output C s_k + d u_k, so the end state
    takes u_l through P^(n-l) G2 (l >= 1) and P^(n-l-1) G1 (l < n), and with the row vectors
    L_l = sum_(k>=l) w_k C P^(k-l) (L_n = w_n C, L_l = w_l C + L_(l+1) P) the mean takes s through L_0 and
    u_l through L_l G2 (l >= 1) + L_(l+1) G1 (l < n) + w_l d: O(n m^2) work and O(n m) memory."""
    nord, phi, g1, g2, cc, dd, ee = filt
    nmax = phi.shape[1]
    n = n_sub
    w = np.where(np.arange(n + 1) % 2 == 1, 4.0, 2.0) / (3.0 * n)
    w[0] = w[n] = 1.0 / (3.0 * n)
    Phi = np.zeros((4, nmax, nmax))
    M = np.zeros((4, n + 1, nmax))
    r = np.zeros((4, nmax))
    rho = np.zeros((4, n + 1))
    for c in range(4):
        m = int(nord[c])
        if m == 0:
            rho[c] = w
            continue
        P, G1, G2, C = phi[c, :m, :m], g1[c, :m], g2[c, :m], cc[c, :m]
        L = np.empty((n + 2, m))  # L[n + 1] = 0
        L[n + 1] = 0.0
        L[n] = w[n] * C
        for k in range(n - 1, -1, -1):
            L[k] = w[k] * C + L[k + 1] @ P
        rho[c] = L[1 : n + 2] @ G1 + dd[c] * w
        rho[c, 1:] += L[1 : n + 1] @ G2
        r[c, :m] = L[0]
        pw1, pw2 = np.empty((n + 1, m)), np.empty((n + 1, m))  # P^i G1, P^i G2
        pw1[0], pw2[0] = G1, G2
        for i in range(1, n + 1):
            pw1[i] = P @ pw1[i - 1]
            pw2[i] = P @ pw2[i - 1]
        M[c, 1:, :m] = pw2[n - 1 :: -1]  # l = 1 .. n: P^(n-l) G2
        M[c, :n, :m] += pw1[n - 1 :: -1]  # l = 0 .. n-1: P^(n-l-1) G1
        Phi[c, :m, :m] = np.linalg.matrix_power(P, n)
    return nord, Phi, M, r, rho, ee


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract", "nsz", "arcp"})
def _integrate_tables(
    p: ndarray,
    f: ndarray,
    n_sub: int,
    n_out: int,
    z0: ndarray,
    out: ndarray,
    cx: float,
    cy: float,
    stp: ndarray,
    prj: ndarray,
    acc: ndarray,
    nq: int,
    ng: int,
    nord: ndarray,
    fphi: ndarray,
    fm: ndarray,
    fr: ndarray,
    frho: ndarray,
    ee: ndarray,
    stick_df: float = 0.0,
    band: float = 0.0,
) -> bool:
    """:func:`_integrate` (the same grid, RK4 step, channels, filters and Simpson block means) with the
    step as tables (:func:`step_tables`: the nonlinear link forces of :func:`physics.kernels.link_nonlinear`
    at each stage's projections, the rest matrices) and the filters per block (:func:`filter_blocks`:
    nord + 1 products per grid point and channel instead of nord^2 + 3 nord).

    ``stick_df`` > 0 (the model's dry friction df, :data:`STICK`): the link **sticks** as Coulomb's does.
    A step that starts stuck, or whose relative velocity v = xd - yd changes sign, is taken with one
    constant friction force G in its four stages: G* that ends the step at v = 0 (the step is affine in
    the stages' forces, so G* is one division). |G*| <= df: the link stays (or gets) stuck, v = 0 at the
    step's end exactly; a stuck link with |G*| > df breaks loose with G = df sign(G*); a slipping link
    whose v reverses with |G*| > df keeps the law's stages. A step starting in the band |s v| < ``band``
    is taken as a stuck one (Karnopp's band: the law's steep part is never stepped). While slipping
    outside it, the kernels' law df (2/pi) atan(s v) acts."""
    ns = stp.shape[0]
    nx = stp.shape[1]
    z = np.empty(ns)
    for a in range(ns):
        z[a] = z0[a]
    xv = np.zeros(nx)
    pv = np.zeros(4)
    zt = np.empty(ns)
    u = np.empty(4)
    nmax = fphi.shape[1]
    S = np.zeros((4, nmax))
    acs = np.zeros((4, nmax))
    st = np.empty(nmax)
    out[:, :] = 0.0
    n_grid = n_out * n_sub
    g0 = ns + 3
    stick = stick_df > 0.0 and ng > 0
    frs = np.zeros(4)  # each stage's friction force (the law's)
    bv = np.zeros(4)  # v at the step's end per unit friction force of stage i
    if stick:
        for i in range(4):
            bv[i] = stp[1, g0 + i * ng] - stp[3, g0 + i * ng]
    stuck = stick and z[1] == z[3]
    for j in range(n_grid + 1):
        f0 = f[2 * j]
        for a in range(ns):
            xv[a] = z[a]
        xv[ns] = f0
        last = j == n_grid
        if not last:
            xv[ns + 1] = f[2 * j + 1]
            xv[ns + 2] = f[2 * j + 2]
        n_st = 0 if ng == 0 else (1 if last else 4)
        for i in range(n_st):
            lim = g0 + i * ng
            for q in range(nq):
                acc_q = 0.0
                for c in range(lim):
                    acc_q += prj[i, q, c] * xv[c]
                pv[q] = acc_q
            g_s, g_p = link_nonlinear(pv[0], pv[1], pv[2], pv[3], p)
            xv[lim] = g_s
            if ng == 2:
                xv[lim + 1] = g_p
            if stick:
                frs[i] = friction_force(pv[1], p[P_df], p[P_s])
        if stick and not last:
            v0 = z[1] - z[3]
            v1 = 0.0
            for c in range(nx):
                v1 += (stp[1, c] - stp[3, c]) * xv[c]
            if stuck or v0 * v1 < 0.0 or abs(v0) * p[P_s] < band:
                bsum = 0.0
                bfr = 0.0
                for i in range(4):
                    bsum += bv[i]
                    bfr += bv[i] * frs[i]
                g_star = (bfr - v1) / bsum
                use = True
                if abs(g_star) <= stick_df:
                    g_c = g_star
                    stuck = True
                elif stuck or abs(v0) * p[P_s] < band:  # breaking loose, or slipping slowly: Coulomb's
                    g_c = stick_df if g_star > 0.0 else -stick_df
                    stuck = False
                else:
                    g_c = 0.0
                    use = False
                if use:
                    for i in range(4):
                        xv[g0 + i * ng] += g_c - frs[i]
        a1 = 0.0
        a3 = 0.0
        for c in range(ns + 1):
            a1 += acc[0, c] * xv[c]
            a3 += acc[1, c] * xv[c]
        for g in range(ng):
            a1 += acc[0, ns + 1 + g] * xv[g0 + g]
            a3 += acc[1, ns + 1 + g] * xv[g0 + g]
        u[0] = z[0]
        u[1] = z[2]
        u[2] = a1 - cx * f0
        u[3] = a3 - cy * f0
        i = j // n_sub
        kk = j % n_sub
        if j == 0:
            for c in range(4):
                for a in range(nord[c]):
                    S[c, a] = ee[c, a] * u[c]
        elif kk == 0:  # the previous block's closing end point, and its end state
            for c in range(4):
                m = nord[c]
                out[i - 1, c] += frho[c, n_sub] * u[c]
                for a in range(m):
                    acs[c, a] += fm[c, n_sub, a] * u[c]
                for a in range(m):
                    acc_a = acs[c, a]
                    for b in range(m):
                        acc_a += fphi[c, a, b] * S[c, b]
                    st[a] = acc_a
                for a in range(m):
                    S[c, a] = st[a]
                    acs[c, a] = 0.0
        if i < n_out:
            for c in range(4):
                m = nord[c]
                acc_o = frho[c, kk] * u[c]
                if kk == 0:
                    for a in range(m):
                        acc_o += fr[c, a] * S[c, a]
                out[i, c] += acc_o
                for a in range(m):
                    acs[c, a] += fm[c, kk, a] * u[c]
        if last:
            break
        for a in range(ns):
            acc_z = 0.0
            for c in range(nx):
                acc_z += stp[a, c] * xv[c]
            zt[a] = acc_z
        for a in range(ns):
            z[a] = zt[a]
        if stuck:
            z[3] = z[1]  # (v = 0 to rounding: exactly)
        if not (abs(z[0]) < 1e6 and abs(z[2]) < 1e6):
            return False
    return True


def filter_grid(chains: dict, h: float) -> tuple[ndarray, ...]:
    """The analog filters of the channels x, y, xdd, ydd discretised exactly for an input linear
    between grid points h apart (first-order hold): (nord, phi, g1, g2, cc, dd, ee) for
    :func:`_integrate` (nord[k] = 0: no filter on channel k), from :meth:`Chain.foh_step` (the cascade
    of the filter's sections: well conditioned at any order and cut-off); dd = 0 (all-pole)."""
    steps = [None if chains.get(ch) is None else chains[ch].foh_step(h) for ch in CHANNELS]
    nmax = max([1] + [st[0].shape[0] for st in steps if st is not None])
    nord = np.zeros(4, np.int64)
    phi = np.zeros((4, nmax, nmax))
    g1, g2, cc, ee = (np.zeros((4, nmax)) for _ in range(4))
    dd = np.zeros(4)  # the declared low-passes are all-pole: no direct term
    for k, st in enumerate(steps):
        if st is None:
            continue
        n = st[0].shape[0]
        nord[k] = n
        phi[k, :n, :n], g1[k, :n], g2[k, :n], cc[k, :n], ee[k, :n] = st
    return nord, phi, g1, g2, cc, dd, ee


def hold_response(chain: Chain, h: float, w: ndarray) -> ndarray:
    """The grid filter's transfer at angular frequencies w: C (e^{i w h} - phi)^-1 (g1 + g2 e^{i w h}) of
    the exact first-order-hold step (:meth:`Chain.foh_step`) -- the analog filter's response to the grid
    samples joined by straight lines, the aliases of the lines' corners included."""
    st = chain.foh_step(h)
    assert st is not None
    phi, g1, g2, cc, _ = st
    z = np.exp(1j * w * h)
    n = phi.shape[0]
    # in phi's eigenvectors (the declared low-passes have distinct poles): sum_k a_k (b1_k + b2_k z) / (z - lam_k),
    # O(n) per frequency instead of a solve; a near-defective phi takes the solve
    lam, V = np.linalg.eig(phi)
    if np.linalg.cond(V) < 1e4:
        a, b1, b2 = cc @ V, np.linalg.solve(V, g1), np.linalg.solve(V, g2)
        return np.real_if_close(((b1[None, :] + b2[None, :] * z[:, None]) / (z[:, None] - lam[None, :])) @ a, tol=0)
    A = z[:, None, None] * np.eye(n)[None] - phi[None]
    b = g1[None, :] + g2[None, :] * z[:, None]
    return np.linalg.solve(A, b[:, :, None])[:, :, 0] @ cc


def _through(out: ndarray, y: ndarray, gs: list, lead: int, nf: int) -> ndarray:
    """``out`` with each column k of y passed through the frequency response gs[k] (None: left as it
    is) by FFT of length nf, the column's first and last values held ``lead`` samples before and
    after it (the chain at rest there, as on the rig)."""
    n = y.shape[0]
    for k, g in enumerate(gs):
        if g is None:
            continue
        u = y[:, k]
        pad = np.concatenate([np.full(lead, u[0]), u, np.full(nf - n - lead, u[-1])])
        out[:, k] = np.fft.irfft(np.fft.rfft(pad) * g, nf)[lead : lead + n]
    return out


def hold_correct(y: ndarray, fs: float, chains: dict, h: float, cache: dict) -> ndarray:
    """Block means (n, 4) of the grid filters' outputs corrected to the analog filters' outputs: each
    filtered channel times G(i w) / G_hold(i w) at the fit rate fs (:func:`hold_response`), which
    removes the straight-line hold's error ((w h)^2 / 12 of the signal at w, less where the filter
    passes the aliases) for the content below the fit's Nyquist frequency."""
    n = y.shape[0]
    lead = min(n, 256)
    nf = 1 << int(math.ceil(math.log2(2 * n + 2 * lead)))

    def make() -> list[ndarray | None]:
        w = 2 * math.pi * np.fft.rfftfreq(nf, 1.0 / fs)
        gs: list[ndarray | None] = []
        for ch in CHANNELS:
            c = chains.get(ch)
            if c is None or c.type is None:
                gs.append(None)
                continue
            g = c.response(w) * np.exp(1j * w * c.delay_s)  # the filter alone
            gs.append(g / hold_response(c, h, w))
        return gs

    gs = _cached(cache, ("hold", nf, fs, h), make)
    if all(g is None for g in gs):
        return y
    return _through(y.copy(), y, gs, lead, nf)


@dataclass
class TView:
    """One transient record prepared for the fit."""

    name: str
    t: ndarray  #: fit-sample times (block means) [s]
    meas: ndarray  #: (n_out, 4) measured block means of x, y, xdd, ydd (NaN: channel not recorded)
    has: ndarray  #: (4,) bool: channel recorded
    force: ndarray  #: measured force at the record's samples [N] (zeros for a free decay)
    dt: float  #: record sample spacing [s]
    q: int  #: record samples per fit sample
    n_out: int
    skip: int  #: fit samples skipped at the start (the chain's start-up)
    chains: dict  #: channel -> acquisition.Chain
    sigma: ndarray = field(default_factory=lambda: np.ones(4))  #: noise std per channel of a fit sample
    free_decay: bool = False
    #: share of the force's power aliased by the sampling, estimated from the measured power above
    #: 0.8 x Nyquist: the true force there (the declared filter's gain divided out) assumed no weaker
    #: at the mirror frequencies fs - f, through the filter's gain there (1 without a filter)
    aliased: float = 0.0
    #: the same for the force's transient content only (:func:`transient_share`: impulses, not the load
    #: cell's stationary noise floor): what a delay shift of the samples gets wrong (``transient._direct_snr``)
    aliased_excess: float = 0.0
    #: amplitude of the force's spectrum folded onto its low band by the sampling, relative to that band
    #: (:func:`folded_share`): an impulse sampled by a few samples has an area known only to about this
    fold: float = 0.0
    z0: ndarray = field(default_factory=lambda: np.zeros(6))  #: start state of the simulation
    phi: ndarray | None = None  #: (n_out, 4, 4) response to unit start states (x, xd, y, yd)
    fcache: dict = field(default_factory=dict)  #: the force and the filters' steps on the last simulation grids
    gcache: dict = field(default_factory=dict)  #: the chains' responses on the fit-rate FFT grid
    raw_noise: dict = field(default_factory=dict)  #: channel -> noise std of one record sample
    chi2_var: float = 1.0  #: var(chi2) / (2 n) of its whitened residual under the noise (:func:`chi2_variance_factor`)
    h_max: float = np.inf  #: longest RK4 step that resolves the force (STEPS_FORCE per period of its 99 % frequency)

    @property
    def fs(self) -> float:
        return 1.0 / (self.dt * self.q)


def make_view(rec: Record, chains: dict, f_mode: float) -> TView:
    """The fit view of a transient record: samples averaged in blocks of q, the chain's start-up
    skipped (f_mode: the nominal's highest modal frequency [Hz])."""
    from ..errors import DataError

    c = rec.columns
    t = np.asarray(c["t"], float)
    n = t.size
    dt = float(t[-1] - t[0]) / (n - 1)
    if np.max(np.abs(np.diff(t) - dt)) > 0.01 * dt:
        raise DataError(
            f"{rec.name}, column 't': a transient record must be uniformly sampled (spacing varies by more "
            f"than 1 % of dt = {dt:.6g} s)"
        )
    f_top, f99, aliased, fold, aliased_excess = f_mode, 0.0, 0.0, 0.0, 0.0
    if "force" in c:
        P = np.abs(np.fft.rfft(np.asarray(c["force"], float) - np.mean(c["force"]))) ** 2
        fr = np.fft.rfftfreq(n, dt)
        cum = np.cumsum(P) / max(P.sum(), 1e-300)
        f99 = float(fr[min(int(np.searchsorted(cum, 0.99)), fr.size - 1)])
        hi = fr > 0.8 * fr[-1]
        cf = chains.get("force")
        mirror = np.ones(int(hi.sum()))
        if cf is not None and cf.type is not None:  # the filter's gain at the mirror frequencies fs - f
            mirror = np.abs(cf.response(2 * math.pi * (1.0 / dt - fr[hi]))) / np.maximum(
                np.abs(cf.response(2 * math.pi * fr[hi])), 1e-12
            )
        aliased = float((P[hi] * mirror**2).sum() / max(P.sum(), 1e-300))
        f_top = min(max(f_mode, f99), 4 * f_mode)
        fold = folded_share(P, fr, dt, f_top, robust_noise(np.asarray(c["force"], float)), cf)
    q = max(1, int(1.0 / (dt * FIT_RATE * f_top)), math.ceil(n / FIT_MAX))
    n_out = n // q
    meas = np.full((n_out, 4), np.nan)
    has = np.zeros(4, bool)
    for k, ch in enumerate(CHANNELS):
        if ch in c:
            meas[:, k] = np.asarray(c[ch], float)[: n_out * q].reshape(n_out, q).mean(axis=1)
            has[k] = True
    tb = t[: n_out * q].reshape(n_out, q).mean(axis=1)
    settle = 0.0
    for ch in ("force", *CHANNELS):
        ch_c = chains.get(ch)
        if ch_c is not None:
            s_c = 10 * ch_c.order / (2 * math.pi * ch_c.cutoff_hz) if ch_c.type is not None else 0.0
            settle = max(settle, s_c + ch_c.delay_s)
    skip = max(1, math.ceil(settle / (dt * q)))
    if "force" in c and aliased > 0:  # after the chain's start-up (its ringing is skipped by the fit too)
        aliased_excess = aliased * transient_share(np.asarray(c["force"], float), hi, mirror, skip * q)
    force = np.asarray(c["force"], float).copy() if "force" in c else np.zeros(n)
    raw = {ch: robust_noise(np.asarray(c[ch], float)) for ch in ("force", *CHANNELS) if ch in c}
    return TView(
        raw_noise=raw,
        h_max=1.0 / (STEPS_FORCE * f99) if f99 > 0 else np.inf,
        name=rec.name,
        t=tb,
        meas=meas,
        has=has,
        force=force,
        dt=dt,
        q=q,
        n_out=n_out,
        skip=skip,
        chains=chains,
        free_decay="force" not in c,
        aliased=aliased,
        aliased_excess=aliased_excess,
        fold=fold,
    )


def transient_share(f: ndarray, band: ndarray, gain: ndarray, start: int = 0) -> float:
    """The share of the force's power in ``band`` (bool over its rfft bins, weighted by ``gain``) that
    is transient -- impulses -- rather than a stationary floor: the band's signal in time, its floor
    the median of its square over the record (a stationary Gaussian's median square is 0.455 of its
    mean), the excess over it. A hammer's hits fill a few % of the time: the median is the floor and
    the hits are the excess; a sweep or a random force has only the load cell's noise floor there
    (measured at 1.5-2 x the white noise of its fourth differences: not white), and a share near 0.
    Samples before ``start`` (the chain's start-up, where a filter started at rest rings) are left out."""
    X = np.fft.rfft(f - np.mean(f))
    Y = np.zeros_like(X)
    Y[band] = X[band] * gain
    u2 = np.fft.irfft(Y, f.size)[start:] ** 2
    tot = float(u2.sum())
    if tot <= 0.0:
        return 0.0
    return max(0.0, 1.0 - u2.size * float(np.median(u2)) / 0.4549 / tot)


def modal_eigenvalues(p: ndarray, inertance: float) -> ndarray:
    """The eigenvalues of the linear part of the model p (friction, cubic term and play left out)
    with an ideal inerter of inertance ``inertance`` between the masses (0: none), read off the
    kernels' right-hand side (:func:`linear_split`): the (x, xd, y, yd) block of its A."""
    from ...physics.params import P_I, P_MODEL

    q = np.array(p, float)
    q[P_MODEL], q[P_I] = (1.0 if inertance > 0 else 0.0), inertance
    return np.asarray(np.linalg.eigvals(linear_split(q)[0][:4, :4]))


def rates(p: ndarray) -> tuple[float, float, float]:
    """(modal, contact, friction) rates [1/s] of the model with parameters p: the largest |eigenvalue|
    of the linear part (friction, play left out), the play chain's contact frequency sqrt(ki / mu)
    (0 without play) and the friction's relaxation rate df (2/pi) s / mu (0 without friction)."""
    from ...physics.params import P_I, P_M, P_MODEL, P_df, P_ki, P_m, P_s

    M, m, I = (float(p[i]) for i in (P_M, P_m, P_I))
    contact = 0.0
    mu = 1.0 / (1.0 / m + 1.0 / M)
    if int(p[P_MODEL]) == 2:  # play: the chain's contact mode
        contact = math.sqrt(p[P_ki] / (1.0 / (1.0 / I + 1.0 / m + 1.0 / M)))
        I = 0.0
    modal = float(np.max(np.abs(modal_eigenvalues(p, I))))
    friction = p[P_df] * 2 / math.pi * p[P_s] / mu if p[P_df] > 0 else 0.0
    if STICK and friction > 0:  # the law's steepest part, |s v| < STICK_BAND, is the stick check's
        friction = max(friction / (1.0 + STICK_BAND**2), STEP_LIMITS[2] / STICK_H)
    return modal, contact, float(friction)


def fastest_rate(p: ndarray) -> float:
    """The nominal's highest modal rate [1/s] (friction and play left out)."""
    return rates(p)[0]


#: RK4 step limits, h x rate: the modes (accuracy), the play contact (an oscillation that only has to
#: stay stable and short), the friction's relaxation (real and stiff: stability of RK4 is 2.78, but its
def folded_share(P: ndarray, fr: ndarray, dt: float, f_top: float, noise: float, chain: Chain | None) -> float:
    """Amplitude of the force's spectrum at the sampling rate fs relative to its mean amplitude below
    f_top (the band the structure answers in): what the sampling folds onto that band, unknowable from
    the samples. A 4 ms half-sine impulse sampled at 2 kHz (8 samples) has its area known only to
    about +-1 %, by the phase of the samples against the impulse (|F(fs)| / |F(0)| = 0.4 %).
    Estimated from the measured amplitude over FOLD_BAND x Nyquist above the force's white noise
    (``P``: |rfft|^2 at ``fr``, ``noise``: one sample's std), the declared filter's gain divided out,
    extrapolated to fs as an impulse's tail with a kink, 1 / f^2 (a smoother impulse falls faster:
    the estimate errs high), times the filter's gain at fs. 0 for a force without content there."""
    n = 2 * (P.size - 1)
    f_n = 0.5 / dt
    lo_b, hi_b = FOLD_BAND
    band, lo = (fr >= lo_b * f_n) & (fr <= hi_b * f_n), (fr > 0) & (fr <= f_top)
    if not band.any() or not lo.any():
        return 0.0
    g_band, g_fs = np.ones(int(band.sum())), 1.0
    if chain is not None and chain.type is not None:
        g_band = np.maximum(np.abs(chain.response(2 * math.pi * fr[band])), 1e-6)
        g_fs = float(np.abs(chain.response(2 * math.pi * 2 * f_n)))
    excess = np.maximum(P[band] - n * noise**2, 0.0) / g_band**2
    # amplitude at fs of a 1 / f^2 tail through the band: sqrt(mean((f / fs)^4 |F(f)|^2))
    a_fs = math.sqrt(float(np.mean(excess * (fr[band] / (2 * f_n)) ** 4)))
    a_lo = math.sqrt(max(float(np.mean(P[lo])), 1e-300))
    return a_fs * g_fs / a_lo


#: band of the force's spectrum (share of Nyquist) from which its content at fs is extrapolated: above
#: the structure's modes, below the top where the noise floor and the filter's roll-off dominate
FOLD_BAND = (0.3, 0.7)


#: stick-slip transitions need accuracy: a 5 N friction truth fitted with its true parameters left
#: chi2/n = 4.6 in ydd with 2.0, 0.84 with 0.5, on unfiltered records)
STEP_LIMITS = (STEP_OMEGA, 1.0, 0.5)
#: grid intervals per fit block at least when a declared filter runs on the grid and the model is not
#: smooth (friction, play: stick-slip and contact put content above the fit rate, which the grid filter
#: has to see): its input is linear between grid points, an error of (w h)^2 / 8 of the signal at w;
#: with 4 (w h = 0.13 at the fit's top frequency) a viscous truth at its true parameters left chi2/n
#: 1.13-1.19 in xdd on records behind a 400 Hz Butterworth (held-out z 5.0: `unexplained`), with 16
#: 0.98-1.02 (z -2.1). With a friction truth, the hold's correction below the fit's Nyquist frequency
#: (:func:`hold_correct`) leaves 0.5 noise std rms in ydd with 8 (0.1 with 16): the stick-slip's
#: content above it is what the grid has to resolve.
FILTER_SUB = 16
#: the same for a smooth model (every content below the fit's Nyquist frequency), where the hold's error
#: is corrected (:func:`hold_correct`): what is left is the force's content between grid points (its
#: spline through the record's samples, sampled at the RK4 step's ends and midpoint). On the bench's
#: viscous records (400 Hz Butterworth, fit blocks of 13 samples at 800 Hz) the block means differ from
#: a 64-interval grid by at most 0.0014 noise std rms with 12 (0.0018 with 16; 0.007 with 10, 0.024 with
#: 8, where a step spans more than a record sample; the code before the correction: 0.028 in the
#: accelerations with 16). Kept at 16 all the same: with 12 the viscous bench's all-records fit stopped
#: at a training chi-square 1544 higher (128694 for 128384 samples) and 1.8 std off main's parameter
#: (the trust region's path with the decay's start state, not the simulation: at fixed parameters 12 and
#: 16 give the same chi2 / n to 4 digits); with 16 it lands where main does (10.00040 / 10.00041 N s/m)
FILTER_SUB_SMOOTH = 16


LINEAR_STEP = True  #: a linear model's RK4 step as matrices (:func:`rk4_affine`); False: its right-hand side
#: the step as tables and the filters per block (:func:`_integrate_tables`, every model kind); False
#: (or LINEAR_STEP False: the right-hand side itself for every model): :func:`_integrate`
STEP_TABLES = True
#: dry friction sticks in the table integrator (:func:`_integrate_tables`, ``stick_df``); False: the
#: kernels' regularised law alone (which creeps where Coulomb's sticks: a stick-slip truth fitted at the
#: slope's bound of 5000 s/m left z = 692 on seed 77's tr000, the creep of its stick phases)
STICK = True
#: the stick check's velocity band, |v| < STICK_BAND / s (Karnopp's): a step starting there is taken with
#: the force that stops the link (stuck) or, when that exceeds df, with df itself (slipping): the law's
#: steep part near v = 0 is never stepped, so the friction's relaxation rate that bounds the RK4 step is
#: the law's outside the band, df (2/pi) s / (1 + STICK_BAND^2) / mu (at the band's edge the law gives
#: 0.98 df)
STICK_BAND = 5.0
#: the RK4 step of a model with dry friction at most this [s] under STICK: the stick and slip phases
#: change at grid points, so their timing is known to h. Measured on a 5 N stick-slip truth (sweep and
#: random force, 1 kHz, 20 s; seed 0 of tests' make): at the truth's force and a slope of 5e4-2e5 s/m,
#: h 1.7e-4 s left chi2/n 0.9-1.0 where the regularised law alone needs h 1.6e-5 s (10 times the
#: cost); h 2e-3 s left the random record's ydd at 12
STICK_H = 1.5e-4


def _stick_df(p: ndarray) -> float:
    return float(p[P_df]) if STICK and p[P_df] > 0 else 0.0


def smooth(p: ndarray) -> bool:
    """The model p has no dry friction and no play (its response holds no stick-slip or contact)."""
    from ...physics.params import P_MODEL, P_df

    return not (p[P_df] > 0 or int(p[P_MODEL]) == 2)


def refinement(v: TView, p: ndarray) -> int:
    """Grid intervals per fit block (even, >= 2): RK4 step h within STEP_LIMITS of every rate, and
    short enough for the force (``h_max``, at most two grid intervals per record sample); with a
    declared filter at least FILTER_SUB (FILTER_SUB_SMOOTH for a :func:`smooth` model)."""
    T = v.dt * v.q
    n = max(2, *(math.ceil(r * T / lim) for r, lim in zip(rates(p), STEP_LIMITS)))
    if math.isfinite(v.h_max):  # the force's own content (a hammer impulse reaches the accelerations directly)
        n = max(n, min(math.ceil(T / v.h_max), 2 * v.q))
    if any(c is not None and c.type is not None for c in v.chains.values()):
        n = max(n, FILTER_SUB_SMOOTH if smooth(p) else FILTER_SUB)  # the filters' input is linear between grid points
    return rung(n)


def rung(n: int) -> int:
    """n grid intervals rounded up to the ladder's next rung: even; above LADDER_EXACT, 2^(k/4) rounded up to
    even (at most 19 % more steps). A fit's parameters move the rates, hence the grid, at every
    evaluation: on the ladder neighbouring models share a grid (the force on it is made once, the
    Jacobian's columns step on the same grid as the point they differ from)."""
    n = max(2, n + (n % 2))
    if n <= LADDER_EXACT:
        return n
    r = LADDER_EXACT
    while r < n:
        r = int(math.ceil(r * 2**0.25))
        r += r % 2
    return r


def apply_chain(
    y: ndarray, fs: float, chains: dict, dt: float | None = None, cache: dict | None = None, filters: bool = True
) -> ndarray:
    """Each simulated channel (columns of y: block means at the fit rate fs) through its declared chain
    G(i w) (with ``filters`` False only its pure delay: the filter already ran on the integration
    grid); with ``dt`` (the record's sample spacing, when blocks hold several samples) also from the
    continuous block mean to the mean of the block's samples: (w dt / 2) / sin(w dt / 2)."""
    out = y.copy()
    n = y.shape[0]
    lead = min(n, 256)  # the record's first value held before it (the chain at rest there, as on the rig)
    nf = 1 << int(math.ceil(math.log2(2 * n + 2 * lead)))
    key = (nf, fs, dt, filters)
    if cache is not None and cache.get("key") == key:
        gs = cache["g"]
    else:
        w = 2 * math.pi * np.fft.rfftfreq(nf, 1.0 / fs)
        disc = None
        if dt is not None:
            a = 0.5 * w * dt
            disc = np.where(a > 1e-12, a / np.sin(np.maximum(a, 1e-12)), 1.0)
        gs = []
        for ch in CHANNELS:
            c = chains.get(ch)
            if c is not None and not filters:
                c = Chain(ch, delay_s=c.delay_s)
            g = None if c is None or (c.type is None and not c.delay_s) else c.response(w)
            if disc is not None:
                g = disc if g is None else g * disc
            gs.append(g)
        if cache is not None:
            cache.update(key=key, g=gs)
    return _through(out, y, gs, lead, nf)


def feedthrough(p: ndarray) -> tuple[float, float]:
    """(d xdd / dF, d ydd / dF) of the model p: the force's direct feed-through into the accelerations
    (state independent: 1 / (M + a) and ya / (M + a) of the kernels' link)."""
    z, k0, k1 = np.zeros(6), np.empty(6), np.empty(6)
    rhs_fext(z, 0.0, p, k0)
    rhs_fext(z, 1.0, p, k1)
    return float(k1[1] - k0[1]), float(k1[3] - k0[3])


def true_force(v: TView) -> ndarray:
    """The measured force with the force channel's declared chain divided out (the true force drives
    the model): 1 / G where |G| > 0.1 (the pass band, exact), no amplification of noise beyond the
    cut-off."""
    f = v.force
    cf = v.chains.get("force")
    if cf is not None:
        nf = 1 << int(math.ceil(math.log2(2 * f.size)))
        w = 2 * math.pi * np.fft.rfftfreq(nf, v.dt)
        g = cf.response(w)
        pad = np.concatenate([f, np.full(nf - f.size, f[-1])])
        ginv = np.conj(g) / np.maximum(np.abs(g) ** 2, 0.01)
        f = np.fft.irfft(np.fft.rfft(pad) * ginv, nf)[: f.size]
    return f


def same_filter(a: Chain | None, b: Chain | None) -> bool:
    """The two chains hold the same analog low-pass (or neither has one)."""
    fa = None if a is None or a.type is None else (a.type, a.order, a.cutoff_hz)
    fb = None if b is None or b.type is None else (b.type, b.order, b.cutoff_hz)
    return fa == fb


def direct_force(v: TView) -> ndarray:
    """(n_out, 2): the force's direct feed-through into the xdd and the ydd channel (per unit of
    d acc / dF) **at the record's own rate**, averaged over each fit block's samples: the measured
    force through G_acc / G_force. Where the acceleration and the force channel hold the same
    analog filter (``all``), the filters cancel exactly and only the delays' difference is applied:
    the accelerometer sampled that very filtered force, aliasing and averaging on reading included,
    so the term is exact however short the impulse. Otherwise the true force (the force's chain
    divided out in its pass band, :func:`true_force`) runs through the acceleration's chain. A hammer
    impulse (4 ms) lives far above the fit rate, where the fit-rate chain would alias it; the rest of
    the accelerations is smooth."""
    cf = v.chains.get("force")
    n = v.n_out * v.q
    lead = min(n, 256)  # the first value held before the record (the chain at rest), as apply_chain
    nf = 1 << int(math.ceil(math.log2(2 * n + 2 * lead)))
    w = 2 * math.pi * np.fft.rfftfreq(nf, v.dt)
    specs: dict[bool, ndarray] = {}

    def spec(measured: bool) -> ndarray:
        if measured not in specs:
            f = (v.force if measured else true_force(v))[:n]
            specs[measured] = np.fft.rfft(np.concatenate([np.full(lead, f[0]), f, np.full(nf - n - lead, f[-1])]))
        return specs[measured]

    out = np.empty((v.n_out, 2))
    for k, ch in enumerate(("xdd", "ydd")):
        c = v.chains.get(ch)
        if cf is not None and cf.type is not None and same_filter(c, cf):
            d = (c.delay_s if c is not None else 0.0) - cf.delay_s
            u = np.fft.irfft(spec(True) * np.exp(-1j * w * d), nf)[lead : lead + n] if d else v.force[:n]
        elif c is not None and (c.type is not None or c.delay_s):
            u = np.fft.irfft(spec(False) * c.response(w), nf)[lead : lead + n]
        else:
            u = true_force(v)[:n]
        out[:, k] = u.reshape(v.n_out, v.q).mean(axis=1)
    return out


#: grid points of the force evaluated at a time (:func:`grid_force`): its temporaries stay near 10 MB
#: (a grid of MAX_GRID intervals holds 8e6 values, 64 MB per temporary)
GRID_CHUNK = 1 << 17
#: a view's cached arrays of one kind (the force on a grid: 2 n_out n_sub + 1 values) at most this many
#: bytes beside the newest: a 30 s record at 71 Hz with friction's fine grid (n_sub ~800) holds 27 MB a
#: grid, and four per record and window (``keep``) held 0.8 GB (seed 9494 tr018, tracemalloc)
CACHE_BYTES = 48 * 2**20
#: grid intervals per fit block below which :func:`rung` keeps the count itself
LADDER_EXACT = 16


def grid_force(v: TView, n_sub: int, gain: float = 1.0) -> ndarray:
    """The measured force at the simulation's grid points and their midpoints (2 n_out n_sub + 1
    values, spacing h / 2 with h = q dt / n_sub, from half a sample before the first): the derivative
    of a cubic spline through the force's running integral (each sample standing for dt) -- exact
    for a smooth force to O(dt^3), and it keeps the area of an impulse shorter than a sample. The
    force channel's declared chain is divided out first (the true force drives the model).

    Each value is a **local mean**, not a point value: (4 M(w / 2) - M(w)) / 3 with M(a) the mean over
    t +- a and w the grid's spacing (Richardson: the point value to O(w^4) for a smooth force, a
    response 1 + O((f w)^4) in its band, 0 at every multiple of 1 / w): on a grid coarser than the
    samples, point values would fold the load cell's white noise from up to the record's Nyquist onto
    the structure's band and inflate the simulated response to it (docs/diagnose-method.md, "the force
    between samples")."""
    from scipy.interpolate import CubicSpline

    def spline() -> CubicSpline:  # the same for every grid: made once per view and force
        f = true_force(v)
        edges = v.dt * (np.arange(f.size + 1) - 0.5)
        return CubicSpline(edges, np.concatenate([[0.0], np.cumsum(f) * v.dt]))

    sp = _cached(v.fcache, ("spline",), spline)
    h = v.dt * v.q / n_sub
    w = 0.5 * h  # the grid's spacing
    lo, hi = sp.x[0], sp.x[-1]
    n = 2 * v.n_out * n_sub + 1
    out = np.empty(n)

    def mean(tg: ndarray, a: float) -> ndarray:  # the force's mean over [t - a, t + a]
        return np.asarray((sp(np.clip(tg + a, lo, hi)) - sp(np.clip(tg - a, lo, hi))) / (2 * a))

    for i in range(0, n, GRID_CHUNK):
        tg = -0.5 * v.dt + w * np.arange(i, min(n, i + GRID_CHUNK))  # time from the first sample
        out[i : i + tg.size] = (4.0 * mean(tg, 0.5 * w) - mean(tg, w)) / 3.0
    return out if gain == 1.0 else out * gain


def _nbytes(val: Any) -> int:
    """The bytes of an array, or of the arrays of a tuple or list (a cache entry)."""
    if isinstance(val, np.ndarray):
        return int(val.nbytes)
    if isinstance(val, (tuple, list)):
        return sum(_nbytes(x) for x in val)
    return 0


def _cached(cache: dict, key: tuple, make: Callable[[], Any], keep: int = 4) -> Any:
    """cache[key], made by ``make`` if absent; at most ``keep`` entries of the same kind (key[0]) kept,
    and of arrays (or tuples of them) at most CACHE_BYTES of that kind (the newest always). Safe when threads share the
    cache (records' Jacobian columns side by side): every entry is complete when it is stored, and a
    reader holds its own reference."""
    val = cache.get(key)
    if val is None:
        val = make()
        same = [k for k in list(cache) if isinstance(k, tuple) and k[0] == key[0] and k != key]
        drop = same[: max(0, len(same) - keep + 1)]
        kept = same[len(drop) :]
        size = _nbytes(val)
        for k in reversed(kept):  # the newest kept while they fit beside the new entry
            size += _nbytes(cache.get(k))
            if size > CACHE_BYTES:
                drop.append(k)
        for k in drop:
            cache.pop(k, None)
        cache[key] = val
    return val


def simulate(v: TView, p: ndarray, z0: ndarray | None = None, force_gain: float = 1.0) -> ndarray | None:
    """(n_out, 4) fit-block means of x, y, xdd, ydd of the model p driven by the record's measured
    force (times force_gain), through the declared chains, from the start state z0 (default
    ``v.z0``); None when the simulation blows up or would need more than MAX_GRID grid points."""
    n_sub = refinement(v, p)
    if n_sub * v.n_out > MAX_GRID:
        return None
    fc = v.fcache
    h = v.dt * v.q / n_sub
    fg = _cached(fc, ("f", n_sub), lambda: grid_force(v, n_sub))
    filt = _cached(fc, ("filt", h), lambda: filter_grid(v.chains, h))
    direct = _cached(fc, ("direct",), lambda: direct_force(v))
    f = fg if force_gain == 1.0 else force_gain * fg  # the force enters linearly
    cx, cy = feedthrough(p)
    out = np.empty((v.n_out, 4))
    start = v.z0 if z0 is None else z0
    tabs = step_tables(p, h) if STEP_TABLES and LINEAR_STEP else None
    if tabs is not None:
        blk = _cached(fc, ("blk", h, n_sub), lambda: filter_blocks(filt, n_sub))
        ok = _integrate_tables(p, f, n_sub, v.n_out, start, out, cx, cy, *tabs, *blk, _stick_df(p), STICK_BAND)
    else:
        lin = rk4_affine(p, h) if LINEAR_STEP else np.zeros((0, 10))
        ok = _integrate(p, f, h, n_sub, v.n_out, start, out, cx, cy, *filt, lin)
    if not ok or not np.all(np.isfinite(out)):
        return None
    out = hold_correct(out, v.fs, v.chains, h, fc)
    y = apply_chain(out, v.fs, v.chains, v.dt if v.q > 1 else None, v.gcache, filters=False)
    y[:, 2] += force_gain * cx * direct[:, 0]
    y[:, 3] += force_gain * cy * direct[:, 1]
    return y


def start_responses(v: TView, p_lin: ndarray) -> ndarray:
    """(n_out, 4, 4): the chained fit-sample responses to unit start states x, xd, y, yd of the
    linear model p_lin with no force (scaled: 1 mm, 1 mm/s x the model's fastest rate)."""
    g, fc = v.force, v.fcache
    v.force, v.fcache = np.zeros_like(g), {}
    try:
        cols = []
        for s in range(4):
            z = np.zeros(6)
            z[s] = 1e-3
            y = simulate(v, p_lin, z)
            cols.append(np.zeros((v.n_out, 4)) if y is None else y)
    finally:
        v.force, v.fcache = g, fc
    return np.stack(cols, axis=2)


def robust_noise(r: ndarray) -> float:
    """Noise std of a sampled channel from its fourth differences: 1.4826 MAD(diff4) / sqrt(70) (white
    noise; a signal at w leaks in as (w dt)^4 of its amplitude: 2e-4 at 5 Hz sampled at 256 Hz, where
    second differences would let 1.5 % in)."""
    d4 = np.diff(r, 4)
    if d4.size < 3:
        return float(np.std(r)) or 1.0
    return float(1.4826 * np.median(np.abs(d4 - np.median(d4))) / math.sqrt(70.0)) or float(np.std(d4)) or 1e-300


def input_noise_series(v: TView, p: ndarray, seed: int = 0) -> ndarray | None:
    """(n, 4) fit-block means of x, y, xdd, ydd of the nominal's response to white noise of the force
    channel's measured std (the measured force is the simulation's input, so its noise reaches every
    simulated channel: directly in the accelerations, through the structure in all of them), the
    first 10 % discarded (zero start); None for a free decay or a noiseless force."""
    sf = v.raw_noise.get("force", 0.0)
    if v.free_decay or sf <= 0:
        return None
    g, fc, z0 = v.force, v.fcache, v.z0
    v.force, v.fcache, v.z0 = np.random.default_rng(seed).normal(0.0, sf, g.size), {}, np.zeros(6)
    try:
        y = simulate(v, p)
    finally:
        v.force, v.fcache, v.z0 = g, fc, z0
    return None if y is None else y[y.shape[0] // 10 :]


def chi2_variance_factor(white: ndarray, y_in: ndarray | None) -> float:
    """var(chi2) / (2 n) of the whitened residual of one record when it is pure noise: the white
    sensor noise (std ``white[k]`` per channel of a fit sample; only the recorded channels) plus the
    response ``y_in`` (n, channels) to the force's noise, which is correlated in time (it passes the
    structure's resonances) and across channels. For a Gaussian vector of covariance S (unit
    diagonal once whitened) var(chi2) = 2 tr(S^2); with S = diag(a) + B (a_k = white share, B the
    input response's covariance) tr(S^2) / n = sum_k (a_k^2 + 2 a_k b_k) + sum_tau sum_kl
    C_kl(tau)^2, the last by Parseval from Welch cross-spectra of y_in (segments of at most 4096
    samples: they resolve a TMD resonance at the fit rates used; the squared estimate's bias 1 / n_seg
    divided out). 1 when the noise is white."""
    from scipy.signal import csd

    k = white.size
    if y_in is None or y_in.shape[0] < 64:
        return 1.0
    var_in = np.var(y_in, axis=0)
    sig2 = white**2 + var_in
    a, b = white**2 / sig2, var_in / sig2
    u = (y_in - y_in.mean(axis=0)) / np.sqrt(sig2)
    nper = min(u.shape[0], 4096)
    tot = float(np.sum(a**2 + 2 * a * b))
    n_seg = 1 + max(0, (u.shape[0] - nper) // (nper // 2))  # Welch's averages: E|S^|^2 = |S|^2 (1 + 1 / n_seg)
    for i in range(k):
        for j in range(k):
            _, s = csd(u[:, i], u[:, j], fs=1.0, nperseg=nper, scaling="density", detrend=False)
            # one-sided density (2 x the two-sided away from 0 and 1/2): sum_tau C^2 = int_-1/2^1/2 |S2|^2 df
            tot += float(0.5 * np.sum(np.abs(s) ** 2) / nper) / (1.0 + 1.0 / n_seg)
    return max(1.0, tot / k)


def param_variance_factor(J: ndarray, white: ndarray, y_in: ndarray | None) -> ndarray:
    """Per parameter: var of its least-squares estimate under the record's noise / the var that
    ``(J^T J)^-1`` states (white noise of unit variance), from the sandwich
    ``A^-1 J^T S J A^-1`` with ``A = J^T J``. ``J``: (n, channels, parameters), the whitened
    residual's derivatives on the fitted samples (0 on the others); ``white``: the white share of
    each channel's noise std (its std once whitened); ``y_in`` (m, channels): the whitened response to
    the force's noise (:func:`input_noise_series` / sigma), correlated in time and across channels, as
    in :func:`chi2_variance_factor`: ``J^T S J = sum_k a_k J_k^T J_k + sum_f conj(J_k(f)) P_kl(f)
    J_l(f) / n`` with P the two-sided Welch cross-spectra (per sample: fs = 1) of y_in interpolated on
    the transform's frequencies. 1 per parameter when the noise is white."""
    from scipy.signal import csd

    n, k, npar = J.shape
    A = np.einsum("tkp,tkq->pq", J, J)
    M = np.einsum("k,tkp,tkq->pq", white**2, J, J)
    if y_in is not None and y_in.shape[0] >= 64:
        u = y_in - y_in.mean(axis=0)
        nper = min(u.shape[0], 4096)
        nfft = 1 << int(math.ceil(math.log2(2 * n)))  # zero padded: the transform's products are linear
        fr = np.fft.rfftfreq(nfft)
        Jf = np.fft.rfft(J, nfft, axis=0)  # (f, k, p)
        wgt = np.full(fr.size, 2.0)  # the one-sided sum stands for both signs of f
        wgt[0] = 1.0
        if nfft % 2 == 0:
            wgt[-1] = 1.0
        for a in range(k):
            for b in range(k):
                f0, s = csd(u[:, a], u[:, b], fs=1.0, nperseg=nper, scaling="density", detrend=False)
                half = 0.5 * s  # one-sided density -> two-sided
                p = np.interp(fr, f0, half.real) + 1j * np.interp(fr, f0, half.imag)
                M += np.real(np.einsum("f,fp,fq->pq", wgt * p, np.conj(Jf[:, a, :]), Jf[:, b, :])) / nfft
    try:
        Ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.ones(npar)
    sand = np.diag(Ai @ M @ Ai)
    base = np.diag(Ai)
    return np.asarray(np.where(base > 0, sand / np.maximum(base, 1e-300), 1.0), float)


def spread(
    v: TView,
    p: ndarray,
    force_gain: float,
    contact: tuple[tuple[float, float], ...],
    seed: int = 0,
    base: ndarray | None = None,
) -> list[ndarray] | None:
    """The spread of the model p's simulation of record v under its nuisances: per entry (ki factor,
    ci factor) of ``contact``, the whitened difference (n_out, 4) between the simulation with the
    force plus an independent realisation of the load cell's measured noise (none for a free decay)
    and the play contact's ki, ci scaled by those factors (nothing changes without play), and the
    simulation itself (``base``: that simulation already made). Both from ``v.z0``. None when a
    simulation blows up (:mod:`.transient_play`: the noise of a rattle that no simulation follows
    sample by sample)."""
    from ...physics.params import P_MODEL, P_ci, P_ki

    if base is None:
        base = simulate(v, p, force_gain=force_gain)
    if base is None:
        return None
    out = []
    sf = 0.0 if v.free_decay else v.raw_noise.get("force", 0.0)
    for j, (fk, fc) in enumerate(contact):
        q = p.copy()
        if int(p[P_MODEL]) == 2:
            q[P_ki] *= fk
            q[P_ci] *= fc
        g, cache = v.force, v.fcache
        if sf > 0:
            v.force = g + np.random.default_rng(seed + j).normal(0.0, sf, g.size)
            v.fcache = {}
        try:
            y = simulate(v, q, force_gain=force_gain)
        finally:
            v.force, v.fcache = g, cache
        if y is None:
            return None
        out.append((y - base) / v.sigma)
    return out
