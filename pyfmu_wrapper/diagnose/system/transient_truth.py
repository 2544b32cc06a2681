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
    Fs = k (1 + drift t / T) (x - y) + k3 (x - y)^3 + c (xd - yd) + c2 |v| v + Ff

with v = xd - yd; ``elastic_inerter`` puts a spring kb in series with the inerter (state w, the
inerter's far terminal: I (xdd - wdd) = kb (w - y)), ``k2`` an asymmetric quadratic spring term.

**Play** (``eps``, the gear's half gap): the inerter acts through a gear whose teeth meet the TMD only
outside a gap of +-eps. The inerter's far terminal w (massless, the flywheel's side of the mesh) is
driven by the contact force P of the relative turn g = w - y of the mesh:

    |g| <= eps: P = 0 (the teeth are apart: the flywheel coasts with the base, wdd = xdd)
    g > eps:    P = max(0, ki (g - eps) + ci gd)     g < -eps: P = min(0, ki (g + eps) + ci gd)
    M xdd = F - Fb - Fs - P,   m ydd = Fs + P,   I (xdd - wdd) = P

(a contact only pushes: it never pulls the teeth back together). The contact is the paper's, stiff
and nearly elastic (``ki`` 2e7 N/m, ``ci`` 0.01-100 N s/m drawn by the suite): each contact is a
bounce and the flywheel rattles in the gap. Integrated by ``odeint`` (LSODA), the contact changes
resolved by its step control (``hmax`` at most 1/20 of the contact's period).

**Dry friction** (``df``): Coulomb friction with a true stick phase, integrated **event by event**
(``scipy.integrate.solve_ivp``, DOP853, rtol 1e-10, stopping at every change of mode). Slipping
(v != 0), Ff = df sign(v). When v reaches 0, the friction force that keeps the two bodies together,
Ff_req = m (F - Fb) / (M + m) - Fo - P (Fo the link's other forces at v = 0, P the play contact: the
ideal inerter carries nothing at v = 0 and vdot = 0), is compared with df: |Ff_req| <= df sticks
(x - y frozen, xd = yd, xdd = ydd = (F - Fb) / (M + m) exactly) until |Ff_req| reaches df, when the
link slips in the direction of Ff_req; else the link slips on, in the direction of Ff_req. No
regularisation anywhere: a stuck link has zero relative velocity to rounding.
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
V0 = 1e-3  #: base friction regularisation [m/s]
#: the play truth's gear contact (the paper's mesh stiffness, docs/physics.md) and its default damping [N s/m]
PLAY_KI, PLAY_CI = 2.0e7, 0.01


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
    """The true system: nominal dicts plus changes (keys as in the module docstring; ``eps``, ``ki``,
    ``ci`` the play's half gap and contact, ``df`` the dry friction's force)."""

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
        self.eps = ch.get("eps", 0.0)
        self.ki, self.ci = ch.get("ki", PLAY_KI), ch.get("ci", PLAY_CI)
        if self.eps < 0 or self.df < 0:
            raise ValueError(f"a play gap and a friction force are >= 0 (eps = {self.eps}, df = {self.df})")
        if self.eps > 0 and self.kb > 0:
            raise ValueError("play and an elastic inerter are two chains of the inerter: one at a time")
        if self.eps > 0 and self.I <= 0:
            raise ValueError("play needs an inerter (I > 0)")

    @property
    def chain(self) -> bool:
        """The inerter acts through a chain (state w, wd: its far terminal): play or a series spring."""
        return self.kb > 0 or self.eps > 0

    def _other(self, t: Any, x: Any, xd: Any, y: Any, yd: Any) -> tuple[Any, Any]:
        """(Fo, Fb): the link's force without dry friction and the base's own (spring, damper, ...)."""
        v, u = xd - yd, x - y
        Fo = (
            self.k * (1 + self.drift * np.asarray(t) / self.T) * u
            + self.k3 * u**3
            + self.k2 * u * np.abs(u)
            + self.c * v
            + self.c2 * np.abs(v) * v
        )
        Fb = self.C * xd + self.K * x + self.K3 * x**3 + self.mu * np.tanh(xd / V0)
        return Fo, Fb

    def _chain_force(self, z: ndarray) -> Any:
        """P, the force the inerter's chain passes to the TMD (and takes from the base)."""
        g, gd = z[4] - z[2], z[5] - z[3]
        if self.kb > 0:
            return self.kb * g
        e = self.eps
        push = np.maximum(0.0, self.ki * (g - e) + self.ci * gd)
        pull = np.minimum(0.0, self.ki * (g + e) + self.ci * gd)
        return np.where(g > e, push, np.where(g < -e, pull, 0.0))

    def deriv(self, t: Any, z: ndarray, F: Callable[[Any], Any], Ff: Any = 0.0) -> ndarray:
        """dz/dt while slipping (or with no dry friction), the link's dry friction force ``Ff`` given;
        vectorised over the columns of z (and t)."""
        x, xd, y, yd = z[0], z[1], z[2], z[3]
        Fo, Fb = self._other(t, x, xd, y, yd)
        Fs = Fo + Ff
        r1 = F(t) - Fb - Fs
        if self.chain:  # I (xdd - wdd) = P, w the inerter's far end (massless: the chain passes P on)
            wd = z[5]
            P = self._chain_force(z)
            xdd = (r1 - P) / self.M
            ydd = (Fs + P) / self.m
            return np.array([xd, xdd, yd, ydd, wd, xdd - P / self.I])
        M1, m1, I = self.M + self.I, self.m + self.I, self.I
        det = M1 * m1 - I * I
        return np.array([xd, (m1 * r1 + I * Fs) / det, yd, (I * r1 + M1 * Fs) / det])

    def _stuck(self, t: Any, z: ndarray, F: Callable[[Any], Any]) -> tuple[ndarray, Any]:
        """(dz/dt, Ff_req) with the link stuck: x and y move as one body under F - Fb; Ff_req the dry
        friction force that holds them together (the ideal inerter carries nothing then)."""
        x, xd, y = z[0], z[1], z[2]
        Fo, Fb = self._other(t, x, xd, y, xd)
        a = (F(t) - Fb) / (self.M + self.m)
        P = self._chain_force(z) if self.chain else 0.0
        ff = self.m * a - Fo - P
        d = [xd, a, xd, a]
        if self.chain:
            d += [z[5], a - P / self.I]
        return np.array(d), ff

    def simulate(
        self, F: Callable[[Any], Any], t: ndarray, z0: ndarray | None = None, max_step: float = 2e-3
    ) -> dict[str, ndarray]:
        """x, y, xdd, ydd, force on the grid t. Without dry friction ``scipy.integrate.odeint`` (LSODA,
        rtol 1e-10; it agrees with solve_ivp's DOP853 at rtol 1e-9 to 1e-7 of the amplitude and is 5-17
        times faster); with dry friction the stick-slip integration of :meth:`_stick_slip`."""
        from scipy.integrate import odeint

        n = 6 if self.chain else 4
        z = np.zeros(n) if z0 is None else np.concatenate([z0, np.zeros(n - len(z0))])
        if self.chain:
            z[4], z[5] = z[2], z[3]  # the chain at rest in the middle of the gap
            if self.kb > 0:
                z[4], z[5] = z[0], z[1]  # (the series spring as before: records byte for byte the same)
        if self.eps > 0:  # a contact period holds ~20 steps at least
            max_step = min(max_step, 2 * math.pi * math.sqrt(self.I / self.ki) / 20)
        if self.df > 0:
            sol_y, mode = self._stick_slip(F, t, z, max_step)
        else:
            with np.errstate(over="ignore", invalid="ignore"):  # an escaping truth: refused below
                y, info = odeint(
                    lambda zz, tt: self.deriv(tt, zz, F),
                    z,
                    t,
                    rtol=1e-10,
                    atol=1e-13,
                    hmax=max_step,
                    mxstep=10**7,
                    full_output=True,
                )
            if info["message"] != "Integration successful.":
                raise TruthEscaped(f"truth integration failed: {info['message']}")
            sol_y, mode = y.T, None
        bad = ~np.all(np.isfinite(sol_y), axis=0)
        if bad.any():
            raise TruthEscaped(
                f"the truth's state is not finite from t = {t[int(np.argmax(bad))]:.4g} s on: it escapes"
            )
        if self.k2 < 0:
            u_max = float(np.max(np.abs(sol_y[0] - sol_y[2])))
            if self.k + 2 * self.k2 * u_max < MIN_TANGENT * self.k:
                raise TruthEscaped(
                    f"the TMD spring softens past {MIN_TANGENT:g} k (k2 = {self.k2:.4g} N/m^2 at a stroke of "
                    f"{1e3 * u_max:.3g} mm): it escapes"
                )
        if mode is None:
            d = self.deriv(t, sol_y, F)
        else:  # each sample's accelerations under its own mode (0 stuck, +-1 slipping)
            d = self.deriv(t, sol_y, F, self.df * mode)
            ds, _ = self._stuck(t, sol_y, F)
            d = np.where(mode == 0, ds, d)
        out = {"x": sol_y[0], "y": sol_y[2], "xdd": d[1], "ydd": d[3], "force": np.asarray(F(t), float)}
        if mode is not None:
            out["mode"] = mode
        return out

    def _stick_slip(self, F: Callable[[Any], Any], t: ndarray, z: ndarray, max_step: float) -> tuple[ndarray, ndarray]:
        """The states on the grid t and each sample's mode (0 stuck, +1 / -1 slipping with v > 0 / < 0),
        integrated mode by mode: DOP853 stops at v = 0 (slipping) or at |Ff_req| = df (stuck)."""
        from scipy.integrate import solve_ivp

        df = self.df
        out = np.full((len(z), t.size), np.nan)
        mode_out = np.zeros(t.size)

        def next_mode(tt: float, zz: ndarray, prev: int) -> int:
            _, ff = self._stuck(tt, zz, F)
            if abs(ff) <= df:
                return 0
            return 1 if ff > 0 else -1

        t0, t1 = float(t[0]), float(t[-1])
        v0 = z[1] - z[3]
        mode = (1 if v0 > 0 else -1) if v0 != 0 else next_mode(t0, z, 0)
        n_seg, short = 0, 0
        while True:
            if mode == 0:
                z[3] = z[1]  # stuck: no relative velocity at all

                def rhs_stuck(tt: float, zz: ndarray) -> ndarray:
                    return self._stuck(tt, zz, F)[0]

                rhs: Callable[..., ndarray] = rhs_stuck

                def ev_hi(tt: float, zz: ndarray) -> float:
                    return self._stuck(tt, zz, F)[1] - df

                def ev_lo(tt: float, zz: ndarray) -> float:
                    return self._stuck(tt, zz, F)[1] + df

                ev_hi.terminal, ev_hi.direction = True, 1.0  # type: ignore[attr-defined]
                ev_lo.terminal, ev_lo.direction = True, -1.0  # type: ignore[attr-defined]
                events = [ev_hi, ev_lo]
            else:
                s = float(mode)

                def rhs_slip(tt: float, zz: ndarray, s: float = s) -> ndarray:
                    return self.deriv(tt, zz, F, s * df)

                rhs = rhs_slip

                def ev_v(tt: float, zz: ndarray) -> float:
                    return zz[1] - zz[3]

                ev_v.terminal, ev_v.direction = True, -s  # type: ignore[attr-defined]
                events = [ev_v]
            with np.errstate(over="ignore", invalid="ignore"):
                sol = solve_ivp(
                    rhs,
                    (t0, t1),
                    z,
                    "DOP853",
                    events=events,
                    dense_output=True,
                    rtol=1e-10,
                    atol=1e-13,
                    max_step=max_step,
                )
            if sol.status < 0:
                raise TruthEscaped(f"truth integration failed: {sol.message}")
            te = float(sol.t[-1])
            sel = (t >= t0) & (t <= te)
            if sel.any():
                out[:, sel] = sol.sol(t[sel])
                mode_out[sel] = mode
                if mode == 0:
                    out[3, sel] = out[1, sel]
            z = np.array(sol.y[:, -1], float)
            if not np.all(np.isfinite(z)):
                raise TruthEscaped(f"the truth's state is not finite at t = {te:.4g} s: it escapes")
            if sol.status == 0 or te >= t1:
                break
            n_seg += 1
            short = short + 1 if te - t0 < 1e-9 else 0
            if short > 50:
                raise TruthEscaped(f"stick-slip chatter at t = {te:.6g} s: the mode does not settle")
            t0 = te
            if mode == 0:
                _, ff = self._stuck(te, z, F)
                mode = 1 if ff > 0 else -1
            else:
                z[3] = z[1]  # v = 0 at the event (to its tolerance): exactly 0 from here
                mode = next_mode(te, z, mode)
        self.segments = n_seg + 1
        return out, mode_out


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
