"""Run a scenario and write its results folder atomically, never touching what the tool did not write.

Files: one ``<study>.csv`` and ``<study>.png`` per study, ``summary.json`` and the marker
``.run-scenario.json`` (tool, scenario, version, the list of files written). The marker is how a
later run recognises a folder as a result of run-scenario, the only kind of non-empty folder it
replaces.

Safety rules (:func:`check_output_dir`, applied before anything is computed; a violation raises
:class:`OutputError`, exit status 2 in the CLI):

* ``--out`` may not be a file, a symbolic link, the current folder or one of its parents, the
  folder of the scenario file or one of its parents, the home folder or ``/``;
* an existing non-empty folder is replaced only if it is an earlier result of run-scenario (its
  marker lists every file in it; a folder written before the marker existed is recognised by its
  ``summary.json`` and holding only the study CSV/PNG files it names); anything else in it is
  named in the error and nothing is touched.

Everything is written into a temporary sibling folder ``.<name>.partial-<pid>-XXXX`` (with a
marker naming the process) that replaces the output folder in one step (Linux ``renameat2``
exchange; elsewhere two renames) when complete; on any failure or interrupt it is removed, so a
results folder that exists is always complete. A partial folder left by a killed run (SIGKILL,
power loss) is recognised by its name *and* marker on the next start and removed (reported on
stderr); one without the marker is only reported.

Checkpoints (finished sweeps, for resuming a killed run) live in ``<out>.checkpoints/`` next to the
output folder (:func:`default_checkpoint_dir`), one per output folder, so two outputs never share
them; it carries its own marker, and a folder of that name that is not ours is refused.
"""

from __future__ import annotations

import ctypes
import datetime as _dt
import json
import math
import os
import re
import shutil
import socket
import tempfile
import time
from collections.abc import Callable, Sequence
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..physics.params import as_dict
from . import plots
from .engines import RunSettings
from .runner import FRCData, MapData, run_studies
from .schema import Scenario
from .summary import study_summary
from .tasks import code_version

if TYPE_CHECKING:
    from pathlib import Path
    from typing import Any

    from .executors import Executor
    from .runner import FRCData, MapData, PhaseData

#: the marker file of every folder run-scenario writes (results, partial folders, checkpoints)
MARKER = ".run-scenario.json"
TOOL = "run-scenario"


class OutputError(ValueError):
    """An output folder the tool refuses to write (it would lose something it did not write)."""


def _version() -> str | None:
    try:
        return metadata.version("pyfmu-wrapper")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return None


def default_output_dir(scn: Scenario) -> Path:
    return Path("results") / scn.name


def default_checkpoint_dir(out_dir: str | os.PathLike[str]) -> Path:
    """Where the resumable checkpoints of a results folder live: ``<out>.checkpoints/`` beside it
    (one folder per output folder: ``--out /tmp/foo`` -> ``/tmp/foo.checkpoints/``)."""
    out = _abs(out_dir)
    return out.with_name(out.name + ".checkpoints")


def _abs(p: str | os.PathLike[str]) -> Path:
    """Absolute, normalised ('.', '..' and doubled slashes removed) without resolving symbolic links."""
    return Path(os.path.abspath(os.fspath(p)))


def read_marker(folder: Path) -> dict[str, Any] | None:
    """The marker of a folder written by run-scenario, or None (absent, unreadable or not ours)."""
    try:
        m = json.loads((Path(folder) / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return m if isinstance(m, dict) and m.get("tool") == TOOL else None


def _write_marker(folder: Path, **fields: Any) -> None:
    m = dict(tool=TOOL, version=_version(), **fields)
    (folder / MARKER).write_text(json.dumps(m, indent=2) + "\n", encoding="utf-8")


def _legacy_result(folder: Path, names: list[str]) -> bool:
    """A result written before the marker existed: summary.json of run-scenario and only the CSV/PNG
    files of the studies it names."""
    try:
        s = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
        studies = {st["name"] for st in s["studies"]}
        if not ("scenario" in s and "code_version" in s):
            return False
    except (OSError, ValueError, UnicodeDecodeError, KeyError, TypeError):
        return False
    allowed = {"summary.json"} | {f"{n}.{e}" for n in studies for e in ("csv", "png")}
    return all(n in allowed and (folder / n).is_file() and not (folder / n).is_symlink() for n in names)


def _foreign_entries(folder: Path) -> list[str]:
    """Entries of an existing output folder that run-scenario did not write (empty: safe to replace)."""
    names = sorted(os.listdir(folder))
    if not names:
        return []
    m = read_marker(folder)
    if m is None or m.get("kind") != "result":
        if MARKER not in names and _legacy_result(folder, names):
            return []
        return names
    ours = set(m.get("files") or []) | {MARKER}
    return [n for n in names if n not in ours or (folder / n).is_symlink() or not (folder / n).is_file()]


def _pid_alive(pid: Any) -> bool:
    try:
        os.kill(int(pid), 0)
    except (ProcessLookupError, ValueError, TypeError):
        return False
    except PermissionError:
        return True
    return True


def _stale_partials(out: Path) -> list[Path]:
    pat = re.compile(re.escape(f".{out.name}.") + r"(partial|old)-")
    try:
        return sorted(p for p in out.parent.iterdir() if pat.match(p.name) and p.is_dir() and not p.is_symlink())
    except FileNotFoundError:
        return []


def clean_stale_partials(out: Path) -> list[str]:
    """Remove the partial folders of ``out`` left by killed runs (name and marker prove they are ours,
    the process that wrote them is gone); report the others. Returns one message per folder. Raises
    :class:`OutputError` if another live run-scenario is writing the same output folder."""
    out = _abs(out)
    notes = []
    for p in _stale_partials(out):
        m = read_marker(p)
        if m is not None and m.get("out") == str(out):
            same_host = m.get("host") == socket.gethostname()
            if same_host and m.get("pid") != os.getpid() and _pid_alive(m.get("pid")):
                raise OutputError(
                    f"{out}: another run-scenario (process {m.get('pid')}, started {m.get('started')}) "
                    f"is writing this output folder now (its partial folder: {p}); wait for it, stop it, "
                    "or choose another --out"
                )
            if same_host:
                shutil.rmtree(p, ignore_errors=True)
                notes.append(
                    f"removed {p}, the partial folder of an interrupted run-scenario "
                    f"(process {m.get('pid')}, started {m.get('started')})"
                )
                continue
        notes.append(
            f"found {p}: it looks like the partial folder of an interrupted run, but it does not carry "
            f"run-scenario's marker for this output (or was written on another machine); left alone: "
            "delete it yourself if you do not need it"
        )
    return notes


def check_output_dir(
    out: str | os.PathLike[str], scenario_path: str | None = None, checkpoint_dir: Path | None = None
) -> list[str]:
    """Refuse an output folder whose replacement could lose anything run-scenario did not write
    (:class:`OutputError`, before any computing), clean the stale partial folders of killed runs.

    Returns the notes to show (stale folders removed or found)."""
    given = os.fspath(out)
    out = _abs(out)
    if out.parent == out or not out.name:
        raise OutputError(f"--out {given}: refusing to write results to the root folder")
    protected = [("the current folder", Path.cwd()), ("your home folder", Path.home())]
    if scenario_path is not None:
        protected.append(("the scenario file", _abs(scenario_path)))
    for what, p in protected:
        for q in {_abs(p), Path(p).resolve()}:
            if out == q or out in q.parents or out.resolve() == q or out.resolve() in q.parents:
                raise OutputError(
                    f"--out {given}: refusing to replace {out}, which is or contains {what} ({q}); "
                    "give a new folder, e.g. --out results/NAME"
                )
    if out.is_symlink():
        raise OutputError(f"--out {given}: {out} is a symbolic link; give the folder itself")
    if out.exists() and not out.is_dir():
        raise OutputError(
            f"--out {given}: {out} exists and is not a folder; refusing to replace it (choose another --out)"
        )
    if out.is_dir():
        foreign = _foreign_entries(out)
        if foreign:
            shown = ", ".join(foreign[:8]) + (f", ... ({len(foreign)} entries)" if len(foreign) > 8 else "")
            raise OutputError(
                f"--out {given}: {out} is a non-empty folder that is not a result of run-scenario "
                f"(it holds {shown}); refusing to replace it: nothing was written. Choose a new "
                "folder, or empty this one yourself"
            )
    ck = _abs(checkpoint_dir) if checkpoint_dir is not None else None
    if ck is not None and ck == default_checkpoint_dir(out) and ck.exists():
        m = read_marker(ck)
        foreign_ck = not ck.is_dir() or ck.is_symlink() or m is None or m.get("kind") != "checkpoints"
        if foreign_ck and not (ck.is_dir() and not os.listdir(ck)):
            raise OutputError(
                f"--out {given}: the checkpoint folder {ck} exists but was not written by "
                "run-scenario; refusing to write into it (move it, or choose another --out)"
            )
    return clean_stale_partials(out)


def run_scenario(
    scn: Scenario,
    out_dir: str | os.PathLike[str],
    settings: RunSettings,
    progress: Callable[..., Any] | None = None,
    executor: Executor | None = None,
    checkpoint_dir: Path | None = None,
    resume: bool = True,
    collect: list | None = None,
) -> Path:
    """Compute every study of ``scn`` and write the results folder ``out_dir`` (replaced if it is an
    earlier result of run-scenario; any other non-empty folder or a file raises :class:`OutputError`
    before computing).

    executor: where the nonlinear sweeps run (:mod:`.executors`; None: in this process, in order);
    checkpoint_dir: folder of finished sweeps to resume from and add to (None: no checkpoints);
    resume=False recomputes every sweep (and overwrites its checkpoint); collect: a list that
    receives the computed study data objects (for callers that draw their own figures).
    Returns the folder. On failure nothing is left at ``out_dir`` that was not there before
    (checkpoints of finished sweeps are kept, so that the next run resumes).
    """
    check_output_dir(out_dir, scn.path, checkpoint_dir)
    out = _abs(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-{os.getpid()}-", dir=out.parent))
    try:
        started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        _write_marker(
            tmp,
            kind="partial",
            out=str(out),
            pid=os.getpid(),
            host=socket.gethostname(),
            started=started,
            scenario=scn.name,
        )
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it private; the results folder is an ordinary one
        t0 = time.perf_counter()
        stats: dict = {}
        ck_marker = None
        if checkpoint_dir is not None and _abs(checkpoint_dir) == default_checkpoint_dir(out):
            ck_marker = dict(
                tool=TOOL,
                version=_version(),
                kind="checkpoints",
                out=str(out),
                note="finished sweeps of run-scenario, for resuming a killed run; safe to delete",
            )
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
        files = []
        for data in datas:
            write_study_csv(data, tmp / f"{data.study.name}.csv")
            fig = plots.plot_study(data)
            plots.save_figure(fig, tmp / f"{data.study.name}.png")
            files += [f"{data.study.name}.csv", f"{data.study.name}.png"]
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
        (tmp / "summary.json").write_text(json.dumps(_finite(summary), indent=2) + "\n", encoding="utf-8")
        files.append("summary.json")
        _write_marker(
            tmp,
            kind="result",
            out=str(out),
            scenario=scn.name,
            scenario_file=str(scn.path),
            code_version=code_version(),
            created=summary["created"],
            files=sorted(files),
            pid=os.getpid(),
            host=socket.gethostname(),
        )
        _replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one atomic step (Linux renameat2 RENAME_EXCHANGE); False if not available."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (38, 22, 95):  # ENOSYS, EINVAL, EOPNOTSUPP: the file system cannot exchange
        return False
    raise OSError(err, os.strerror(err), str(b))


def _replace_dir(tmp: Path, out: Path) -> None:
    """Put the complete folder ``tmp`` at ``out``. An existing ``out`` (checked to be ours) is swapped
    out in one step and removed; no ``.old`` folder is left behind."""
    if not out.exists():
        os.rename(tmp, out)
        return
    if _exchange(tmp, out):  # out is now the new result, tmp the previous one
        shutil.rmtree(tmp, ignore_errors=True)
        return
    old = out.with_name(f".{out.name}.old-{os.getpid()}-{os.urandom(4).hex()}")
    os.rename(out, old)
    try:
        os.rename(tmp, out)
    except BaseException:
        os.rename(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)


def write_study_csv(data: FRCData | MapData | PhaseData, path: Path) -> None:
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


def cosim_time_split(datas: Sequence[Any]) -> dict[str, Any] | None:
    """Where the co-simulation's time went, summed over every study's sweep table: seconds inside each
    FMU's fmi2 calls (``fmus``), in the compiled stepping loop's own work (``master_loop``), in steps
    taken on the Python path (``python_steps``) and the rest of the points' wall time (``steady_state_logic``:
    shooting, windows, re-initialisations). None when no point was co-simulated."""
    from .sweeptable import TIMING_COLUMNS

    tables = [d.table for d in datas if getattr(d, "table", None) is not None]
    rows = [t[t[list(TIMING_COLUMNS)].notna().any(axis=1)] for t in tables if set(TIMING_COLUMNS) <= set(t.columns)]
    rows = [t for t in rows if len(t)]
    if not rows:
        return None
    t = pd.concat(rows)
    s = {c: float(np.nansum(t[c].to_numpy(float))) for c in TIMING_COLUMNS}
    wall = float(np.nansum(t["wall_time"].to_numpy(float)))
    fmus = {"base": s["fmu_time_base"], "tmd": s["fmu_time_tmd"]}
    return dict(
        points=int(len(t)),
        wall_time=wall,
        fmus=fmus,
        master_loop=s["master_loop_time"],
        python_steps=s["python_step_time"],
        steady_state_logic=wall - sum(fmus.values()) - s["master_loop_time"] - s["python_step_time"],
    )


def make_summary(
    scn: Scenario,
    settings: RunSettings,
    datas: list[FRCData | MapData | PhaseData],
    compute_time: float,
    total_time: float,
) -> dict:
    try:
        version = metadata.version("pyfmu-wrapper")
    except metadata.PackageNotFoundError:  # pragma: no cover
        version = None
    return dict(
        scenario=dict(
            name=scn.name, description=scn.description, file=str(scn.path), schema_version=scn.schema_version
        ),
        engine=settings.engine,
        workers=settings.workers,
        parameters=dict(base=as_dict(scn.base), tmd=as_dict(scn.tmd)),
        settings=settings.used(),
        not_used=[b for b in ("solver", "cosim") if b in scn.raw and b not in settings.used()],
        code_version=code_version(),
        timings=dict(
            compute=compute_time,
            total=total_time,
            studies={d.study.name: d.wall_time for d in datas},
            cosim=cosim_time_split(datas),
        ),
        studies=[study_summary(d) for d in datas],
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
