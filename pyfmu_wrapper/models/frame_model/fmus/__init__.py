"""The frame model's FMU, ShearFrame: its variable table, slave, exact step and native functions, declared by one module.

The unit's ``fmus()`` imports the declaring module (:mod:`.shear_frame`) when it is first called, so importing
the unit stays cheap. Nothing here imports the unit's package (``models/frame_model/__init__.py``): it imports
this folder; the packing comes from :mod:`..packing`.
"""
