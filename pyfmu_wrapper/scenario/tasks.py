"""The unit of parallel work of a scenario, :class:`SweepTask` (one configuration swept over the
frequencies), the function every executor runs on it (:func:`run_task`), and where finished tasks are kept
(:class:`Checkpoint`). The executors that run tasks are in :mod:`.executors`.

Resume: a :class:`Checkpoint` folder holds one file per finished task, named by a hash of everything
the result depends on: the code version (:func:`code_version`, a hash of the package's sources), the
base and TMD parameters, the frequencies, the engine, the sweep block (direction, continuation) and
the resolved settings of every engine that computes the rows (the monolithic solver's for
'monolithic', the co-simulation's for 'cosim', both for 'both'; see :meth:`SweepTask.key`). It is
written atomically (temporary file + rename) as soon as a task finishes, so a sweep that is killed
restarts where it stopped: finished tasks are read back, only the missing ones are computed. A
change of any input, or of any source file (Python or C), changes the hash, so a checkpoint
written by other code or other settings is never reused. The file's name also carries the hash of
its own contents (``<key>-<content hash>.csv``): an edited or damaged checkpoint is not read back
but computed again, and said so. ``run-scenario`` keeps them in
``<out>.checkpoints/<study>/`` beside its output folder (:func:`.outdir.default_checkpoint_dir`);
``reproduce`` in ``<results>/.cache/<scenario>/<study>/``.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import tempfile
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..codeversion import PACKAGE_DIR, numbers_hash
from ..physics.params import BaseParams, TMDParams, as_dict
from .engines import RunSettings, compute_sweep
from .sweeptable import SWEEP_COLUMNS

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

#: bump when the layout or meaning of a checkpoint file changes
CHECKPOINT_FORMAT = 4  # 4: the column amplitude_periodic


def code_version() -> str:
    """The code version a checkpoint key includes: :func:`pyfmu_wrapper.codeversion.numbers_hash`, the
    sha256 of every source that can change a number, Python and C (first 16 hex digits; computed once
    per process)."""
    return numbers_hash(PACKAGE_DIR)[:16]


@dataclass(frozen=True)
class SweepTask:
    """One configuration swept over the frequencies: the natural unit of parallel work."""

    base: BaseParams
    tmd: TMDParams
    omegas: np.ndarray
    settings: RunSettings

    def units(self) -> int:
        """Progress units of this task (one per frequency and direction)."""
        return len(self.omegas) * len(self.settings.directions())

    def key_payload(self) -> dict:
        """Everything the result depends on: code version, parameters, frequencies, engine and the
        resolved settings of the engines that compute the rows (:meth:`RunSettings.used`)."""
        s = self.settings
        payload = dict(
            format=CHECKPOINT_FORMAT,
            code=code_version(),
            base=as_dict(self.base),
            tmd=as_dict(self.tmd),
            omegas=[float(w).hex() for w in np.asarray(self.omegas, float)],
            settings=s.used(),
        )
        if s.workers != 1 and s.sweep.continuation:  # split sweeps (sequential executor) differ slightly
            payload["workers"] = s.workers
        return payload

    def key(self) -> str:
        """Hash of :meth:`key_payload` (the checkpoint file name)."""
        text = json.dumps(self.key_payload(), sort_keys=True, default=_exact_json)
        return hashlib.sha256(text.encode()).hexdigest()[:32]


def _exact_json(obj: Any) -> Any:
    """JSON of values json cannot write itself (numpy scalars, enums, dataclasses), without rounding."""
    if isinstance(obj, np.generic):
        return obj.item()
    if hasattr(obj, "__dataclass_fields__"):
        return asdict(obj)
    return repr(obj)


def run_task(task: SweepTask, keep_workers: bool = False, progress: Callable[..., Any] | None = None) -> pd.DataFrame:
    """Compute one task (the function every executor runs): the engine's sweep table.

    With ``sweep.continuation: false`` every frequency is its own one-point sweep, started from the
    engine's initial guess (the same rows, in the same order, as a continued sweep would give).
    keep_workers: keep ``settings.workers`` (the sequential executor); otherwise the executor is the
    parallelism and each sweep runs in one process (strict continuation). progress(n): called as
    frequency points finish (reporting only; the numbers do not depend on it).
    """
    settings = task.settings if keep_workers else replace(task.settings, workers=1)
    omegas = np.sort(np.asarray(task.omegas, float))
    if settings.sweep.continuation or len(omegas) < 2:
        return compute_sweep(task.base, task.tmd, omegas, settings, progress)
    parts = [compute_sweep(task.base, task.tmd, omegas[i : i + 1], settings, progress) for i in range(len(omegas))]
    table = pd.concat(parts, ignore_index=True)
    order = {d: k for k, d in enumerate(settings.directions())}
    key = table["direction"].map(order).fillna(0) * 1e9 + np.where(table["direction"] == "down", -1, 1) * table["omega"]
    return table.iloc[np.argsort(key.to_numpy(), kind="stable")].reset_index(drop=True)


# --- checkpoints ---------------------------------------------------------------------------------

_DTYPES = dict(
    engine=str,
    method=str,
    direction=str,
    omega=float,
    amplitude=float,
    amplitude_periodic=float,
    periods=int,
    converged=bool,
    irregular=bool,
    change=float,
    steps=int,
    rejected=int,
    wall_time=float,
)


class Checkpoint:
    """A folder of finished tasks, one CSV per task (lossless: floats written with 17 digits)."""

    def __init__(self, folder: Path, resume: bool = True, marker: dict | None = None) -> None:
        self.folder = Path(folder)
        self.resume = resume  #: False: never read back (recompute, overwrite)
        self.marker = marker  #: written as ``../.run-scenario.json`` with the first file (run-scenario's own folder)
        self.rejected: list[str] = []  #: checkpoint files found but not used (edited, damaged)

    def path(self, task: SweepTask, content: bytes | None = None) -> Path:
        """``<key>-<first 16 hex digits of the content's sha256>.csv``; without content, the pattern."""
        tag = "*" if content is None else hashlib.sha256(content).hexdigest()[:16]
        return self.folder / f"{task.key()}-{tag}.csv"

    def load(self, task: SweepTask) -> pd.DataFrame | None:
        if not self.resume or not self.folder.is_dir():
            return None
        for p in sorted(self.folder.glob(self.path(task).name)):
            try:
                data = p.read_bytes()
            except OSError:
                continue
            if p.name != self.path(task, data).name:
                self.rejected.append(f"{p} (its contents changed since it was written)")
                continue
            try:
                t = pd.read_csv(io.BytesIO(data), keep_default_na=True)
                t = t[list(SWEEP_COLUMNS)].astype({k: v for k, v in _DTYPES.items() if k in SWEEP_COLUMNS})
            except Exception:  # noqa: BLE001 - a damaged file: compute the task again
                self.rejected.append(f"{p} (unreadable)")
                continue
            if len(t) == task.units():
                return t
        return None

    def save(self, task: SweepTask, table: pd.DataFrame) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        if self.marker is not None and not (self.folder.parent / ".run-scenario.json").exists():
            (self.folder.parent / ".run-scenario.json").write_text(
                json.dumps(self.marker, indent=2) + "\n", encoding="utf-8"
            )
        buf = io.StringIO()
        table[list(SWEEP_COLUMNS)].to_csv(buf, index=False, float_format="%.17g")
        data = buf.getvalue().encode()
        fd, tmp = tempfile.mkstemp(prefix=".task-", suffix=".tmp", dir=self.folder)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, self.path(task, data))
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise

    def finished(self) -> int:
        return len(list(self.folder.glob("*.csv"))) if self.folder.is_dir() else 0


@dataclass
class TaskStats:
    """How many tasks a run read from checkpoints and how many it computed."""

    cached: int = 0
    computed: int = 0
    rejected: list[str] = field(default_factory=list)  #: checkpoint files not used (edited or damaged)
    wall_time: float = 0.0
