"""The linear TMD model's FMU, LinearTMD: its variable table, slave and step, declared by one module.

The unit names the declaring module (:mod:`.linear_tmd_fmu`) by its dotted name, so nothing in ``physics/``
core imports this folder (docs/architecture.md).
"""
