"""The pendulum TMD model's FMU, PendulumTMD: the pendulum on a moving pivot, coupled by forces to the paper's
BaseOscillator (declared by ``base_tmd``) in the model's co-simulation (``../cosim.py``).

Its variable table (:mod:`.variables`), its equations with inputs and their integrator (:mod:`.step`), its
Python slave (:mod:`.slave`) and native functions (:mod:`.native`), declared by one module
(:mod:`.pendulum_tmd_fmu`), which the unit's ``fmus()`` imports when it is first called, so importing the unit
stays cheap. Nothing here imports the unit's package (``models/pendulum_tmd/__init__.py``): it imports this
folder; the packing comes from :mod:`..packing`.
"""
