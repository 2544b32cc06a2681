"""Co-simulation master for FMI 2.0 co-simulation FMUs (fmpy), and its application to the base + TMD pair."""
from .graph import Connection, ConnectionGraph, build_graph
from .master import SCHEMES, Master, MasterError, Result

__all__ = ["Connection", "ConnectionGraph", "build_graph", "Master", "MasterError", "Result", "SCHEMES"]
