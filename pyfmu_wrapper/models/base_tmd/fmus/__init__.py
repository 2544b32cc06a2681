"""The FMUs of the paper's model (``base_tmd``): BaseOscillator and TMDInerter, each declared by one module.

Their variable tables, slaves, outputs, integrators and native functions live here; the unit names the
declaring modules (:mod:`.base_oscillator`, :mod:`.tmd_inerter`) by their dotted names, so nothing in
``physics/`` core imports this folder (docs/architecture.md).
"""
