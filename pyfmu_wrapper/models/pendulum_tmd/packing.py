"""The pendulum TMD's packed parameter array: a :class:`~.params.PendulumTMDParams` -> the array the compiled
functions read.

The layout is :mod:`.equations`' (F and w at the paper's indices, the model's own parameters from ``Q_AT``).
Its own module so that the unit (``__init__.py``) and the FMU's slave (``fmus/slave.py``) both import it
without importing each other.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...physics.params import P_F, P_W, TMDParams
from .equations import N_PACKED, Q_AT
from .params import PendulumTMDParams


def pendulum_tmd_pack(s: PendulumTMDParams, tmd: TMDParams | None = None, omega: float = 0.0) -> NDArray[np.float64]:
    """The packed array of :mod:`.equations` (``tmd`` is not used: the absorber is in ``s``)."""
    p = np.zeros(N_PACKED)
    p[P_F], p[P_W] = s.force_amplitude, omega
    p[Q_AT:] = (s.mass, s.stiffness, s.damping, s.pendulum_mass, s.length, s.pivot_damping)
    return p
