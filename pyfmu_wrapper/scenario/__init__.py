"""Scenario files: YAML schema (version 2; version 1 files still read), loader, engines, runner and output
(see docs/scenarios.md).

The names below are imported on first use (a module ``__getattr__``): ``scenario.names``, which a
console script reads to build its ``--help``, costs nothing of the loader (numpy, yaml)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .loader import load_scenario, parse_scenario
    from .schema import (
        SCHEMA_VERSION,
        Curve,
        FRCStudy,
        MapStudy,
        PhasePortraitStudy,
        Scenario,
        ScenarioError,
        SolverConfig,
    )

_WHERE = {
    "load_scenario": "loader",
    "parse_scenario": "loader",
    "Scenario": "schema",
    "ScenarioError": "schema",
    "SolverConfig": "schema",
    "Curve": "schema",
    "FRCStudy": "schema",
    "MapStudy": "schema",
    "PhasePortraitStudy": "schema",
    "SCHEMA_VERSION": "schema",
}

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
assert set(__all__) == set(_WHERE)


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{where}", __name__), name)
