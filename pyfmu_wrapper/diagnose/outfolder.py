"""The output folders of the diagnose tools (``diagnose``, ``make-benchmark``), on the shared rules
of :mod:`pyfmu_wrapper.safeio` (a new or empty folder, or an unchanged previous result of the same
tool, checked before computing and again at the swap; a folder that changed during the run is left
as it is and the result put beside it), and the check of a ``--out`` file (``score``) before any
computing.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Literal, NoReturn

from ..errors import InputError
from ..safeio import ResultFolder as _SafeFolder

if TYPE_CHECKING:
    from typing import Any

DIAGNOSE_MARKER = ".pyfmu-diagnose"  #: marks a folder written by diagnose
BENCHMARK_MARKER = ".pyfmu-benchmark"  #: marks a folder written by make-benchmark
TOOLS = {DIAGNOSE_MARKER: "diagnose", BENCHMARK_MARKER: "make-benchmark"}


def check_out_folder(out: Path | str, tool: str, marker: str) -> Path:
    """Refuse (an InputError, before any computing) an --out that is a file, or a non-empty folder
    that is not an unchanged previous result of ``tool``; returns the folder."""
    _SafeFolder(out, tool, marker).check()
    return Path(out)


def check_out_file(out: Path | str, what: str = "score.json") -> Path:
    """Refuse (InputError, before any computing) a ``--out`` file that cannot be written: a folder,
    a missing or unwritable parent folder. (Whether an existing file may be replaced is the caller's.)"""
    o = Path(out)
    if o.is_dir():
        raise InputError(f"--out {o}: is a folder; give a file name for {what}")
    parent = o.parent if str(o.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(
            f"--out {o}: the folder {parent} does not exist (or is not a folder): create it first; "
            "checked before scoring so that no work is lost"
        )
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--out {o}: the folder {parent} is not writable (permission denied)")
    if o.exists() and not os.access(o, os.W_OK):
        raise InputError(f"--out {o}: the file is not writable (permission denied)")
    return o


def _interrupt(signum: int, frame: Any) -> NoReturn:
    raise KeyboardInterrupt(f"signal {signum}")


class ResultFolder:
    """``with ResultFolder(out, marker) as tmp:`` write into tmp; on success tmp replaces ``out`` (the
    shared rules: :class:`pyfmu_wrapper.safeio.ResultFolder`); on failure, Ctrl-C, SIGTERM or SIGHUP
    tmp is removed. Partial folders of a killed run are removed on the next start, and said so."""

    def __init__(self, out: Path, marker: str) -> None:
        self.out, self.marker = Path(out), marker
        self.folder = _SafeFolder(out, TOOLS[marker], marker)

    def __enter__(self) -> Path:
        import signal
        import sys
        import threading

        for note in self.folder.clean_stale():
            print(f"{TOOLS[self.marker]}: note: {note}", file=sys.stderr)
        self.tmp = self.folder.begin()
        self.saved = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
                if sig is not None:
                    self.saved[sig] = signal.signal(sig, _interrupt)
        return self.tmp

    def __exit__(self, et: object, ev: object, tb: object) -> Literal[False]:
        import signal

        for sig, h in self.saved.items():
            signal.signal(sig, h)
        if et is not None:
            self.folder.abort()
            return False
        self.folder.commit()
        return False
