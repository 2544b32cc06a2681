"""Steady states and frequency sweeps of the base + TMD system by co-simulation of the two FMUs.

This is the co-simulation engine, the counterpart of :mod:`pyfmu_wrapper.solvers.monolithic`:
on the pair wired by :mod:`.system` (a generic :class:`~pyfmu_wrapper.master.master.Master`) it
applies the steady-state definition of the monolithic solver
(:mod:`pyfmu_wrapper.solvers.monolithic`): A_k = max |x| over forcing period k, from the base
outputs x, xd at the communication points with the cubic Hermite interpolant between them;
windows of W periods (1 without play, 20 with a gap), W_j = max of A_k in window j; W = 1 stops
when the estimated distance of the base state to the periodic orbit is below ``tol``, W > 1
when two windows agree to ``tol_window`` or their scatter is known (irregular responses are
flagged; :class:`~pyfmu_wrapper.solvers.steady.WindowCriterion`). The communication step is
T / ``steps_per_period`` so that periods start at communication points. Each frequency starts from the previous frequency's
final state (x, xd, y, yd read from the FMU outputs; d, dd of the play chain from
:func:`~pyfmu_wrapper.solvers.monolithic.initial_guess`) or, for the first one, from
:func:`initial_guess`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..master.master import Master
from ..physics.params import BaseParams, InerterModel, TMDParams
from ..solvers.hermite import hermite_absmax_series as _hermite_absmax  # the one Hermite maximum of both engines
from ..solvers.monolithic import SolverSettings, companion_start
from ..solvers.shooting import shoot
from ..solvers.start import initial_guess
from ..solvers.steady import WindowCriterion
from ..solvers.sweep import run_sweep_pieces
from .settings import CosimSettings
from .system import fmu_parameters, make_master


@dataclass
class CosimSteadyState:
    omega: float
    amplitude: float
    state: np.ndarray  #: x, xd, y, yd, d, dd at the end (d, dd: not observable, from the start guess)
    periods: int
    converged: bool
    change: float
    steps: int
    wall_time: float
    period_max: np.ndarray | None = field(repr=False, default=None)
    irregular: bool = False  #: settled into irregular motion; ``change`` is then its scatter


class _Periods:
    """Runs whole periods on an initialised master and returns x, xd at the communication points.

    A period is one block of the master's :meth:`~pyfmu_wrapper.master.master.Master.advance`
    (the compiled loop: no Python work per step), recorded into preallocated arrays."""

    def __init__(self, master: Master, n: int, T: float):
        self.m, self.n, self.h = master, n, T / n
        self.ix, self.iv = master.signals.index("base.x"), master.signals.index("base.xd")
        self.t_rec = np.zeros(n)
        self.y_rec = np.zeros((n + 1, master.nsig))

    def period(self, samples: np.ndarray | None = None) -> float:
        m = self.m
        rec = self.y_rec if samples is None else samples
        rec[0] = m.y
        m.advance(self.n, self.h, self.t_rec, rec[1:])
        self.x = np.ascontiguousarray(rec[:, self.ix])  # x, xd at the communication points of the period
        self.v = np.ascontiguousarray(rec[:, self.iv])
        return _hermite_absmax(self.x, self.v, self.h)


def _state_of(master: Master, z_guess: np.ndarray) -> np.ndarray:
    s = master.signals
    y = master.y
    return np.array(
        [y[s.index("base.x")], y[s.index("base.xd")], y[s.index("tmd.y")], y[s.index("tmd.yd")], z_guess[4], z_guess[5]]
    )


def _can_shoot(tmd: TMDParams) -> bool:
    """Shooting needs the whole state observable at the FMU outputs: x, xd, y, yd (no play chain)."""
    return tmd.inerter != InerterModel.PLAY


def _start(
    master: Master, base: BaseParams, tmd: TMDParams, omega: float, z: ArrayLike, settings: CosimSettings
) -> None:
    master.initialize(0.0, fmu_parameters(base, tmd, omega, z, settings.fmu_rtol))


def _shoot(
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: np.ndarray,
    settings: CosimSettings,
    run: _Periods,
    hint: dict,
) -> Any:
    """Newton shooting (:func:`~pyfmu_wrapper.solvers.shooting.shoot`, the one shared with the
    monolithic solver) on the co-simulated period map z -> z(T) over z = (x, xd, y, yd); each
    evaluation re-initialises the FMUs from z. The Jacobian comes from the previous frequency of
    the sweep (``hint['A']``) or from finite differences. Returns the ShootingResult or None."""
    z = np.array(z0[:4], dtype=float)
    tail = np.asarray(z0[4:6], dtype=float)
    amp = max(
        math.hypot(z[0], z[1] / omega),
        math.hypot(z[2], z[3] / omega),
        1e-6 * abs(base.force_amplitude) / base.stiffness,
    )

    def period_map(zz: np.ndarray) -> tuple[np.ndarray, float]:
        _start(master, base, tmd, omega, np.concatenate([zz, tail]), settings)
        a = run.period()
        return _state_of(master, np.zeros(6))[:4], a

    res = shoot(
        period_map, z, np.array([amp, amp * omega, amp, amp * omega]), settings.tol, settings.max_newton, hint.get("A")
    )
    if res is None:
        hint.pop("A", None)
    else:
        hint["A"] = res.jacobian
    return res


def steady_state(
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: ArrayLike | None = None,
    settings: CosimSettings = CosimSettings(),
    hint: dict | None = None,
) -> CosimSteadyState:
    """Co-simulated steady state at omega [rad/s] (definition in the module doc).

    Window 1 without play: Newton shooting on the co-simulated period map (``settings.shooting``,
    :func:`~pyfmu_wrapper.solvers.shooting.shoot`, shared with the monolithic solver), the
    amplitude is max |x| over the period started from the converged state; otherwise
    (or if Newton fails) period after period until the window criterion holds.
    hint: a dict carried along a sweep (the shooting Jacobian)."""
    t_start = time.perf_counter()
    hint = {} if hint is None else hint
    W = settings.window_for(tmd)
    if W > 1 and settings.play_start == "companion":
        # the play model starts from the orbit of its smooth companion (ideal inerter), as in the
        # monolithic solver: the windows then settle in about two (see companion_start)
        z = companion_start(
            base, tmd, omega, SolverSettings(rtol=1e-8, atol_scale=1e-8), hint.setdefault("monolithic", {})
        )
    else:
        guess = initial_guess(base, tmd, omega)
        z = guess if z0 is None else np.array(z0, dtype=float)
        if tmd.inerter == InerterModel.PLAY and z0 is not None:
            z = np.concatenate([z[:4], guess[4:]])
    T = 2.0 * math.pi / omega
    n = settings.steps_for(tmd)
    run = _Periods(master, n, T)
    steps = 0
    if W == 1 and settings.shooting and _can_shoot(tmd):
        res = _shoot(master, base, tmd, omega, z, settings, run, hint)
        if res is not None:  # the master stands at the end of the period from res.z
            return CosimSteadyState(
                omega=float(omega),
                amplitude=res.amplitude,
                state=_state_of(master, z),
                periods=res.periods,
                converged=True,
                change=res.change,
                steps=res.periods * n,
                wall_time=time.perf_counter() - t_start,
                period_max=np.array([res.amplitude]),
            )
        steps = 0
    _start(master, base, tmd, omega, z, settings)
    crit = WindowCriterion.from_settings(settings, W, base, omega)
    ix, iv = master.signals.index("base.x"), master.signals.index("base.xd")
    if W == 1:
        crit.add(abs(master.y[ix]), (master.y[ix], master.y[iv]))  # the start, for the first residual
        crit.period_max.clear()
    k = 0
    while k < crit.max_periods:
        k += 1
        if crit.add(run.period(), (master.y[ix], master.y[iv])):
            break
    amplitude, converged, change = crit.result()
    return CosimSteadyState(
        omega=float(omega),
        amplitude=amplitude,
        state=_state_of(master, z),
        periods=k,
        converged=converged,
        change=change,
        steps=steps + k * n,
        wall_time=time.perf_counter() - t_start,
        period_max=np.array(crit.period_max),
        irregular=crit.irregular,
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
            ss = steady_state(master, base, tmd, float(w), start, settings, hint)
            z, w_prev = ss.state, float(w)
            rows.append(
                dict(
                    direction=direction,
                    omega=float(w),
                    amplitude=ss.amplitude,
                    periods=ss.periods,
                    converged=ss.converged,
                    irregular=ss.irregular,
                    change=ss.change,
                    steps=ss.steps,
                    rejected=0,
                    wall_time=ss.wall_time,
                    **_time_split(before, master.timing()),
                )
            )
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
        )
    )
    try:
        if samples_per_period is not None:
            settings = replace(settings, steps_per_period=int(samples_per_period))
        ss = steady_state(m, base, tmd, omega, None, settings)
        n = settings.steps_for(tmd)
        run = _Periods(m, n, 2 * math.pi / omega)
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
