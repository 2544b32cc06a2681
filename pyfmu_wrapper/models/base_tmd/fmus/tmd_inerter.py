"""Declares the TMDInerter FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .native import tmd_step
from .native_model import tmd_functions, tmd_table
from .slaves import TMDInerterSlave
from .variables import TMD_INERTER

FMU = FmuModel(
    spec=TMD_INERTER,
    slave=TMDInerterSlave,
    native=NativeFmu(step=tmd_step, functions=tmd_functions, table=tmd_table),
)
