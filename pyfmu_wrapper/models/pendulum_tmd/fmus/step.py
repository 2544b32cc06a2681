"""The PendulumTMD FMU's equations with its inputs, their RODAS4 integrator, its step and its outputs, as
compiled functions called by both step paths: the Python slave (:mod:`.slave`) and the native step
(:mod:`.native`), so the two are bit-identical.

State z = [x, xd, th, thd]: the pivot's displacement and velocity as the pendulum integrates them within a
step, the pendulum's angle and rate. At the start of every step the pivot is put on the body's motion the
inputs give there (x, xd: the body's outputs at that communication point); within the step it moves with the
acceleration of the model's equations (:func:`~pyfmu_wrapper.models.pendulum_tmd.equations.pendulum_accelerations`,
g1 = 1, g2 = kappa, r = the input ``xdd``): with kappa = 1/M the body's own equation, so the pivot reacts to
the rod's force at every instant (the interface Jacobian); with kappa = 0 the input is the pivot's
acceleration. The bob's horizontal velocity yd = xd + L cos th thd is then the integral of its acceleration
within the step, so ``force`` = m ydd, its time derivative times m, hands the body the exact impulse of the
bob over the step through a momentum (``rate``) connection from ``yd``; at the step's start the pivot's jump
to the body's motion corrects the bob's momentum by the error the body's extrapolated acceleration made over
the last step (it telescopes: nothing accumulates).

Input polynomials u = [t0, x, x', x'', xd, xd', xd'', xdd, xdd', xdd''] (:func:`~pyfmu_wrapper.physics.kernels.input_value`),
then u[:data:`U_KAPPA`] = kappa (set by configure).
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
from ..equations import Q_L, Q_m, pendulum_accelerations
from .variables import PENDULUM_TMD_FMU

#: the inputs x, xd, xdd as polynomials of degree <= 2 (3 entries each after t0), then the compliance
U_KAPPA = 1 + 3 * 3
U_SIZE = U_KAPPA + 1
#: the outputs :func:`pendulum_outputs` writes, in the order of the variable table (checked on import)
OUTPUTS = ("force", "y", "yd", "th", "thd")
OUT_VR, OUT_INT = output_layout(PENDULUM_TMD_FMU, OUTPUTS)
#: a doStep longer than this [s] is integrated in pieces (as every FMU of the project)
CHUNK = NATIVE_MAX_STEP
#: the integrator's friction band: unused (the model is smooth)
BAND = 1e-6


@njit(cache=True)
def fmu_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt of the pendulum on its pivot (module doc); z and t real or complex."""
    xdd, thdd = pendulum_accelerations(1.0, u[U_KAPPA], input_value(u, 2, t), z[2], z[3], p)
    out[0] = z[1]
    out[1] = xdd
    out[2] = z[3]
    out[3] = thdd


#: J = d rhs / dz and ft = d rhs / dt of :func:`fmu_rhs` by the complex step
fmu_jacobian = complex_step_jacobian(fmu_rhs, "pendulum_tmd_fmu")
#: the pendulum with its inputs, for the integrator (its own name: its own compiled integrator)
FMU_MODEL = smooth_model("pendulum_tmd_fmu", fmu_rhs, fmu_jacobian, ("x", "xd", "th", "thd"))
integrate = make_integrator(FMU_MODEL)


@njit(cache=True)
def pendulum_outputs(z: Vec, xdd: complex, kappa: float, p: Vec, out: NDArray) -> None:
    """force, y, yd, th, thd for the state z and the input xdd (real or complex: the directional
    derivatives by the complex step)."""
    acc, thdd = pendulum_accelerations(1.0, kappa, xdd, z[2], z[3], p)
    m, L = p[Q_m], p[Q_L]
    th, thd = z[2], z[3]
    s, c = np.sin(th), np.cos(th)
    out[0] = m * (acc + L * (thdd * c - thd * thd * s))
    out[1] = z[0] + L * s
    out[2] = z[1] + L * c * thd
    out[3] = th
    out[4] = thd


@njit(cache=True)
def fill_atol(a: float, p: Vec, atol: Vec) -> None:
    """The integrator's absolute tolerance per state from the FMU parameter ``atol`` = a: a for the pivot's
    displacement and velocity, a / L for the angle and its rate (a swing of the bob of a)."""
    b = a / p[Q_L]
    atol[0] = a
    atol[1] = a
    atol[2] = b
    atol[3] = b


@njit(cache=True)
def advance_pendulum(
    z: Vec, t: float, h: float, p: Vec, u: Vec, rtol: float, atol: Vec, h_next: float, stats: NDArray[np.int64]
) -> tuple[int, float, float]:
    """z at t -> at t + h (module doc): the pivot put on the inputs' x, xd at t, then RODAS4, long steps in
    pieces of :data:`CHUNK`, within :data:`~pyfmu_wrapper.fmi.contract.MAX_INTEGRATOR_STEPS` integrator steps.
    Returns (code, the next suggested step size, the time reached): code 0, or why it stopped (1 + the
    integrator's status, or ``FAIL_BUDGET``; z is then where it stopped)."""
    z[0] = u[1]
    z[1] = u[4]
    n = 1 if h <= CHUNK else int(math.ceil(h / CHUNK))
    start = stats[STAT_STEPS]
    hn = h_next
    no_t, no_s = np.zeros(0), np.zeros((0, 4))
    for k in range(n):
        lo, hi = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
        hn, _, status, tf = integrate(
            z, lo, hi, p, u, rtol, atol, hn, h if n == 1 else hi - lo, no_t, no_s, BAND, stats, MAX_INTEGRATOR_STEPS
        )
        if status != 0:
            return 1 + status, hn, tf
        if stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
            return FAIL_BUDGET, hn, hi
    return 0, hn, t + h
