"""Scenario files: YAML schema (version 1), loader and runner (see docs/scenarios.md)."""
from .loader import load_scenario, parse_scenario
from .schema import SCHEMA_VERSION, Curve, FRCStudy, MapStudy, PhasePortraitStudy, Scenario, ScenarioError, SolverConfig

__all__ = ["load_scenario", "parse_scenario", "Scenario", "ScenarioError", "SolverConfig", "Curve", "FRCStudy",
           "MapStudy", "PhasePortraitStudy", "SCHEMA_VERSION"]
