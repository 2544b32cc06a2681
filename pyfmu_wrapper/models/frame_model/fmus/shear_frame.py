"""Declares the ShearFrame FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .variables import SHEAR_FRAME

_HERE = "pyfmu_wrapper.models.frame_model.fmus"

FMU = FmuModel(
    spec=SHEAR_FRAME,
    native=NativeFmu(
        step=f"{_HERE}.native:frame_step",
        functions=f"{_HERE}.native:frame_functions",
        table=f"{_HERE}.native:frame_table",
    ),
)
