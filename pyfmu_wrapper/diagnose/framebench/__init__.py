"""``make-benchmark --suite frame`` (issue 41): shear-frame datasets with a TMD or TMDI measured by
accelerometers under transient forces, their truths simulated by an integrator of their own
(:mod:`.truth`), written by :mod:`.suite`, scored by ``benchmarks/bench_diagnose_frame.py``."""
