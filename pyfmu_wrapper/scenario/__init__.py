"""Scenario files: YAML schema (version 2; version 1 files still read), loader, engines, runner and output
(see docs/scenarios.md)."""

from .loader import load_scenario, parse_scenario
from .schema import SCHEMA_VERSION, Curve, FRCStudy, MapStudy, PhasePortraitStudy, Scenario, ScenarioError, SolverConfig

__all__ = [
    "load_scenario",
    "parse_scenario",
    "Scenario",
    "ScenarioError",
    "SolverConfig",
    "Curve",
    "FRCStudy",
    "MapStudy",
    "PhasePortraitStudy",
    "SCHEMA_VERSION",
]
