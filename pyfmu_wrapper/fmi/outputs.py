"""The FMUs' outputs, one compiled function per subsystem, called by both step paths: the native step
(:mod:`.native`, after a compiled doStep) and the Python slave (:mod:`.slaves`: after a long or
retaken doStep, in initialisation, and with complex inputs for the directional derivatives by complex
step). Each writes the outputs into ``out`` in the order of the FMU's output variables
(``spec.of("output")`` of :mod:`.variables`; :data:`BASE_OUTPUTS`, :data:`TMD_OUTPUTS` name them and
the import below checks the order against the variable table). The physics is the kernels'.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._jit import njit
from ..physics import kernels as kn
from .variables import BASE_OSCILLATOR, TMD_INERTER
from .varspec import BOOLEAN, INTEGER, FmuSpec

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


def output_layout(spec: FmuSpec, names: tuple[str, ...]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """(value references, is-integer flags) of the outputs, in the order the functions above write
    them; refuses a variable table whose outputs are not ``names`` in that order."""
    outs = spec.of("output")
    if tuple(v.name for v in outs) != names:
        raise RuntimeError(f"{spec.model_name}: outputs {[v.name for v in outs]} != {list(names)} (fmi/outputs.py)")
    return (
        np.array([v.vr for v in outs], dtype=np.int64),
        np.array([v.type in (INTEGER, BOOLEAN) for v in outs], dtype=np.bool_),
    )


BASE_OUT_VR, BASE_OUT_INT = output_layout(BASE_OSCILLATOR, BASE_OUTPUTS)
TMD_OUT_VR, TMD_OUT_INT = output_layout(TMD_INERTER, TMD_OUTPUTS)
