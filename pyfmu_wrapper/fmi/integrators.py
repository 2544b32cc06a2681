"""The integrators of the two FMU subsystems, built from their models by the generic factory
(:func:`pyfmu_wrapper.solvers.rodas.make_integrator`): the base oscillator (``x, xd``) and the TMD
(``y, yd, d, dd``), as the Python slaves and the native step use them. Compiling only these two
keeps the FMU's first-load compile time small (the coupled system's integrator is not needed here).
"""

from __future__ import annotations

from ..physics import models
from ..solvers.rodas import make_integrator

#: the models, for messages (:func:`~pyfmu_wrapper.solvers.rodas.failure_message`)
BASE_MODEL, TMD_MODEL = models.BASE, models.TMD
integrate_base = make_integrator(models.BASE)
integrate_tmd = make_integrator(models.TMD)
