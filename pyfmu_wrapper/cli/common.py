"""What every console script shares before it imports anything heavy: ``--version`` (the package's
version) and the rule that arguments and input files are checked before numba, scipy, pandas or
matplotlib are imported (those imports sit inside each ``main``, after the checks; tests/test_cli_fast.py
measures it)."""

from __future__ import annotations

import argparse

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
