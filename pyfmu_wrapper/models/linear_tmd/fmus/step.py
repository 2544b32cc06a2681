"""The LinearTMD FMU's equations with its input and their RODAS4 integrator, as the slave steps them.

The model's right-hand side (:func:`~pyfmu_wrapper.models.linear_tmd.equations.linear_tmd_rhs`) with the
input ``f_ext`` (a polynomial of degree <= 2 in the step, :func:`~pyfmu_wrapper.physics.kernels.input_value`)
added to the main mass's force; its Jacobian by the complex step; the integrator built from them by
:func:`~pyfmu_wrapper.solvers.rodas.make_integrator` (compiled once, cached on disk).
"""

from __future__ import annotations

from ...._jit import njit
from ....physics.jacobians import complex_step_jacobian
from ....physics.kernels import Vec, input_value
from ....physics.models import smooth_model
from ....solvers.rodas import make_integrator
from ..equations import L_M, linear_tmd_rhs


@njit(cache=True)
def fmu_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt of the model with the input force u (input 0) on the main mass; z and t real or complex."""
    linear_tmd_rhs(t, z, p, u, out)
    out[1] = out[1] + input_value(u, 0, t) / p[L_M]


#: J = d rhs / dz and ft = d rhs / dt of :func:`fmu_rhs` by the complex step
fmu_jacobian = complex_step_jacobian(fmu_rhs, "linear_tmd_fmu")

#: the model with its input, for the integrator (its own name: its own compiled integrator)
FMU_MODEL = smooth_model("linear_tmd_fmu", fmu_rhs, fmu_jacobian, ("x", "xd", "y", "yd"))
integrate = make_integrator(FMU_MODEL)
