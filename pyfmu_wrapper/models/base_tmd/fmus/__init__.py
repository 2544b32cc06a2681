"""The FMUs of the paper's model (``base_tmd``): BaseOscillator and TMDInerter, each declared by one module.

Their variable tables, slaves, outputs, integrators and native functions live here; the unit's ``fmus()``
imports the declaring modules (:mod:`.base_oscillator`, :mod:`.tmd_inerter`) when it is first called, so
importing the unit stays cheap. Nothing here imports the unit's package (``models/base_tmd/__init__.py``):
it imports this folder.
"""
