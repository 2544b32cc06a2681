"""Engines that compute frequency sweeps and steady-state time series for the scenario runner.

The single dispatch point is :func:`compute_sweep` (and :func:`compute_time_series` for phase
portraits). An engine is a pair of functions registered in :data:`ENGINES`; today only
``monolithic`` exists (exact frequency response for linear configurations, the monolithic
steady-state solver otherwise). A co-simulation engine ('cosim') or a comparison ('both') is
added by registering another :class:`Engine` whose sweep returns the same table columns
(:data:`SWEEP_COLUMNS`); the runner, the plots and the summary need no change.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pandas as pd

from ..physics.params import BaseParams, TMDParams
from ..solvers.frequency_response import exact_amplitude, exact_response
from ..solvers.monolithic import periodic_time_series
from ..solvers.sweep import sweep
from .schema import SolverConfig

#: columns of every sweep table (one row per direction and omega)
SWEEP_COLUMNS = ("engine", "method", "direction", "omega", "amplitude", "periods", "converged", "change",
                 "steps", "rejected", "wall_time")


@dataclass(frozen=True)
class RunSettings:
    """What an engine needs besides the parameters: its name and the scenario's solver block."""

    engine: str = "monolithic"
    solver: SolverConfig = SolverConfig()
    workers: int = 1  #: processes per nonlinear sweep (1: strict stepped-sine continuation)

    def directions(self) -> list[str]:
        return ["up", "down"] if self.solver.direction == "both" else [self.solver.direction]


@dataclass(frozen=True)
class TimeSeries:
    """A steady-state time series: t [s] from 0, states[:, 6] = x, xd, y, yd, d, dd, and diagnostics."""

    t: np.ndarray
    states: np.ndarray
    method: str
    converged: bool
    periods: int
    change: float
    amplitude: float


@dataclass(frozen=True)
class Engine:
    sweep: Callable[[BaseParams, TMDParams, np.ndarray, RunSettings, Callable | None], pd.DataFrame]
    time_series: Callable[[BaseParams, TMDParams, float, int, int, RunSettings], TimeSeries]
    description: str = ""


def uses_exact(tmd: TMDParams, settings: RunSettings) -> bool:
    """Whether a configuration is computed from the exact frequency response."""
    return tmd.is_linear and settings.solver.linear == "exact"


def _exact_table(base, tmd, omegas, settings, progress, engine) -> pd.DataFrame:
    t0 = time.perf_counter()
    amp = exact_amplitude(base, tmd, omegas)
    dt = (time.perf_counter() - t0) / max(len(omegas), 1)
    n = len(omegas)
    direction = "down" if settings.solver.direction == "down" else "up"  # no hysteresis: one branch
    if progress is not None:
        progress(n * len(settings.directions()))
    return pd.DataFrame(dict(engine=engine, method="exact", direction=direction, omega=np.asarray(omegas, float),
                             amplitude=amp, periods=0, converged=True, change=0.0, steps=0, rejected=0,
                             wall_time=dt))[list(SWEEP_COLUMNS)]


def _monolithic_sweep(base, tmd, omegas, settings: RunSettings, progress=None) -> pd.DataFrame:
    if uses_exact(tmd, settings):
        return _exact_table(base, tmd, omegas, settings, progress, "monolithic")
    res = sweep(base, tmd, omegas, direction=settings.solver.direction, settings=settings.solver.settings(),
                progress=progress, workers=settings.workers)
    table = res.table.copy()
    table.insert(0, "method", "steady_state")
    table.insert(0, "engine", "monolithic")
    return table[list(SWEEP_COLUMNS)]


def _monolithic_time_series(base, tmd, omega, n_periods, samples_per_period, settings: RunSettings) -> TimeSeries:
    if uses_exact(tmd, settings):
        T = 2.0 * np.pi / omega
        t = np.arange(n_periods * samples_per_period) * (T / samples_per_period)
        Z = exact_response(base, tmd, [omega])[0]
        states = np.real(Z[None, :] * np.exp(1j * omega * t)[:, None])
        return TimeSeries(t=t, states=states, method="exact", converged=True, periods=0, change=0.0,
                          amplitude=float(abs(Z[0])))
    t, states, ss = periodic_time_series(base, tmd, omega, n_periods=n_periods,
                                         samples_per_period=samples_per_period, settings=settings.solver.settings())
    return TimeSeries(t=t, states=states, method="steady_state", converged=bool(ss.converged), periods=int(ss.periods),
                      change=float(ss.change), amplitude=float(ss.amplitude))


#: registered engines; the CLI offers exactly these names
ENGINES: dict[str, Engine] = {
    "monolithic": Engine(_monolithic_sweep, _monolithic_time_series,
                         "exact frequency response (linear) / monolithic steady-state solver (nonlinear)"),
}


class EngineError(ValueError):
    """An unknown engine name."""


def _engine(name: str) -> Engine:
    try:
        return ENGINES[name]
    except KeyError:
        raise EngineError(f"unknown engine {name!r}; available: {sorted(ENGINES)}") from None


def compute_sweep(base: BaseParams, tmd: TMDParams, omegas, settings: RunSettings,
                  progress: Callable[[int], object] | None = None) -> pd.DataFrame:
    """Base amplitude [m] at each omega [rad/s] by the engine named in ``settings``.

    Returns a table with :data:`SWEEP_COLUMNS`; ``progress(n)`` is called as points finish
    (each omega of each direction counts one).
    """
    return _engine(settings.engine).sweep(base, tmd, np.asarray(omegas, dtype=float), settings, progress)


def compute_time_series(base: BaseParams, tmd: TMDParams, omega: float, n_periods: int, samples_per_period: int,
                        settings: RunSettings) -> TimeSeries:
    """Steady-state time series over n_periods at omega [rad/s] by the engine named in ``settings``."""
    return _engine(settings.engine).time_series(base, tmd, float(omega), int(n_periods), int(samples_per_period),
                                                settings)
