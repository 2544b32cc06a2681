"""The frame model's equations as the integrator takes them: right-hand side, Jacobian, switching functions
(:mod:`.equations`), the unit's ``ode`` (:data:`FRAME`). Its own module so that the unit (``__init__.py``) and the
FrameSystem FMU (``fmus/system.py``) both import it without importing each other."""

from __future__ import annotations

from ...physics.models import OdeModel, bind_describe, contact_mode_index, mode_describer
from .equations import frame_jacobian, frame_rhs, frame_switching

FRAME = OdeModel(
    name="frame",
    rhs=frame_rhs,
    jacobian=frame_jacobian,
    switching=frame_switching,
    mode=contact_mode_index,
    n_switches=3,
    n_modes=3,
    switch_tolerance=(-1, 4, 4),
    state_names=("x_top", "xd_top", "y", "yd", "d", "dd"),
    describe=bind_describe(mode_describer(True, 4), frame_switching),
)
