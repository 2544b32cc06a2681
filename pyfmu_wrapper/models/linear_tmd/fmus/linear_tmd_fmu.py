"""Declares the LinearTMD FMU: its variable table and its slave (Python-hosted only, no native functions)."""

from __future__ import annotations

from ....fmi.fmumodel import FmuModel
from .slave import LinearTMDSlave
from .variables import LINEAR_TMD_FMU

FMU = FmuModel(spec=LINEAR_TMD_FMU, slave=LinearTMDSlave)
