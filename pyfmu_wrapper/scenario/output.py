"""Run a scenario and write its results folder atomically, never touching what the tool did not write.

Files: one ``<study>.csv`` and ``<study>.png`` per study, ``summary.json``, ``summary.md`` (the same
numbers in a few lines a person can paste into a report: peaks, reductions, convergence, timings) and the marker
``.run-scenario.json`` (tool, scenario, version, the list of files written). The marker is how a
later run recognises a folder as a result of run-scenario, the only kind of non-empty folder it
replaces.

The folder's rules (where it goes, what may be replaced, the atomic swap, the markers) are
:mod:`.outdir`.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from . import plots
from .engines import RunSettings
from .outdir import (
    abs_path,
    check_checkpoint_dir,
    checkpoint_marker,
    default_checkpoint_dir,
    result_folder,
    tool_version,
)
from .runner import FRCData, MapData, run_studies
from .schema import Scenario
from .summary import attachment, model_parameters, response_body, study_summary, summary_markdown
from .tasks import code_version

if TYPE_CHECKING:
    from pathlib import Path
    from typing import Any

    from .executors import Executor
    from .runner import FRCData, MapData, PhaseData


def run_scenario(
    scn: Scenario,
    out_dir: str | os.PathLike[str],
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
    executor: Executor | None = None,
    checkpoint_dir: Path | None = None,
    resume: bool = True,
    collect: list | None = None,
    stats_out: dict | None = None,
) -> Path:
    """Compute every study of ``scn`` and write the results folder ``out_dir`` (replaced if it is an
    earlier result of run-scenario; any other non-empty folder or a file raises :class:`OutputError`
    before computing).

    executor: where the nonlinear sweeps run (:mod:`.executors`; None: in this process, in order);
    checkpoint_dir: folder of finished sweeps to resume from and add to (None: no checkpoints);
    resume=False recomputes every sweep (and overwrites its checkpoint); collect: a list that
    receives the computed study data objects (for callers that draw their own figures); stats_out: a
    dict that receives the task statistics per study (how many sweeps were read from checkpoints).
    Returns the folder; raises :class:`~pyfmu_wrapper.safeio.Diverted` when the folder changed
    during the run (the result is then beside it, the folder untouched). On failure nothing is left at ``out_dir`` that was not there before
    (checkpoints of finished sweeps are kept, so that the next run resumes).
    """
    rf = result_folder(out_dir, scn.path)
    rf.check()
    out = rf.out
    check_checkpoint_dir(out, checkpoint_dir)
    tmp = rf.begin()
    try:
        t0 = time.perf_counter()
        stats: dict = {}
        ck_marker = None
        if checkpoint_dir is not None and abs_path(checkpoint_dir) == default_checkpoint_dir(out):
            ck_marker = checkpoint_marker(out)
        datas = run_studies(
            scn,
            settings,
            progress,
            executor=executor,
            checkpoint_dir=checkpoint_dir,
            stats=stats,
            resume=resume,
            checkpoint_marker=ck_marker,
        )
        compute_time = time.perf_counter() - t0
        if collect is not None:
            collect.extend(datas)
        if stats_out is not None:
            stats_out.update(stats)
        for data in datas:
            write_study_csv(data, tmp / f"{data.study.name}.csv")
            fig = plots.plot_study(data)
            plots.save_figure(fig, tmp / f"{data.study.name}.png")
        summary = make_summary(scn, settings, datas, compute_time, time.perf_counter() - t0)
        used = executor.processes_used() if executor is not None and hasattr(executor, "processes_used") else 1
        summary["workers"] = used
        summary["executor"] = dict(
            name=getattr(executor, "name", "sequential"),
            description=executor.describe() if executor is not None else "sequential (this process)",
            processes_requested=getattr(executor, "jobs", 1) if executor is not None else 1,
            processes_used=used,
            checkpoint_dir=None if checkpoint_dir is None else str(checkpoint_dir),
            tasks={k: dict(cached=v.cached, computed=v.computed, wall_time=v.wall_time) for k, v in stats.items()},
        )
        summary = _finite(summary)
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        (tmp / "summary.md").write_text(summary_markdown(summary, response_body(scn.base)), encoding="utf-8")
    except BaseException:
        rf.abort()
        raise
    return rf.commit(
        version=tool_version(),
        scenario=scn.name,
        scenario_file=str(abs_path(scn.path)) if scn.path else None,
        code_version=code_version(),
        created=summary["created"],
        pid=os.getpid(),
        host=socket.gethostname(),
    )


def write_study_csv(data: FRCData | MapData | PhaseData, path: Path) -> None:
    if isinstance(data, FRCData):
        frc_table(data).to_csv(path, index=False, float_format="%.10g")
        return
    if isinstance(data, MapData):
        data.table.to_csv(path, index=False, float_format="%.10g")
        return
    rows = []
    for (w, label), ts in data.series.items():
        df = pd.DataFrame(ts.states, columns=["x", "xd", "y", "yd", "d", "dd"])
        df.insert(0, "t", ts.t)
        df.insert(0, "curve", label)
        df.insert(0, "omega", w)
        rows.append(df)
    pd.concat(rows, ignore_index=True).to_csv(path, index=False, float_format="%.10g")


def frc_table(data: FRCData) -> pd.DataFrame:
    """The FRC study's table as its CSV holds it: on a structure with places to attach the TMD (a
    frame), each curve's attachment in two last columns (``tmd_storey``, ``inerter_to``: 0 the ground;
    empty for a curve without TMD; last, so the sweep columns keep their places)."""
    tab = data.table
    atts = {label: attachment(s) for label, s in data.structures.items()}
    if not any(a is not None for a in atts.values()):
        return tab
    tab = tab.copy()
    without = {c.label for c in data.study.curves if c.without_tmd}
    for col, key in (("tmd_storey", "storey"), ("inerter_to", "inerter_to")):
        vals = [
            None if (lab in without or atts.get(lab) is None) else int(atts[lab][key])  # type: ignore[index]
            for lab in tab["curve"]
        ]
        tab[col] = pd.array(vals, dtype="Int64")
    return tab


def cosim_time_split(datas: Sequence[Any]) -> dict[str, Any] | None:
    """Where the co-simulation's time went, summed over every study's sweep table: seconds inside each
    FMU's fmi2 calls (``fmus``), in the compiled stepping loop's own work (``master_loop``), in steps
    taken on the Python path (``python_steps``) and the rest of the points' wall time (``steady_state_logic``:
    shooting, windows, re-initialisations). A model whose co-simulation does not measure the split (the
    frame's) still gets its co-simulated points and their wall time, the split null and ``split_measured``
    false. None when no point was co-simulated."""
    from .sweeptable import TIMING_COLUMNS

    tables = [d.table for d in datas if getattr(d, "table", None) is not None]
    rows = []
    for t in tables:
        if "engine" not in t or "wall_time" not in t:
            continue
        cosim = t["engine"].isin(["cosim", "both"]).to_numpy()
        if set(TIMING_COLUMNS) <= set(t.columns):
            cosim = cosim | t[list(TIMING_COLUMNS)].notna().any(axis=1).to_numpy()
        if cosim.any():
            rows.append(t[cosim])
    if not rows:
        return None
    t = pd.concat(rows)
    wall = float(np.nansum(t["wall_time"].to_numpy(float)))
    timed = t[t[list(TIMING_COLUMNS)].notna().any(axis=1)] if set(TIMING_COLUMNS) <= set(t.columns) else t.iloc[:0]
    if not len(timed):
        return dict(
            points=int(len(t)),
            wall_time=wall,
            split_measured=False,
            fmus=None,
            master_loop=None,
            python_steps=None,
            steady_state_logic=None,
        )
    s = {c: float(np.nansum(timed[c].to_numpy(float))) for c in TIMING_COLUMNS}
    fmus = {"base": s["fmu_time_base"], "tmd": s["fmu_time_tmd"]}
    timed_wall = float(np.nansum(timed["wall_time"].to_numpy(float)))
    return dict(
        points=int(len(t)),
        wall_time=wall,
        split_measured=len(timed) == len(t),
        fmus=fmus,
        master_loop=s["master_loop_time"],
        python_steps=s["python_step_time"],
        steady_state_logic=timed_wall - sum(fmus.values()) - s["master_loop_time"] - s["python_step_time"],
    )


def make_summary(
    scn: Scenario,
    settings: RunSettings,
    datas: list[FRCData | MapData | PhaseData],
    compute_time: float,
    total_time: float,
) -> dict:
    version = tool_version()
    return dict(
        scenario=dict(
            name=scn.name, description=scn.description, file=str(scn.path), schema_version=scn.schema_version
        ),
        engine=settings.engine,
        workers=settings.workers,
        parameters=model_parameters(scn.base, scn.tmd),
        settings=settings.used(),
        not_used=[b for b in ("solver", "cosim") if b in scn.raw and b not in settings.used()],
        code_version=code_version(),
        timings=dict(
            compute=compute_time,
            total=total_time,
            studies={d.study.name: d.wall_time for d in datas},
            cosim=cosim_time_split(datas),
        ),
        studies=[study_summary(d, scn.base) for d in datas],
        created=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        versions=dict(pyfmu_wrapper=version, numpy=np.__version__),
    )


def _finite(obj: Any) -> Any:
    """JSON has no inf/nan: write them as null."""
    if isinstance(obj, dict):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
