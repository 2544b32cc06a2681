"""Co-simulation master for FMI 2.0 and 3.0 co-simulation FMUs (fmpy): FMI and coupling only.

The base + TMD application (co-simulated steady state, sweeps, SSP export of the pair) is
:mod:`pyfmu_wrapper.cosim`.
"""

from .graph import Connection, ConnectionGraph, build_graph
from .master import SCHEMES, Master, MasterError, Result

__all__ = ["Connection", "ConnectionGraph", "build_graph", "Master", "MasterError", "Result", "SCHEMES"]
