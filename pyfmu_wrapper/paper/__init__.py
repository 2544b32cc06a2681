"""The paper's study: its scenarios run and checked (:mod:`.reproduce`), its claims judged by computed
comparisons (:mod:`.claims`, numbers from :mod:`.claim_data`), the TMD parameter optimisation
(:mod:`.optimise`), its figures (:mod:`.figures`) and the reproduction report (:mod:`.report`).
The console commands are ``reproduce`` and ``optimise`` (:mod:`pyfmu_wrapper.cli`)."""
