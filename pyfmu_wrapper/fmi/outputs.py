"""The order in which an FMU's compiled outputs function writes its outputs, checked against its variable table.

Each FMU has one compiled outputs function (in its model's folder, e.g.
:mod:`pyfmu_wrapper.models.base_tmd.fmus.outputs`), called by both step paths: the native step after a
compiled doStep and the Python slave (after a long or retaken doStep, in initialisation, and with complex
inputs for the directional derivatives by complex step). It writes ``out`` in the order of the FMU's output
variables; :func:`output_layout` checks that order and gives the value references the outputs go to.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .varspec import BOOLEAN, INTEGER, FmuSpec


def output_layout(spec: FmuSpec, names: tuple[str, ...]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """(value references, is-integer flags) of the outputs, in the order the functions above write
    them; refuses a variable table whose outputs are not ``names`` in that order."""
    outs = spec.of("output")
    if tuple(v.name for v in outs) != names:
        raise RuntimeError(
            f"{spec.model_name}: outputs {[v.name for v in outs]} != {list(names)} (its outputs function)"
        )
    return (
        np.array([v.vr for v in outs], dtype=np.int64),
        np.array([v.type in (INTEGER, BOOLEAN) for v in outs], dtype=np.bool_),
    )
