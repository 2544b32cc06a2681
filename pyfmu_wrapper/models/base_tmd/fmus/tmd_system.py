"""Declares the TMDSystem FMU (the base with its TMD-inerter in one FMU): its variable table, its slave, its
native functions (co-simulation and Model Exchange)."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .system_native import system_functions, system_step, system_table
from .system_slave import TMDSystemSlave
from .variables import TMD_SYSTEM

FMU = FmuModel(
    spec=TMD_SYSTEM,
    slave=TMDSystemSlave,
    native=NativeFmu(step=system_step, functions=system_functions, table=system_table),
    system=True,
)
