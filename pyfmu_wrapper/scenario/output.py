"""Run a scenario and write its results folder atomically.

Files: one ``<study>.csv`` and ``<study>.png`` per study and ``summary.json``. Everything is
written into a temporary sibling folder (``.<name>.partial-XXXX``) that is renamed to the output
folder only when complete; on any failure it is removed, so a results folder that exists is
always complete.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import shutil
import tempfile
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd

from .. import plots
from ..physics.params import as_dict
from .engines import RunSettings
from .executors import code_version
from .runner import FRCData, MapData, run_studies, study_summary
from .schema import Scenario


def default_output_dir(scn: Scenario) -> Path:
    return Path("results") / scn.name


def default_checkpoint_dir(out_dir) -> Path:
    """Where the resumable checkpoints of a results folder live: ``<parent>/.cache/<name>/``."""
    out = Path(out_dir)
    return out.parent / ".cache" / out.name


def run_scenario(scn: Scenario, out_dir, settings: RunSettings, progress=None, executor=None,
                 checkpoint_dir=None, resume: bool = True, collect: list | None = None) -> Path:
    """Compute every study of ``scn`` and write the results folder ``out_dir`` (replaced if present).

    executor: where the nonlinear sweeps run (:mod:`.executors`; None: in this process, in order);
    checkpoint_dir: folder of finished sweeps to resume from and add to (None: no checkpoints);
    resume=False recomputes every sweep (and overwrites its checkpoint); collect: a list that
    receives the computed study data objects (for callers that draw their own figures).
    Returns the folder. On failure nothing is left at ``out_dir`` that was not there before
    (checkpoints of finished sweeps are kept, so that the next run resumes).
    """
    out = Path(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it private; the results folder is an ordinary one
    try:
        t0 = time.perf_counter()
        stats: dict = {}
        datas = run_studies(scn, settings, progress, executor=executor, checkpoint_dir=checkpoint_dir, stats=stats,
                            resume=resume)
        compute_time = time.perf_counter() - t0
        if collect is not None:
            collect.extend(datas)
        for data in datas:
            write_study_csv(data, tmp / f"{data.study.name}.csv")
            fig = plots.plot_study(data)
            plots.save_figure(fig, tmp / f"{data.study.name}.png")
        summary = make_summary(scn, settings, datas, compute_time, time.perf_counter() - t0)
        summary["executor"] = dict(
            name=getattr(executor, "name", "sequential"),
            description=executor.describe() if executor is not None else "sequential (this process)",
            checkpoint_dir=None if checkpoint_dir is None else str(checkpoint_dir),
            tasks={k: dict(cached=v.cached, computed=v.computed, wall_time=v.wall_time) for k, v in stats.items()})
        (tmp / "summary.json").write_text(json.dumps(_finite(summary), indent=2) + "\n", encoding="utf-8")
        _replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _replace_dir(tmp: Path, out: Path) -> None:
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        os.rename(out, old / "x")
        os.rename(tmp, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(tmp, out)


def write_study_csv(data, path) -> None:
    if isinstance(data, (FRCData, MapData)):
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


def make_summary(scn: Scenario, settings: RunSettings, datas, compute_time: float, total_time: float) -> dict:
    try:
        version = metadata.version("pyfmu-wrapper")
    except metadata.PackageNotFoundError:  # pragma: no cover
        version = None
    return dict(
        scenario=dict(name=scn.name, description=scn.description, file=str(scn.path),
                      schema_version=scn.schema_version),
        engine=settings.engine,
        workers=settings.workers,
        parameters=dict(base=as_dict(scn.base), tmd=as_dict(scn.tmd)),
        settings=settings.used(),
        not_used=[b for b in ("solver", "cosim") if b in scn.raw and b not in settings.used()],
        code_version=code_version(),
        timings=dict(compute=compute_time, total=total_time, studies={d.study.name: d.wall_time for d in datas}),
        studies=[study_summary(d) for d in datas],
        created=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        versions=dict(pyfmu_wrapper=version, numpy=np.__version__),
    )


def _finite(obj):
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
