"""Writers of generated artefacts that restate declarations: the documentation tables
(:mod:`.docs`: ``python -m pyfmu_wrapper.generate.docs``) and the Modelica sources' defaults and
cases (:mod:`.modelica`: ``python -m pyfmu_wrapper.generate.modelica``). Both have ``--check``."""
