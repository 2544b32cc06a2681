"""The frame's packed parameter array: a :class:`~.params.FrameParams` and the paper's TMD -> the array the compiled functions read.

The layout is :mod:`.equations`' (the paper's array, then the frame's part at ``F_*``). Its own module so that
the unit (``__init__.py``) and the FMU's slave (``fmus/slave.py``) both import it without importing each other.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...physics.params import N_PARAMS, BaseParams, TMDParams, pack
from .equations import F_LOAD, F_N, F_TMD, F_TO, F_VALUES
from .params import FrameParams


def frame_pack(frame: FrameParams, tmd: TMDParams, omega: float = 0.0) -> NDArray[np.float64]:
    """The packed array (:mod:`.equations`): the paper's, with the first storey in the base's slots,
    then the frame's part."""
    n = frame.n
    first = BaseParams(
        mass=frame.masses[0],
        stiffness=frame.stiffnesses[0],
        damping=frame.dampings[0],
        force_amplitude=frame.force_amplitude,
    )
    p = np.zeros(N_PARAMS + 4 + 3 * n)
    p[:N_PARAMS] = pack(first, tmd, omega)
    p[F_N], p[F_LOAD], p[F_TMD], p[F_TO] = n, frame.loaded_storey, frame.tmd_at, frame.terminal
    p[F_VALUES : F_VALUES + n] = frame.masses
    p[F_VALUES + n : F_VALUES + 2 * n] = frame.stiffnesses
    p[F_VALUES + 2 * n :] = frame.dampings
    return p
