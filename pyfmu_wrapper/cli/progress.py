"""The progress report of run-scenario: points done, elapsed time and an estimate of the time left,
one line redrawn on a terminal, a plain line every few seconds in a log."""

from __future__ import annotations

import sys
import threading
import time
from typing import Literal, TextIO


def _fmt_time(s: float | None) -> str:
    if s is None:
        return "?"
    s = max(0, int(round(s)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """Progress per frequency point, with an ETA from the speed of the points computed so far.

    Called as ``progress(n)`` (n points finished, fractions allowed) or ``progress.skip(n)`` (points
    read from checkpoints or closed-form: counted as done, not in the speed). A background thread
    redraws one line every second on a terminal (``\\r``) and, when stderr is not a terminal (a log
    file, a pipe), writes one plain line every ``interval`` seconds (every ``6 * interval`` s while
    nothing has moved).
    """

    def __init__(
        self,
        total: float,
        name: str,
        stream: TextIO | None = None,
        tty: bool | None = None,
        interval: float = 5.0,
        enabled: bool = True,
        instant: float = 0.0,
    ) -> None:
        self.total, self.name = float(total), name
        self.instant = float(instant)  #: points known to cost nothing (closed form, repeated sweeps)
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)()) if tty is None else tty
        self.interval = 1.0 if self.tty else float(interval)
        self.enabled = enabled
        self.done = self.skipped = 0.0
        self.t0 = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._last = (0.0, -1.0)  # (time, done) of the last line written
        self._thread: threading.Thread | None = None
        #: per sweep (an FRC curve, a map row) reported by task_points: [points, done, first report
        #: time, last report time, points of the first report]
        self._tasks: dict[object, list[float]] = {}
        self._parallel = 1  #: the most sweeps seen running at once

    def task_points(self, key: object, n: float, units: float) -> None:
        """``n`` points of the sweep ``key`` (of ``units`` points) finished: counted as ``progress(n)``,
        and the sweep's own cost per point measured for the time left (:meth:`eta`)."""
        now = time.monotonic()
        with self._lock:
            self.done += n
            rec = self._tasks.get(key)
            if rec is None:
                self._tasks[key] = [float(units), float(n), now, now, float(n)]
            else:
                rec[1] += n
                rec[3] = now
            running = sum(1 for r in self._tasks.values() if r[1] < r[0] - 1e-9)
            self._parallel = max(self._parallel, running)

    def _eta_per_sweep(self, left: float) -> float | None:
        """Time left from the measured cost per point of each sweep: a sweep that has reported twice
        costs what its own points cost so far (an expensive curve after a cheap one is not
        underestimated); the others, and the points of sweeps not started, the mean of those costs;
        the sum divided by the sweeps seen running at once. None until a sweep has a cost."""
        costs = {}
        for k, (_, done, t1, t2, n1) in self._tasks.items():
            if done > n1 + 1e-9 and t2 > t1:
                costs[k] = (t2 - t1) / (done - n1)
        if not costs:
            return None
        mean = sum(costs.values()) / len(costs)
        tracked = 0.0
        work = 0.0
        for k, (units, done, *_) in self._tasks.items():
            rest = max(0.0, units - done)
            tracked += rest
            work += rest * costs.get(k, mean)
        work += max(0.0, left - tracked) * mean
        return work / max(1, self._parallel)

    def __enter__(self) -> Progress:
        if self.enabled:
            self._thread = threading.Thread(target=self._loop, name="run-scenario-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close(final=exc[0] is None)
        return False

    def __call__(self, n: float = 1) -> None:
        with self._lock:
            self.done += n

    def skip(self, n: float = 1) -> None:
        with self._lock:
            self.done += n
            self.skipped += n

    def note(self, text: str) -> None:
        """One line of a step that is not a point (``building FMUs``), written at once (nothing when disabled)."""
        if self.enabled:
            with self._lock:
                self.stream.write(
                    ("\r" if self.tty else "") + f"run-scenario: {text}".ljust(110 if self.tty else 0) + "\n"
                )
                self.stream.flush()

    def eta(self) -> float | None:
        """Seconds left: the points still to compute (those known to cost nothing left out) at the
        measured cost per point of each sweep when the sweeps report themselves (:meth:`task_points`,
        the process pool's), else at the speed of the points computed so far (None: unknown yet)."""
        with self._lock:
            computed = self.done - self.skipped
            left = self.total - self.done - max(0.0, self.instant - self.skipped)
        elapsed = time.monotonic() - self.t0
        if left <= 0:
            return 0.0
        with self._lock:
            per_sweep = self._eta_per_sweep(left) if self._tasks else None
        if per_sweep is not None:
            return per_sweep
        if computed <= 0 or elapsed <= 0:
            return None
        return left * elapsed / computed

    def line(self) -> str:
        with self._lock:
            done = self.done
        pct = 100.0 * done / self.total if self.total else 100.0
        eta = self.eta()
        left = "estimating the time left" if eta is None else f"about {_fmt_time(eta)} left"
        return (
            f"run-scenario: {self.name}: {done:.0f}/{self.total:.0f} points ({pct:.0f} %), "
            f"{_fmt_time(time.monotonic() - self.t0)} elapsed, {left}"
        )

    def _emit(self, final: bool = False) -> None:
        text = self.line()
        if self.tty:
            self.stream.write("\r" + text.ljust(110) + ("\n" if final else ""))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self._last = (time.monotonic(), self.done)

    def _loop(self) -> None:
        while not self._stop.wait(0.2):
            now = time.monotonic()
            since = now - self._last[0]
            moved = self.done != self._last[1]
            if since >= self.interval and (moved or self.tty or since >= 6 * self.interval):
                self._emit()

    def close(self, final: bool = True) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
            if final:
                self._emit(final=True)
            elif self.tty:
                self.stream.write("\n")
                self.stream.flush()


class StageProgress:
    """The progress report of ``diagnose`` (:mod:`pyfmu_wrapper.diagnose.progress`): the stage it is in,
    the candidate fits done, the elapsed time. Every new stage is one line; while a stage runs, a
    background thread redraws the line every second on a terminal, and in a log writes a plain line
    every ``interval`` seconds when candidates were done since the last one. Nothing is written in
    the first ``quiet_start`` seconds: a refusal of bad input stays the one line it is."""

    def __init__(
        self,
        prog: str,
        stream: TextIO | None = None,
        tty: bool | None = None,
        interval: float = 5.0,
        enabled: bool = True,
        quiet_start: float = 1.0,
    ) -> None:
        self.prog = prog
        self.quiet_start = float(quiet_start)
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)()) if tty is None else tty
        self.interval = 1.0 if self.tty else float(interval)
        self.enabled = enabled
        self.t0 = time.monotonic()
        self.name = "starting"
        self.done = 0  #: candidate fits done in the current stage
        self.total = 0  #: candidate fits done in all
        self.last = ""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._written = (self.t0, 0)
        self._pending = False  # a stage not yet written
        self._any = False  # anything written
        self._thread: threading.Thread | None = None
        self._open = False  # a redrawn line is on the terminal

    def __enter__(self) -> StageProgress:
        if self.enabled:
            self._thread = threading.Thread(target=self._loop, name="diagnose-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close(final=exc[0] is None)
        return False

    def stage(self, name: str) -> None:
        with self._lock:
            self.name, self.done, self.last = name, 0, ""
            self._pending = True
        if time.monotonic() - self.t0 >= self.quiet_start:
            self._emit(newline_before=True)

    def candidate(self, label: str) -> None:
        with self._lock:
            self.done += 1
            self.total += 1
            self.last = label

    def line(self) -> str:
        with self._lock:
            name, done, last = self.name, self.done, self.last
        fits = f", {done} candidate fit{'s' if done != 1 else ''} done" + (f" (last: {last})" if last else "")
        return f"{self.prog}: {name}{fits if done else ''}, {_fmt_time(time.monotonic() - self.t0)} elapsed"

    def _emit(self, newline_before: bool = False, final: bool = False) -> None:
        if not self.enabled:
            return
        text = self.line()
        if self.tty:
            lead = "\n" if (newline_before and self._open) else "\r"
            self.stream.write(lead + text.ljust(110) + ("\n" if final else ""))
            self._open = not final
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self._written = (time.monotonic(), self.total)
        self._pending, self._any = False, True

    def _loop(self) -> None:
        while not self._stop.wait(0.2):
            now = time.monotonic()
            if now - self.t0 < self.quiet_start:
                continue
            since = now - self._written[0]
            if self._pending:
                self._emit(newline_before=True)
            elif since >= self.interval and (self.tty or self.total != self._written[1]):
                self._emit()

    def close(self, final: bool = True) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if final and self._any:  # a run long enough to have reported: its end too
            self.stage("done")
            if self.tty and self._open:
                self.stream.write("\n")
                self.stream.flush()
                self._open = False
        elif self.tty and self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False
