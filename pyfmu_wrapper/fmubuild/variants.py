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


#: what this process has built or checked: (models, build, FMI version) -> {model identifier: archive}
_CHECKED: dict[tuple[tuple[int, ...], str, int], dict[str, Path]] = {}


def ensure_variant(fmus: Iterable[FmuModel], fmu_build: str = "native", fmi_version: int = 2) -> dict[str, Path]:
    """{model identifier: archive} of ``fmus`` in the build ``fmu_build`` ("native" or "python") and FMI version,
    each built if missing or stale.

    A process checks each variant's sources once (hashing them walks the package: 0.1-0.2 s, which a
    co-simulation paid at every master it made, a sweep piece or a peak refinement); later calls return the
    archives it found while they exist. Sources edited while a process runs are seen by the next one (the
    workers of ``run-scenario`` are forked after the parent's check, :func:`~pyfmu_wrapper.scenario.engines.prepare_cosim`).
    """
    fmus = tuple(fmus)
    key = (tuple(id(f) for f in fmus), fmu_build, fmi_version)
    done = _CHECKED.get(key)
    if done is not None and all(p.exists() for p in done.values()):
        return dict(done)
    if fmu_build == "native":
        from .native_build import ensure_native_fmus

        out = dict(ensure_native_fmus(fmus, fmi_version=fmi_version))
    elif fmu_build == "python":
        from .build import ensure_fmus

        out = dict(ensure_fmus(fmus, fmi_version=fmi_version))
    else:
        raise ValueError(f"fmu_build must be one of {BUILDS}, got {fmu_build!r}")
    _CHECKED[key] = {k: Path(v) for k, v in out.items()}
    return out
