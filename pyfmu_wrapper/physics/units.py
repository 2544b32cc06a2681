"""The registry of model units (:class:`~pyfmu_wrapper.physics.unit.ModelUnit`): one registration line
per model. The engines find a structure's model here (``MODELS.of(structure)``) and nowhere else;
docs/adding-a-model.md says how to add one."""

from __future__ import annotations

from . import base_tmd, frame_model, linear_tmd
from .unit import Registry

MODELS = Registry()
MODELS.register(base_tmd.UNIT)
MODELS.register(frame_model.UNIT)
MODELS.register(linear_tmd.UNIT)
