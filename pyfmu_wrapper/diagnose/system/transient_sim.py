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
(no anti-alias approximation). The declared acquisition chain of each channel (analog low-pass,
delay) is applied to the simulated channel as ``G(i w)`` in the frequency domain (linear and time
invariant, so it commutes with the averaging); the fit skips the first ``settle`` seconds where
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
from typing import TYPE_CHECKING

import numpy as np

from ..._jit import njit
from ...physics.kernels import rhs_fext

if TYPE_CHECKING:
    from numpy import ndarray

    from ..records import Record

CHANNELS = ("x", "y", "xdd", "ydd")  #: response channels, in this order in every array
FIT_MAX = 20000  #: fit samples per record at most (every q consecutive samples averaged)
FIT_RATE = 25.0  #: fit samples per period of the highest frequency that matters (see :func:`make_view`)
STEP_OMEGA = 0.25  #: RK4 step: h * (fastest rate of the model) at most this


@njit(cache=True)
def _integrate(p: ndarray, f: ndarray, h: float, n_sub: int, n_out: int, z0: ndarray, out: ndarray) -> bool:
    """RK4 on the grid t_j = j h (force f_j at every grid point); out[i] = the trapezoid mean over
    grid points i n_sub .. (i + 1) n_sub of (x, y, xdd, ydd): the mean over one fit block.
    Returns False when the state blows up (a candidate far outside its stable range)."""
    z = z0.copy()
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    zt = np.empty(6)
    out[:, :] = 0.0
    n_grid = n_out * n_sub
    inv = 1.0 / n_sub
    for j in range(n_grid + 1):
        f0 = f[j]
        rhs_fext(z, f0, p, k1)
        i = j // n_sub
        w = inv if j % n_sub else 0.5 * inv
        if i < n_out:
            out[i, 0] += w * z[0]
            out[i, 1] += w * z[2]
            out[i, 2] += w * k1[1]
            out[i, 3] += w * k1[3]
        if j % n_sub == 0 and i > 0:  # the block's closing end point
            out[i - 1, 0] += 0.5 * inv * z[0]
            out[i - 1, 1] += 0.5 * inv * z[2]
            out[i - 1, 2] += 0.5 * inv * k1[1]
            out[i - 1, 3] += 0.5 * inv * k1[3]
        if j == n_grid:
            break
        f1 = f[j + 1]
        fm = 0.5 * (f0 + f1)
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
    z0: ndarray = field(default_factory=lambda: np.zeros(6))  #: start state of the simulation
    phi: ndarray | None = None  #: (n_out, 4, 4) response to unit start states (x, xd, y, yd)
    fcache: dict = field(default_factory=dict)  #: the force on the last simulation grid

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
    f_top = f_mode
    if "force" in c:
        P = np.abs(np.fft.rfft(np.asarray(c["force"], float) - np.mean(c["force"]))) ** 2
        fr = np.fft.rfftfreq(n, dt)
        cum = np.cumsum(P) / max(P.sum(), 1e-300)
        f_top = min(max(f_mode, float(fr[min(int(np.searchsorted(cum, 0.99)), fr.size - 1)])), 4 * f_mode)
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
    force = np.asarray(c["force"], float).copy() if "force" in c else np.zeros(n)
    return TView(
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
    )


def fastest_rate(p: ndarray) -> float:
    """Largest |eigenvalue| [1/s] of the model with parameters p (linearised: friction by its slope
    at v = 0, the play chain by its contact stiffness and damping)."""
    from ...physics.params import P_C, P_I, P_K, P_M, P_MODEL, P_c, P_ci, P_df, P_k, P_ki, P_m, P_s

    M, K, C, m, k, c, I = (p[i] for i in (P_M, P_K, P_C, P_m, P_k, P_c, P_I))
    cf = c + p[P_df] * 2 / math.pi * p[P_s]
    rates = []
    if int(p[P_MODEL]) == 2:  # play: the chain's contact mode (stiff) is the fastest
        ki, ci = p[P_ki], p[P_ci]
        mu = 1.0 / (1.0 / I + 1.0 / m + 1.0 / M)
        rates += [math.sqrt(ki / mu), ci / mu]
        I = 0.0
    Mt = np.array([[M + I, -I], [-I, m + I]])
    Kt = np.array([[K + k, -k], [-k, k]])
    Ct = np.array([[C + cf, -cf], [-cf, cf]])
    Mi = np.linalg.inv(Mt)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ Kt, -Mi @ Ct]])
    rates.append(float(np.max(np.abs(np.linalg.eigvals(A)))))
    return max(rates)


def refinement(v: TView, p: ndarray) -> int:
    """Grid intervals per fit block (even, >= 2): RK4 step h with h * fastest rate <= STEP_OMEGA."""
    n = max(2, math.ceil(fastest_rate(p) * v.dt * v.q / STEP_OMEGA))
    return n + (n % 2)


def apply_chain(y: ndarray, fs: float, chains: dict) -> ndarray:
    """Each simulated channel (columns of y, at the fit rate) through its declared chain G(i w)."""
    out = y.copy()
    n = y.shape[0]
    nf = 1 << int(math.ceil(math.log2(2 * n)))
    w = 2 * math.pi * np.fft.rfftfreq(nf, 1.0 / fs)
    for k, ch in enumerate(CHANNELS):
        c = chains.get(ch)
        if c is None or (c.type is None and not c.delay_s):
            continue
        u = y[:, k]
        pad = np.concatenate([u, np.full(nf - n, u[-1])])
        out[:, k] = np.fft.irfft(np.fft.rfft(pad) * c.response(w), nf)[:n]
    return out


def grid_force(v: TView, n_sub: int, gain: float = 1.0) -> ndarray:
    """The measured force at the simulation's grid points (n_out n_sub + 1 of them, spacing
    h = q dt / n_sub, starting half a sample before the first): the mean of the record over
    [t - h/2, t + h/2] (each sample standing for dt) when h >= dt, else interpolated linearly. The
    force channel's declared chain is divided out first (the true force drives the model)."""
    f = v.force * gain
    cf = v.chains.get("force")
    if cf is not None:
        nf = 1 << int(math.ceil(math.log2(2 * f.size)))
        w = 2 * math.pi * np.fft.rfftfreq(nf, v.dt)
        g = cf.response(w)
        pad = np.concatenate([f, np.full(nf - f.size, f[-1])])
        f = np.fft.irfft(np.fft.rfft(pad) / np.where(np.abs(g) > 1e-3, g, 1e-3), nf)[: f.size]
    h = v.dt * v.q / n_sub
    tg = -0.5 * v.dt + h * np.arange(v.n_out * n_sub + 1)  # time from the first sample
    if h < v.dt:
        return np.interp(tg, v.dt * np.arange(f.size), f)
    edges = v.dt * (np.arange(f.size + 1) - 0.5)
    cum = np.concatenate([[0.0], np.cumsum(f) * v.dt])
    lo = np.interp(tg - 0.5 * h, edges, cum)
    hi = np.interp(tg + 0.5 * h, edges, cum)
    return (hi - lo) / h


def simulate(v: TView, p: ndarray, z0: ndarray | None = None, force_gain: float = 1.0) -> ndarray | None:
    """(n_out, 4) fit-block means of x, y, xdd, ydd of the model p driven by the record's measured
    force (times force_gain), through the declared chains; None when the simulation blows up."""
    n_sub = refinement(v, p)
    key = (n_sub, force_gain)
    if v.fcache.get("key") != key:
        v.fcache = {"key": key, "f": grid_force(v, n_sub, force_gain)}
    out = np.empty((v.n_out, 4))
    ok = _integrate(p, v.fcache["f"], v.dt * v.q / n_sub, n_sub, v.n_out, v.z0 if z0 is None else z0, out)
    if not ok or not np.all(np.isfinite(out)):
        return None
    return apply_chain(out, v.fs, v.chains)


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
    """Noise std of a residual from its second differences: 1.4826 MAD(diff2) / sqrt(6) (white noise;
    a residual that is smooth at the fit rate hardly contributes)."""
    d2 = np.diff(r, 2)
    if d2.size < 3:
        return float(np.std(r)) or 1.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0)) or float(np.std(d2)) or 1e-300
