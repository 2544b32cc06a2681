"""What every console script shares before it imports anything heavy: ``--version`` (the package's
version) and the rule that arguments and input files are checked before numba, scipy, pandas or
matplotlib are imported (those imports sit inside each ``main``, after the checks; tests/test_cli_fast.py
measures it)."""

from __future__ import annotations

import argparse
import os

DIST = "pyfmu_wrapper"


def package_version() -> str:
    """The installed distribution's version (pyproject.toml's ``version``), or the source's when the
    package runs from a checkout that is not installed."""
    from importlib import metadata

    try:
        return metadata.version(DIST)
    except metadata.PackageNotFoundError:  # pragma: no cover - a bare checkout on PYTHONPATH
        return "unknown (not installed)"


def add_version(parser: argparse.ArgumentParser) -> None:
    """``--version``: print ``<prog> <version>`` and exit 0."""
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")


def check_creatable(out: str | os.PathLike[str], option: str = "--out") -> None:
    """Refuse (:class:`pyfmu_wrapper.errors.InputError`, one line, exit status 2) an output folder the
    tool cannot create, before any work: its nearest existing parent must be a folder in which a
    folder can be made (tried with an empty probe folder of this tool's own, removed at once: the
    permissions alone do not tell, e.g. /proc for root)."""
    import tempfile

    from ..errors import InputError

    p = os.path.abspath(os.fspath(out))
    parent = p
    while not os.path.exists(parent):
        up = os.path.dirname(parent)
        if up == parent:
            break
        parent = up
    if os.path.isdir(p):
        parent = os.path.dirname(p) or p  # an existing folder is replaced by one made beside it
    if not os.path.isdir(parent):
        raise InputError(f"{option} {out}: {parent} is not a folder; cannot create the output folder there")
    try:
        probe = tempfile.mkdtemp(prefix=".probe-", dir=parent)
    except OSError as exc:
        raise InputError(
            f"{option} {out}: cannot create a folder in {parent} ({exc.strerror or exc}); choose a writable place"
        ) from None
    os.rmdir(probe)
