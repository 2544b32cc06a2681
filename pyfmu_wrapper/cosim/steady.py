"""Steady states and frequency sweeps of the base + TMD system by co-simulation of the two FMUs.

This is the co-simulation engine, the counterpart of :mod:`pyfmu_wrapper.solvers.monolithic`:
on the pair wired by :mod:`.system` (a generic :class:`~pyfmu_wrapper.master.master.Master`) it
applies the steady-state definition of the monolithic solver
(:mod:`pyfmu_wrapper.solvers.monolithic`): A_k = max |x| over forcing period k, from the base
outputs x, xd at the communication points with the cubic Hermite interpolant between them;
windows of W periods (1 without play, 20 with a gap), W_j = max of A_k in window j; W = 1 stops
when the estimated distance of the base state to the periodic orbit is below ``tol``, W > 1
when two windows agree to ``tol_window`` or their scatter is known (irregular responses are
flagged; :class:`~pyfmu_wrapper.solvers.steady.WindowCriterion`; the run at one step count is
:mod:`.periods`). The communication step is T / N so that periods start at communication points,
N the larger of the accuracy model's and the structure's own time scales' (:mod:`.timescales`);
every point's coupling error is estimated by step doubling and held against ``coupling_tol``
(:mod:`.checked`, :func:`steady_state`): refined, or reported not converged with its ``reason``.
Each frequency starts from the previous frequency's final state (x, xd, y, yd read from the FMU outputs; d, dd of the play chain from
:func:`~pyfmu_wrapper.solvers.monolithic.initial_guess`) or, for the first one, from
:func:`initial_guess`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..master.instance import MasterError
from ..master.master import Master
from ..physics.params import BaseParams, TMDParams
from ..solvers.start import initial_guess
from ..solvers.sweep import run_sweep_pieces
from . import timescales
from .checked import check_mode, companion_error, own_error, relative_gap
from .periods import CosimSteadyState, Periods, run_steady
from .settings import CosimSettings
from .system import make_master
from .timescales import choose_steps, fastest

__all__ = ["CosimSteadyState", "continuation_start", "periodic_time_series", "steady_state", "sweep"]


#: the most times the coupling-error check doubles the steps of one point
MAX_DOUBLINGS = 3


def _no_result(base: BaseParams, tmd: TMDParams, omega: float, z0: ArrayLike | None) -> CosimSteadyState:
    """A point with no steady state: no amplitude, not converged, the start state it would have used."""
    z = initial_guess(base, tmd, omega) if z0 is None else np.array(z0, dtype=float)
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
    base: BaseParams,
    tmd: TMDParams,
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
    fixed = settings.steps_per_period is not None
    cap = int(settings.max_steps_per_period)
    choice = choose_steps(base, tmd, omega, settings.steps_for(tmd), cap, fixed)
    if choice.refused is not None:
        return replace(_no_result(base, tmd, omega, z0), wall_time=time.perf_counter() - t_start, reason=choice.refused)
    n = choice.steps
    tol = settings.coupling_tolerance(tmd)
    mode = check_mode(base, tmd, settings)
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
                companion = companion_error(master, base, tmd, omega, settings, hint, n)
            elif mode == "doubling":  # the play run itself at n/2 first: the master ends on the n run
                coarse = previous[1] if previous is not None and 2 * previous[0] == n else math.nan
                if math.isnan(coarse):
                    coarse = run_steady(master, base, tmd, omega, z0, settings, hint, max(n // 2, 8)).amplitude
            ss = run_steady(master, base, tmd, omega, z0, settings, hint, n)
            if mode == "own":
                est = own_error(master, base, tmd, omega, ss, settings, hint, previous, restart)
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
        ss = _no_result(base, tmd, omega, z0)
    reason = ss.reason or problem
    if problem and not ss.reason and ss.steps_per_period:
        limit = "a fixed steps_per_period" if fixed else f"max_steps_per_period = {cap} or {MAX_DOUBLINGS} doublings"
        reason = f"{problem} ({limit}; {fastest(base, tmd).what} is {fastest(base, tmd).omega:.4g} rad/s)"
    return replace(
        ss,
        converged=bool(ss.converged and not problem),
        reason=reason,
        coupling_error=float(est),
        steps=steps,
        periods=periods,
        wall_time=time.perf_counter() - t_start,
    )


def _time_split(before: dict, after: dict) -> dict:
    """Where the wall time of a steady state went (:meth:`Master.timing` before and after): seconds
    inside each FMU's fmi2 calls of the compiled loop (``fmu_time_<instance>``), the compiled
    loop's own work (``master_loop_time``) and the steps taken on the Python path
    (``python_step_time``); the rest of ``wall_time`` is the steady-state logic (shooting,
    windows, re-initialisations)."""
    out = {
        f"fmu_time_{k}": v["seconds"] - before["fmus"].get(k, {"seconds": 0.0})["seconds"]
        for k, v in after["fmus"].items()
    }
    out["master_loop_time"] = after["master_seconds"] - before["master_seconds"]
    out["python_step_time"] = after["python_seconds"] - before["python_seconds"]
    return out


def continuation_start(base: BaseParams, tmd: TMDParams, z_prev: ArrayLike, w_prev: float, w: float) -> np.ndarray:
    """Start state at w from the steady state z_prev found at w_prev: z_prev shifted by the change
    of the linear steady state (:func:`initial_guess`) between the two frequencies. Exact for a
    linear configuration; for a nonlinear one it keeps the branch (the nonlinear part of z_prev)
    while removing most of the transient a plain restart from z_prev would excite."""
    return np.asarray(z_prev, float) + initial_guess(base, tmd, w) - initial_guess(base, tmd, w_prev)


def _sweep_piece(
    base: BaseParams,
    tmd: TMDParams,
    seq: Sequence[float],
    direction: str,
    settings: CosimSettings,
    z0: ArrayLike | None,
    queue: Any = None,
) -> Any:
    master = make_master(
        base,
        tmd,
        settings.scheme,
        settings.order,
        coupling=settings.coupling,
        interface_jacobian=settings.interface_jacobian,
        fmi_version=settings.fmi_version,
        fmu_build=settings.fmu_build,
    )
    rows = []
    z = None if z0 is None else np.asarray(z0, dtype=float)
    hint: dict = {}
    w_prev = None
    try:
        for w in seq:
            start = z
            if z is not None and w_prev is not None:
                start = continuation_start(base, tmd, z, w_prev, float(w))
            before = master.timing()
            ss = steady_state(master, base, tmd, float(w), start, settings, hint, restart=False)
            z, w_prev = ss.state, float(w)
            rows.append(ss.row(direction) | _time_split(before, master.timing()))
            if queue is not None:
                queue.put(1)
    finally:
        master.close()
    return rows, z


def sweep(
    base: BaseParams,
    tmd: TMDParams,
    omegas: Sequence[float] | np.ndarray,
    direction: str = "up",
    settings: CosimSettings = CosimSettings(),
    progress: Callable[..., Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int = 1,
) -> pd.DataFrame:
    """Co-simulated steady-state amplitudes over omegas (sorted), up, down or both.

    workers > 1 splits each direction into that many contiguous pieces, one process each (the
    first piece continues from z0, the others start from :func:`initial_guess`), exactly as the
    monolithic :func:`~pyfmu_wrapper.solvers.sweep.sweep` does, so both engines meet the same branch.
    """
    rows, _ = run_sweep_pieces(_sweep_piece, base, tmd, omegas, direction, settings, progress, z0, workers)
    return pd.DataFrame(rows)


def periodic_time_series(
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    n_periods: int = 1,
    samples_per_period: int | None = None,
    settings: CosimSettings = CosimSettings(),
    master: Master | None = None,
) -> tuple[np.ndarray, np.ndarray, CosimSteadyState]:
    """Steady state, then n_periods more recorded at the communication points.

    Returns (t, states[:, 6] = x, xd, y, yd, d, dd (d, dd: nan, not outputs of the FMUs), steady state).
    ``samples_per_period`` overrides the communication steps per period (the record is at the
    communication points)."""
    own = master is None
    m = (
        master
        if master is not None
        else make_master(
            base,
            tmd,
            settings.scheme,
            settings.order,
            coupling=settings.coupling,
            interface_jacobian=settings.interface_jacobian,
            fmi_version=settings.fmi_version,
            fmu_build=settings.fmu_build,
        )
    )
    try:
        if samples_per_period is not None:
            settings = replace(settings, steps_per_period=int(samples_per_period))
        ss = steady_state(m, base, tmd, omega, None, settings)
        n = ss.steps_per_period or settings.steps_for(tmd)
        if not ss.steps_per_period:  # refused or failed: nothing to record
            t = np.arange(n_periods * n) * (2 * math.pi / omega / n)
            return t, np.full((t.size, 6), np.nan), ss
        run = Periods(m, n, 2 * math.pi / omega)
        rec = []
        for _ in range(n_periods):
            buf = np.zeros((n + 1, m.nsig))
            run.period(buf)
            rec.append(buf[:-1])
        Y = np.vstack(rec)
        s = m.signals
        states = np.full((Y.shape[0], 6), np.nan)
        for j, p in enumerate(("base.x", "base.xd", "tmd.y", "tmd.yd")):
            states[:, j] = Y[:, s.index(p)]
        t = np.arange(Y.shape[0]) * (2 * math.pi / omega / n)
        return t, states, ss
    finally:
        if own:
            m.close()


def refusal(base: Any, tmd: TMDParams, omegas: object, cap: int) -> str | None:
    """The frequencies of ``omegas`` the pair's time scales cannot step within ``cap`` steps per
    period (:func:`.timescales.refusal`): what ``run-scenario`` refuses up front."""
    return timescales.refusal(base, tmd, omegas, cap)
