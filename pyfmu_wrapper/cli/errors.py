"""One bad-input policy for every console script.

``@cli_main("prog")`` wraps a ``main(argv) -> int``: the project's typed input errors (every
subclass of :class:`pyfmu_wrapper.errors.InputError`: scenario, parameter, setting, data, engine,
optimisation and output errors), bytes that are not UTF-8, and an ``OSError`` naming a file
become **one line** on stderr, ``prog: error: <what and where>``, and exit status 2, without a
traceback. Anything else is a bug: its traceback is shown (exit 1).
``argparse`` errors keep their own exit status 2. Ctrl-C gives exit 130.

Messages show plain numbers (``nan``, ``0.5``), never ``np.float64(nan)``
(:func:`pyfmu_wrapper.errors.plain_text`).

Set ``PYFMU_TRACEBACK=1`` to see the traceback of an input error too (debugging).
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
from collections.abc import Callable
from typing import Any

from ..errors import InputError, plain_text


def is_input_error(exc: BaseException) -> bool:
    if isinstance(exc, (InputError, UnicodeDecodeError)):
        return True
    return isinstance(exc, OSError) and getattr(exc, "filename", None) is not None


def message(exc: BaseException) -> str:
    """One line: the message of an input error with plain numbers."""
    if isinstance(exc, OSError) and getattr(exc, "filename", None) is not None:
        text = f"{exc.filename}: {exc.strerror or exc}"
        if getattr(exc, "filename2", None):
            text += f" ({exc.filename2})"
    elif isinstance(exc, UnicodeDecodeError):
        text = (
            f"input is not UTF-8 text: bytes {exc.object[exc.start : exc.end].hex(' ')} at byte offset "
            f"{exc.start} ({exc.reason})"
        )
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(plain_text(text).split())


def report(prog: str, exc: BaseException) -> int:
    if os.environ.get("PYFMU_TRACEBACK"):
        import traceback

        traceback.print_exception(exc)
    print(f"{prog}: error: {message(exc)}", file=sys.stderr)
    return 2


def cli_main(prog: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorator for a console script's ``main(argv=None) -> int`` (see the module doc)."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(*args: Any, **kwargs: Any) -> int:
            try:
                return main(*args, **kwargs)
            except KeyboardInterrupt:
                print(f"\n{prog}: interrupted", file=sys.stderr)
                return 130
            except BrokenPipeError:  # the reader went away (``diagnose ... | head``): end quietly, as a
                # Unix tool killed by SIGPIPE; what was written to files is complete
                with contextlib.suppress(OSError, ValueError):  # no error at exit's flush
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                return 141
            except Exception as exc:  # noqa: BLE001 - typed input errors only; the rest re-raised
                if is_input_error(exc):
                    return report(prog, exc)
                raise

        return run

    return wrap
