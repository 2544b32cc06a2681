"""What a sweep table is (its columns, :data:`SWEEP_COLUMNS`, the same for every engine) and what it
says: its peaks (:func:`find_peaks`), its steady-state diagnostics, its irregular points, and (engine
'both') the co-simulation's difference from the monolithic engine per frequency."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

if TYPE_CHECKING:
    from collections.abc import Callable

    from pandas import Series


#: columns of every sweep table (one row per direction and omega)
SWEEP_COLUMNS = (
    "engine",
    "method",
    "direction",
    "omega",
    "amplitude",
    "amplitude_periodic",
    "periods",
    "converged",
    "irregular",
    "change",
    "steps",
    "rejected",
    "wall_time",
    "reference",
    "difference",
    "reference_irregular",
    "reference_change",
    "fmu_time_base",
    "fmu_time_tmd",
    "master_loop_time",
    "python_step_time",
    "coupling_error",
    "reason",
)
#: co-simulation only (NaN for the monolithic engine): ``coupling_error``, the estimated relative
#: amplitude error of the coupling (step doubling, ``cosim.checked``), and ``reason``, why a point is
#: not converged (``cosim.steady.steady_state``); and the seconds inside the FMUs' fmi2 calls of the
#: compiled stepping loop by role (``fmu_time_base``: the structure's FMU, ``fmu_time_tmd``: the absorber's,
#: whatever each model names its instances), the loop's own work, and the steps taken on the Python path
#: (``cosim.steady._time_split``); the rest of ``wall_time`` is the steady-state logic
#: ``amplitude_periodic``: max |x - mean| over one period of the harmonic series fitted to x over the point's
#: final steady windows (:meth:`~pyfmu_wrapper.solvers.steady.WindowCriterion.periodic`: the periodic part of a
#: rattling play chain, whose ``amplitude``, the largest window maximum, also holds its non-periodic motion),
#: as the diagnosis takes a steady record's amplitude; the amplitude itself for the exact response
TIMING_COLUMNS = ("fmu_time_base", "fmu_time_tmd", "master_loop_time", "python_step_time")


def with_sweep_columns(table: pd.DataFrame) -> pd.DataFrame:
    """The table with exactly :data:`SWEEP_COLUMNS`; a column an engine does not fill (the timing split
    of the monolithic engine, of the Python stepping path) is NaN."""
    for col in SWEEP_COLUMNS:
        if col not in table:
            table[col] = np.nan
    return table[list(SWEEP_COLUMNS)]


def find_peaks(
    omegas: Series, amplitudes: Series, refine: Callable[..., Any] | None = None, highest_only: bool = False
) -> dict:
    """Peak summary of one curve: global maximum and the interior local maxima (``refined``: whether the
    global maximum was located between grid points).

    refine: optional callable(omegas array) -> amplitudes for a curve with one state per frequency (the
    exact response, a linear co-simulation); each local maximum (``highest_only``: the highest one) is then
    located between its grid neighbours (to 1e-9 rad/s; a co-simulated one to 1e-6 of its frequency) instead
    of on the grid. A refined value below the grid's (or NaN: not converged) leaves the grid point.
    """
    w = np.asarray(omegas, float)
    a = np.asarray(amplitudes, float)
    finite = np.isfinite(a)  # a point the co-simulation refused has no amplitude (NaN): not a peak
    if not finite.any():
        return dict(peak_amplitude=None, peak_omega=None, local_maxima=[])
    w, a = w[finite], a[finite]
    local = []
    interior = [i for i in range(1, len(a) - 1) if a[i] >= a[i - 1] and a[i] > a[i + 1]]
    top = max(interior, key=lambda i: a[i]) if interior else -1
    refined = False
    for i in interior:
        wi, ai = w[i], a[i]
        if refine is not None and (i == top or not highest_only):

            def neg(x: float, grid: float = float(ai)) -> float:
                v = float(refine(np.array([x]))[0])
                return -v if np.isfinite(v) else -grid

            r = minimize_scalar(
                neg,
                bounds=(w[i - 1], w[i + 1]),
                method="bounded",
                options=dict(xatol=1e-6 * w[i] if highest_only else 1e-9),
            )
            if -r.fun >= ai:
                wi, ai = float(r.x), float(-r.fun)
                refined = refined or i == top
        local.append(dict(omega=float(wi), amplitude=float(ai)))
    k = int(np.argmax(a))
    best = dict(omega=float(w[k]), amplitude=float(a[k]))
    for p in local:
        if p["amplitude"] >= best["amplitude"]:
            best = dict(p)
    return dict(peak_amplitude=best["amplitude"], peak_omega=best["omega"], local_maxima=local, peak_refined=refined)


def sweep_diagnostics(t: pd.DataFrame) -> dict:
    return dict(
        method=str(t["method"].iloc[0]),
        all_converged=bool(t["converged"].all()),
        not_converged=int((~t["converged"].astype(bool)).sum()),
        irregular=int(t["irregular"].fillna(False).astype(bool).sum()) if "irregular" in t else 0,
        periods_min=int(t["periods"].min()),
        periods_max=int(t["periods"].max()),
        periods_mean=float(t["periods"].mean()),
        max_change=float(t["change"].max()),
        wall_time=float(t["wall_time"].sum()),
        **_reasons(t),
    )


def _reasons(t: pd.DataFrame) -> dict:
    """``not_converged_reasons``: omega and reason of each point reported not converged with a reason
    (the co-simulation's coupling-error check and refusals; absent when there is none)."""
    if "reason" not in t:
        return {}
    out = [
        dict(omega=float(w), reason=str(r))
        for w, r, c in zip(t["omega"], t["reason"], t["converged"])
        if not bool(c) and isinstance(r, str) and r
    ]
    return dict(not_converged_reasons=out) if out else {}


def irregular_mask(t: pd.DataFrame) -> np.ndarray:
    """Points whose response is irregular (rattling, non-periodic) in either engine."""
    irr = t["irregular"].fillna(False).astype(bool).to_numpy() if "irregular" in t else np.zeros(len(t), bool)
    if "reference_irregular" in t:
        irr = irr | (t["reference_irregular"].to_numpy(float) == 1.0)
    return irr


def engine_differences(t: pd.DataFrame) -> dict:
    """Engine 'both': the relative difference co-simulation / monolithic - 1 per frequency; the
    headline maximum is over the points *both engines call regular* only: converged and periodic (an
    irregular point has no single amplitude: it is listed apart with the window scatter of each
    engine; a point the co-simulation reports not converged is counted apart, with its own largest
    difference)."""
    if "reference" not in t or not np.isfinite(t["reference"].to_numpy(float)).any():
        return {}
    d = t["difference"].to_numpy(float)
    w = t["omega"].to_numpy(float)
    irr = irregular_mask(t)
    conv = t["converged"].fillna(False).astype(bool).to_numpy() if "converged" in t else np.ones(len(t), bool)
    reg = np.where(irr | ~conv | ~np.isfinite(d), np.nan, np.abs(d))
    out: dict[str, Any] = dict(regular_points=int(np.isfinite(reg).sum()))
    nc = np.where(~irr & ~conv & np.isfinite(d), np.abs(d), np.nan)
    out["not_converged_points"] = int(np.isfinite(nc).sum())
    out["max_abs_difference_not_converged"] = float(np.nanmax(nc)) if np.isfinite(nc).any() else None
    if np.isfinite(reg).any():
        k = int(np.nanargmax(reg))
        out.update(max_abs_difference=float(reg[k]), omega_max_difference=float(w[k]))
    else:
        out.update(max_abs_difference=None, omega_max_difference=None)
    ref_change = t["reference_change"].to_numpy(float) if "reference_change" in t else np.full(len(t), np.nan)
    out["irregular_points"] = [
        dict(
            omega=float(w[i]),
            difference=float(d[i]) if np.isfinite(d[i]) else None,
            scatter=float(t["change"].iloc[i]),
            reference_scatter=float(ref_change[i]),
        )
        for i in np.flatnonzero(irr)
    ]
    out["difference"] = [
        dict(
            omega=float(wi),
            cosim=float(a),
            monolithic=float(r),
            difference=float(x) if np.isfinite(x) else None,
            irregular=bool(ir),
        )
        for wi, a, r, x, ir in zip(w, t["amplitude"], t["reference"], d, irr)
    ]
    return out
