"""Compute the studies of a scenario (no files, no plotting: see :mod:`.output` and :mod:`.plots`; the
summary and closing report of the data: :mod:`.summary`).

Each study gives a data object: :class:`FRCData` (a long sweep table, one block per curve),
:class:`MapData` (amplitude[value, omega]) or :class:`PhaseData` (time series per omega and curve).
Identical (parameters, frequencies) sweeps are computed once per run and shared between studies.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .engines import (
    BLOCK_USERS,
    RunSettings,
    compute_sweep,
    compute_time_series,
    peak_refiner,
    prepare_cosim,
    uses_exact,
)
from .executors import run_tasks
from .schema import Curve, FRCStudy, MapStudy, PhasePortraitStudy, Scenario
from .sweeptable import engine_differences, find_peaks, sweep_diagnostics
from .tasks import Checkpoint, SweepTask, TaskStats, run_task

if TYPE_CHECKING:
    from pathlib import Path

    from numpy import ndarray
    from pandas import DataFrame

    from ..physics.params import BaseParams, TMDParams
    from .engines import RunSettings
    from .executors import Executor


@dataclass
class FRCData:
    study: FRCStudy
    table: pd.DataFrame  #: SWEEP_COLUMNS plus 'curve' (the label)
    peaks: dict  #: label -> {direction -> peak summary}
    wall_time: float = 0.0
    structures: dict = field(default_factory=dict)  #: label -> the primary structure the curve ran on


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


def study_configurations(scn: Scenario) -> list[tuple[str, Any, np.ndarray]]:
    """Every TMD configuration a scenario computes, with where it comes from and its frequencies:
    (``studies[i] 'name' curve 'label'`` or ``... value v``, TMD parameters, omegas [rad/s])."""
    out = []
    for i, st in enumerate(scn.studies):
        where = f"studies[{i}] ({st.name})"
        if isinstance(st, MapStudy):
            out += [(f"{where} {st.parameter} = {v:g}", tmd, st.omegas) for v, tmd in zip(st.values, st.tmds)]
        else:
            out += [(f'{where} curve "{c.label}"', c.tmd, st.omegas) for c in st.curves]
    return out


def instant_units(scn: Scenario, settings: RunSettings) -> int:
    """Progress units of a run that cost (almost) nothing: sweeps computed in closed form (the exact
    response of linear configurations with the monolithic engine) and sweeps that repeat one computed
    earlier in the run (shared between studies). An ETA leaves them out of the work still to do."""
    nd = len(settings.directions())
    seen, n = set(), 0
    for st in scn.studies:
        if isinstance(st, FRCStudy):
            pairs = [(curve_structure(scn, c), c.tmd) for c in st.curves]
        elif isinstance(st, MapStudy):
            pairs = [(scn.base, tmd) for tmd in st.tmds]
        else:
            continue
        for base, tmd in pairs:
            key = (base, tmd, np.asarray(st.omegas, float).tobytes())
            if key in seen or uses_exact(base, tmd, settings):
                n += len(st.omegas) * nd
            seen.add(key)
    return n


class _Cache:
    """Sweeps already computed in this run, keyed by (parameters, frequencies).

    Nonlinear sweeps not yet computed go to the executor (:mod:`.executors`; None: computed here,
    in order) and through the study's checkpoint folder, so a killed run resumes where it stopped.
    """

    def __init__(
        self,
        executor: Executor | None = None,
        checkpoint_dir: Path | None = None,
        resume: bool = True,
        checkpoint_marker: dict[str, str] | None = None,
    ) -> None:
        self.resume = resume
        self.checkpoint_marker = checkpoint_marker
        self.tables: dict[Any, Any] = {}
        self.executor = executor
        self.checkpoint_dir = None if checkpoint_dir is None else Path(checkpoint_dir)
        self.stats: dict[str, Any] = {}  #: study name -> TaskStats

    def sweep(
        self,
        base: BaseParams,
        tmd: TMDParams,
        omegas: ndarray,
        settings: RunSettings,
        progress: Callable[..., Any] | None,
    ) -> DataFrame:
        key = (base, tmd, np.asarray(omegas, float).tobytes())
        if key in self.tables:
            if progress is not None:
                getattr(progress, "skip", progress)(len(omegas) * len(settings.directions()))
            return self.tables[key]
        if settings.sweep.continuation or uses_exact(base, tmd, settings):
            table = compute_sweep(base, tmd, omegas, settings, progress)
        else:  # independent points from the linear guess: same task function as the executors
            task = SweepTask(base, tmd, np.asarray(omegas, float), settings)
            table = run_task(task)
            if progress is not None:
                progress(task.units())
        self.tables[key] = table
        return table

    def sweeps(
        self,
        base: Any,
        tmds: list[TMDParams],
        omegas: ndarray,
        settings: RunSettings,
        progress: Callable[..., Any] | None,
        study_name: str,
    ) -> list[Any]:
        """Tables of several configurations over the same frequencies, in order; ``base``: the
        primary structure of every configuration, or a list of one per configuration."""
        omegas = np.asarray(omegas, float)
        out = [None] * len(tmds)
        bases = list(base) if isinstance(base, list) else [base] * len(tmds)
        todo: dict[tuple, list[int]] = {}  # key -> indices (identical configurations are computed once)
        for i, tmd in enumerate(tmds):
            key = (bases[i], tmd, omegas.tobytes())
            if key in self.tables:
                out[i] = self.tables[key]
                if progress is not None:  # computed earlier in this run: not in the speed of an ETA
                    getattr(progress, "skip", progress)(len(omegas) * len(settings.directions()))
            elif uses_exact(bases[i], tmd, settings) or (self.executor is None and self.checkpoint_dir is None):
                out[i] = self.sweep(bases[i], tmd, omegas, settings, progress)
            else:
                todo.setdefault(key, []).append(i)
        if todo:
            keys = list(todo)
            tasks = [SweepTask(k[0], k[1], omegas, settings) for k in keys]
            ckpt = (
                None
                if self.checkpoint_dir is None
                else Checkpoint(self.checkpoint_dir / study_name, self.resume, marker=self.checkpoint_marker)
            )
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


def curve_structure(scn: Scenario, curve: Curve) -> Any:
    """The primary structure a curve is computed on: its own (a frame with its TMD attached
    elsewhere) or the scenario's."""
    return scn.base if curve.structure is None else curve.structure


def frc_response(
    scn: Scenario,
    study: FRCStudy,
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
    cache: _Cache | None = None,
) -> FRCData:
    cache = cache or _Cache()
    t0 = time.perf_counter()
    parts: list[pd.DataFrame] = []
    peaks: dict[str, dict[str, dict[str, Any]]] = {}  # curve label -> direction -> peak and diagnostics
    bases = [curve_structure(scn, c) for c in study.curves]
    tables = cache.sweeps(bases, [c.tmd for c in study.curves], study.omegas, settings, progress, study.name)
    for curve, base, table in zip(study.curves, bases, tables):
        table = table.copy()
        table.insert(0, "curve", curve.label)
        parts.append(table)
        refine, highest_only = peak_refiner(base, curve.tmd, settings)
        peaks[curve.label] = {}
        for d, td in table.groupby("direction", sort=False):
            found = find_peaks(td["omega"], td["amplitude"], refine, highest_only=highest_only)
            peaks[curve.label][d] = dict(found, **sweep_diagnostics(td))
            peaks[curve.label][d].update(engine_differences(td))
        close = getattr(refine, "close", None)
        if close is not None:
            close()
    return FRCData(
        study,
        pd.concat(parts, ignore_index=True),
        peaks,
        time.perf_counter() - t0,
        {c.label: b for c, b in zip(study.curves, bases)},
    )


def map_response(
    scn: Scenario,
    study: MapStudy,
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
    cache: _Cache | None = None,
) -> MapData:
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


def phase_portraits(
    scn: Scenario, study: PhasePortraitStudy, settings: RunSettings, progress: Callable[..., Any] | None = None
) -> PhaseData:
    t0 = time.perf_counter()
    data = PhaseData(study)
    for w in study.omegas:
        for curve in study.curves:
            data.series[(w, curve.label)] = compute_time_series(
                curve_structure(scn, curve), curve.tmd, w, study.n_periods, study.samples_per_period, settings
            )
            if progress is not None:
                progress(1)
    data.wall_time = time.perf_counter() - t0
    return data


def run_studies(
    scn: Scenario,
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
    executor: Executor | None = None,
    checkpoint_dir: Path | None = None,
    stats: dict | None = None,
    resume: bool = True,
    checkpoint_marker: dict | None = None,
) -> list:
    """Compute every study of the scenario, in order.

    executor: where nonlinear sweeps run (see :mod:`.executors`; None: here, in order);
    checkpoint_dir: folder of per-study checkpoints (``<dir>/<study>/``) for resuming, or None;
    stats: optional dict filled with study name -> :class:`TaskStats` (tasks read back / computed);
    checkpoint_marker: written as ``.run-scenario.json`` into ``checkpoint_dir`` with its first checkpoint.
    """
    cache = _Cache(executor, checkpoint_dir, resume, checkpoint_marker)
    if stats is not None:
        cache.stats = stats
    structures = [scn.base] + [c.structure for st in scn.studies for c in getattr(st, "curves", ()) if c.structure]
    note = getattr(progress, "note", None)
    if note is not None and settings.engine in BLOCK_USERS["cosim"]:
        note("building FMUs (the co-simulation's, once for every worker; nothing to do when they are up to date)")
    t_fmus = time.perf_counter()
    built = prepare_cosim(structures, settings)
    if note is not None and built:
        note(f"FMUs ready: {', '.join(built)} ({time.perf_counter() - t_fmus:.1f} s)")
    out: list[FRCData | MapData | PhaseData] = []
    for st in scn.studies:
        if isinstance(st, FRCStudy):
            out.append(frc_response(scn, st, settings, progress, cache))
        elif isinstance(st, MapStudy):
            out.append(map_response(scn, st, settings, progress, cache))
        else:
            out.append(phase_portraits(scn, st, settings, progress))
    return out
