"""The results folder of run-scenario: where it goes, and the rules that keep the tool from losing
anything it did not write.

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
import json
import os
import re
import shutil
import socket
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .schema import Scenario

#: the marker file of every folder run-scenario writes (results, partial folders, checkpoints)
MARKER = ".run-scenario.json"
TOOL = "run-scenario"


class OutputError(ValueError):
    """An output folder the tool refuses to write (it would lose something it did not write)."""


def tool_version() -> str | None:
    """The installed version of this package (None when it runs from a source tree not installed)."""
    try:
        return metadata.version("pyfmu-wrapper")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return None


def default_output_dir(scn: Scenario) -> Path:
    """Where a scenario's results go when no ``--out`` is given: ``results/<scenario name>``."""
    return Path("results") / scn.name


def default_checkpoint_dir(out_dir: str | os.PathLike[str]) -> Path:
    """Where the resumable checkpoints of a results folder live: ``<out>.checkpoints/`` beside it
    (one folder per output folder: ``--out /tmp/foo`` -> ``/tmp/foo.checkpoints/``)."""
    out = abs_path(out_dir)
    return out.with_name(out.name + ".checkpoints")


def abs_path(p: str | os.PathLike[str]) -> Path:
    """Absolute, normalised ('.', '..' and doubled slashes removed) without resolving symbolic links."""
    return Path(os.path.abspath(os.fspath(p)))


def read_marker(folder: Path) -> dict[str, Any] | None:
    """The marker of a folder written by run-scenario, or None (absent, unreadable or not ours)."""
    try:
        m = json.loads((Path(folder) / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return m if isinstance(m, dict) and m.get("tool") == TOOL else None


def write_marker(folder: Path, **fields: Any) -> None:
    """Write the run-scenario marker of ``folder`` (tool, version and ``fields``)."""
    m = dict(tool=TOOL, version=tool_version(), **fields)
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
    out = abs_path(out)
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
    out = abs_path(out)
    if out.parent == out or not out.name:
        raise OutputError(f"--out {given}: refusing to write results to the root folder")
    protected = [("the current folder", Path.cwd()), ("your home folder", Path.home())]
    if scenario_path is not None:
        protected.append(("the scenario file", abs_path(scenario_path)))
    for what, p in protected:
        for q in {abs_path(p), Path(p).resolve()}:
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
    ck = abs_path(checkpoint_dir) if checkpoint_dir is not None else None
    if ck is not None and ck == default_checkpoint_dir(out) and ck.exists():
        m = read_marker(ck)
        foreign_ck = not ck.is_dir() or ck.is_symlink() or m is None or m.get("kind") != "checkpoints"
        if foreign_ck and not (ck.is_dir() and not os.listdir(ck)):
            raise OutputError(
                f"--out {given}: the checkpoint folder {ck} exists but was not written by "
                "run-scenario; refusing to write into it (move it, or choose another --out)"
            )
    return clean_stale_partials(out)


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


def replace_dir(tmp: Path, out: Path) -> None:
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
