"""Truth of the frame benchmark: a shear frame of n storeys with a TMD or TMDI (and what the suite's
out-of-vocabulary kinds add to it), written here from the structure and integrated by
``scipy.integrate.odeint`` (LSODA, rtol 1e-10), then measured as a rig does.

Independent on purpose: neither the project's kernels and frame model (``models/frame_model``) nor its
exact linear reference (:mod:`pyfmu_wrapper.physics.frame`, which the tests hold this against) nor the
diagnosis is used; only the declared anti-alias filter's prototype is shared
(:func:`..acquisition.analog_lowpass`: scipy's filter design, the declaration's meaning).

Nodes (displacements, absolute, [m]): storeys 1..n (indices 0..n-1), the TMD mass (index n), then the
foundation mass (``foundation``) and a secondary absorber mass (``secondary``) when present. Storey i
joins node i to the node below (the foundation under storey 1 when there is one, else the ground) by
a spring k_i and a damper c_i; the TMD hangs on storey ``tmd.storey`` by k, c; its ideal inerter of
inertance I joins the TMD mass to ``tmd.inerter_to`` (a storey, or 0: the ground) and enters the
mass matrix like a mass between two nodes. With q the displacements::

    (M + B) q'' = e F(t) - C q' - K q + f_nl(t, q, q')

f_nl holds the out-of-vocabulary storey forces, each acting in storey j on its drift d = q_j - q_below
(tension positive: -s on node j, +s on the node below): ``cubic`` s = k3 d^3 (a hardening storey
spring), ``friction`` s = F tanh(d' / v0) (a slipping brace, v0 = 1 mm/s), ``drift``
s = (start + share t / T) k_j d (a storey stiffness changing linearly through the record).

The force F(t) is the cubic spline through its samples on the fine grid (:class:`FineForce`): the
truth is driven by exactly the samples the suite records (before their noise and any force gain).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy import ndarray

FRICTION_V0 = 1e-3  #: regularisation of the dry friction [m/s]


class TruthFailed(RuntimeError):
    """The truth's integration did not succeed (the suite draws the dataset again)."""


class FineForce:
    """F(t) the cubic spline (scipy's ``CubicSpline``, not-a-knot) through the samples ``values`` at
    t = k dt (k = 0, 1, ...): C2-smooth, so the integrator's steps are not cut at every sample as a
    polyline's kinks would; 0 before the first sample and the last value after the last."""

    def __init__(self, dt: float, values: ndarray) -> None:
        from scipy.interpolate import CubicSpline

        self.dt, self.values = float(dt), np.asarray(values, float)
        self._spline = CubicSpline(self.dt * np.arange(self.values.size), self.values)
        self._last = self.values.size - 1
        self._c = [row.tolist() for row in self._spline.c]  # (4, m): c0 dx^3 + c1 dx^2 + c2 dx + c3

    def __call__(self, t: Any) -> Any:
        if np.ndim(t) == 0:  # the integrator's scalar calls: plain floats
            tf = float(t)
            if tf <= 0.0:
                return self._c[3][0] if tf == 0.0 else 0.0
            k = int(tf / self.dt)
            if k >= self._last:
                return float(self.values[-1])
            x = tf - k * self.dt
            c = self._c
            return ((c[0][k] * x + c[1][k]) * x + c[2][k]) * x + c[3][k]
        tt = np.asarray(t, float)
        return np.where(tt < 0.0, 0.0, self._spline(np.minimum(tt, self.dt * self._last)))


@dataclass
class FrameTruth:
    """The true structure. ``tmd``: {storey, inerter_to, mass, stiffness, damping, inertance} (storeys
    1..n; inerter_to 0 = the ground). The optional dicts are the out-of-vocabulary additions:
    ``cubic`` {storey, k3}, ``friction`` {storey, force}, ``drift`` {storey, share, T, start},
    ``foundation`` {mass, stiffness, damping}, ``secondary`` {storey, mass, stiffness, damping}."""

    masses: list[float]
    stiffnesses: list[float]
    dampings: list[float]
    force_storey: int
    tmd: dict[str, Any]
    cubic: dict[str, Any] | None = None
    friction: dict[str, Any] | None = None
    drift: dict[str, Any] | None = None
    foundation: dict[str, Any] | None = None
    secondary: dict[str, Any] | None = None
    _mats: tuple = field(default=(), init=False, repr=False)

    @property
    def n(self) -> int:
        return len(self.masses)

    @property
    def size(self) -> int:
        return self.n + 1 + (self.foundation is not None) + (self.secondary is not None)

    def _below(self, j: int) -> int | None:
        """Node under storey j (1-based): the storey below, the foundation, or None (the ground)."""
        if j > 1:
            return j - 2
        return self.n + 1 if self.foundation is not None else None

    def matrices(self) -> tuple[ndarray, ndarray, ndarray, ndarray]:
        """(M + B, C, K, e) written element by element."""
        N, n = self.size, self.n
        M, C, K = np.zeros((N, N)), np.zeros((N, N)), np.zeros((N, N))
        e = np.zeros(N)

        def between(A: ndarray, a: int, b: int | None, v: float) -> None:
            A[a, a] += v
            if b is not None:
                A[b, b] += v
                A[a, b] -= v
                A[b, a] -= v

        for j in range(1, n + 1):
            M[j - 1, j - 1] = self.masses[j - 1]
            between(K, j - 1, self._below(j), self.stiffnesses[j - 1])
            between(C, j - 1, self._below(j), self.dampings[j - 1])
        d = self.tmd
        M[n, n] = d["mass"]
        between(K, n, int(d["storey"]) - 1, d["stiffness"])
        between(C, n, int(d["storey"]) - 1, d["damping"])
        to = int(d.get("inerter_to", d["storey"]))
        between(M, n, to - 1 if to > 0 else None, d.get("inertance", 0.0))
        if self.foundation is not None:
            f = self.foundation
            M[n + 1, n + 1] = f["mass"]
            between(K, n + 1, None, f["stiffness"])
            between(C, n + 1, None, f["damping"])
        if self.secondary is not None:
            s, a = self.secondary, N - 1
            M[a, a] = s["mass"]
            between(K, a, int(s["storey"]) - 1, s["stiffness"])
            between(C, a, int(s["storey"]) - 1, s["damping"])
        e[self.force_storey - 1] = 1.0
        return M, C, K, e

    def _prepare(self) -> tuple:
        if not self._mats:
            M, C, K, e = self.matrices()
            Mi = np.linalg.inv(M)
            N = self.size
            J = np.zeros((2 * N, 2 * N))
            J[:N, N:] = np.eye(N)
            J[N:, :N], J[N:, N:] = -Mi @ K, -Mi @ C
            self._mats = (Mi, Mi @ K, Mi @ C, Mi @ e, J)
        return self._mats

    def storey_forces(self, t: Any, q: ndarray, qd: ndarray) -> ndarray:
        """f_nl (rows: nodes) of the out-of-vocabulary storey forces; q, qd: (N,) or (N, m)."""
        f = np.zeros_like(q)
        for spec, law in ((self.cubic, "cubic"), (self.friction, "friction"), (self.drift, "drift")):
            if spec is None:
                continue
            j = int(spec["storey"])
            b = self._below(j)
            d = q[j - 1] - (q[b] if b is not None else 0.0)
            if law == "cubic":
                s = spec["k3"] * d**3
            elif law == "friction":
                dd = qd[j - 1] - (qd[b] if b is not None else 0.0)
                s = spec["force"] * np.tanh(dd / FRICTION_V0)
            else:
                s = (spec.get("start", 0.0) + spec["share"] * np.asarray(t) / spec["T"]) * self.stiffnesses[j - 1] * d
            f[j - 1] -= s
            if b is not None:
                f[b] += s
        return f

    def accelerations(self, t: Any, q: ndarray, qd: ndarray, F: Any) -> ndarray:
        Mi, MK, MC, Me, _ = self._prepare()
        a = -MK @ q - MC @ qd + np.multiply.outer(Me, F) if np.ndim(F) else -MK @ q - MC @ qd + Me * F
        if self.cubic or self.friction or self.drift:
            a = a + Mi @ self.storey_forces(t, q, qd)
        return a

    def simulate(
        self, F: Callable[[Any], Any], t: ndarray, z0: ndarray | None = None, hmax: float = 0.0
    ) -> dict[str, ndarray]:
        """Displacements ``q`` (N, len(t)), velocities ``qd`` and accelerations ``qdd`` on the grid t
        (starting at rest unless z0 = [q, qd] is given); ``hmax`` [s] the integrator's largest step
        (0: free; a hammer record gives a fraction of its pulse width so that no pulse is stepped over)."""
        from scipy.integrate import odeint

        N = self.size
        _, MK, MC, Me, J = self._prepare()
        nl = bool(self.cubic or self.friction or self.drift)
        Mi = self._mats[0]

        def rhs(z: ndarray, tt: float) -> ndarray:
            q, qd = z[:N], z[N:]
            a = Me * F(tt) - MK @ q - MC @ qd
            if nl:
                a += Mi @ self.storey_forces(tt, q, qd)
            return np.concatenate((qd, a))

        z = np.zeros(2 * N) if z0 is None else np.asarray(z0, float)
        with np.errstate(over="ignore", invalid="ignore"):
            y, info = odeint(
                rhs,
                z,
                t,
                Dfun=lambda z, tt: J,
                rtol=1e-10,
                atol=1e-14,
                hmax=hmax,
                mxstep=10**7,
                full_output=True,
            )
        if info["message"] != "Integration successful." or not np.all(np.isfinite(y)):
            raise TruthFailed(f"the truth's integration failed: {info['message']}")
        q, qd = y[:, :N].T, y[:, N:].T
        return {"q": q, "qd": qd, "qdd": self.accelerations(t, q, qd, np.asarray(F(t), float))}


def channels(truth: FrameTruth, sim: dict[str, ndarray], names: list[str]) -> dict[str, ndarray]:
    """The named measured quantities of a simulation: ``x<i>dd`` / ``x<i>`` (storey i, absolute),
    ``ydd`` / ``y`` (the TMD mass)."""
    out = {}
    for c in names:
        acc = c.endswith("dd")
        stem = c[:-2] if acc else c
        node = truth.n if stem == "y" else int(stem[1:]) - 1
        out[c] = sim["qdd" if acc else "q"][node]
    return out


def acquire(
    sig: dict[str, ndarray],
    t: ndarray,
    step: int,
    filt: dict[str, Any] | None = None,
    gains: dict[str, float] | None = None,
    delays: dict[str, float] | None = None,
    clips: dict[str, float] | None = None,
) -> dict[str, ndarray]:
    """The rig's noise-free samples of fine-grid signals: sensor gain (measured = (1 + g) true), the
    declared anti-alias filter ``filt`` {type, order, cutoff_hz} on every channel (``scipy.signal.lsim``
    on the fine grid, exact for an input linear between samples, from rest), an undeclared delay [s]
    (linear interpolation), a clipping level [same unit as the channel] (ADC saturation), then every
    ``step``-th sample."""
    from scipy import signal

    from ..acquisition import analog_lowpass

    ss = signal.tf2ss(*analog_lowpass(filt["type"], filt["order"], filt["cutoff_hz"])) if filt else None
    out = {"t": t[::step] - t[0]}
    for ch, u in sig.items():
        u = np.asarray(u, float) * (1.0 + (gains or {}).get(ch, 0.0))
        if ss is not None and np.any(u):
            _, u, _ = signal.lsim(ss, u, t, interp=True)
        d = (delays or {}).get(ch, 0.0)
        if d:
            u = np.interp(t - d, t, u, left=0.0)
        c = (clips or {}).get(ch)
        if c is not None:
            u = np.clip(u, -c, c)
        out[ch] = np.asarray(u, float)[::step]
    return out


def hammer_force(
    rng: np.random.Generator, t: ndarray, n_hits: int, peak: float, width: float, T: float
) -> tuple[ndarray, list[float]]:
    """Half-sine pulses of ``width`` [s] at random times (at least 1.5 s apart, in the first 85 % of
    the record), peaks 50-100 % of ``peak``; returns the force on the grid t and the hit times."""
    times: list[float] = []
    for _ in range(50 * n_hits):
        if len(times) == n_hits:
            break
        t0 = float(rng.uniform(0.05 * T, 0.85 * T))
        if all(abs(t0 - s) > 1.5 for s in times):
            times.append(t0)
    times.sort()
    F = np.zeros_like(t)
    for t0 in times:
        u = (t - t0) / width
        on = (u >= 0) & (u <= 1)
        F[on] += peak * rng.uniform(0.5, 1.0) * np.sin(math.pi * u[on])
    return F, times


def sweep_force(t: ndarray, T: float, f0: float, f1: float, amp: float, log: bool) -> ndarray:
    """A linear or logarithmic sine sweep f0 -> f1 [Hz] over T, its amplitude ramped in over 2 s and
    out over the last 1 s."""
    if log:
        b = math.log(f1 / f0) / T
        ph = 2 * math.pi * f0 * (np.exp(b * t) - 1) / b
    else:
        ph = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) / T * t**2)
    return amp * _taper(t, T) * np.sin(ph)


def random_force(rng: np.random.Generator, t: ndarray, T: float, f_lo: float, f_hi: float, rms: float) -> ndarray:
    """Band-limited random force: 80 sines of random frequency in [f_lo, f_hi] and phase, of the given
    rms, tapered in and out."""
    f = rng.uniform(f_lo, f_hi, 80)
    ph = rng.uniform(0, 2 * math.pi, 80)
    s = np.zeros_like(t)
    for fk, pk in zip(f, ph):
        s += np.sin(2 * math.pi * fk * t + pk)
    return rms * math.sqrt(2.0 / 80) * _taper(t, T) * s


def _taper(t: ndarray, T: float) -> ndarray:
    return np.minimum(np.minimum(t / 2.0, 1.0), np.clip((T - t) / 1.0, 0.0, 1.0))
