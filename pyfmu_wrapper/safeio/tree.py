"""What a folder holds and what a tool wrote: file hashes, markers, the entries a tool did not write,
removal of only what is provably ours, and the renames that never replace (Linux ``renameat2``).
The rules they serve are described in :mod:`.folder`."""

from __future__ import annotations

import contextlib
import ctypes
import datetime as _dt
import hashlib
import json
import os
import stat
from pathlib import Path
from typing import Any

from ..errors import InputError


class OutputError(InputError):
    """An output the tool refuses to write: it would lose something the tool did not write."""


class Diverted(OutputError):
    """The result was complete, but the output folder changed during the run: the result was put
    beside it (:attr:`path`) and the folder left as it was."""

    def __init__(self, message: str, path: Path) -> None:
        super().__init__(message)
        self.path = path


def abs_path(p: str | os.PathLike[str]) -> Path:
    """Absolute, normalised ('.', '..' and doubled slashes removed) without resolving symbolic links."""
    return Path(os.path.abspath(os.fspath(p)))


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def walk(folder: Path) -> tuple[dict[str, Path], list[str], list[str]]:
    """(regular files, folders, anything else: links, devices...) under ``folder``, as relative POSIX
    paths; symbolic links are never followed."""
    files: dict[str, Path] = {}
    dirs: list[str] = []
    odd: list[str] = []
    for root, dnames, fnames in os.walk(folder, followlinks=False):
        r = Path(root)
        for n in list(dnames):
            p = r / n
            rel = p.relative_to(folder).as_posix()
            if p.is_symlink():
                odd.append(rel)
                dnames.remove(n)
            else:
                dirs.append(rel)
        for n in fnames:
            p = r / n
            rel = p.relative_to(folder).as_posix()
            st = os.lstat(p)
            (files.__setitem__(rel, p) if stat.S_ISREG(st.st_mode) else odd.append(rel))
    return files, sorted(dirs), sorted(odd)


def read_marker(folder: Path, marker: str, tool: str) -> dict[str, Any] | None:
    """The marker of a folder written by ``tool``, or None (absent, unreadable or not ours)."""
    try:
        with open(Path(folder) / marker, "rb") as fh:
            m = json.loads(fh.read(1 << 24).decode("utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return m if isinstance(m, dict) and m.get("tool") == tool else None


def write_marker(folder: Path, marker: str, tool: str, **fields: Any) -> None:
    m = dict(tool=tool, **fields)
    (Path(folder) / marker).write_text(json.dumps(m, indent=2) + "\n", encoding="utf-8")


def inventory(folder: Path, marker: str) -> dict[str, Any]:
    """What a marker records of a complete folder: every file with its SHA-256, every subfolder."""
    files, dirs, odd = walk(folder)
    if odd:
        raise OSError(f"{folder}: holds entries that are not files or folders: {odd[:3]}")
    return dict(files={n: sha256_file(p) for n, p in sorted(files.items()) if n != marker}, dirs=dirs)


def foreign_entries(folder: Path, marker: str, tool: str, kind: str = "result") -> list[str]:
    """What in ``folder`` ``tool`` did not write, or changed since: empty when the folder is empty or
    provably an unchanged result of the tool. Each entry names the path and why."""
    try:
        names = sorted(os.listdir(folder))
    except FileNotFoundError:
        return []
    if not names:
        return []
    m = read_marker(folder, marker, tool)
    if m is None or m.get("kind") != kind or not isinstance(m.get("files"), dict):
        return [n for n in names if n != marker] or [f"{marker} (not {tool}'s marker of a result)"]
    files, dirs, odd = walk(folder)
    known_dirs = set(m.get("dirs") or [])
    bad = [f"{n} (not a file or folder)" for n in odd]
    bad += [f"{d}/ (not written by {tool})" for d in dirs if d not in known_dirs]
    for n, p in files.items():
        if n == marker:
            continue
        want = m["files"].get(n)
        if want is None:
            bad.append(f"{n} (not written by {tool})")
        elif sha256_file(p) != want:
            bad.append(f"{n} (changed since {tool} wrote it)")
    return sorted(bad)


def shown(entries: list[str], n: int = 6) -> str:
    return ", ".join(entries[:n]) + (f", ... ({len(entries)} entries)" if len(entries) > n else "")


def pid_alive(pid: Any) -> bool:
    try:
        os.kill(int(pid), 0)
    except (ProcessLookupError, ValueError, TypeError):
        return False
    except PermissionError:
        return True
    return True


def stamp() -> str:
    return _dt.datetime.now().strftime("%Y%m%dT%H%M%S")


_RENAME_EXCHANGE, _RENAME_NOREPLACE, _AT_FDCWD = 2, 1, -100


def _renameat2(a: Path, b: Path, flags: int) -> bool:
    """renameat2(a, b, flags) (Linux); False when the system or the file system lacks it."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), flags) == 0:
        return True
    err = ctypes.get_errno()
    if err in (38, 22, 95):  # ENOSYS, EINVAL, EOPNOTSUPP
        return False
    raise OSError(err, os.strerror(err), str(b))


def exchange(a: Path, b: Path) -> None:
    """Swap two folders: in one step where the system can, else by three renames."""
    if _renameat2(a, b, _RENAME_EXCHANGE):
        return
    mid = a.with_name(a.name + ".swap")
    os.rename(b, mid)
    os.rename(a, b)
    os.rename(mid, a)


def move_new(src: Path, dst: Path) -> None:
    """Rename a folder to a name nothing holds (never onto an existing, even empty, folder)."""
    if not _renameat2(src, dst, _RENAME_NOREPLACE):
        if dst.exists() or dst.is_symlink():
            raise FileExistsError(17, "exists", str(dst))
        os.rename(src, dst)


def remove_own(folder: Path, marker: str, tool: str) -> list[str]:
    """Remove a folder of ours file by file: each file only if its hash is still the recorded one.
    Returns what was left (empty: the folder is gone)."""
    m = read_marker(folder, marker, tool) or {}
    files_m = m.get("files")
    want: dict[str, str] = files_m if isinstance(files_m, dict) else {}
    files, dirs, odd = walk(folder)
    left = list(odd)
    for n, p in files.items():
        if n == marker:
            continue
        if want.get(n) is not None and sha256_file(p) == want[n]:
            p.unlink()
        else:
            left.append(n)
    if left:
        return sorted(left)
    with contextlib.suppress(FileNotFoundError):
        (folder / marker).unlink()
    for d in sorted(dirs, key=lambda s: -s.count("/")):
        try:
            (folder / d).rmdir()
        except OSError:
            left.append(d)
    if not left:
        try:
            folder.rmdir()
        except OSError:
            left.append(".")
    return left


def remove_partial(tmp: Path) -> None:
    """Remove a partial folder this process created (everything in it is ours by construction)."""
    import shutil

    shutil.rmtree(tmp, ignore_errors=True)
