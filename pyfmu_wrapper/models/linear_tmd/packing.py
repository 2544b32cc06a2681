"""The linear TMD's packed parameter array: a :class:`~.params.LinearTMDParams` -> the array the compiled functions read.

The layout is :mod:`.equations`' (F and w at the paper's indices, the model's own parameters from ``L_AT``).
Its own module so that the unit (``__init__.py``) and the FMU's slave (``fmus/slave.py``) both import it
without importing each other.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...physics.params import P_F, P_W, TMDParams
from .equations import L_AT, N_PACKED
from .params import LinearTMDParams


def linear_tmd_pack(s: LinearTMDParams, tmd: TMDParams | None = None, omega: float = 0.0) -> NDArray[np.float64]:
    """The packed array of :mod:`.equations` (``tmd`` is not used: the absorber is in ``s``)."""
    p = np.zeros(N_PACKED)
    p[P_F], p[P_W] = s.force_amplitude, omega
    p[L_AT:] = (s.mass, s.stiffness, s.damping, s.absorber_mass, s.absorber_stiffness, s.absorber_damping)
    return p
