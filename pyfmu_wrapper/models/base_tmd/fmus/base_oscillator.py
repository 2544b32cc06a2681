"""Declares the BaseOscillator FMU: its variable table, its slave, its native functions."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel, NativeFmu
from .variables import BASE_OSCILLATOR

_HERE = "pyfmu_wrapper.models.base_tmd.fmus"

FMU = FmuModel(
    spec=BASE_OSCILLATOR,
    native=NativeFmu(
        step=f"{_HERE}.native:base_step",
        functions=f"{_HERE}.native_model:base_functions",
        table=f"{_HERE}.native_model:base_table",
    ),
)
