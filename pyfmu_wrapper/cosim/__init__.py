"""The co-simulation engine: steady states, their coupling-error check and sweeps of any co-simulated
system of FMUs on the generic master (:mod:`pyfmu_wrapper.master`), behind a small protocol
(:mod:`.system`: :class:`~.system.CosimSystem`, :class:`~.system.CosimEngine`).

A model's system lives in its folder (the paper's pair: :mod:`pyfmu_wrapper.models.base_tmd.cosim`; the
frame's: :mod:`pyfmu_wrapper.models.frame_model.cosim`) and reaches these modules, never the reverse.
:mod:`.steady` computes co-simulated steady states, sweeps and steady-state time series with the
steady-state definition shared with the monolithic engine (:mod:`pyfmu_wrapper.solvers.steady`).
"""
