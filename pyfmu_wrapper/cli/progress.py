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
        speed of the points computed so far (None: unknown yet)."""
        with self._lock:
            computed = self.done - self.skipped
            left = self.total - self.done - max(0.0, self.instant - self.skipped)
        elapsed = time.monotonic() - self.t0
        if left <= 0:
            return 0.0
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
