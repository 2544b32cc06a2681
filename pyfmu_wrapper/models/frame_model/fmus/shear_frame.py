"""Declares the ShearFrame FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .native import frame_functions, frame_step, frame_table
from .slave import ShearFrameSlave
from .variables import SHEAR_FRAME

FMU = FmuModel(
    spec=SHEAR_FRAME,
    slave=ShearFrameSlave,
    native=NativeFmu(step=frame_step, functions=frame_functions, table=frame_table),
)
