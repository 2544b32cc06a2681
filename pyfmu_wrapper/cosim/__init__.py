"""The base + TMD application of the co-simulation master: the co-simulation engine.

A model's own wiring may live in its folder (the frame's: :mod:`pyfmu_wrapper.models.frame_model.cosim`,
named by its unit). :mod:`.system` wires the BaseOscillator and TMDInerter FMUs (connections, FMU parameters, the
master, SSP export of the pair); :mod:`.steady` computes co-simulated steady states, sweeps and
steady-state time series with the steady-state definition shared with the monolithic engine
(:mod:`pyfmu_wrapper.solvers.steady`). The generic master (FMI and coupling only) is
:mod:`pyfmu_wrapper.master`.
"""
