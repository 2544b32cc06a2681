"""The names a command line offers for run-scenario's engines and executors, in a module that imports
nothing heavy: a console script checks them, and the scenario, before it imports the engines (pandas,
scipy) or numba (docs/scenarios.md, "Refusals"). :data:`pyfmu_wrapper.scenario.engines.ENGINES` and
:mod:`pyfmu_wrapper.scenario.executors` register exactly these names (checked at their import)."""

from __future__ import annotations

#: the computation engines (pyfmu_wrapper.scenario.engines.ENGINES)
ENGINE_NAMES = ("both", "cosim", "monolithic")
DEFAULT_ENGINE = "cosim"
#: where sweeps run (pyfmu_wrapper.scenario.executors)
EXECUTORS = ("local", "dask", "sequential")
