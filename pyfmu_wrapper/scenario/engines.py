"""Engines that compute frequency sweeps and steady-state time series for the scenario runner.

The single dispatch point is :func:`compute_sweep` (and :func:`compute_time_series` for phase
portraits). An engine is a pair of functions registered in :data:`ENGINES`:

* ``cosim`` (the default of ``run-scenario``): co-simulation of the model's FMUs (its unit's
  :class:`~pyfmu_wrapper.cosim.system.CosimEngine`: the paper's BaseOscillator and TMDInerter, a frame's,
  a pendulum's) by the master of :mod:`pyfmu_wrapper.master` for every configuration, linear ones
  included; steady state as the monolithic solver defines it (:mod:`pyfmu_wrapper.cosim.steady`).
* ``monolithic``: exact frequency response for linear configurations, the monolithic
  steady-state solver otherwise.
* ``both``: the co-simulation, held against the monolithic engine: the table has the
  co-simulated amplitude in ``amplitude``, the monolithic one in ``reference`` and the relative
  difference cosim / monolithic - 1 in ``difference``, with the monolithic point's own
  ``reference_irregular`` flag and window scatter ``reference_change`` (NaN for the single engines).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..errors import InputError
from ..models import MODELS
from ..models.solve import exact_amplitude, exact_response, periodic_time_series, sweep
from ..physics.params import TMDParams
from .names import DEFAULT_ENGINE as DEFAULT_ENGINE  # re-exported: the default of every caller
from .names import ENGINE_NAMES
from .schema import SolverConfig, SweepConfig
from .sweeptable import with_sweep_columns

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy import ndarray

    from ..cosim.settings import CosimSettings
    from ..physics.params import TMDParams
    from .schema import Scenario

#: the engine run-scenario uses unless told otherwise
#: a reference amplitude below this fraction of its curve's largest is zero to rounding: its
#: relative difference is reported as NaN
ZERO_REFERENCE = 1e-9


#: the engines that use each settings block of a scenario
BLOCK_USERS = {"sweep": ("cosim", "monolithic", "both"), "solver": ("monolithic", "both"), "cosim": ("cosim", "both")}


@dataclass(frozen=True)
class RunSettings:
    """What an engine needs besides the parameters: its name and the scenario's settings blocks.

    sweep: direction and continuation (every engine); solver: the monolithic engine's block (read
    by 'monolithic' and by 'both' for its reference); cosim: the co-simulation engine's
    :class:`~pyfmu_wrapper.cosim.settings.CosimSettings` (None: its defaults; read by 'cosim' and 'both').
    """

    engine: str = "monolithic"
    solver: SolverConfig = SolverConfig()
    cosim: object = None  #: pyfmu_wrapper.cosim.settings.CosimSettings (None: its defaults)
    workers: int = 1  #: processes per nonlinear sweep (1: strict stepped-sine continuation)
    sweep: SweepConfig = SweepConfig()

    @classmethod
    def for_scenario(
        cls, scn: Scenario, engine: str = "monolithic", workers: int = 1, cosim: CosimSettings | None = None
    ) -> RunSettings:
        """The settings of a scenario for ``engine``; ``cosim`` replaces the scenario's cosim block."""
        _engine(engine)
        unit = MODELS.of(scn.base)
        if engine in BLOCK_USERS["cosim"] and not unit.cosim:
            raise EngineError(
                f"engine {engine!r}: the co-simulation has no FMUs of model {unit.name!r} yet "
                f"({unit.description}); run it with --engine monolithic"
            )
        if cosim is None and engine in BLOCK_USERS["cosim"]:
            cosim = scn.cosim.settings()
        return cls(engine=engine, solver=scn.solver, cosim=cosim, workers=workers, sweep=scn.sweep)

    def directions(self) -> list[str]:
        return ["up", "down"] if self.sweep.direction == "both" else [self.sweep.direction]

    def used(self) -> dict:
        """The settings the engine actually uses, block by block (the others are absent), fully resolved."""
        from dataclasses import asdict

        out = dict(engine=self.engine, sweep=self.sweep.as_dict())
        if self.engine in BLOCK_USERS["solver"]:
            out["solver"] = dict(asdict(self.solver.settings()), linear=self.solver.linear)
        if self.engine in BLOCK_USERS["cosim"]:
            out["cosim"] = asdict(_cosim_settings(self))
        return out


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
    sweep: Callable[[Any, TMDParams, np.ndarray, RunSettings, Callable[..., Any] | None], pd.DataFrame]
    time_series: Callable[[Any, TMDParams, float, int, int, RunSettings], TimeSeries]
    description: str = ""


def uses_exact(base: Any, tmd: TMDParams, settings: RunSettings) -> bool:
    """Whether a configuration is computed from the exact frequency response (monolithic engine only)."""
    return settings.engine == "monolithic" and _mono_exact(base, tmd, settings)


def _mono_exact(base: Any, tmd: TMDParams, settings: RunSettings) -> bool:
    """The model unit says the configuration is linear and the settings ask for the exact path."""
    return settings.solver.linear == "exact" and MODELS.of(base).is_linear(base, tmd)


def _exact_table(
    base: Any,
    tmd: TMDParams,
    omegas: ndarray,
    settings: RunSettings,
    progress: Callable[..., Any] | None,
    engine: str,
) -> pd.DataFrame:
    t0 = time.perf_counter()
    amp = exact_amplitude(base, tmd, omegas)
    dt = (time.perf_counter() - t0) / max(len(omegas), 1)
    n = len(omegas)
    direction = "down" if settings.sweep.direction == "down" else "up"  # no hysteresis: one branch
    if progress is not None:  # closed form, instantaneous: not counted in the speed of an ETA
        getattr(progress, "skip", progress)(n * len(settings.directions()))
    omegas = np.asarray(omegas, float)
    return with_sweep_columns(
        pd.DataFrame(
            dict(
                engine=engine,
                method="exact",
                direction=direction,
                omega=omegas,
                amplitude=amp,
                amplitude_periodic=amp,
                periods=0,
                converged=True,
                irregular=False,
                change=0.0,
                steps=0,
                rejected=0,
                wall_time=dt,
                reference=np.nan,
                difference=np.nan,
                reference_irregular=np.nan,
                reference_change=np.nan,
            )
        )
    )


def _monolithic_sweep(
    base: Any,
    tmd: TMDParams,
    omegas: ndarray,
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
) -> pd.DataFrame:
    if _mono_exact(base, tmd, settings):
        return _exact_table(base, tmd, omegas, settings, progress, "monolithic")
    res = sweep(
        base,
        tmd,
        omegas,
        direction=settings.sweep.direction,
        settings=settings.solver.settings(),
        progress=progress,
        workers=settings.workers,
    )
    table = res.table.copy()
    table.insert(0, "method", "steady_state")
    table.insert(0, "engine", "monolithic")
    table["reference"] = np.nan
    table["difference"] = np.nan
    table["reference_irregular"] = np.nan
    table["reference_change"] = np.nan
    return with_sweep_columns(table)


def _monolithic_time_series(
    base: Any, tmd: TMDParams, omega: float, n_periods: int, samples_per_period: int, settings: RunSettings
) -> TimeSeries:
    if _mono_exact(base, tmd, settings):
        T = 2.0 * np.pi / omega
        t = np.arange(n_periods * samples_per_period) * (T / samples_per_period)
        Z = exact_response(base, tmd, [omega])[0]
        states = np.real(Z[None, :] * np.exp(1j * omega * t)[:, None])
        return TimeSeries(
            t=t, states=states, method="exact", converged=True, periods=0, change=0.0, amplitude=float(abs(Z[0]))
        )
    t, states, ss = periodic_time_series(
        base,
        tmd,
        omega,
        n_periods=n_periods,
        samples_per_period=samples_per_period,
        settings=settings.solver.settings(),
    )
    return TimeSeries(
        t=t,
        states=states,
        method="steady_state",
        converged=bool(ss.converged),
        periods=int(ss.periods),
        change=float(ss.change),
        amplitude=float(ss.amplitude),
    )


def _cosim_settings(settings: RunSettings) -> Any:
    """The co-simulation settings of a run (its own block only: nothing is read from ``solver``)."""
    from ..cosim.settings import CosimSettings

    return settings.cosim if settings.cosim is not None else CosimSettings()


def cosim_engine(base: Any) -> Any:
    """The co-simulation of a structure's model, as its unit holds it
    (:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.cosim`: a :class:`~pyfmu_wrapper.cosim.system.CosimEngine`
    with ``sweep`` and optionally ``periodic_time_series`` (phase portraits), ``refusal`` (the frequencies its
    time scales cannot step, for an up-front refusal) and ``steps_at``); no model is named here. None: the
    model has none."""
    load = MODELS.of(base).cosim
    return load() if load is not None else None


def prepare_cosim(structures: Iterable[Any], settings: RunSettings) -> list[str]:
    """Build, or check, the FMUs of the co-simulation of each structure's model once, here, before any sweep starts
    (the workers, forked from this process, then find them built and their modules imported, instead of each
    building or hashing them at once): the names of the FMUs; none for an engine that does not co-simulate."""
    if settings.engine not in BLOCK_USERS["cosim"]:
        return []
    cs = _cosim_settings(settings)
    names: list[str] = []
    for unit in dict.fromkeys(MODELS.of(s) for s in structures):
        engine = unit.cosim() if unit.cosim is not None else None
        if engine is not None and engine.prepare is not None:
            names += [n for n in engine.prepare(cs) if n not in names]
    return names


def peak_refiner(base: Any, tmd: TMDParams, settings: RunSettings) -> tuple[Callable[..., Any] | None, bool]:
    """How a curve's peak is refined between its grid points (:func:`.sweeptable.find_peaks`): (amplitudes at
    given frequencies, whether only the curve's highest maximum is refined), or (None, False): not refined.

    * the monolithic engine's linear configurations: the exact response at every local maximum;
    * the co-simulation's linear configurations (one periodic state per frequency): the co-simulation itself at
      extra frequencies around the curve's highest maximum only (:class:`~pyfmu_wrapper.cosim.steady.PointSolver`:
      co-simulated steady states on one master, by continuation; a point that does not converge counts as no
      amplitude; the caller closes it);
    * a nonlinear configuration is not refined: its response may jump or rattle between grid points, where a
      point solved alone need not be on the curve's branch (its peak is the grid's)."""
    if uses_exact(base, tmd, settings):
        return (lambda x: exact_amplitude(base, tmd, x)), False
    engine = cosim_engine(base) if settings.engine == "cosim" else None
    if engine is not None and engine.points is not None and MODELS.of(base).is_linear(base, tmd):
        return engine.points(base, tmd, _cosim_settings(settings)), True
    return None, False


def _cosim_system(base: Any) -> Callable[..., pd.DataFrame]:
    """The co-simulation sweep of a structure's model (:func:`cosim_engine`)."""
    sweep: Callable[..., pd.DataFrame] = cosim_engine(base).sweep
    return sweep


def _cosim_sweep(
    base: Any, tmd: TMDParams, omegas: ndarray, settings: RunSettings, progress: Callable[..., Any] | None = None
) -> pd.DataFrame:
    cs = _cosim_settings(settings)
    table = _cosim_system(base)(
        base, tmd, omegas, direction=settings.sweep.direction, settings=cs, progress=progress, workers=settings.workers
    )
    table.insert(0, "method", cs.method)
    table.insert(0, "engine", "cosim")
    table["reference"] = np.nan
    table["difference"] = np.nan
    table["reference_irregular"] = np.nan
    table["reference_change"] = np.nan
    return with_sweep_columns(table)


def _both_sweep(
    base: Any, tmd: TMDParams, omegas: ndarray, settings: RunSettings, progress: Callable[..., Any] | None = None
) -> pd.DataFrame:
    """Co-simulation and monolithic engine; the co-simulated rows carry the monolithic amplitude
    ('reference') and the relative difference cosim / monolithic - 1 ('difference'; NaN where the
    reference is zero to rounding, :data:`ZERO_REFERENCE`)."""
    half = None if progress is None else _Half(progress)  # each engine's points count one half
    co = _cosim_sweep(base, tmd, omegas, settings, half)
    mono = _monolithic_sweep(base, tmd, omegas, settings, half)
    ref = {(d, float(w)): i for i, (d, w) in enumerate(zip(mono["direction"], mono["omega"]))}
    # the exact response has a single branch ('up' or 'down'): use it for both directions
    one = {float(w): i for i, w in enumerate(mono["omega"])}
    rows = [ref.get((d, float(w)), one.get(float(w))) for d, w in zip(co["direction"], co["omega"])]

    def pick(col: str, missing: float = np.nan) -> list[Any]:
        v = mono[col].to_numpy()
        return [v[i] if i is not None else missing for i in rows]

    co["reference"] = pick("amplitude")
    co["reference_irregular"] = [
        float(bool(x)) if not (isinstance(x, float) and np.isnan(x)) else np.nan for x in pick("irregular")
    ]
    co["reference_change"] = np.asarray(pick("change"), float)
    co["difference"] = co["amplitude"] / co["reference"] - 1.0
    # a reference that is zero to rounding (the undamped ideal inerter's antiresonance, ~1e-16 m
    # against a peak of ~0.1 m) has no relative difference: NaN there, not 1e10
    for _, rows in co.groupby("direction"):
        ref_abs = rows["reference"].abs()
        zero = rows.index[ref_abs <= ZERO_REFERENCE * ref_abs.max()]
        co.loc[zero, "difference"] = np.nan
    co["engine"] = "both"
    co["wall_time"] = co["wall_time"].to_numpy()  # co-simulation time per point
    return with_sweep_columns(co)


class _Half:
    """progress(n) of one of the two engines of 'both': each of its points is half a table row."""

    def __init__(self, progress: Callable) -> None:
        self.progress = progress

    def __call__(self, n: int) -> None:
        self.progress(0.5 * n)

    def skip(self, n: int) -> None:
        getattr(self.progress, "skip", self.progress)(0.5 * n)


def _cosim_time_series(
    base: Any, tmd: TMDParams, omega: float, n_periods: int, samples_per_period: int, settings: RunSettings
) -> TimeSeries:
    from dataclasses import replace as _replace

    engine = cosim_engine(base)
    cosim_series = None if engine is None else engine.periodic_time_series
    if cosim_series is None or engine.steps_at is None:
        raise EngineError(f"the co-simulated phase portrait is not written for model {MODELS.of(base).name!r}")

    cs = _cosim_settings(settings)
    # record at the communication points: at least the requested samples per period
    n = max(int(samples_per_period), engine.steps_at(base, tmd, omega, cs))  # the structure's step too
    t, states, ss = cosim_series(base, tmd, omega, n_periods, None, _replace(cs, steps_per_period=n))
    if n != samples_per_period:  # resample to the requested grid (cubic Hermite on x, xd; linear otherwise)
        T = 2.0 * np.pi / omega
        tt = np.arange(n_periods * samples_per_period) * (T / samples_per_period)
        states = np.column_stack([np.interp(tt, t, states[:, j]) for j in range(states.shape[1])])
        t = tt
    return TimeSeries(
        t=t,
        states=states,
        method=cs.method,
        converged=bool(ss.converged),
        periods=int(ss.periods),
        change=float(ss.change),
        amplitude=float(ss.amplitude),
    )


#: registered engines; the CLI offers exactly these names
ENGINES: dict[str, Engine] = {
    "cosim": Engine(
        _cosim_sweep,
        _cosim_time_series,
        "co-simulation of the model's FMUs (the paper's BaseOscillator and TMDInerter; pyfmu_wrapper.cosim)",
    ),
    "monolithic": Engine(
        _monolithic_sweep,
        _monolithic_time_series,
        "exact frequency response (linear) / monolithic steady-state solver (nonlinear)",
    ),
    "both": Engine(
        _both_sweep, _cosim_time_series, "co-simulation held against the monolithic engine (difference per frequency)"
    ),
}
assert tuple(sorted(ENGINES)) == ENGINE_NAMES, "scenario/names.py lists the engines the command line offers"


class EngineError(InputError):
    """An unknown engine name."""


def _engine(name: str) -> Engine:
    try:
        return ENGINES[name]
    except KeyError:
        raise EngineError(f"unknown engine {name!r}; available: {sorted(ENGINES)}") from None


def compute_sweep(
    base: Any,
    tmd: TMDParams,
    omegas: Sequence[float] | ndarray,
    settings: RunSettings,
    progress: Callable[[int], object] | None = None,
) -> pd.DataFrame:
    """Base amplitude [m] at each omega [rad/s] by the engine named in ``settings``.

    Returns a table with :data:`SWEEP_COLUMNS`; ``progress(n)`` is called as points finish
    (each omega of each direction counts one).
    """
    return _engine(settings.engine).sweep(base, tmd, np.asarray(omegas, dtype=float), settings, progress)


def compute_time_series(
    base: Any, tmd: TMDParams, omega: float, n_periods: int, samples_per_period: int, settings: RunSettings
) -> TimeSeries:
    """Steady-state time series over n_periods at omega [rad/s] by the engine named in ``settings``."""
    return _engine(settings.engine).time_series(
        base, tmd, float(omega), int(n_periods), int(samples_per_period), settings
    )
