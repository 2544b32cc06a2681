"""What ``diagnose`` reports while it works: the stage it is in and the candidate fits done, with the
elapsed time (the console script shows them, :class:`pyfmu_wrapper.cli.progress.StageProgress`).

The diagnosis calls :func:`stage` when it enters a stage (reading, FRC records, time records,
transient records, report) and :func:`candidate` after each candidate fit (an effect or a set of
effects fitted); with no reporter installed (a library call, the tests) both do nothing.
"""

from __future__ import annotations

from typing import Protocol


class Reporter(Protocol):
    def stage(self, name: str) -> None: ...

    def candidate(self, label: str) -> None: ...


_REPORTER: Reporter | None = None


def set_reporter(reporter: Reporter | None) -> Reporter | None:
    """Install ``reporter`` (None: none); returns the one it replaces."""
    global _REPORTER
    old, _REPORTER = _REPORTER, reporter
    return old


def stage(name: str) -> None:
    """The diagnosis enters stage ``name``."""
    if _REPORTER is not None:
        _REPORTER.stage(name)


def candidate(label: str) -> None:
    """A candidate fit (``label``: its effects) is done."""
    if _REPORTER is not None:
        _REPORTER.candidate(label)
