"""The FMUs of a co-simulation in the build it asks for: native (the model compiled into the binary, no Python on
the target: :mod:`.native_build`) or Python-hosted (the debugging reference: :mod:`.build`), built if missing or
stale. The one place a caller chooses between the two builders by name."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..fmi.fmumodel import FmuModel

#: the builds a co-simulation can run (``CosimSettings.fmu_build``)
BUILDS = ("native", "python")


def ensure_variant(fmus: Iterable[FmuModel], fmu_build: str = "native", fmi_version: int = 2) -> dict[str, Path]:
    """{model identifier: archive} of ``fmus`` in the build ``fmu_build`` ("native" or "python") and FMI version,
    each built if missing or stale."""
    if fmu_build == "native":
        from .native_build import ensure_native_fmus

        return dict(ensure_native_fmus(tuple(fmus), fmi_version=fmi_version))
    if fmu_build == "python":
        from .build import ensure_fmus

        return dict(ensure_fmus(tuple(fmus), fmi_version=fmi_version))
    raise ValueError(f"fmu_build must be one of {BUILDS}, got {fmu_build!r}")
