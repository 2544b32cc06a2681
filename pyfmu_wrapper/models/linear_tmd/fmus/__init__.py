"""The linear TMD model's FMU, LinearTMD: its variable table, slave and step, declared by one module.

The unit's ``fmus()`` imports the declaring module (:mod:`.linear_tmd_fmu`) when it is first called, so
importing the unit stays cheap. Nothing here imports the unit's package (``models/linear_tmd/__init__.py``):
it imports this folder; the packing comes from :mod:`..packing`.
"""
