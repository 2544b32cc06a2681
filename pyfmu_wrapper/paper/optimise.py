"""One-parameter optimisation of the TMD against a named objective (see docs/optimisation.md).

The paper (Brzeski & Perlikowski 2017, Sects. 4-5) quotes optimised values of the TMD damping c
and of the dry-friction force df without saying what was optimised. The objective that
reproduces all six of them is the **H2 norm of the base displacement**, the integral over
frequency of the squared steady-state amplitude of the base, ``J = int |X(w)|^2 dw``:

==========  ======  ===========  ======
quantity    paper   this module  error
==========  ======  ===========  ======
c, Case 1   56.38   56.45        +0.1 %
c, Case 2   31.73   31.74        +0.0 %
c, Case 3   6.45    6.34         -1.7 %
df, Case 1  45.78   45.72        -0.1 %
df, Case 2  37.65   37.79        +0.4 %
df, Case 3  15.44   15.45        +0.0 %
==========  ======  ===========  ======

(c: objective ``h2``, exact over all frequencies; df: objective ``h2`` over 15..25 rad/s with the
nonlinear solver, 101 frequencies, sweep up or down; with 401 frequencies 45.80, 37.70, 15.4-15.5.)
The min-max of the peak amplitude (objective ``peak``), the obvious guess, is off by 23-55 %.
The table of all the candidates tried is in docs/optimisation.md (benchmarks/bench_optimise.py).

Objectives: the registry :data:`~.objectives.OBJECTIVES` of :mod:`.objectives` (``peak``, ``mean``,
``mean_square``, ``h2``, ``peak_relative``).

Linear configurations (no friction, no gap) use the exact frequency response; the others use
stepped-sine sweeps of the monolithic solver (:func:`pyfmu_wrapper.solvers.sweep.sweep`).
The optimiser scans the bounds on a coarse grid, then refines the best bracket with Brent's
bounded method (:func:`scipy.optimize.minimize_scalar`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..physics.params import BaseParams, ParameterError, TMDParams, field_names
from ..solvers.monolithic import SolverSettings
from .objectives import Objective, OptimisationError, get_objective, linear_response

if TYPE_CHECKING:
    import pandas as pd

#: default search bounds per parameter (the ranges of the paper's maps, Figs. 3-4)
DEFAULT_BOUNDS = {"damping": (0.0, 100.0), "friction_force": (0.0, 100.0)}

#: default settings for nonlinear evaluations (a 101-point dry-friction FRC in ~0.5 s)
FAST_SETTINGS = SolverSettings(rtol=1e-7, atol_scale=1e-7, tol=1e-5)


# --- parameters ---------------------------------------------------------------------------------


def split_parameter(parameter: str) -> tuple[str, str]:
    """'tmd.damping' -> ('tmd', 'damping'); a bare TMD field name means the TMD."""
    owner, _, name = parameter.rpartition(".")
    owner = owner or "tmd"
    if owner not in ("tmd", "base"):
        raise OptimisationError(f"parameter must be tmd.<field> or base.<field>, got {parameter!r}")
    names = field_names(TMDParams if owner == "tmd" else BaseParams)
    if name not in names or name == "inerter":
        raise OptimisationError(f"unknown {owner} parameter {name!r}; known: {[n for n in names if n != 'inerter']}")
    return owner, name


def with_parameter(base: BaseParams, tmd: TMDParams, parameter: str, value: float) -> tuple[BaseParams, TMDParams]:
    owner, name = split_parameter(parameter)
    if owner == "tmd":
        return base, replace(tmd, **{name: float(value)})  # type: ignore[arg-type]
    return replace(base, **{name: float(value)}), tmd  # type: ignore[arg-type]


# --- evaluation ---------------------------------------------------------------------------------


@dataclass
class Evaluator:
    """Objective of one configuration; picks the exact response or a sweep, and caches."""

    base: BaseParams
    tmd: TMDParams
    parameter: str
    objective: Objective
    omegas: np.ndarray
    direction: str = "up"
    settings: SolverSettings = FAST_SETTINGS
    linear: str = "exact"  #: 'exact' or 'simulate' (sweep linear configurations too)
    workers: int = 1
    use_exact: bool = True  #: use objective.exact for linear configurations (False: band integral everywhere)
    curves: dict | None = None  #: optional shared cache value -> (amplitude, method, converged)
    rows: list = field(default_factory=list)
    _cache: dict = field(default_factory=dict, repr=False)

    def curve(self, value: float) -> tuple[np.ndarray, str, bool]:
        """(amplitude curve on self.omegas, method, all converged) at a parameter value."""
        if self.curves is not None:
            key = (self.objective.relative, round(float(value), 12))
            if key not in self.curves:
                self.curves[key] = self._curve(value)
            return self.curves[key]
        return self._curve(value)

    def _curve(self, value: float) -> tuple[np.ndarray, str, bool]:
        base, tmd = with_parameter(self.base, self.tmd, self.parameter, value)
        if tmd.is_linear and self.linear == "exact":
            X, R = linear_response(base, tmd, self.omegas)
            return np.abs(R if self.objective.relative else X), "exact", True
        if self.objective.relative:
            raise OptimisationError(
                f"objective {self.objective.name!r} needs a linear configuration "
                "(exact frequency response); this one is nonlinear"
            )
        from ..models.solve import sweep

        tab = sweep(base, tmd, self.omegas, self.direction, self.settings, workers=self.workers).table
        amp = tab.groupby("omega")["amplitude"].max()  # 'both': the envelope of the two branches
        amp = amp.reindex(np.sort(self.omegas)).to_numpy()
        return amp, "sweep", bool(tab["converged"].all())

    def __call__(self, value: float) -> float:
        key = round(float(value), 12)
        if key in self._cache:
            return self._cache[key]
        t0 = time.perf_counter()
        base, tmd = with_parameter(self.base, self.tmd, self.parameter, value)
        exact = self.objective.exact
        if self.use_exact and exact is not None and tmd.is_linear and self.linear == "exact":
            J, method, conv = exact(base, tmd), "exact", True
        else:
            amp, method, conv = self.curve(value)
            J = self.objective.reduce(np.sort(self.omegas), amp)
        self._cache[key] = J
        self.rows.append(
            dict(value=float(value), objective=J, method=method, converged=conv, wall_time=time.perf_counter() - t0)
        )
        return J


@dataclass
class OptimisationResult:
    """Outcome of :func:`optimise`."""

    parameter: str
    objective: str
    value: float  #: the optimal parameter value
    objective_value: float
    bounds: tuple[float, float]
    band: tuple[float, float] | None  #: None when the objective was evaluated exactly over all frequencies
    evaluations: pd.DataFrame  #: value, objective, method, converged, wall_time (in evaluation order)
    at_bound: bool  #: the optimum sits on a bound (widen the bounds)
    wall_time: float

    @property
    def n_evaluations(self) -> int:
        return len(self.evaluations)

    def summary(self) -> str:
        band = "all frequencies (exact)" if self.band is None else f"{self.band[0]:g}..{self.band[1]:g} rad/s"
        flag = "  [at a bound: widen --bounds]" if self.at_bound else ""
        return (
            f"{self.parameter} = {self.value:.6g}  ({self.objective} = {self.objective_value:.6g} over {band}; "
            f"{self.n_evaluations} evaluations, {self.wall_time:.1f} s){flag}"
        )


def frequency_grid(band: Sequence[float], points: int) -> np.ndarray:
    lo, hi = float(band[0]), float(band[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise OptimisationError(f"band must be 0 < LO < HI [rad/s], got {band!r}")
    if int(points) < 2:
        raise OptimisationError(f"points must be >= 2, got {points!r}")
    return np.linspace(lo, hi, int(points))


@dataclass(frozen=True)
class OptimiseConfig:
    """How :func:`optimise` searches and measures.

    band: (lo, hi) [rad/s] sampled at ``points`` frequencies (default 2001 for linear
      configurations, 101 for nonlinear ones), or give ``omegas`` explicitly;
    bounds: (lo, hi) of the parameter (default :data:`DEFAULT_BOUNDS`);
    direction: sweep direction for nonlinear configurations, 'up', 'down' or 'both' (then the
      pointwise larger amplitude of the two branches is used);
    settings: the monolithic solver's settings for nonlinear configurations (default FAST_SETTINGS);
    linear: 'exact' or 'simulate' (sweep linear configurations too);
    scan: points of the coarse scan (default 41 for linear, 11 for nonlinear);
    xtol: absolute tolerance on the parameter (default 1e-6 (hi - lo) linear, 1e-3 (hi - lo) nonlinear);
    workers: processes per nonlinear sweep.
    """

    band: tuple = (15.0, 25.0)
    bounds: tuple | None = None
    omegas: object = None
    points: int | None = None
    direction: str = "up"
    settings: SolverSettings | None = None
    linear: str = "exact"
    scan: int | None = None
    xtol: float | None = None
    workers: int = 1


def optimise(
    base: BaseParams,
    tmd: TMDParams,
    parameter: str,
    objective: str | Objective = "h2",
    config: OptimiseConfig | None = None,
    *,
    progress: Callable[[float, float], Any] | None = None,
    curve_cache: dict[Any, Any] | None = None,
) -> OptimisationResult:
    """Minimise ``objective`` over one parameter of the base or the TMD.

    parameter: 'tmd.damping', 'tmd.friction_force', ... (a bare name means the TMD);
    objective: a name in :data:`OBJECTIVES` or an :class:`Objective`;
    config: band, bounds, frequencies, solver and search settings (:class:`OptimiseConfig`; None: defaults);
    progress: optional callable(value, objective) after each evaluation;
    curve_cache: optional dict shared between calls that differ only in the objective (same base,
      tmd, parameter, omegas, direction, settings): the computed amplitude curves are kept there.

    If either bound makes the configuration nonlinear, every value (linear ones included, e.g.
    df = 0) is measured on the same band, so that the objective is one function of the parameter.
    """
    cfg = config if config is not None else OptimiseConfig()
    if not isinstance(cfg, OptimiseConfig):
        raise OptimisationError(f"config must be an OptimiseConfig, got {type(cfg).__name__}")
    band, bounds, omegas, points, direction = cfg.band, cfg.bounds, cfg.omegas, cfg.points, cfg.direction
    settings, linear, scan, xtol, workers = cfg.settings, cfg.linear, cfg.scan, cfg.xtol, cfg.workers
    obj = get_objective(objective)
    owner, name = split_parameter(parameter)
    parameter = f"{owner}.{name}"
    if bounds is None:
        if owner != "tmd" or name not in DEFAULT_BOUNDS:
            raise OptimisationError(
                f"give bounds for {parameter} (defaults exist for {['tmd.' + k for k in DEFAULT_BOUNDS]})"
            )
        bounds = DEFAULT_BOUNDS[name]
    lo, hi = float(bounds[0]), float(bounds[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise OptimisationError(f"bounds must be LO < HI, got {bounds!r}")
    if direction not in ("up", "down", "both"):
        raise OptimisationError(f"direction must be 'up', 'down' or 'both', got {direction!r}")
    if linear not in ("exact", "simulate"):
        raise OptimisationError(f"linear must be 'exact' or 'simulate', got {linear!r}")
    # validate the end points (raises ParameterError for non-physical values)
    try:
        b_lo, t_lo = with_parameter(base, tmd, parameter, lo)
        b_hi, t_hi = with_parameter(base, tmd, parameter, hi)
    except ParameterError as exc:
        raise OptimisationError(f"bounds {bounds!r}: {exc}") from None
    nonlinear = not (t_lo.is_linear and t_hi.is_linear) or linear == "simulate"
    used_band: tuple[float, float] | None  # the band of the objective (None: exact over all frequencies)
    if omegas is None:
        omegas = frequency_grid(band, points if points is not None else (101 if nonlinear else 2001))
        used_band = (float(band[0]), float(band[1]))
    else:
        omegas = np.sort(np.asarray(omegas, dtype=float))
        if omegas.size < 1 or not np.all(omegas > 0):
            raise OptimisationError("omegas must be positive frequencies [rad/s]")
        used_band = (float(omegas[0]), float(omegas[-1]))
    if obj.exact is not None and not nonlinear:
        used_band = None
    ev = Evaluator(
        base,
        tmd,
        parameter,
        obj,
        omegas,
        direction,
        settings or FAST_SETTINGS,
        linear,
        workers,
        use_exact=not nonlinear,
        curves=curve_cache,
    )

    def f(v: float) -> float:
        J = ev(v)
        if progress is not None:
            progress(float(v), J)
        return J

    t0 = time.perf_counter()
    n_scan = int(scan) if scan else (11 if nonlinear else 41)
    grid = np.linspace(lo, hi, max(n_scan, 3))
    vals = np.array([f(v) for v in grid])
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    tol = xtol if xtol is not None else (1e-3 if nonlinear else 1e-6) * (hi - lo)
    from scipy.optimize import minimize_scalar  # imported when optimising: checking the command line costs nothing

    res = minimize_scalar(f, bounds=(a, b), method="bounded", options=dict(xatol=tol))
    best_v, best_J = (float(res.x), float(res.fun)) if res.fun <= vals[i] else (float(grid[i]), float(vals[i]))
    at_bound = best_v - lo <= 2 * tol or hi - best_v <= 2 * tol
    return OptimisationResult(
        parameter=parameter,
        objective=obj.name,
        value=best_v,
        objective_value=best_J,
        bounds=(lo, hi),
        band=used_band,
        evaluations=_frame(ev.rows),
        at_bound=bool(at_bound),
        wall_time=time.perf_counter() - t0,
    )


def _frame(rows: Any) -> pd.DataFrame:
    import pandas as pd

    return pd.DataFrame(rows)
