"""The output folders of the diagnose tools (``diagnose``, ``make-benchmark``): a new or empty
folder, or a previous result of the same tool (marked by a marker file). The result is written to a
hidden sibling folder first (with the permissions the umask gives) and swapped in, so a failed run
leaves the old result, and nothing the tool did not write is ever deleted or overwritten. Also the
check of a ``--out`` file (``score``) before any computing.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Literal, NoReturn

from ..cli.errors import InputError

if TYPE_CHECKING:
    from typing import Any

DIAGNOSE_MARKER = ".pyfmu-diagnose"  #: marks a folder written by diagnose
BENCHMARK_MARKER = ".pyfmu-benchmark"  #: marks a folder written by make-benchmark
#: files of a result written before the markers existed (recognised as a previous result)
_LEGACY = {
    DIAGNOSE_MARKER: ("diagnosis.json", {"report.md", "diagnosis.json"}, (".png",)),
    BENCHMARK_MARKER: ("manifest.json", {"manifest.json", "score.json"}, ()),
}


def _files(folder: Path) -> set:
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if not p.is_dir()}


def _foreign(folder: Path, marker: str) -> list | None:
    """Files in ``folder`` that the tool writing ``marker`` did not write (None: not a result at all)."""
    m = folder / marker
    if m.is_file():
        try:
            written = set(json.loads(m.read_text(encoding="utf-8"))["files"])
        except (ValueError, KeyError, TypeError, OSError):
            return None
        return sorted(_files(folder) - written - {marker})
    key, names, suffixes = _LEGACY[marker]  # a result written before the marker existed
    if not (folder / key).is_file():
        return None
    bad = []
    for e in folder.iterdir():
        if e.is_file() and (e.name in names or e.suffix in suffixes):
            continue
        if marker == BENCHMARK_MARKER and e.is_dir() and (e / "dataset.yaml").is_file():
            continue
        bad.append(e.name)
    return sorted(bad)


def _is_result(folder: Path, marker: str) -> bool:
    """True when ``folder`` holds a previous result of the tool that writes ``marker``, and nothing else."""
    return _foreign(folder, marker) == []


def check_out_folder(out: Path | str, tool: str, marker: str) -> Path:
    """Refuse (InputError, before any computing) an --out that is a file, or a non-empty folder
    that is not a previous result of ``tool`` (or holds files ``tool`` did not write)."""
    out = Path(out)
    if out.exists() or out.is_symlink():
        if not out.is_dir():
            raise InputError(
                f"--out {out}: is a file, not a folder; {tool} writes a folder and never overwrites "
                "a file: choose a new folder name"
            )
        if any(out.iterdir()):
            bad = _foreign(out, marker)
            if bad is None:
                raise InputError(
                    f"--out {out}: the folder is not empty and is not a previous {tool} result (no "
                    f"{marker} marker): choose a new or empty folder; {tool} never deletes or "
                    "overwrites files it did not write"
                )
            if bad:
                raise InputError(
                    f"--out {out}: a previous {tool} result, but it also holds files {tool} did not "
                    f"write ({', '.join(bad[:3])}{', ...' if len(bad) > 3 else ''}): move them or "
                    "choose another folder; the result is replaced as a whole"
                )
    elif not out.parent.is_dir() and out.parent != Path(""):
        out.parent.mkdir(parents=True, exist_ok=True)
    return out


def current_umask() -> int:
    """The process's file-mode creation mask (read by setting and restoring it)."""
    m = os.umask(0o022)
    os.umask(m)
    return m


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


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _interrupt(signum: int, frame: Any) -> NoReturn:
    raise KeyboardInterrupt(f"signal {signum}")


class ResultFolder:
    """``with ResultFolder(out, marker) as tmp:`` write into tmp; on success tmp replaces ``out``
    (a previous result of the same tool, or an empty folder); on failure, Ctrl-C, SIGTERM or SIGHUP
    tmp is removed. Partial folders of a killed run (``.<out>.partial-<pid>-*`` of a dead process)
    are removed on the next start, and said so."""

    def __init__(self, out: Path, marker: str) -> None:
        self.out, self.marker = Path(out), marker
        self.parent = self.out.parent if str(self.out.parent) else Path(".")

    def _stale(self) -> None:
        for p in self.parent.glob(f".{self.out.name}.partial-*"):
            try:
                pid = int(p.name.rsplit(".partial-", 1)[1].split("-")[0])
            except ValueError:
                continue
            if p.is_dir() and not _pid_alive(pid):
                shutil.rmtree(p, ignore_errors=True)
                print(f"removed {p}: the partial result of an interrupted run (process {pid})", file=sys.stderr)

    def __enter__(self) -> Path:
        import signal
        import threading

        self._stale()
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.partial-{os.getpid()}-", dir=self.parent))
        os.chmod(self.tmp, 0o777 & ~current_umask())  # mkdtemp makes it 0700; a result folder follows the umask
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
            shutil.rmtree(self.tmp, ignore_errors=True)
            return False
        files = sorted(_files(self.tmp))
        (self.tmp / self.marker).write_text(
            json.dumps(
                {
                    "note": "written by pyfmu_wrapper; replaced as a whole when the tool runs again with the same --out, "
                    "refused if other files are added",
                    "files": files,
                },
                indent=0,
            )
            + "\n"
        )
        old = None
        if self.out.exists():  # checked before computing: a previous result or an empty folder
            if not (not any(self.out.iterdir()) or _is_result(self.out, self.marker)):
                raise InputError(
                    f"--out {self.out}: files appeared in the folder during the run; nothing there "
                    f"was touched and the result was left in {self.tmp}"
                )
            old = self.parent / f".{self.out.name}.old-{os.getpid()}"
            os.replace(self.out, old)
        os.replace(self.tmp, self.out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return False
