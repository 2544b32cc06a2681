"""The frame model's FMU, ShearFrame: its variable table, slave, exact step and native functions, declared by one module.

The unit names the declaring module (:mod:`.shear_frame`) by its dotted name, so nothing in ``physics/``
core imports this folder (docs/architecture.md).
"""
