"""Declares the FrameSystem FMU (the shear frame with its TMD-inerter in one FMU): its variable table, its slave,
its native functions (co-simulation and Model Exchange)."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .system_native import frame_system_functions, frame_system_step, frame_system_table
from .system_slave import FrameSystemSlave
from .system_variables import FRAME_SYSTEM

FMU = FmuModel(
    spec=FRAME_SYSTEM,
    slave=FrameSystemSlave,
    native=NativeFmu(step=frame_system_step, functions=frame_system_functions, table=frame_system_table),
    system=True,
)
