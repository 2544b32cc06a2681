"""Compute the studies of a scenario (no files, no plotting: see :mod:`.output` and ``plots``).

Each study gives a data object: :class:`FRCData` (a long sweep table, one block per curve),
:class:`MapData` (amplitude[value, omega]) or :class:`PhaseData` (time series per omega and curve).
Identical (parameters, frequencies) sweeps are computed once per run and shared between studies.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

from ..physics.params import as_dict
from ..solvers.frequency_response import exact_amplitude
from .engines import RunSettings, compute_sweep, compute_time_series, uses_exact
from .executors import Checkpoint, SweepTask, TaskStats, run_task, run_tasks
from .schema import FRCStudy, MapStudy, PhasePortraitStudy, Scenario


@dataclass
class FRCData:
    study: FRCStudy
    table: pd.DataFrame  #: SWEEP_COLUMNS plus 'curve' (the label)
    peaks: dict  #: label -> {direction -> peak summary}
    wall_time: float = 0.0


@dataclass
class MapData:
    study: MapStudy
    amplitude: np.ndarray  #: [len(values), len(omegas)], max over the sweep directions [m]
    table: pd.DataFrame  #: long table: SWEEP_COLUMNS plus 'value'
    wall_time: float = 0.0


@dataclass
class PhaseData:
    study: PhasePortraitStudy
    series: dict = field(default_factory=dict)  #: (omega, label) -> TimeSeries
    wall_time: float = 0.0


def work_units(scn: Scenario, settings: RunSettings) -> int:
    """Number of progress units a run reports (one per frequency point and direction)."""
    nd = len(settings.directions())
    n = 0
    for st in scn.studies:
        if isinstance(st, FRCStudy):
            n += len(st.curves) * len(st.omegas) * nd
        elif isinstance(st, MapStudy):
            n += len(st.values) * len(st.omegas) * nd
        else:
            n += len(st.omegas) * len(st.curves)
    return n


def instant_units(scn: Scenario, settings: RunSettings) -> int:
    """Progress units of a run that cost (almost) nothing: sweeps computed in closed form (the exact
    response of linear configurations with the monolithic engine) and sweeps that repeat one computed
    earlier in the run (shared between studies). An ETA leaves them out of the work still to do."""
    nd = len(settings.directions())
    seen, n = set(), 0
    for st in scn.studies:
        if isinstance(st, FRCStudy):
            tmds = [c.tmd for c in st.curves]
        elif isinstance(st, MapStudy):
            tmds = list(st.tmds)
        else:
            continue
        for tmd in tmds:
            key = (tmd, np.asarray(st.omegas, float).tobytes())
            if key in seen or uses_exact(tmd, settings):
                n += len(st.omegas) * nd
            seen.add(key)
    return n


class _Cache:
    """Sweeps already computed in this run, keyed by (parameters, frequencies).

    Nonlinear sweeps not yet computed go to the executor (:mod:`.executors`; None: computed here,
    in order) and through the study's checkpoint folder, so a killed run resumes where it stopped.
    """

    def __init__(self, executor=None, checkpoint_dir=None, resume=True, checkpoint_marker=None):
        self.resume = resume
        self.checkpoint_marker = checkpoint_marker
        self.tables = {}
        self.executor = executor
        self.checkpoint_dir = None if checkpoint_dir is None else Path(checkpoint_dir)
        self.stats = {}  #: study name -> TaskStats

    def sweep(self, base, tmd, omegas, settings, progress):
        key = (tmd, np.asarray(omegas, float).tobytes())
        if key in self.tables:
            if progress is not None:
                getattr(progress, "skip", progress)(len(omegas) * len(settings.directions()))
            return self.tables[key]
        if settings.sweep.continuation or uses_exact(tmd, settings):
            table = compute_sweep(base, tmd, omegas, settings, progress)
        else:  # independent points from the linear guess: same task function as the executors
            task = SweepTask(base, tmd, np.asarray(omegas, float), settings)
            table = run_task(task)
            if progress is not None:
                progress(task.units())
        self.tables[key] = table
        return table

    def sweeps(self, base, tmds, omegas, settings, progress, study_name) -> list:
        """Tables of several configurations over the same frequencies, in order."""
        omegas = np.asarray(omegas, float)
        out = [None] * len(tmds)
        todo: dict[tuple, list[int]] = {}  # key -> indices (identical configurations are computed once)
        for i, tmd in enumerate(tmds):
            key = (tmd, omegas.tobytes())
            if key in self.tables:
                out[i] = self.tables[key]
                if progress is not None:  # computed earlier in this run: not in the speed of an ETA
                    getattr(progress, "skip", progress)(len(omegas) * len(settings.directions()))
            elif uses_exact(tmd, settings) or (self.executor is None and self.checkpoint_dir is None):
                out[i] = self.sweep(base, tmd, omegas, settings, progress)
            else:
                todo.setdefault(key, []).append(i)
        if todo:
            keys = list(todo)
            tasks = [SweepTask(base, k[0], omegas, settings) for k in keys]
            ckpt = None if self.checkpoint_dir is None else Checkpoint(self.checkpoint_dir / study_name, self.resume,
                                                                   marker=self.checkpoint_marker)
            stats = self.stats.setdefault(study_name, TaskStats())
            extra = [len(todo[k]) - 1 for k in keys]
            tables = run_tasks(tasks, self.executor, ckpt, progress, stats)
            for k, t, dup in zip(keys, tables, extra):
                self.tables[k] = t
                for i in todo[k]:
                    out[i] = t
                if progress is not None and dup:
                    getattr(progress, "skip", progress)(dup * len(omegas) * len(settings.directions()))
        return out


def find_peaks(omegas, amplitudes, refine=None) -> dict:
    """Peak summary of one curve: global maximum and the interior local maxima.

    refine: optional callable(omegas array) -> amplitudes for a smooth (exact) curve; each local
    maximum is then located to 1e-9 rad/s between its grid neighbours instead of on the grid.
    """
    w = np.asarray(omegas, float)
    a = np.asarray(amplitudes, float)
    local = []
    for i in range(1, len(a) - 1):
        if a[i] >= a[i - 1] and a[i] > a[i + 1]:
            wi, ai = w[i], a[i]
            if refine is not None:
                r = minimize_scalar(lambda x: -float(refine(np.array([x]))[0]), bounds=(w[i - 1], w[i + 1]),
                                    method="bounded", options=dict(xatol=1e-9))
                if -r.fun >= ai:
                    wi, ai = float(r.x), float(-r.fun)
            local.append(dict(omega=float(wi), amplitude=float(ai)))
    k = int(np.argmax(a))
    best = dict(omega=float(w[k]), amplitude=float(a[k]))
    for p in local:
        if p["amplitude"] >= best["amplitude"]:
            best = dict(p)
    return dict(peak_amplitude=best["amplitude"], peak_omega=best["omega"], local_maxima=local)


def _diagnostics(t: pd.DataFrame) -> dict:
    return dict(method=str(t["method"].iloc[0]), all_converged=bool(t["converged"].all()),
                not_converged=int((~t["converged"].astype(bool)).sum()),
                irregular=int(t["irregular"].fillna(False).astype(bool).sum()) if "irregular" in t else 0,
                periods_min=int(t["periods"].min()), periods_max=int(t["periods"].max()),
                periods_mean=float(t["periods"].mean()), max_change=float(t["change"].max()),
                wall_time=float(t["wall_time"].sum()))


def _irregular_mask(t: pd.DataFrame) -> np.ndarray:
    """Points whose response is irregular (rattling, non-periodic) in either engine."""
    irr = t["irregular"].fillna(False).astype(bool).to_numpy() if "irregular" in t else np.zeros(len(t), bool)
    if "reference_irregular" in t:
        irr = irr | (t["reference_irregular"].to_numpy(float) == 1.0)
    return irr


def _differences(t: pd.DataFrame) -> dict:
    """Engine 'both': the relative difference co-simulation / monolithic - 1 per frequency; the
    headline maximum is over the *regular* points only (an irregular point has no single amplitude:
    it is listed apart with the window scatter of each engine)."""
    if "difference" not in t or not np.isfinite(t["difference"].to_numpy(float)).any():
        return {}
    d = t["difference"].to_numpy(float)
    w = t["omega"].to_numpy(float)
    irr = _irregular_mask(t)
    reg = np.where(irr | ~np.isfinite(d), np.nan, np.abs(d))
    out: dict[str, Any] = dict(regular_points=int(np.isfinite(reg).sum()))
    if np.isfinite(reg).any():
        k = int(np.nanargmax(reg))
        out.update(max_abs_difference=float(reg[k]), omega_max_difference=float(w[k]))
    else:
        out.update(max_abs_difference=None, omega_max_difference=None)
    ref_change = t["reference_change"].to_numpy(float) if "reference_change" in t else np.full(len(t), np.nan)
    out["irregular_points"] = [dict(omega=float(w[i]), difference=float(d[i]) if np.isfinite(d[i]) else None,
                                    scatter=float(t["change"].iloc[i]), reference_scatter=float(ref_change[i]))
                               for i in np.flatnonzero(irr)]
    out["difference"] = [dict(omega=float(wi), cosim=float(a), monolithic=float(r),
                              difference=float(x) if np.isfinite(x) else None, irregular=bool(ir))
                         for wi, a, r, x, ir in zip(w, t["amplitude"], t["reference"], d, irr)]
    return out


def frc_response(scn: Scenario, study: FRCStudy, settings: RunSettings, progress=None, cache=None) -> FRCData:
    cache = cache or _Cache()
    t0 = time.perf_counter()
    parts: list[pd.DataFrame] = []
    peaks: dict[str, dict[str, dict[str, Any]]] = {}  # curve label -> direction -> peak and diagnostics
    tables = cache.sweeps(scn.base, [c.tmd for c in study.curves], study.omegas, settings, progress, study.name)
    for curve, table in zip(study.curves, tables):
        table = table.copy()
        table.insert(0, "curve", curve.label)
        parts.append(table)
        refine = (lambda x, tmd=curve.tmd: exact_amplitude(scn.base, tmd, x)) if uses_exact(curve.tmd, settings) else None
        peaks[curve.label] = {}
        for d, td in table.groupby("direction", sort=False):
            peaks[curve.label][d] = dict(find_peaks(td["omega"], td["amplitude"], refine), **_diagnostics(td))
            peaks[curve.label][d].update(_differences(td))
    return FRCData(study, pd.concat(parts, ignore_index=True), peaks, time.perf_counter() - t0)


def map_response(scn: Scenario, study: MapStudy, settings: RunSettings, progress=None, cache=None) -> MapData:
    cache = cache or _Cache()
    t0 = time.perf_counter()
    amp = np.empty((len(study.values), len(study.omegas)))
    parts = []
    tables = cache.sweeps(scn.base, list(study.tmds), study.omegas, settings, progress, study.name)
    for i, (v, table) in enumerate(zip(study.values, tables)):
        table = table.copy()
        table.insert(0, "value", float(v))
        parts.append(table)
        amp[i] = table.groupby("omega")["amplitude"].max().reindex(study.omegas).to_numpy()
    return MapData(study, amp, pd.concat(parts, ignore_index=True), time.perf_counter() - t0)


def phase_portraits(scn: Scenario, study: PhasePortraitStudy, settings: RunSettings, progress=None) -> PhaseData:
    t0 = time.perf_counter()
    data = PhaseData(study)
    for w in study.omegas:
        for curve in study.curves:
            data.series[(w, curve.label)] = compute_time_series(scn.base, curve.tmd, w, study.n_periods,
                                                                study.samples_per_period, settings)
            if progress is not None:
                progress(1)
    data.wall_time = time.perf_counter() - t0
    return data


def run_studies(scn: Scenario, settings: RunSettings, progress=None, executor=None, checkpoint_dir=None,
                stats: dict | None = None, resume: bool = True, checkpoint_marker: dict | None = None) -> list:
    """Compute every study of the scenario, in order.

    executor: where nonlinear sweeps run (see :mod:`.executors`; None: here, in order);
    checkpoint_dir: folder of per-study checkpoints (``<dir>/<study>/``) for resuming, or None;
    stats: optional dict filled with study name -> :class:`TaskStats` (tasks read back / computed);
    checkpoint_marker: written as ``.run-scenario.json`` into ``checkpoint_dir`` with its first checkpoint.
    """
    cache = _Cache(executor, checkpoint_dir, resume, checkpoint_marker)
    if stats is not None:
        cache.stats = stats
    out: list[FRCData | MapData | PhaseData] = []
    for st in scn.studies:
        if isinstance(st, FRCStudy):
            out.append(frc_response(scn, st, settings, progress, cache))
        elif isinstance(st, MapStudy):
            out.append(map_response(scn, st, settings, progress, cache))
        else:
            out.append(phase_portraits(scn, st, settings, progress))
    return out


# --- summary -----------------------------------------------------------------------------------

def study_summary(data) -> dict:
    st = data.study
    d = dict(kind=st.kind, name=st.name, title=st.title, wall_time=data.wall_time)
    if isinstance(data, FRCData):
        d["omegas"] = _grid(st.omegas)
        d["curves"] = [dict(label=c.label, without_tmd=c.without_tmd, tmd=as_dict(c.tmd),
                            inertance_ratio=c.tmd.inertance_ratio, directions=data.peaks[c.label])
                       for c in st.curves]
    elif isinstance(data, MapData):
        d.update(parameter=st.parameter, values=_grid(st.values), omegas=_grid(st.omegas),
                 amplitude_min=float(data.amplitude.min()), amplitude_max=float(data.amplitude.max()),
                 **{k: v for k, v in _diagnostics(data.table).items() if k != "method"},
                 methods=sorted(set(data.table["method"])))
        d["peak_per_value"] = [dict(value=float(v), peak_amplitude=float(row.max()),
                                    peak_omega=float(st.omegas[int(np.argmax(row))]))
                               for v, row in zip(st.values, data.amplitude)]
    else:
        d.update(n_periods=st.n_periods, samples_per_period=st.samples_per_period, portraits=[])
        for (w, label), ts in data.series.items():
            x, xd = ts.states[:, 0], ts.states[:, 1]
            d["portraits"].append(dict(omega=w, curve=label, method=ts.method, converged=ts.converged,
                                       periods=ts.periods, change=ts.change, amplitude=ts.amplitude,
                                       x_max=float(np.abs(x).max()), xd_max=float(np.abs(xd).max())))
    return d


def _grid(a) -> dict:
    a = np.asarray(a, float)
    return dict(start=float(a[0]), stop=float(a[-1]), count=int(a.size))


# --- closing report ------------------------------------------------------------------------------

def _w(x) -> str:
    return f"{float(x):g}"


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100.0 * float(x):.3g} %"


def _points(rows: pd.DataFrame, limit: int = 12, with_value: bool = False) -> str:
    """'19.5, 20 rad/s', or for irregular points '20 rad/s (window scatter 67 %, not converged)'."""
    items = []
    for _, r in rows.head(limit).iterrows():
        s = _w(r["omega"])
        if with_value:
            s = f"({_w(r['value'])}, {s})"
        if bool(r.get("irregular", False)):
            notes = []
            if np.isfinite(float(r.get("change", np.nan))):
                notes.append(f"window scatter {_pct(r['change'])}")
            if not bool(r["converged"]):
                notes.append("not converged")
            s += " rad/s" + (f" ({', '.join(notes)})" if notes else "")
        items.append(s)
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    text = ", ".join(items) + more
    return text if text.endswith(")") or text.endswith("rad/s") else text + " rad/s"


def _flag_groups(t: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """(regular points not converged, irregular points, number of points not converged in all)."""
    irr = t["irregular"].fillna(False).astype(bool) if "irregular" in t else pd.Series(False, index=t.index)
    conv = t["converged"].astype(bool)
    return t[~conv & ~irr], t[irr], int((~conv).sum())


def study_report(data) -> list[str]:
    """One line per study for the end of a run: which points did not converge or are irregular
    (and, for engine 'both', the difference over the regular points and the irregular ones apart)."""
    st = data.study
    lines = []
    if isinstance(data, PhaseData):
        bad = [f"{_w(w)} rad/s ({label})" for (w, label), ts in data.series.items() if not ts.converged]
        n = len(data.series)
        lines.append(f"{st.name}: all {n} phase portraits reached their steady state" if not bad else
                     f"{st.name}: {len(bad)} of {n} phase portraits not converged: " + "; ".join(bad))
        return lines
    t = data.table
    if isinstance(data, MapData):
        nc, irr, n_nc = _flag_groups(t)
        if not len(nc) and not len(irr):
            lines.append(f"{st.name}: all {len(t)} points converged and periodic")
        else:
            parts = []
            if len(nc):
                parts.append(f"not converged at ({st.parameter}, omega) = {_points(nc, with_value=True)}")
            if len(irr):
                parts.append(f"irregular at ({st.parameter}, omega) = {_points(irr, with_value=True)}")
            lines.append(f"{st.name}: {n_nc} of {len(t)} points not converged, {len(irr)} irregular: "
                         + "; ".join(parts))
        return lines
    parts, n_nc, n_irr = [], 0, 0
    for (label, d), td in t.groupby(["curve", "direction"], sort=False):
        nc, irr, k = _flag_groups(td)
        n_nc, n_irr = n_nc + k, n_irr + len(irr)
        sub = []
        if len(nc):
            sub.append(f"not converged at {_points(nc)}")
        if len(irr):
            sub.append(f"irregular at {_points(irr)}")
        if sub:
            parts.append(f'"{label}" ({d}): ' + ", ".join(sub))
    if not parts:
        lines.append(f"{st.name}: all {len(t)} points converged and periodic")
    else:
        lines.append(f"{st.name}: {n_nc} of {len(t)} points not converged, {n_irr} irregular: " + "; ".join(parts))
    if "difference" in t and np.isfinite(t["difference"].to_numpy(float)).any():
        diff = _differences(t)
        where = "" if diff["omega_max_difference"] is None else f" (at {_w(diff['omega_max_difference'])} rad/s)"
        line = (f"{st.name}: co-simulation against monolithic: max |difference| = {_pct(diff['max_abs_difference'])} "
                f"over the {diff['regular_points']} regular points{where}")
        if diff["irregular_points"]:
            irr_t = t[_irregular_mask(t)]
            items = []
            for (_, r), ip in zip(irr_t.iterrows(), diff["irregular_points"]):
                items.append(f'{_w(ip["omega"])} rad/s "{r["curve"]}" ({r["direction"]}): difference '
                             f'{_pct(ip["difference"])}, window scatter {_pct(ip["scatter"])} co-simulation / '
                             f'{_pct(ip["reference_scatter"])} monolithic')
            line += "; irregular points (not in that maximum): " + "; ".join(items)
        lines.append(line)
    return lines
