"""Declares the PendulumTMD FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .native import pendulum_functions, pendulum_step, pendulum_table
from .slave import PendulumTMDSlave
from .variables import PENDULUM_TMD_FMU

FMU = FmuModel(
    spec=PENDULUM_TMD_FMU,
    slave=PendulumTMDSlave,
    native=NativeFmu(step=pendulum_step, functions=pendulum_functions, table=pendulum_table),
)
