"""The run paths (DT_RUNPATH, DT_RPATH) of a 64-bit little-endian ELF shared object, read and rewritten
in place, for the runtime a standalone FMU bundles (:mod:`.standalone`).

A build interpreter's ``libpython`` and extension modules carry a RUNPATH into its own installation
(``/root/.pyenv/versions/3.11.7/lib``): on a target the loader would probe that folder first. A
bundled copy gets an ``$ORIGIN``-relative run path instead (where the bundled ``libpython`` lies,
relative to the file), written over the old string in the dynamic string table and padded with NUL
bytes; the new path is never longer than the old one (when it would be, the run path is emptied:
the stub loads the bundled ``libpython`` itself before any extension module needs it).
"""

from __future__ import annotations

import struct
from pathlib import Path

DT_NULL, DT_STRTAB, DT_RPATH, DT_RUNPATH = 0, 5, 15, 29
PT_LOAD, PT_DYNAMIC = 1, 2


def _dynamic(data: bytes) -> tuple[int, list[tuple[int, int]]] | None:
    """(file offset of the dynamic string table, [(tag, value)] of the dynamic section), or None when
    ``data`` is not a 64-bit little-endian ELF file with a dynamic section."""
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        return None
    phoff, phentsize, phnum = struct.unpack_from("<Q", data, 0x20)[0], *struct.unpack_from("<HH", data, 0x36)
    loads, dyn = [], None
    for i in range(phnum):
        p_type, _, p_offset, p_vaddr, _, p_filesz, _, _ = struct.unpack_from("<IIQQQQQQ", data, phoff + i * phentsize)
        if p_type == PT_LOAD:
            loads.append((p_vaddr, p_offset, p_filesz))
        elif p_type == PT_DYNAMIC:
            dyn = (p_offset, p_filesz)
    if dyn is None:
        return None
    entries = []
    for off in range(dyn[0], dyn[0] + dyn[1], 16):
        tag, val = struct.unpack_from("<qQ", data, off)
        if tag == DT_NULL:
            break
        entries.append((tag, val))
    strtab = next((v for t, v in entries if t == DT_STRTAB), None)
    if strtab is None:
        return None
    for vaddr, offset, size in loads:
        if vaddr <= strtab < vaddr + size:
            return strtab - vaddr + offset, entries
    return None


def run_paths(path: Path) -> list[str]:
    """The run paths (RUNPATH and RPATH strings) of an ELF file; [] when it has none or is not one."""
    data = path.read_bytes()
    found = _dynamic(data)
    if found is None:
        return []
    strtab, entries = found
    out = []
    for tag, val in entries:
        if tag in (DT_RPATH, DT_RUNPATH):
            end = data.index(b"\0", strtab + val)
            out.append(data[strtab + val : end].decode("utf-8", "replace"))
    return out


def set_run_path(path: Path, new: str) -> bool:
    """Rewrite every run path of the ELF file ``path`` to ``new`` in place (emptied when ``new`` is
    longer than the old string). Returns whether the file had a run path."""
    data = bytearray(path.read_bytes())
    found = _dynamic(bytes(data))
    if found is None:
        return False
    strtab, entries = found
    changed = False
    for tag, val in entries:
        if tag not in (DT_RPATH, DT_RUNPATH):
            continue
        start = strtab + val
        end = data.index(b"\0", start)
        enc = new.encode()
        if len(enc) > end - start:
            enc = b""
        data[start:end] = enc + b"\0" * (end - start - len(enc))
        changed = True
    if changed:
        path.write_bytes(bytes(data))
    return changed
