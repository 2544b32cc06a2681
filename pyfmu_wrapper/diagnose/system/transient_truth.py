"""Truth for transient records (tests and ``make-benchmark``): the coupled base + TMD driven by a
swept sine, random or burst force, hammer impulses, or released from a displaced start, simulated
by an integrator of its own (``scipy.integrate.odeint``, right-hand side written here, not the
project's kernels) and measured as a rig does (anti-alias filter, delay, sensor gain and offset,
white ADC noise, sampling).

Independent on purpose: the diagnosis simulates its candidates with the kernels' equations
(:mod:`.transient_sim` integrates :func:`pyfmu_wrapper.physics.kernels.rhs_fext`; the steady path
uses the project's solver), so a truth written here and integrated otherwise is what catches an
error of sign, convention or integration in the diagnosis's own simulation. Only the declared
anti-alias filter's prototype is shared (:func:`..acquisition.analog_lowpass`: it is scipy's, not a
model of ours).

Truth model (ideal inerter I, passive sign convention of the physics notes)::

    (M + I) xdd - I ydd = F(t) - C xd - K x - K3 x^3 - mu tanh(xd / v0) - Fs
    -I xdd + (m + I) ydd = Fs
    Fs = k (1 + drift t / T) (x - y) + k3 (x - y)^3 + c (xd - yd) + c2 |v| v + df (2/pi) atan(s v)

with v = xd - yd; ``elastic_inerter`` puts a spring kb in series with the inerter (state u, the
inerter terminal: I (xdd - udd) = kb (u - y)), ``k2`` an asymmetric quadratic spring term.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy import ndarray

#: a truth is refused (:class:`TruthEscaped`) when its TMD spring's tangent stiffness k + 2 k2 |u| falls
#: below this share of k anywhere on the trajectory: a softening ``k2`` past its force maximum escapes
#: to infinity (seed 5252: two asymmetric-spring truths wrote NaN records), no rig's spring
MIN_TANGENT = 0.1
FRICTION_SLOPE = 2.0e3  #: regularisation of the truth's dry friction [s/m] (transition at ~1 mm/s)
V0 = 1e-3  #: base friction regularisation [m/s]


class TruthEscaped(RuntimeError):
    """The truth's simulation left the physical range (non-finite, or a softening spring past its
    force maximum): the caller draws a weaker truth instead of writing the record."""


def force_signal(kind: str, rng: np.random.Generator, T: float, amp: float, **kw: Any) -> Callable[[Any], Any]:
    """F(t) [N], vectorised. kinds: sweep_lin, sweep_log (kw f0, f1 [Hz]; f1 < f0: down), random, burst
    (kw f_lo, f_hi; amp = rms), hammer (amp = peak; kw n_hits, width), decay (no force)."""
    if kind in ("sweep_lin", "sweep_log"):
        f0, f1 = kw.get("f0", 1.5), kw.get("f1", 5.0)
        ramp = min(2.0, 0.05 * T)
        if kind == "sweep_lin":

            def ph(t: Any) -> Any:
                return 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) / T * t**2)
        else:
            b = math.log(f1 / f0) / T

            def ph(t: Any) -> Any:
                return 2 * math.pi * f0 * (np.exp(b * t) - 1) / b

        return lambda t: amp * np.minimum(np.asarray(t) / ramp, 1.0) * np.sin(ph(t))
    if kind in ("random", "burst"):
        f_lo, f_hi = kw.get("f_lo", 1.0), kw.get("f_hi", 8.0)
        n = 60
        f = rng.uniform(f_lo, f_hi, n)
        phs = rng.uniform(0, 2 * math.pi, n)
        a = amp * math.sqrt(2.0 / n)
        on = kw.get("on", 0.6)
        period = kw.get("period", T / 6)

        def F(t: Any) -> Any:
            t = np.asarray(t, float)
            s = a * np.sum(np.sin(2 * math.pi * f[:, None] * np.atleast_1d(t)[None, :] + phs[:, None]), axis=0)
            if kind == "burst":
                ph_ = np.mod(np.atleast_1d(t), period) / period
                s = s * np.where(ph_ < on, np.sin(math.pi * np.minimum(ph_ / on, 1.0)) ** 0.5, 0.0)
            return s if t.ndim else s[0]

        return F
    if kind == "hammer":
        n_hits, width = int(kw.get("n_hits", 6)), kw.get("width", 0.004)
        times = np.sort(rng.uniform(0.05 * T, 0.85 * T, n_hits))
        peaks = amp * rng.uniform(0.5, 1.0, n_hits)

        hits = [(float(t0), float(p)) for t0, p in zip(times, peaks)]

        def H(t: Any) -> Any:
            if np.ndim(t) == 0:  # the integrator's scalar calls: plain floats (numpy per hit cost 60 % of a run)
                tf = float(t)
                return sum(p * math.sin(math.pi * (tf - t0) / width) for t0, p in hits if 0.0 <= tf - t0 <= width)
            t = np.asarray(t, float)
            tt = np.atleast_1d(t)
            s = np.zeros_like(tt)
            for t0, p in zip(times, peaks):
                u = (tt - t0) / width
                s += np.where((u >= 0) & (u <= 1), p * np.sin(math.pi * np.clip(u, 0, 1)), 0.0)
            return s if t.ndim else s[0]

        H.hits = times  # type: ignore[attr-defined]
        return H
    if kind == "decay":
        return lambda t: 0.0 * np.asarray(t, float)
    raise ValueError(f"unknown force kind {kind!r}")


class Truth:
    """The true system: nominal dicts plus changes (keys as in the module docstring)."""

    def __init__(self, base: dict, tmd: dict, T: float, **ch: float) -> None:
        self.M = float(base["mass"]) + ch.get("dM", 0.0)
        self.K = float(base["stiffness"]) + ch.get("dK", 0.0)
        self.C = float(base["damping"]) + ch.get("dC", 0.0)
        self.m = float(tmd["mass"]) + ch.get("dm", 0.0) - ch.get("dI_split", 0.0)
        self.k = float(tmd["stiffness"]) + ch.get("dk", 0.0)
        self.c = float(tmd["damping"]) + ch.get("dc", 0.0)
        self.I = float(tmd.get("inertance", 0.0)) + ch.get("dI", 0.0) + ch.get("dI_split", 0.0)
        self.df, self.k3, self.c2 = ch.get("df", 0.0), ch.get("k3", 0.0), ch.get("c2", 0.0)
        self.mu, self.K3, self.k2 = ch.get("mu", 0.0), ch.get("K3", 0.0), ch.get("k2", 0.0)
        self.kb, self.drift, self.T = ch.get("kb", 0.0), ch.get("drift", 0.0), T

    def deriv(self, t: Any, z: ndarray, F: Callable[[Any], Any]) -> ndarray:
        """dz/dt, vectorised over the columns of z (and t)."""
        x, xd, y, yd = z[0], z[1], z[2], z[3]
        v = xd - yd
        u = x - y
        Fs = (
            self.k * (1 + self.drift * np.asarray(t) / self.T) * u
            + self.k3 * u**3
            + self.k2 * u * np.abs(u)
            + self.c * v
            + self.c2 * np.abs(v) * v
            + self.df * (2 / math.pi) * np.arctan(FRICTION_SLOPE * v)
        )
        Fb = self.C * xd + self.K * x + self.K3 * x**3 + self.mu * np.tanh(xd / V0)
        r1 = F(t) - Fb - Fs
        if self.kb > 0:  # elastic inerter: I (xdd - wdd) = kb (w - y), w the inerter's far end
            w, wd = z[4], z[5]
            P = self.kb * (w - y)
            xdd = (r1 - P) / self.M
            ydd = (Fs + P) / self.m
            return np.array([xd, xdd, yd, ydd, wd, xdd - P / self.I])
        M1, m1, I = self.M + self.I, self.m + self.I, self.I
        det = M1 * m1 - I * I
        return np.array([xd, (m1 * r1 + I * Fs) / det, yd, (I * r1 + M1 * Fs) / det])

    def simulate(
        self, F: Callable[[Any], Any], t: ndarray, z0: ndarray | None = None, max_step: float = 2e-3
    ) -> dict[str, ndarray]:
        """x, y, xdd, ydd, force on the grid t (``scipy.integrate.odeint``: LSODA, rtol 1e-10; it
        agrees with solve_ivp's DOP853 at rtol 1e-9 to 1e-7 of the amplitude and is 5-17 times faster)."""
        from scipy.integrate import odeint

        n = 6 if self.kb > 0 else 4
        z = np.zeros(n) if z0 is None else np.concatenate([z0, np.zeros(n - len(z0))])
        if self.kb > 0:
            z[4], z[5] = z[0], z[1]
        with np.errstate(over="ignore", invalid="ignore"):  # an escaping truth: refused below
            y, info = odeint(
                lambda zz, tt: self.deriv(tt, zz, F),
                z,
                t,
                rtol=1e-10,
                atol=1e-13,
                hmax=max_step,
                mxstep=10**6,
                full_output=True,
            )
        if info["message"] != "Integration successful.":
            raise TruthEscaped(f"truth integration failed: {info['message']}")
        bad = ~np.all(np.isfinite(y), axis=1)
        if bad.any():
            raise TruthEscaped(
                f"the truth's state is not finite from t = {t[int(np.argmax(bad))]:.4g} s on: it escapes"
            )
        sol_y = y.T
        if self.k2 < 0:
            u_max = float(np.max(np.abs(sol_y[0] - sol_y[2])))
            if self.k + 2 * self.k2 * u_max < MIN_TANGENT * self.k:
                raise TruthEscaped(
                    f"the TMD spring softens past {MIN_TANGENT:g} k (k2 = {self.k2:.4g} N/m^2 at a stroke of "
                    f"{1e3 * u_max:.3g} mm): it escapes"
                )
        d = self.deriv(t, sol_y, F)
        return {"x": sol_y[0], "y": sol_y[2], "xdd": d[1], "ydd": d[3], "force": np.asarray(F(t), float)}


def measure(
    sig: dict[str, ndarray],
    t: ndarray,
    step: int,
    rng: np.random.Generator,
    noise: dict[str, float],
    acq: dict[str, Any] | None = None,
    gains: dict[str, float] | None = None,
    offsets: dict[str, float] | None = None,
) -> dict[str, ndarray]:
    """What the rig records: sensor gain/offset, the declared analog chain (filter by lsim at the
    dense rate, delay), every step-th sample, white noise of std noise[ch] x rms."""
    from scipy import signal

    from ..acquisition import analog_lowpass

    out = {"t": t[::step] - t[0]}
    for ch, u in sig.items():
        u = np.asarray(u, float) * (1 + (gains or {}).get(ch, 0.0)) + (offsets or {}).get(ch, 0.0)
        spec = {**((acq or {}).get("all") or {}), **((acq or {}).get(ch) or {})}  # key by key, as declared
        if spec and spec.get("filter"):
            fl = spec["filter"]
            A, B, C, D = signal.tf2ss(*analog_lowpass(fl["type"], fl["order"], fl["cutoff_hz"]))
            x0 = -np.linalg.solve(A, B[:, 0]) * u[0]
            _, u, _ = signal.lsim((A, B, C, D), u, t, X0=x0)
        if spec and spec.get("delay_s"):
            u = np.interp(t - spec["delay_s"], t, u)
        s = u[::step]
        out[ch] = s + rng.normal(0, noise.get(ch, 0.0) * (np.std(s) or 1.0), s.size)
    return out
