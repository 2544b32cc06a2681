"""The registry of model units (:class:`~pyfmu_wrapper.physics.unit.ModelUnit`): one folder per model
above the engines, and one registration line each. The applications (``run-scenario``, the paper, the
generators, the diagnosis) find a structure's model here (``MODELS.of(structure)``) and hand the unit to
the solvers, the FMU builders and the co-simulation engine, which know no model; docs/adding-a-model.md
says how to add one."""

from __future__ import annotations

from ..physics.unit import Registry
from . import base_tmd, frame_model, linear_tmd, pendulum_tmd

MODELS = Registry()
MODELS.register(base_tmd.UNIT)
MODELS.register(frame_model.UNIT)
MODELS.register(linear_tmd.UNIT)
MODELS.register(pendulum_tmd.UNIT)
