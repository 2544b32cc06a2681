"""Output folders that never lose what the tool did not write: one implementation for every writer
(``run-scenario``, ``diagnose``, ``make-benchmark``, ``reproduce``).

**A result folder** (:class:`ResultFolder`) is written whole into a hidden sibling
``.<name>.partial-<pid>-XXXX`` and put in place in one step when complete. Its marker file (one
name per tool) records the tool, the kind ``result`` and every file and folder written, each file
with its SHA-256. The folder at ``--out`` is replaced only when everything in it is provably the
tool's own, unchanged (:func:`foreign_entries`); the check is made twice:

* before computing (:meth:`ResultFolder.check`): a file, a symbolic link, ``/``, a protected folder
  (the current folder, home, the input's folder), anything in the folder the tool did not write or
  a file edited since it wrote it, an unwritable parent or folder: refused (:class:`OutputError`,
  exit status 2), nothing computed, nothing touched;
* at the swap (:meth:`ResultFolder.commit`): the new folder and the old one are exchanged in one
  step (Linux ``renameat2(RENAME_EXCHANGE)``; two renames elsewhere), then the old folder, now at the
  hidden name, is checked again. If anything appeared or changed in it during the run, the exchange
  is undone, the user's folder is left exactly as it is, and the new result is moved beside it,
  ``<name>.new-<time>``, and the caller says where (:class:`Diverted`). Otherwise the old folder is
  removed file by file, each file's hash checked again just before it is unlinked; a file that
  changed in that last instant, or anything left, keeps the folder as ``<name>.old-<time>``.

So nothing the tool did not write is ever deleted or overwritten, even when it appears while the
tool runs. A partial folder left by a killed run is recognised by its name and marker (naming the
process and the host) and removed on the next start; one without the marker is only reported.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import os
import re
import socket
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .tree import (
    Diverted,
    OutputError,
    abs_path,
    exchange,
    foreign_entries,
    inventory,
    move_new,
    pid_alive,
    read_marker,
    remove_own,
    remove_partial,
    shown,
    stamp,
    write_marker,
)


class ResultFolder:
    """A results folder written complete or not at all, never over what ``tool`` did not write
    (see the module doc). Use::

        rf = ResultFolder(out, "diagnose", ".pyfmu-diagnose")
        notes = rf.check()        # before computing: OutputError on anything in the way
        tmp = rf.begin()          # write the result into tmp
        path = rf.commit(extra)   # swap it in (Diverted: put beside, the user's folder untouched)
        # on failure: rf.abort()
    """

    def __init__(
        self,
        out: str | os.PathLike[str],
        tool: str,
        marker: str,
        *,
        option: str = "--out",
        protect: Iterable[tuple[str, Path]] = (),
        same: dict[str, Any] | None = None,
    ) -> None:
        self.given = os.fspath(out)
        self.out = abs_path(out)
        self.tool, self.marker, self.option = tool, marker, option
        self.protect = [("the current folder", Path.cwd()), ("your home folder", Path.home()), *protect]
        self.same = same or {}  #: marker fields an earlier result must match to be replaced (e.g. its input file)
        self.tmp: Path | None = None

    def _fail(self, text: str) -> OutputError:
        return OutputError(f"{self.option} {self.given}: {text}")

    def check(self) -> list[str]:
        """Refuse, before computing, an output that could lose anything; clean stale partial folders.
        Returns the notes to show."""
        out = self.out
        if out.parent == out or not out.name:
            raise self._fail("refusing to write results to the root folder")
        for what, p in self.protect:
            for q in {abs_path(p), Path(p).resolve()}:
                if out == q or out in q.parents or out.resolve() == q or out.resolve() in q.parents:
                    raise self._fail(f"refusing to replace {out}, which is or contains {what} ({q}); give a new folder")
        if out.is_symlink():
            raise self._fail(f"{out} is a symbolic link; give the folder itself")
        if out.exists() and not out.is_dir():
            raise self._fail(f"{out} exists and is not a folder; refusing to replace it (choose another {self.option})")
        for anc in out.parents:
            if anc.exists():
                if not anc.is_dir():
                    raise self._fail(f"{anc} is a file, so {out} cannot be a folder")
                if not os.access(anc, os.W_OK | os.X_OK) and anc == out.parent:
                    raise self._fail(f"cannot write into {anc}: permission denied; nothing was computed")
                break
        if out.is_dir():
            foreign = foreign_entries(out, self.marker, self.tool)
            if foreign and read_marker(out, self.marker, self.tool) is None:
                raise self._fail(
                    f"{out} is a non-empty folder that is not a result of {self.tool} (it holds {shown(foreign)}); "
                    "refusing to replace it: nothing was computed or touched. Choose a new folder, or empty this one "
                    "yourself"
                )
            if foreign:
                raise self._fail(
                    f"{out} holds what {self.tool} did not write, or changed since ({shown(foreign)}); refusing to "
                    "replace it: nothing was computed or touched. Choose a new folder, or move those yourself"
                )
            m = read_marker(out, self.marker, self.tool)
            for k, v in self.same.items():
                if m is not None and m.get(k) is not None and m.get(k) != v:
                    raise self._fail(
                        f"{out} holds the result of another {k.replace('_', ' ')} ({m.get(k)}, not {v}); refusing "
                        "to replace it. Give another --out, or delete that folder yourself"
                    )
            self._probe(out)
        notes = self.clean_stale()
        return notes

    def _probe(self, folder: Path) -> None:
        """A folder we will move must be writable (a read-only or immutable folder is found now)."""
        try:
            fd, name = tempfile.mkstemp(prefix=f".{self.tool}-probe-", dir=folder)
            os.close(fd)
            os.unlink(name)
        except OSError as exc:
            raise self._fail(f"cannot write into {folder}: {exc.strerror or exc}; nothing was computed") from None

    def _partials(self) -> list[Path]:
        pat = re.compile(re.escape(f".{self.out.name}.") + r"(partial|old)-")
        try:
            return sorted(
                p for p in self.out.parent.iterdir() if pat.match(p.name) and p.is_dir() and not p.is_symlink()
            )
        except FileNotFoundError:
            return []

    def clean_stale(self) -> list[str]:
        """Remove partial folders of killed runs of this output (name and marker prove them ours, the
        process is gone); report the others. OutputError if a live run writes the same output."""
        notes = []
        for p in self._partials():
            m = read_marker(p, self.marker, self.tool)
            if m is not None and m.get("kind") == "partial" and m.get("out") == str(self.out):
                same_host = m.get("host") == socket.gethostname()
                if same_host and m.get("pid") != os.getpid() and pid_alive(m.get("pid")):
                    raise self._fail(
                        f"another {self.tool} (process {m.get('pid')}, started {m.get('started')}) is writing this "
                        f"output folder now (its partial folder: {p}); wait for it, stop it, or choose another folder"
                    )
                if same_host:
                    remove_partial(p)
                    notes.append(
                        f"removed {p}, the partial folder of an interrupted {self.tool} (process {m.get('pid')}, "
                        f"started {m.get('started')})"
                    )
                    continue
            notes.append(
                f"found {p}: it looks like the partial folder of an interrupted run, but it does not carry "
                f"{self.tool}'s marker for this output (or was written on another machine); left alone"
            )
        return notes

    def begin(self) -> Path:
        """Create the hidden partial folder beside the output (an ordinary folder: mode from the umask)."""
        self.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.partial-{os.getpid()}-", dir=self.out.parent))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)
        self.tmp = tmp
        write_marker(
            tmp,
            self.marker,
            self.tool,
            kind="partial",
            out=str(self.out),
            pid=os.getpid(),
            host=socket.gethostname(),
            started=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        )
        return tmp

    def abort(self) -> None:
        if self.tmp is not None:
            remove_partial(self.tmp)
            self.tmp = None

    def commit(self, **fields: Any) -> Path:
        """Write the marker (every file with its hash, plus ``fields``) and put the folder in place.
        Returns the output folder; raises :class:`Diverted` (the result beside it) when the output
        folder changed during the run."""
        tmp = self.tmp
        assert tmp is not None, "begin() first"
        write_marker(
            tmp, self.marker, self.tool, kind="result", out=str(self.out), **fields, **inventory(tmp, self.marker)
        )
        self.tmp = None
        out = self.out
        if not (out.exists() or out.is_symlink()):
            try:
                move_new(tmp, out)
                return out
            except FileExistsError:
                pass  # it appeared during the run: handled as an existing folder
        if out.is_symlink() or not out.is_dir():
            return self._divert(tmp, [f"{out.name} (appeared during the run)"])
        exchange(tmp, out)  # out: the new result; tmp: what was there
        foreign = foreign_entries(tmp, self.marker, self.tool)
        if foreign:
            exchange(tmp, out)  # undo: the user's folder back, untouched
            return self._divert(tmp, foreign)
        left = remove_own(tmp, self.marker, self.tool)
        if left:
            kept = out.with_name(f"{out.name}.old-{stamp()}")
            with contextlib.suppress(OSError):
                move_new(tmp, kept)
        return out

    def _divert(self, tmp: Path, foreign: list[str]) -> Path:
        beside = self.out.with_name(f"{self.out.name}.new-{stamp()}")
        move_new(tmp, beside)
        raise Diverted(
            f"{self.out} changed while {self.tool} ran ({shown(foreign)}): it was left exactly as it is, and the "
            f"new result was written to {beside} instead",
            beside,
        )
