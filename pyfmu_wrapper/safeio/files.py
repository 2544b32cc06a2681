"""Single files a tool writes into a folder it shares with other files (``reproduce --out docs``).

The folder's marker (``.reproduce.json`` for reproduce) records every file the tool wrote there,
with its SHA-256. A file is replaced only when the marker records it and its contents are still the
recorded ones; anything else at that name (a user's file, or the tool's file edited since) is
refused before computing (:meth:`OwnedFiles.check`) and, if it appears or changes during the run,
kept: the new file is written beside it as ``<name>.new-<time><suffix>`` and the caller is told
(:attr:`OwnedFiles.diverted`). Each file is written to a temporary name and renamed into place.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from .tree import Diverted, OutputError, abs_path, read_marker, sha256_file, stamp


class OwnedFiles:
    """The files ``tool`` owns in ``folder`` (see the module doc)."""

    def __init__(self, folder: str | os.PathLike[str], tool: str, marker: str, option: str = "--out") -> None:
        self.given = os.fspath(folder)
        self.folder = abs_path(folder)
        self.tool, self.marker, self.option = tool, marker, option
        self.diverted: list[tuple[str, Path]] = []  #: (name, where the new file went instead)

    def _recorded(self) -> dict[str, str]:
        m = read_marker(self.folder, self.marker, self.tool) or {}
        files = m.get("files")
        return dict(files) if isinstance(files, dict) else {}

    def _in_the_way(self, name: str, recorded: dict[str, str]) -> str | None:
        """Why the file at ``name`` may not be replaced (None: absent, or ours and unchanged)."""
        p = self.folder / name
        if not (p.exists() or p.is_symlink()):
            return None
        if p.is_symlink() or not p.is_file():
            return f"{name} (not a regular file)"
        if name not in recorded:
            return f"{name} (not written by {self.tool})"
        if sha256_file(p) != recorded[name]:
            return f"{name} (changed since {self.tool} wrote it)"
        return None

    def check(self, names: list[str]) -> None:
        """Refuse, before computing, a folder that is a file or unwritable, or any of ``names`` that
        is in the way (:class:`OutputError`)."""
        f = self.folder
        if f.exists() and not f.is_dir():
            raise OutputError(
                f"{self.option} {self.given}: is a file, not a folder; {self.tool} never overwrites a file"
            )
        probe = next((p for p in [f, *f.parents] if p.exists()), None)
        if probe is None or not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
            raise OutputError(f"{self.option} {self.given}: cannot write into {probe}; nothing was computed")
        for parent in {(f / n).parent for n in names}:
            if parent.exists() and not parent.is_dir():
                raise OutputError(f"{self.option} {self.given}: {parent} is a file, not a folder; nothing was computed")
        recorded = self._recorded()
        bad = [w for n in names if (w := self._in_the_way(n, recorded)) is not None]
        if bad:
            raise OutputError(
                f"{self.option} {self.given}: {', '.join(bad)}: {self.tool} replaces only files it wrote and nobody "
                "changed since; nothing was computed or touched. Move them, or choose another folder"
            )

    def write(self, name: str, data: bytes) -> Path:
        """Write one file (atomically); kept beside a file in the way. Returns where it went."""
        target = self.folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        recorded = self._recorded()
        if self._in_the_way(name, recorded) is not None:
            target = target.with_name(f"{target.stem}.new-{stamp()}{target.suffix}")
            self.diverted.append((name, target))
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.chmod(tmp, 0o666 & ~_umask())
            if target == self.folder / name and self._in_the_way(name, self._recorded()) is not None:
                target = target.with_name(f"{target.stem}.new-{stamp()}{target.suffix}")  # changed meanwhile
                self.diverted.append((name, target))
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        if not self.diverted or self.diverted[-1][1] != target:
            recorded = self._recorded()
            recorded[name] = sha256_file(target)
            self._write_marker(recorded)
        return target

    def write_tree(self, stage: Path) -> list[Path]:
        """Write every file under the folder ``stage`` at the same relative name."""
        return [
            self.write(p.relative_to(stage).as_posix(), p.read_bytes())
            for p in sorted(stage.rglob("*"))
            if p.is_file() and not p.is_symlink()
        ]

    def _write_marker(self, files: dict[str, str]) -> None:
        m = dict(
            tool=self.tool, kind="files", note=f"files written by {self.tool}; others are never touched", files=files
        )
        fd, tmp = tempfile.mkstemp(prefix=f".{self.marker}.", dir=self.folder)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(m, indent=1, sort_keys=True) + "\n")
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, self.folder / self.marker)


def _umask() -> int:
    u = os.umask(0)
    os.umask(u)
    return u


def replace_checked(part: Path, target: Path, ours: Callable[[Path], bool], tool: str) -> Path:
    """Put a finished file (``part``, beside ``target``) at ``target``, checking again, just before,
    that whatever is at ``target`` is the tool's own (``ours``, e.g. an FMU carrying the tool's
    source hash): if something else appeared there while the tool worked, it is left as it is, the
    new file goes beside it (``<stem>.new-<time><suffix>``) and :class:`Diverted` says where."""
    if (target.exists() or target.is_symlink()) and (target.is_symlink() or not target.is_file() or not ours(target)):
        beside = target.with_name(f"{target.stem}.new-{stamp()}{target.suffix}")
        os.replace(part, beside)
        raise Diverted(
            f"{target} appeared while {tool} ran and was not written by it: left as it is; the new file is {beside}",
            beside,
        )
    os.replace(part, target)
    return target
