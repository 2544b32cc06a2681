"""Declares the LinearTMD FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .native import linear_functions, linear_step, linear_table
from .slave import LinearTMDSlave
from .variables import LINEAR_TMD_FMU

FMU = FmuModel(
    spec=LINEAR_TMD_FMU,
    slave=LinearTMDSlave,
    native=NativeFmu(step=linear_step, functions=linear_functions, table=linear_table),
)
