"""Where the sweeps of a scenario run: in this process, over the local cores, or on a Dask cluster.

The unit of parallel work is a :class:`SweepTask`: one parameter configuration swept over all the
frequencies of a study with continuation (one row of a two-parameter map, or one FRC curve). A
101 x 51 map is 51 independent tasks of 101 steady states. Every executor runs the *same* task
function, :func:`.tasks.run_task`, so a map computed sequentially, over local processes or on a Dask
cluster is the same map, number for number.

Executors (``make_executor(name, ...)``):

* ``sequential`` -- in this process, in order (what the runner does without an executor);
* ``local`` -- a :class:`concurrent.futures.ProcessPoolExecutor` over the local cores (default: all);
* ``dask`` -- ``distributed.Client(address).submit`` on an existing scheduler
  (``--scheduler tcp://host:8786``), or on a given ``Client`` (e.g. of a ``LocalCluster``). The
  workers need ``pyfmu_wrapper`` importable (the same environment). No other machinery is used.

:func:`run_tasks` reads finished tasks back from a :class:`~.tasks.Checkpoint` (resume) and has the
executor compute the missing ones, checkpointing each as it arrives.

Progress: the executors of this module report every finished frequency point (``progress(n)``,
fractions allowed), from worker processes too (a queue the pool's workers share); other executor
objects (anything with ``submit_all(tasks)``) report whole tasks. Interrupts: :meth:`LocalExecutor.abort`
ends the worker processes at once (the CLI calls it on SIGINT, SIGTERM and SIGHUP); on Linux the
workers also die with their parent (``PR_SET_PDEATHSIG``), so a killed run leaves no orphan worker.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import TYPE_CHECKING, Any

import pandas as pd

from .names import EXECUTORS
from .tasks import Checkpoint, SweepTask, TaskStats, run_task

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator

    from pandas import DataFrame

    from .tasks import SweepTask

#: EXECUTORS: the names the command line offers (scenario/names.py, imported light)


# --- executors -----------------------------------------------------------------------------------


class SequentialExecutor:
    """Runs the tasks in this process, in order."""

    name = "sequential"
    jobs = 1
    reports_points = True  #: submit_all takes progress(i, n): n points of task i finished

    def submit_all(
        self, tasks: list[SweepTask], progress: Callable[..., Any] | None = None
    ) -> Iterator[tuple[int, pd.DataFrame]]:
        for i, t in enumerate(tasks):
            cb = None if progress is None else (lambda n, i=i: progress(i, n))
            yield i, run_task(t, keep_workers=True, progress=cb)

    def close(self) -> None:
        pass

    def abort(self) -> None:
        pass

    def processes_used(self) -> int:
        return 1

    def describe(self) -> str:
        return "sequential (this process)"


_WORKER_QUEUE = None  # set in each worker of a LocalExecutor's pool: where finished points are reported


def _worker_init(queue: Any) -> None:
    """Initializer of the local pool's workers: report points through ``queue``; die with the parent
    (Linux PR_SET_PDEATHSIG), leave SIGINT to the parent (which ends the workers itself)."""
    global _WORKER_QUEUE
    _WORKER_QUEUE = queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):  # not the parent's handlers (forked): a worker ends when told to
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG
        if os.getppid() == 1:  # the parent died before prctl: do not run on as an orphan
            os._exit(1)
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass


def _run_task_reporting(token: tuple[int, int], task: SweepTask) -> pd.DataFrame:
    q = _WORKER_QUEUE
    cb = None if q is None else (lambda n: q.put((token, n)))
    return run_task(task, progress=cb)


class LocalExecutor:
    """A process pool over the local cores (``jobs`` processes; 0 or None: all cores)."""

    name = "local"
    reports_points = True

    def __init__(self, jobs: int | None = 0) -> None:
        self.jobs = int(jobs) if jobs else (os.cpu_count() or 1)
        self._pool: ProcessPoolExecutor | None = None
        self._queue: Any = None  #: a multiprocessing queue while the pool runs (its type depends on the context)
        self._max_processes = 0  #: worker processes started (0: everything ran in this process)
        self._batch = 0

    def submit_all(
        self, tasks: list[SweepTask], progress: Callable[..., Any] | None = None
    ) -> Iterator[tuple[int, DataFrame]]:
        if not tasks:
            return
        if self.jobs == 1 or len(tasks) == 1:
            yield from SequentialExecutor().submit_all(tasks, progress)
            return
        if self._pool is None:
            self._queue = mp.get_context("fork").Queue() if "fork" in mp.get_all_start_methods() else mp.Queue()
            self._pool = ProcessPoolExecutor(max_workers=self.jobs, initializer=_worker_init, initargs=(self._queue,))
        self._batch += 1
        futs = {self._pool.submit(_run_task_reporting, (self._batch, i), t): i for i, t in enumerate(tasks)}
        started = len(getattr(self._pool, "_processes", None) or ()) or self.jobs
        self._max_processes = max(self._max_processes, min(started, len(tasks)))  # busy at most one task each
        # no cancelling here when the caller stops early: close() cancels what has not started, abort()
        # ends the workers (a cancelled future in a pool whose workers are then ended makes the pool's
        # manager thread fail: CPython 3.11 sets the 'broken pool' exception on it)
        pending = set(futs)
        while pending:
            done, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            self._drain(progress)
            for f in done:
                yield futs[f], f.result()

    def _drain(self, progress: Callable[..., Any] | None) -> None:
        import queue as _queue

        while True:
            try:
                (batch, i), n = self._queue.get_nowait()
            except _queue.Empty:
                return
            if progress is not None and batch == self._batch:
                progress(i, n)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._queue is not None:
            self._queue.close()
            self._queue = None

    def abort(self) -> None:
        """End the worker processes now (an interrupt): no task finishes, no worker is left running."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        items = getattr(pool, "_pending_work_items", None)
        if isinstance(items, dict):  # cancelled ones would make the manager thread fail (see submit_all)
            for k, item in list(items.items()):
                if item.future.cancelled():
                    items.pop(k, None)
        procs = list((getattr(pool, "_processes", None) or {}).values())
        for p in procs:
            with contextlib.suppress(Exception):  # already gone
                p.terminate()
        for p in procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join(timeout=5)
        pool.shutdown(wait=False, cancel_futures=True)
        if self._queue is not None:
            self._queue.cancel_join_thread()
            self._queue.close()
            self._queue = None

    def processes_used(self) -> int:
        """Processes that computed sweeps: the pool's workers started, or 1 (this process)."""
        return max(1, self._max_processes)

    def describe(self) -> str:
        return f"local process pool ({self.jobs} processes)"


class DaskExecutor:
    """``distributed.Client.submit`` of the same task function on a Dask cluster.

    scheduler: address of a running scheduler (``tcp://host:8786``), or a ``distributed.Client``
    (tests pass the client of a ``LocalCluster``).
    """

    name = "dask"

    def __init__(self, scheduler: Any) -> None:
        try:
            import distributed
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise RuntimeError("the dask executor needs dask[distributed]: pip install 'pyfmu-wrapper[dask]'") from exc
        self._distributed = distributed
        if isinstance(scheduler, distributed.Client):
            self.client, self._own = scheduler, False
        else:
            if not scheduler:
                raise ValueError("the dask executor needs a scheduler address (--scheduler tcp://HOST:PORT)")
            self.client, self._own = distributed.Client(scheduler), True

    def submit_all(
        self, tasks: list[SweepTask], progress: Callable[..., Any] | None = None
    ) -> Iterator[tuple[int, pd.DataFrame]]:
        if not tasks:
            return
        futs = [self.client.submit(run_task, t, pure=False) for t in tasks]
        index = {f.key: i for i, f in enumerate(futs)}
        try:
            for f in self._distributed.as_completed(futs):
                yield index[f.key], f.result()
        finally:
            self.client.cancel([f for f in futs if not f.done()])

    def close(self) -> None:
        if self._own:
            self.client.close()

    def abort(self) -> None:
        self.close()

    def processes_used(self) -> int:
        try:
            return len(self.client.scheduler_info().get("workers", {})) or 1
        except Exception:  # noqa: BLE001 - a closed client
            return 1

    def describe(self) -> str:
        return f"dask ({self.client.scheduler.address})"


#: what runs a scenario's sweep tasks (``make_executor``)
Executor = SequentialExecutor | LocalExecutor | DaskExecutor


def make_executor(name: str = "local", jobs: int | None = 0, scheduler: str | None = None) -> Executor:
    """An executor by name: 'local' (process pool, ``jobs`` processes), 'dask' (``scheduler``), 'sequential'."""
    if name == "local":
        return LocalExecutor(jobs)
    if name == "dask":
        return DaskExecutor(scheduler)
    if name == "sequential":
        return SequentialExecutor()
    raise ValueError(f"unknown executor {name!r}; available: {list(EXECUTORS)}")


def run_tasks(
    tasks: list[SweepTask],
    executor: Executor | None = None,
    checkpoint: Checkpoint | None = None,
    progress: Callable[[float], object] | None = None,
    stats: TaskStats | None = None,
) -> list[pd.DataFrame]:
    """Results of ``tasks`` in order: read from ``checkpoint`` where finished, computed by ``executor``
    (None: sequentially here) otherwise; each computed result is checkpointed as soon as it arrives."""
    stats = stats if stats is not None else TaskStats()
    t0 = time.perf_counter()
    out: list[pd.DataFrame | None] = [None] * len(tasks)
    missing = []
    for i, t in enumerate(tasks):
        got = checkpoint.load(t) if checkpoint is not None else None
        if got is not None:
            out[i] = got
            stats.cached += 1
            if progress is not None:  # read back, not computed: not counted in the speed of an ETA
                getattr(progress, "skip", progress)(t.units())
        else:
            missing.append(i)
    if checkpoint is not None:
        stats.rejected += checkpoint.rejected
        checkpoint.rejected = []
    ex = executor if executor is not None else SequentialExecutor()
    reported = [0.0] * len(missing)  # points of each missing task already reported

    per_sweep = getattr(progress, "task_points", None)  # a progress that measures each sweep's own cost

    def report(j: int, n: float) -> None:
        if per_sweep is not None:
            per_sweep(id(todo[j]), n, todo[j].units())
        elif progress is not None:
            progress(n)

    def points(j: int, n: float) -> None:  # capped: a late report of a finished task is not counted twice
        n = min(n, todo[j].units() - reported[j])
        if n > 0 and progress is not None:  # points is handed over only with a progress
            reported[j] += n
            report(j, n)

    todo = [tasks[i] for i in missing]
    results = (
        ex.submit_all(todo, points)
        if getattr(ex, "reports_points", False) and progress is not None
        else ex.submit_all(todo)
    )
    for j, table in results:
        i = missing[j]
        out[i] = table
        stats.computed += 1
        if checkpoint is not None:
            checkpoint.save(tasks[i], table)
        if progress is not None and tasks[i].units() - reported[j] > 1e-9:
            report(j, tasks[i].units() - reported[j])
        reported[j] = tasks[i].units()
    stats.wall_time += time.perf_counter() - t0
    return out
