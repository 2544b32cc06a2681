"""The outputs of the paper's two FMUs, one compiled function each, called by both step paths.

The native step (:mod:`.native`, after a compiled doStep) and the Python slave (:mod:`.slaves`: after a
long or retaken doStep, in initialisation, and with complex inputs for the directional derivatives by
complex step) call the same function. Each writes the outputs into ``out`` in the order of the FMU's
output variables (:data:`BASE_OUTPUTS`, :data:`TMD_OUTPUTS` name them and
:func:`~pyfmu_wrapper.fmi.outputs.output_layout` checks the order against the variable table on import).
The physics is the kernels'.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...._jit import njit
from ....fmi.outputs import output_layout
from ....physics import kernels as kn
from .variables import BASE_OSCILLATOR, TMD_INERTER

BASE_OUTPUTS = ("x", "xd", "xdd", "f_exc", "xdd_free")
TMD_OUTPUTS = ("force", "y", "yd", "inerter_force", "contact")


@njit(cache=True)
def base_outputs(z: NDArray[np.float64], t: float, f_link: complex, p: NDArray[np.float64], out: NDArray) -> None:
    """BaseOscillator: x, xd, xdd (under the link force f_link), the excitation F cos(w t) and the
    acceleration without the link force, at time t."""
    x, xd = z[0], z[1]
    fexc = kn.excitation(t, p)
    out[0] = x
    out[1] = xd
    out[2] = kn.base_acceleration(x, xd, f_link, 0.0, fexc, p)
    out[3] = fexc
    out[4] = kn.base_acceleration(x, xd, 0.0, 0.0, fexc, p)


@njit(cache=True)
def tmd_outputs(
    z: NDArray[np.float64], x: complex, xd: complex, xdd: complex, kappa: float, p: NDArray[np.float64], out: NDArray
) -> None:
    """TMDInerter: the force on the base, y, yd, the inerter chain's force and the gear contact state,
    for the base motion (x, xd, xdd) and the mounting compliance kappa."""
    force, chain, contact = kn.tmd_outputs(z, x, xd, xdd, kappa, p)
    out[0] = force
    out[1] = z[0]
    out[2] = z[1]
    out[3] = chain
    out[4] = contact


BASE_OUT_VR, BASE_OUT_INT = output_layout(BASE_OSCILLATOR, BASE_OUTPUTS)
TMD_OUT_VR, TMD_OUT_INT = output_layout(TMD_INERTER, TMD_OUTPUTS)
