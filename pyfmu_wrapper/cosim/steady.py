"""Steady states and frequency sweeps of a co-simulated system of FMUs (:class:`~.system.CosimSystem`).

This is the co-simulation engine, the counterpart of :mod:`pyfmu_wrapper.solvers.monolithic`:
on the system's master (a generic :class:`~pyfmu_wrapper.master.master.Master`, its FMUs and
connections the model's) it applies the steady-state definition of the monolithic solver
(:mod:`pyfmu_wrapper.solvers.monolithic`): A_k = max |z[0]| over forcing period k, from the observed
outputs of z[0], z[1] at the communication points with the cubic Hermite interpolant between them;
windows of W periods (1 without play, 20 with a gap), W_j = max of A_k in window j; W = 1 stops
when the estimated distance of the observed state to the periodic orbit is below ``tol``, W > 1
when two windows agree to ``tol_window`` or their scatter is known (irregular responses are
flagged; :class:`~pyfmu_wrapper.solvers.steady.WindowCriterion`; the run at one step count is
:mod:`.periods`). The communication step is T / N so that periods start at communication points,
N the larger of the accuracy model's and the system's own time scales' (:mod:`.timescales`);
every point's coupling error is estimated by step doubling and held against ``coupling_tol``
(:mod:`.checked`, :func:`steady_state`): refined, or reported not converged with its ``reason``.
Each frequency starts from the previous frequency's final state (the states the FMU outputs show;
the others, the play chain's d, dd, from the unit's start state) or, for the first one, from the
unit's start state (:func:`~.periods.start_state`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..master.instance import MasterError
from ..master.master import Master
from ..physics.unit import SmallForcing
from ..solvers.sweep import run_sweep_pieces
from .checked import check_mode, companion_error, own_error, relative_gap
from .periods import CosimSteadyState, Periods, run_steady, start_state
from .settings import CosimSettings
from .system import CosimEngine, CosimSystem
from .timescales import choose_steps, fastest, refusal

__all__ = [
    "CosimSteadyState",
    "continuation_start",
    "engine_of",
    "periodic_time_series",
    "steady_state",
    "steps_at",
    "sweep",
]


#: the most times the coupling-error check doubles the steps of one point
MAX_DOUBLINGS = 3


def _no_result(system: CosimSystem, omega: float, z0: ArrayLike | None) -> CosimSteadyState:
    """A point with no steady state: no amplitude, not converged, the start state it would have used."""
    z = start_state(system, omega) if z0 is None else np.array(z0, dtype=float)
    return CosimSteadyState(
        omega=float(omega),
        amplitude=math.nan,
        state=z,
        periods=0,
        converged=False,
        change=math.nan,
        steps=0,
        wall_time=0.0,
    )


def steady_state(
    master: Master,
    system: CosimSystem,
    omega: float,
    z0: ArrayLike | None = None,
    settings: CosimSettings = CosimSettings(),
    hint: dict | None = None,
    restart: bool = True,
) -> CosimSteadyState:
    """Co-simulated steady state at omega [rad/s] (definition in the module doc), checked.

    The steps per period are the larger of the accuracy model's and the structure's
    (:func:`~.timescales.choose_steps`; a structure that needs more than
    ``settings.max_steps_per_period`` is refused: amplitude NaN, not converged, ``reason`` naming
    the parameters). The coupling error of the result is estimated by step doubling
    (:mod:`.checked`) and held against ``settings.coupling_tolerance``: above it the steps are
    doubled (at most :data:`MAX_DOUBLINGS` times, within the cap; never with a fixed
    ``steps_per_period``) and the point is reported not converged, with the reason, if it still
    misses. A failure of the FMUs (an unstable exchange) also doubles the steps.
    hint: a dict carried along a sweep (the shooting Jacobian, the companion's orbit); restart: leave
    the master on the converged orbit (for a time series that follows; a sweep does not need it)."""
    t_start = time.perf_counter()
    hint = {} if hint is None else hint
    base, tmd = system.structure, system.tmd
    fixed = settings.steps_per_period is not None
    cap = int(settings.max_steps_per_period)
    choice = choose_steps(system, omega, settings.steps_for(tmd), cap, fixed)
    if choice.refused is not None:
        return replace(_no_result(system, omega, z0), wall_time=time.perf_counter() - t_start, reason=choice.refused)
    n = choice.steps
    tol = settings.coupling_tolerance(tmd)
    mode = check_mode(system, settings)
    previous: tuple[int, float] | None = None
    last: tuple[CosimSteadyState, float, str] | None = None  #: the last run that finished
    steps = periods = 0
    while True:
        ss: CosimSteadyState | None = None
        est, problem = math.nan, ""
        try:
            coarse = math.nan
            companion = (math.nan, math.nan)
            if mode == "companion":
                companion = companion_error(master, system, omega, settings, hint, n)
            elif mode == "doubling":  # the play run itself at n/2 first: the master ends on the n run
                coarse = previous[1] if previous is not None and 2 * previous[0] == n else math.nan
                if math.isnan(coarse):
                    coarse = run_steady(master, system, omega, z0, settings, hint, max(n // 2, 8)).amplitude
            ss = run_steady(master, system, omega, z0, settings, hint, n)
            if mode == "own":
                est = own_error(master, system, omega, ss, settings, hint, previous, restart)
            elif mode == "doubling":
                est = relative_gap(ss.amplitude, coarse, base)
            else:  # the companion's gap against the play model's amplitude
                est = relative_gap(companion[0], companion[1], base, ss.amplitude)
        except MasterError as exc:
            problem = f"the FMUs failed at {n} steps per period: {str(exc).splitlines()[0][:300]}"
            hint.pop("A", None)
            hint.pop("companion_cosim", None)
        if ss is not None:
            steps, periods = steps + ss.steps, periods + ss.periods
            if not (est <= tol):
                problem = (
                    f"coupling error estimate {est:.3g} (step doubling) above the tolerance {tol:g} "
                    f"at {n} steps per period"
                )
            last = (ss, est, problem)
        elif last is not None:  # a refinement failed: report the last run that finished, with its problem
            ss, est, problem = last[0], last[1], f"{last[2]}; at {n} steps per period: {problem}"
            break
        if not problem or fixed or 2 * n > cap or n >= choice.steps * 2**MAX_DOUBLINGS:
            break
        previous = None if ss is None else (n, ss.amplitude)
        z0 = z0 if ss is None else ss.state
        n *= 2
    if ss is None:
        ss = _no_result(system, omega, z0)
    reason = ss.reason or problem
    if problem and not ss.reason and ss.steps_per_period:
        limit = "a fixed steps_per_period" if fixed else f"max_steps_per_period = {cap} or {MAX_DOUBLINGS} doublings"
        reason = f"{problem} ({limit}; {fastest(system).what} is {fastest(system).omega:.4g} rad/s)"
    return replace(
        ss,
        converged=bool(ss.converged and not problem),
        reason=reason,
        coupling_error=float(est),
        steps=steps,
        periods=periods,
        wall_time=time.perf_counter() - t_start,
    )


def _time_split(before: dict, after: dict, structure: str) -> dict:
    """Where the wall time of a steady state went (:meth:`Master.timing` before and after): seconds
    inside the FMUs' fmi2 calls of the compiled loop, by their role in the system (``fmu_time_base``: the
    structure's FMU, the instance ``structure`` whose outputs are the observed displacement and rate;
    ``fmu_time_tmd``: the absorber's, every other instance, whatever the model names it), the compiled
    loop's own work (``master_loop_time``) and the steps taken on the Python path
    (``python_step_time``); the rest of ``wall_time`` is the steady-state logic (shooting,
    windows, re-initialisations)."""
    out: dict[str, float] = {}
    for k, v in after["fmus"].items():
        role = "fmu_time_base" if k == structure else "fmu_time_tmd"
        out[role] = out.get(role, 0.0) + (v["seconds"] - before["fmus"].get(k, {"seconds": 0.0})["seconds"])
    out["master_loop_time"] = after["master_seconds"] - before["master_seconds"]
    out["python_step_time"] = after["python_seconds"] - before["python_seconds"]
    return out


def continuation_start(system: CosimSystem, z_prev: ArrayLike, w_prev: float, w: float) -> np.ndarray:
    """Start state at w from the steady state z_prev found at w_prev: z_prev shifted by the change
    of the unit's start state (:func:`~.periods.start_state`: the linear companion's steady state)
    between the two frequencies. Exact for a linear configuration; for a nonlinear one it keeps the
    branch (the nonlinear part of z_prev) while removing most of the transient a plain restart from
    z_prev would excite. A unit that continues from small forcing has no linear companion: z_prev."""
    if isinstance(system.unit.start, SmallForcing):
        return np.asarray(z_prev, float)
    return np.asarray(z_prev, float) + start_state(system, w) - start_state(system, w_prev)


def _sweep_piece(
    system: CosimSystem,
    base: Any,
    tmd: Any,
    seq: Sequence[float],
    direction: str,
    settings: CosimSettings,
    z0: ArrayLike | None,
    queue: Any = None,
) -> Any:
    """One contiguous piece of a sweep on one master (``base``, ``tmd``: the system's, as
    :func:`~pyfmu_wrapper.solvers.sweep.run_sweep_pieces` hands them)."""
    master = system.make_master(settings)
    structure = system.observed[0].split(".", 1)[0]  # the structure's FMU instance (the timing split's roles)
    rows = []
    z = None if z0 is None else np.asarray(z0, dtype=float)
    hint: dict = {}
    w_prev = None
    try:
        for w in seq:
            start = z
            if z is not None and w_prev is not None:
                start = continuation_start(system, z, w_prev, float(w))
            before = master.timing()
            ss = steady_state(master, system, float(w), start, settings, hint, restart=False)
            z, w_prev = ss.state, float(w)
            rows.append(ss.row(direction) | _time_split(before, master.timing(), structure))
            if queue is not None:
                queue.put(1)
    finally:
        master.close()
    return rows, z


def sweep(
    system: CosimSystem,
    omegas: Sequence[float] | np.ndarray,
    direction: str = "up",
    settings: CosimSettings = CosimSettings(),
    progress: Callable[..., Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int = 1,
) -> pd.DataFrame:
    """Co-simulated steady-state amplitudes over omegas (sorted), up, down or both.

    workers > 1 splits each direction into that many contiguous pieces, one process each (the
    first piece continues from z0, the others start from the unit's start state), exactly as the
    monolithic :func:`~pyfmu_wrapper.solvers.sweep.sweep` does, so both engines meet the same branch.
    """
    piece = partial(_sweep_piece, system)
    rows, _ = run_sweep_pieces(piece, system.structure, system.tmd, omegas, direction, settings, progress, z0, workers)
    return pd.DataFrame(rows)


def periodic_time_series(
    system: CosimSystem,
    omega: float,
    n_periods: int = 1,
    samples_per_period: int | None = None,
    settings: CosimSettings = CosimSettings(),
    master: Master | None = None,
) -> tuple[np.ndarray, np.ndarray, CosimSteadyState]:
    """Steady state, then n_periods more recorded at the communication points.

    Returns (t, states[:, n] (the pair's x, xd, y, yd, d, dd; the states no FMU output shows, the play
    chain's d, dd: nan), steady state). ``samples_per_period`` overrides the communication steps per
    period (the record is at the communication points)."""
    own = master is None
    m = master if master is not None else system.make_master(settings)
    n_state = system.unit.n_state(system.structure)
    try:
        if samples_per_period is not None:
            settings = replace(settings, steps_per_period=int(samples_per_period))
        ss = steady_state(m, system, omega, None, settings)
        n = ss.steps_per_period or settings.steps_for(system.tmd)
        if not ss.steps_per_period:  # refused or failed: nothing to record
            t = np.arange(n_periods * n) * (2 * math.pi / omega / n)
            return t, np.full((t.size, n_state), np.nan), ss
        run = Periods(m, n, 2 * math.pi / omega, system.observed)
        rec = []
        for _ in range(n_periods):
            buf = np.zeros((n + 1, m.nsig))
            run.period(buf)
            rec.append(buf[:-1])
        Y = np.vstack(rec)
        s = m.signals
        states = np.full((Y.shape[0], n_state), np.nan)
        for j, p in enumerate(system.state_outputs):
            if p is not None:
                states[:, j] = Y[:, s.index(p)]
        t = np.arange(Y.shape[0]) * (2 * math.pi / omega / n)
        return t, states, ss
    finally:
        if own:
            m.close()


def steps_at(system: CosimSystem, omega: float, settings: CosimSettings) -> int:
    """Steps per period at omega [rad/s] before any refinement: the larger of the accuracy model's
    (:meth:`~.settings.CosimSettings.steps_for`) and the structure's (:func:`~.timescales.choose_steps`);
    the accuracy model's where the structure is refused (the steady state then reports why)."""
    choice = choose_steps(system, omega, settings.steps_for(system.tmd), settings.max_steps_per_period, False)
    return choice.steps or settings.steps_for(system.tmd)


# -- a model's co-simulation as run-scenario calls it, from its system --------------------------------------

#: make_system(structure, tmd) -> the model's CosimSystem (its unit bound: ``partial(PairSystem, unit)``)
SystemFactory = Callable[[Any, Any], CosimSystem]


def _sweep_of(
    make_system: SystemFactory,
    structure: Any,
    tmd: Any,
    omegas: Sequence[float] | np.ndarray,
    direction: str = "up",
    settings: CosimSettings = CosimSettings(),
    progress: Callable[..., Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int = 1,
) -> pd.DataFrame:
    return sweep(make_system(structure, tmd), omegas, direction, settings, progress, z0, workers)


def _time_series_of(
    make_system: SystemFactory,
    structure: Any,
    tmd: Any,
    omega: float,
    n_periods: int = 1,
    samples_per_period: int | None = None,
    settings: CosimSettings = CosimSettings(),
    master: Master | None = None,
) -> tuple[np.ndarray, np.ndarray, CosimSteadyState]:
    return periodic_time_series(make_system(structure, tmd), omega, n_periods, samples_per_period, settings, master)


class PointSolver:
    """Co-simulated steady-state amplitudes at frequencies asked one call at a time, all on one master (built at
    the first call) and one shooting hint, each started by continuation from the last converged point: the
    amplitude function a linear curve's peak is refined with between its grid points
    (:func:`pyfmu_wrapper.scenario.engines.peak_refiner`). A point that does not converge gives NaN. Call
    :meth:`close` when done."""

    def __init__(self, system: CosimSystem, settings: CosimSettings) -> None:
        self.system, self.settings = system, settings
        self.master: Master | None = None
        self.hint: dict = {}
        self.z: np.ndarray | None = None
        self.w = math.nan

    def __call__(self, omegas: ArrayLike) -> np.ndarray:
        out = []
        for w in np.atleast_1d(np.asarray(omegas, dtype=float)):
            if self.master is None:
                self.master = self.system.make_master(self.settings)
            start = None if self.z is None else continuation_start(self.system, self.z, self.w, float(w))
            ss = steady_state(self.master, self.system, float(w), start, self.settings, self.hint, restart=False)
            if ss.converged:
                self.z, self.w = ss.state, float(w)
            out.append(ss.amplitude if ss.converged else math.nan)
        return np.array(out)

    def close(self) -> None:
        if self.master is not None:
            self.master.close()
            self.master = None


def _points_of(make_system: SystemFactory, structure: Any, tmd: Any, settings: CosimSettings) -> PointSolver:
    return PointSolver(make_system(structure, tmd), settings)


def _refusal_of(make_system: SystemFactory, structure: Any, tmd: Any, omegas: object, cap: int) -> str | None:
    return refusal(make_system(structure, tmd), omegas, cap)


def _steps_at_of(make_system: SystemFactory, structure: Any, tmd: Any, omega: float, settings: CosimSettings) -> int:
    return steps_at(make_system(structure, tmd), omega, settings)


def engine_of(make_system: SystemFactory, prepare: Callable[..., list[str]] | None = None) -> CosimEngine:
    """A model's :class:`~.system.CosimEngine` on this engine, from the factory of its system
    (``make_system(structure, tmd)``): its sweep, phase portrait, up-front refusal and step count, each taking
    the structure and the TMD as ``run-scenario`` calls them; ``prepare``: builds or checks its FMUs
    (:attr:`~.system.CosimEngine.prepare`)."""
    return CosimEngine(
        sweep=partial(_sweep_of, make_system),
        periodic_time_series=partial(_time_series_of, make_system),
        refusal=partial(_refusal_of, make_system),
        steps_at=partial(_steps_at_of, make_system),
        prepare=prepare,
        points=partial(_points_of, make_system),
    )
