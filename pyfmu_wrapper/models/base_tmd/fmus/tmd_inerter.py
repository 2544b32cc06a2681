"""Declares the TMDInerter FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .variables import TMD_INERTER

_HERE = "pyfmu_wrapper.models.base_tmd.fmus"

FMU = FmuModel(
    spec=TMD_INERTER,
    native=NativeFmu(
        step=f"{_HERE}.native:tmd_step",
        functions=f"{_HERE}.native_model:tmd_functions",
        table=f"{_HERE}.native_model:tmd_table",
    ),
)
