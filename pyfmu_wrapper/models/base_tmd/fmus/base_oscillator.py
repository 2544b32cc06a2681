"""Declares the BaseOscillator FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .native import base_step
from .native_model import base_functions, base_table
from .slaves import BaseOscillatorSlave
from .variables import BASE_OSCILLATOR

FMU = FmuModel(
    spec=BASE_OSCILLATOR,
    slave=BaseOscillatorSlave,
    native=NativeFmu(step=base_step, functions=base_functions, table=base_table),
)
