"""The LinearTMD FMU's equations with its input, their RODAS4 integrator, its step and its outputs, as
compiled functions called by both step paths: the Python slave (:mod:`.slave`) and the native step
(:mod:`.native`), so the two are bit-identical.

The model's right-hand side (:func:`~pyfmu_wrapper.models.linear_tmd.equations.linear_tmd_rhs`) with the
input ``f_ext`` (a polynomial of degree <= 2 in the step, :func:`~pyfmu_wrapper.physics.kernels.input_value`)
added to the main mass's force; its Jacobian by the complex step; the integrator built from them by
:func:`~pyfmu_wrapper.solvers.rodas.make_integrator` (compiled once, cached on disk). Input polynomials
u = [t0, f, f', f''].
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...._jit import njit
from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS, NATIVE_MAX_STEP
from ....fmi.outputs import output_layout
from ....physics.jacobians import complex_step_jacobian
from ....physics.kernels import Vec, input_value
from ....physics.models import smooth_model
from ....solvers.rodas import STAT_STEPS, make_integrator
from ..equations import L_M, linear_tmd_rhs
from .variables import LINEAR_TMD_FMU

#: the input polynomial of f_ext: [t0, f, f', f'']
U_SIZE = 1 + 3
#: the outputs :func:`linear_outputs` writes, in the order of the variable table (checked on import)
OUTPUTS = ("x", "xd", "xdd", "y", "yd")
OUT_VR, OUT_INT = output_layout(LINEAR_TMD_FMU, OUTPUTS)
#: a doStep longer than this [s] is integrated in pieces (as every FMU of the project)
CHUNK = NATIVE_MAX_STEP
#: the integrator's friction band: unused (the model is linear)
BAND = 1e-6


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


@njit(cache=True)
def linear_outputs(z: Vec, t: float, f: complex, p: Vec, u: Vec, out: NDArray) -> None:
    """x, xd, xdd, y, yd for the state z at t and the input f (real or complex: the directional
    derivatives by the complex step)."""
    rates = np.empty(4)
    linear_tmd_rhs(t, z, p, u, rates)
    out[0] = z[0]
    out[1] = z[1]
    out[2] = rates[1] + f / p[L_M]
    out[3] = z[2]
    out[4] = z[3]


@njit(cache=True)
def advance_linear(
    z: Vec, t: float, h: float, p: Vec, u: Vec, rtol: float, atol: Vec, h_next: float, stats: NDArray[np.int64]
) -> tuple[int, float, float]:
    """z at t -> at t + h: RODAS4, long steps in pieces of :data:`CHUNK`, within
    :data:`~pyfmu_wrapper.fmi.contract.MAX_INTEGRATOR_STEPS` integrator steps. Returns (code, the next
    suggested step size, the time reached): code 0, or why it stopped (1 + the integrator's status, or
    ``FAIL_BUDGET``; z is then where it stopped)."""
    n = 1 if h <= CHUNK else int(math.ceil(h / CHUNK))
    start = stats[STAT_STEPS]
    hn = h_next
    no_t, no_s = np.zeros(0), np.zeros((0, 4))
    for k in range(n):
        lo, hi = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
        hn, _, status, tf = integrate(
            z, lo, hi, p, u, rtol, atol, hn, hi - lo, no_t, no_s, BAND, stats, MAX_INTEGRATOR_STEPS
        )
        if status != 0:
            return 1 + status, hn, tf
        if stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
            return FAIL_BUDGET, hn, hi
    return 0, hn, t + h
