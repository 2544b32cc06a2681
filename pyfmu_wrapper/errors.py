"""The bottom of the bad-input policy: the base class of every typed input error and the readers of
input files with located, bounded errors. Every part of the package may import it; it imports
nothing of the project.

:class:`InputError` is the base of every error that means "the input is wrong" (a scenario, a
parameter, a setting, a data file, a command-line value, an output in the way): the console
scripts (:mod:`pyfmu_wrapper.cli.errors`) turn any of them into one line on stderr and exit
status 2. The readers refuse a file larger than :data:`MAX_INPUT_BYTES` before reading it, name the
line and byte of bytes that are not UTF-8, and :func:`short` quotes a value in bounded time and
length whatever it is.
"""

from __future__ import annotations

import codecs
import os
import re
import stat
from typing import Any


class InputError(ValueError):
    """Bad input: the base of every typed input error (one line, exit status 2 in a console script)."""


_NP_REPR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool|str)_?\d*\(([^()]*)\)")


def plain_text(text: str) -> str:
    """``np.float64(0.5)`` -> ``0.5`` everywhere in a message."""
    return _NP_REPR.sub(r"\1", text)


def plain(x: Any) -> Any:
    """A number as a person writes it: numpy scalars as Python numbers (repr ``nan``, ``0.5``)."""
    item = getattr(x, "item", None)
    if item is not None and getattr(x, "shape", None) == ():
        return item()
    return x


# --- bytes that are not UTF-8 ------------------------------------------------------------------


def bad_bytes_message(
    name: str, data: bytes, exc: UnicodeDecodeError, offset0: int = 0, line0: int = 1, line_start0: int = 0
) -> str:
    """``name: line L, column C (byte offset O): bytes ff fe are not UTF-8 text`` for a decode error
    in ``data`` (a block of the file starting at byte offset0, on line line0 whose first byte is at
    line_start0)."""
    off = exc.start
    nl = data.rfind(b"\n", 0, off)
    line = line0 + data.count(b"\n", 0, off)
    col = off - nl if nl >= 0 else offset0 + off - line_start0 + 1
    return (
        f"{name}: line {line}, column {col} (byte offset {offset0 + off}): bytes "
        f"{data[exc.start : exc.end].hex(' ')} are not UTF-8 text ({exc.reason}); save the file as UTF-8"
    )


def decode_utf8(data: bytes, name: str, error: type[Exception] = InputError) -> str:
    """Decode UTF-8 (a BOM is dropped); bad bytes raise ``error`` naming the file, line and offset."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(bad_bytes_message(name, data, exc)) from None


#: the largest input file a tool reads whole, in bytes (scenario, model and dataset YAML files):
#: far above any real one, far below what exhausts memory; raised by ``--max-input-size`` (MB)
MAX_INPUT_BYTES = 16 * 2**20


def set_max_input_size(megabytes: float | None) -> None:
    """Raise or lower :data:`MAX_INPUT_BYTES` (the console scripts' ``--max-input-size MB``)."""
    global MAX_INPUT_BYTES
    if megabytes is None:
        return
    if not (megabytes > 0 and megabytes < 1e7):
        raise InputError(f"--max-input-size {megabytes}: must be a size in MB, > 0")
    MAX_INPUT_BYTES = int(megabytes * 2**20)


def _mb(n: float) -> str:
    return f"{n / 2**20:.3g} MB"


def read_bytes_limited(
    path: str | os.PathLike[str], error: type[Exception] = InputError, limit: int | None = None, what: str = "file"
) -> bytes:
    """The bytes of a file, refused with ``error`` (naming the file, its size and the limit) when it
    holds more than ``limit`` bytes (default :data:`MAX_INPUT_BYTES`). The size is read before the
    contents, and at most ``limit + 1`` bytes are ever read: a device (``/dev/zero``), a pipe or a
    sparse file of any size costs no more than the limit."""
    limit = MAX_INPUT_BYTES if limit is None else int(limit)
    name = os.fspath(path)
    with open(path, "rb") as fh:
        try:
            st = os.fstat(fh.fileno())
            size = st.st_size if stat.S_ISREG(st.st_mode) else None
        except OSError:  # pragma: no cover
            size = None
        if size is not None and size > limit:
            raise error(
                f"{name}: the {what} is {_mb(size)}, more than the limit of {_mb(limit)} for a {what}; "
                "if it really is that large, raise the limit with --max-input-size MB"
            )
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise error(
            f"{name}: the {what} holds more than the limit of {_mb(limit)} (it is not a regular file, or it "
            "grew while being read); if it really is that large, raise the limit with --max-input-size MB"
        )
    return data


def read_utf8(
    path: str | os.PathLike[str], error: type[Exception] = InputError, limit: int | None = None, what: str = "file"
) -> str:
    """The text of a file (at most ``limit`` bytes, :func:`read_bytes_limited`); bad bytes raise
    ``error`` naming file, line, column and byte offset."""
    return decode_utf8(read_bytes_limited(path, error, limit, what), os.fspath(path), error)


def short(value: Any, width: int = 80) -> str:
    """The repr of a value cut to about ``width`` characters, in bounded time and memory whatever the
    value is (a deeply nested or alias-shared structure, a megabyte string)."""
    import reprlib

    r = reprlib.Repr()
    r.maxlevel, r.maxdict, r.maxlist, r.maxtuple, r.maxset = 3, 6, 6, 6, 6
    r.maxstring, r.maxother, r.maxlong = width, width, 40
    text = r.repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def scan_utf8_lines(path: str | os.PathLike[str], error: type[Exception] = InputError, block: int = 1 << 24) -> int:
    """Stream a (large) text file once: check it is UTF-8 and count its lines, in bounded memory."""
    dec = codecs.getincrementaldecoder("utf-8")()
    lines, offset, line_start, last = 0, 0, 0, b""
    with open(path, "rb") as fh:
        while True:
            data = fh.read(block)
            if not data:
                break
            if not data.isascii():
                try:
                    dec.decode(data)
                except UnicodeDecodeError as exc:
                    raise error(bad_bytes_message(os.fspath(path), data, exc, offset, lines + 1, line_start)) from None
            n = data.count(b"\n")
            if n:
                line_start = offset + data.rfind(b"\n") + 1
            lines += n
            offset += len(data)
            last = data[-1:]
    try:
        dec.decode(b"", final=True)
    except UnicodeDecodeError:
        raise error(
            f"{os.fspath(path)}: the file ends inside a multi-byte character (byte offset {offset}): "
            "not UTF-8 text; save the file as UTF-8"
        ) from None
    return lines + (1 if last not in (b"", b"\n") else 0)
