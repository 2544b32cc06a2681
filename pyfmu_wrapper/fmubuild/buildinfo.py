"""What both FMU builders share (:mod:`.build` and :mod:`.standalone`): the build error and the
installed versions of the packages an FMU records."""

from __future__ import annotations


class BuildError(RuntimeError):
    """The FMU could not be built (no compiler, no headers, no shared libpython...)."""


def version_of(name: str) -> str:
    """The installed version of distribution ``name`` ("none" if not installed)."""
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "none"
