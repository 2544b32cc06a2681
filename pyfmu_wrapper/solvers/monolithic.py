"""Monolithic time-domain solver of the coupled base + TMD system.

Steady state (documented definition)
------------------------------------
The forcing is F cos(w t). The solver integrates whole forcing periods T = 2 pi / w and records
A_k = max |x(t)| over period k from the dense output of the integrator. Periods are grouped in
windows of ``window`` periods and W_j = max of A_k over window j.

* ``window = 1`` (default for configurations without play, and for the play chain with eps = 0):
  the response is periodic, z(t + T) = z(t). It is found by Newton shooting on the period map
  z -> z(T) (the monodromy matrix by finite differences over the active states), which
  converges in a few iterations from a nearby state instead of waiting tens of periods for a
  2.5 %-damped transient to decay. Converged when the Newton correction is below ``tol`` times
  the state scale; the amplitude is max |x| over the period started from the corrected state.
  If Newton does not converge from a far start, ten periods are integrated to let the transient
  decay and Newton is tried again. With ``shooting=False`` the solver integrates period after
  period and stops when the estimated distance of the base state (x, xd/w) at the period start
  to the periodic orbit, r rho / (1 - rho) from the residual r between consecutive period starts
  and its contraction rho, is below ``tol`` * A (:class:`WindowCriterion`): a beating transient
  cannot fool it, and the offset of a TMD stuck by friction (a mode the base does not see) does
  not hold it up.
* ``window > 1`` (default 20 for the play model with a gap): the rattling gear makes the
  response never exactly periodic. The run stops when two consecutive windows agree,
  |W_j - W_{j-1}| <= tol_window * W_j (regular, converged), or, once three windows after the
  first exist, when their running maximum has not grown by more than tol_window for two
  windows: the amplitude is that maximum and ``change`` the scatter (max - min) / max of those
  windows. Converged if the scatter is within ``scatter_tol`` (default 5e-3, the accuracy
  asked of both engines), else flagged ``irregular`` and not converged (at 20 rad/s with
  c = 0 the window maximum scatters by ~20 % for ever). No absolute tolerance: a tiny
  amplitude near the antiresonance must settle relative to itself. ``max_periods_window``
  bounds the periods either way.

The reported amplitude is W of the last window. Each solve returns its diagnostics (periods
used, converged flag, last change, integrator steps). ``max_periods`` bounds the work; a point that
does not settle is reported as not converged, never silently.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..physics.params import InerterModel, TMDParams
from ..physics.unit import ModelUnit, SmallForcing
from . import settings_table as _table
from .harmonic import periodic_max
from .rodas import DEFAULT_MAX_STEPS, OK, STAT_EVENTS, STAT_REJECTED, STAT_STEPS, failure_message, make_integrator
from .settings_table import MONO
from .shooting import shoot
from .start import initial_guess
from .steady import SteadySettings, WindowCriterion

#: x samples per period for the periodic amplitude (``SteadyState.amplitude_periodic``): enough for the
#: series to keep :data:`~.harmonic.H_MAX` harmonics (0.45 x 512 > 150), as a record's fit at 1 kHz does
PERIODIC_SAMPLES = 512


def integrator(unit: ModelUnit) -> Any:
    """The compiled integrator of a model unit (built once per model, see ``make_integrator``)."""
    return make_integrator(unit.ode)


class SolverError(RuntimeError):
    """The integrator could not proceed (step size underflow, step cap, non-finite state); the
    message names the time, the state and its contact / friction mode."""


@dataclass(frozen=True)
class SolverSettings(SteadySettings):
    """Accuracy and steady-state settings of the monolithic solver.

    The steady-state fields (tol, tol_window, window, min_periods, max_periods,
    scatter_tol, play_start, shooting, max_newton) are those of
    :class:`~pyfmu_wrapper.solvers.steady.SteadySettings`, with its defaults. Own fields:
    rtol: relative tolerance of the integrator; atol_scale: absolute tolerance as a fraction of
    the static deflection F/K (per state, scaled by the natural frequency for rates);
    max_periods_window: bound on the periods of a windowed steady state (module doc);
    max_steps: cap on integrator steps per period (a stalled integration ends with
    :class:`SolverError` naming time, state and mode, never a hang).
    """

    rtol: float = _table.default("rtol", MONO)
    atol_scale: float = _table.default("atol_scale", MONO)
    max_periods_window: int = _table.default("max_periods_window", MONO)
    max_steps: int = _table.default("max_steps", MONO)
    # (validated by SteadySettings.validate against solvers/settings_table.py)


@dataclass
class SteadyState:
    """Result of a steady-state solve at one excitation frequency."""

    omega: float
    amplitude: float  #: max |x| over the last window [m]
    state: np.ndarray  #: state at the end (phase w t = 0 mod 2 pi)
    periods: int
    converged: bool
    change: float  #: relative convergence measure at the end
    steps: int
    rejected: int
    events: int
    period_max: np.ndarray = field(repr=False)  #: max |x| of every period [m]
    wall_time: float = 0.0
    irregular: bool = False  #: settled into irregular motion; ``change`` is then its scatter
    reason: str = ""  #: why it is not converged ("" when it is)
    amplitude_periodic: float = math.nan  #: max |x - mean| of the periodic part (:meth:`WindowCriterion.periodic`) [m]


def integrator_atol(unit: ModelUnit, base: Any, tmd: TMDParams, omega: float, settings: SolverSettings) -> np.ndarray:
    """The absolute tolerance per state of the structure's model (its unit's rule)."""
    return unit.atol(base, tmd, omega, settings.atol_scale)


class _Runner:
    """Holds the packed parameters and work arrays for repeated period integrations."""

    def __init__(self, unit: ModelUnit, base: Any, tmd: TMDParams, omega: float, settings: SolverSettings) -> None:
        self.unit = unit
        self.integrate = integrator(unit)
        self.p = unit.pack(base, tmd, omega)
        self.T = 2.0 * math.pi / omega
        self.atol = unit.atol(base, tmd, omega, settings.atol_scale)
        self.active = unit.active(base, tmd)
        self.rtol = settings.rtol
        self.max_steps = int(settings.max_steps)
        self.band = 1.0 / tmd.friction_slope
        self.u = np.zeros(1)
        self.stats = np.zeros(4, dtype=np.int64)
        self.h = self.T / 200.0
        self.hmax = self.T / 20.0
        self.no_samples = np.zeros(0)
        self.no_out = np.zeros((0, unit.n_state(base)))
        #: the phases each settling period samples for the periodic amplitude, and their states
        self.phases = np.linspace(0.0, self.T, PERIODIC_SAMPLES, endpoint=False)
        self.sampled = np.zeros((PERIODIC_SAMPLES, unit.n_state(base)))

    def period(
        self,
        z: NDArray[np.float64],
        t0: float,
        sample_times: NDArray[np.float64] | None = None,
        samples: NDArray[np.float64] | None = None,
    ) -> float:
        st = self.no_samples if sample_times is None else sample_times
        sa = self.no_out if samples is None else samples
        h, xmax, status, t = self.integrate(
            z,
            t0,
            t0 + self.T,
            self.p,
            self.u,
            self.rtol,
            self.atol,
            self.h,
            self.hmax,
            st,
            sa,
            self.band,
            self.stats,
            self.max_steps,
        )
        if status != OK:
            raise SolverError(
                f"omega = {2 * math.pi / self.T:.10g} rad/s, period from t0 = {t0:.6g} s: "
                + failure_message(status, self.unit.ode, t, z, self.p, self.atol, self.band, self.max_steps)
            )
        if not np.all(np.isfinite(z)):
            raise SolverError(
                f"omega = {2 * math.pi / self.T:.10g} rad/s: non-finite state {z} after the period from t0 = {t0:.6g} s"
            )
        self.h = h
        return xmax


def companion_start(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    omega: float,
    settings: SolverSettings,
    hint: dict[str, Any] | None = None,
) -> np.ndarray:
    """Start state for the play model: the periodic orbit of its smooth companion (the same
    links with an ideal inerter), with the gear chain at the contact the ideal inerter force
    asks for (d = sign(P) (eps + |P| / ki), dd = 0).

    The play response differs from the companion's only by the rattling, so the windowed
    steady state settles in about two windows from here, where a start from the previous
    frequency's state drags a transient that decays with the 2.5 %-damped base (~100 periods).
    With ``hint`` (carried along a sweep) the companion orbit itself is continued.
    """
    ideal = replace(tmd, inerter=InerterModel.IDEAL, play_gap=0.0)
    sub = None if hint is None else hint.setdefault("companion", {})
    z0 = None if sub is None else sub.get("z")
    ss = steady_state(unit, base, ideal, omega, z0, replace(settings, window=1), sub)
    z = ss.state.copy() if ss.converged else initial_guess(unit, base, ideal, omega)
    if sub is not None and ss.converged:
        sub["z"] = ss.state.copy()
    P = unit.inerter_force(z, unit.pack(base, ideal, omega))
    z[4] = math.copysign(tmd.play_gap + abs(P) / tmd.mesh_stiffness, P)
    z[5] = 0.0
    return z


def steady_state(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    omega: float,
    z0: ArrayLike | None = None,
    settings: SolverSettings = SolverSettings(),
    hint: dict[str, Any] | None = None,
) -> SteadyState:
    """Integrate from z0 (default: :func:`initial_guess`) until the steady state (module doc).

    unit: the structure's model; base: the primary structure's parameters (BaseParams, FrameParams, ...).
    hint: a dict carried along a sweep (shooting keeps its Jacobian there for the next point).
    """
    if not (omega > 0 and math.isfinite(omega)):
        raise ValueError(f"omega must be a positive number of rad/s, got {omega!r}")
    t_start = time.perf_counter()
    run = _Runner(unit, base, tmd, omega, settings)
    W = settings.window_for(tmd)
    if z0 is not None:
        z = run.unit.check_state(base, np.array(z0, dtype=float))
    elif W > 1 and settings.play_start == "companion":
        z = companion_start(unit, base, tmd, omega, settings, hint)
    elif W == 1 and settings.shooting and isinstance(unit.start, SmallForcing):
        z = small_forcing_start(unit, base, tmd, omega, settings)
    else:
        z = initial_guess(unit, base, tmd, omega)
    try:
        return _settle(run, base, tmd, omega, z, W, settings, hint, t_start)
    except SolverError as exc:  # the integrator gave up: this point is not converged, with the reason
        s = run.stats
        return SteadyState(
            omega=omega,
            amplitude=float("nan"),
            state=z,
            periods=0,
            converged=False,
            change=float("inf"),
            steps=int(s[STAT_STEPS]),
            rejected=int(s[STAT_REJECTED]),
            events=int(s[STAT_EVENTS]),
            period_max=np.zeros(0),
            wall_time=time.perf_counter() - t_start,
            reason=f"the integrator failed: {str(exc).splitlines()[0][:1000]}",
        )


def small_forcing_start(
    unit: ModelUnit, base: Any, tmd: TMDParams, omega: float, settings: SolverSettings
) -> np.ndarray:
    """The start of a unit that continues from small forcing (:class:`~pyfmu_wrapper.physics.unit.SmallForcing`):
    the linearisation's steady state at the first fraction of the force, then the periodic solution at each
    fraction in turn from the last one scaled up to the next force; returns the state scaled to the full
    force (the start of the full-force solve). A fraction that does not converge ends the continuation with
    the last converged state (the full-force solve then falls back on its own start rules)."""
    F = float(base.force_amplitude)
    fractions = [f for f in unit.start.fractions if 0.0 < f < 1.0]  # type: ignore[union-attr]
    if F == 0.0 or not fractions:
        return initial_guess(unit, base, tmd, omega)
    z = initial_guess(unit, replace(base, force_amplitude=fractions[0] * F), tmd, omega)
    done = None
    for frac in fractions:
        ss = steady_state(unit, replace(base, force_amplitude=frac * F), tmd, omega, z, settings)
        if not ss.converged:
            break
        done, z = frac, ss.state.copy()
    if done is None:
        return initial_guess(unit, base, tmd, omega)
    return z / done  # the last solution scaled to the full force: exact in the linear limit


def _settle(
    run: _Runner,
    base: Any,
    tmd: TMDParams,
    omega: float,
    z: np.ndarray,
    W: int,
    settings: SolverSettings,
    hint: dict[str, Any] | None,
    t_start: float,
) -> SteadyState:
    """The steady state from z (module doc): Newton shooting (window 1) or windows of periods."""
    if W == 1 and settings.shooting:
        # Newton shooting; if it fails from a far start, let the transient decay a little and retry
        spent = 0
        while spent < settings.max_periods:
            try:
                res = _shoot(run, tmd, z, settings, hint)
            except SolverError:  # a Newton iterate the integrator cannot follow: as a failed Newton
                res = None
                if hint is not None:
                    hint.pop("J", None)
            if res is not None:
                zs, amp, k, change = res
                s = run.stats
                return SteadyState(
                    omega=omega,
                    amplitude=amp,
                    state=zs,
                    periods=spent + k,
                    converged=True,
                    change=change,
                    steps=int(s[STAT_STEPS]),
                    rejected=int(s[STAT_REJECTED]),
                    events=int(s[STAT_EVENTS]),
                    period_max=np.array([amp]),
                    wall_time=time.perf_counter() - t_start,
                    amplitude_periodic=periodic_max(run.sampled[:, 0]),  # the last map call was from zs
                )
            spent += settings.max_newton * 5
            for _ in range(10):
                run.period(z, 0.0)
            spent += 10
        return SteadyState(
            omega=omega,
            amplitude=float("nan"),
            state=z,
            periods=spent,
            converged=False,
            change=float("inf"),
            steps=int(run.stats[STAT_STEPS]),
            rejected=int(run.stats[STAT_REJECTED]),
            events=int(run.stats[STAT_EVENTS]),
            period_max=np.zeros(0),
            wall_time=time.perf_counter() - t_start,
            reason=f"Newton shooting did not converge within max_periods = {settings.max_periods} periods",
        )
    crit = WindowCriterion.from_settings(settings, W, base, omega)
    k = 0
    if W == 1:
        crit.add(abs(z[0]), z)  # the start state, for the residual of the first period
        crit.period_max.clear()
    while k < crit.max_periods:
        k += 1
        if crit.add(run.period(z, 0.0, run.phases, run.sampled), z, run.sampled[:, 0]):  # restarts at phase 0: t0 = 0
            break
    amplitude, converged, change = crit.result()
    pmax = crit.period_max
    s = run.stats
    return SteadyState(
        omega=omega,
        amplitude=amplitude,
        state=z,
        periods=k,
        converged=converged,
        change=change,
        steps=int(s[STAT_STEPS]),
        rejected=int(s[STAT_REJECTED]),
        events=int(s[STAT_EVENTS]),
        period_max=np.array(pmax),
        wall_time=time.perf_counter() - t_start,
        irregular=crit.irregular,
        amplitude_periodic=crit.periodic(),
        reason=""
        if converged
        else (
            f"irregular response: the window maxima scatter by {change:.3g}"
            if crit.irregular
            else f"no steady state within {k} periods (last relative change {change:.3g})"
        ),
    )


def _shoot(
    run: _Runner, tmd: TMDParams, z: np.ndarray, settings: SolverSettings, hint: dict[str, Any] | None = None
) -> tuple[np.ndarray, float, int, float] | None:
    """Newton shooting (:func:`~pyfmu_wrapper.solvers.shooting.shoot`) on the period map of the
    active states; returns (state after the period, amplitude, periods, change) or None.

    The Jacobian is taken from ``hint['J']`` (the previous frequency of a sweep) when given; on
    success ``hint['J']`` holds the last one."""
    act = run.active
    last = {}

    def period_map(za: np.ndarray) -> tuple[np.ndarray, float]:
        zf = z.copy()
        zf[act] = za
        amp = run.period(zf, 0.0, run.phases, run.sampled)  # sampled: the periodic amplitude of the last call
        last["z"] = zf
        return zf[act], amp

    res = shoot(
        period_map,
        z[act],
        run.atol[act] / settings.atol_scale,
        settings.tol,
        settings.max_newton,
        None if hint is None else hint.get("J"),
    )
    if res is None:
        return None
    if hint is not None:
        hint["J"] = res.jacobian
    return last["z"], res.amplitude, res.periods, res.change  # the last map call was from res.z


def simulate(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    omega: float,
    t_end: float,
    z0: ArrayLike | None = None,
    n_samples: int = 1001,
    sample_times: ArrayLike | None = None,
    rtol: float = 1e-9,
    atol: float | ArrayLike | None = None,
    max_steps: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Transient simulation from z0 (default rest) over [0, t_end]; returns (t, states[len(t), n])
    (n: the length of the structure's model state).

    max_steps caps the integrator steps (default: DEFAULT_MAX_STEPS per forcing period); a stalled
    run raises :class:`SolverError` naming time, state and mode.
    """
    n = unit.n_state(base)
    p = unit.pack(base, tmd, omega)
    z = np.zeros(n) if z0 is None else unit.check_state(base, np.array(z0, dtype=float))
    t = np.linspace(0.0, t_end, n_samples) if sample_times is None else np.asarray(sample_times, dtype=float)
    out = np.zeros((t.size, n))
    if atol is None:
        atol = integrator_atol(unit, base, tmd, omega, SolverSettings(atol_scale=1e-7))
    stats = np.zeros(4, dtype=np.int64)
    T = 2 * math.pi / omega
    atol = np.asarray(atol, dtype=float)
    if max_steps is None:  # the per-period cap, for every period of the run
        max_steps = DEFAULT_MAX_STEPS * max(1, math.ceil(t_end / T))
    _, _, status, tf = integrator(unit)(
        z,
        0.0,
        float(t_end),
        p,
        np.zeros(1),
        rtol,
        atol,
        T / 200,
        T / 20,
        t,
        out,
        1.0 / tmd.friction_slope,
        stats,
        int(max_steps),
    )
    if status != OK:
        raise SolverError(failure_message(status, unit.ode, tf, z, p, atol, 1.0 / tmd.friction_slope, max_steps))
    return t, out


def periodic_time_series(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    omega: float,
    n_periods: int = 1,
    samples_per_period: int = 400,
    z0: ArrayLike | None = None,
    settings: SolverSettings = SolverSettings(),
) -> tuple[np.ndarray, np.ndarray, SteadyState]:
    """Steady-state time series: settle at omega, then record n_periods (t from 0, states)."""
    ss = steady_state(unit, base, tmd, omega, z0, settings)
    run = _Runner(unit, base, tmd, omega, settings)
    z = ss.state.copy()
    n = samples_per_period
    ts, zs = [], []
    for k in range(n_periods):
        st = np.linspace(0.0, run.T, n, endpoint=False)
        out = np.zeros((n, z.shape[0]))
        run.period(z, 0.0, st, out)
        ts.append(st + k * run.T)
        zs.append(out)
    return np.concatenate(ts), np.concatenate(zs), ss
