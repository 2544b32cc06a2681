"""The model functions a native FMU needs besides its step (:mod:`.native`), as numba cfuncs (issue 30).

A native FMU (:mod:`.native_build`) runs with no Python: its stub calls these compiled functions
where the Python-hosted FMU calls its slave (:mod:`.slaves`). Each computes what the slave computes,
with the same compiled code, so the numbers are bit-identical (tests/test_native_fmu.py):

- ``configure(reals, ints, p, z, u) -> int32``: the slave's ``configure``: the packed parameters
  (:func:`~pyfmu_wrapper.physics.params.pack`, as a table generated from the registry: the slot of
  each registry parameter is read from its FMU variable, the other subsystem's slots hold the
  defaults ``pack`` puts there), the initial state and, for the TMD, the mounting compliance.
  Returns :data:`~.contract.NATIVE_OK`, or the number of the first cross-field check of
  :class:`~pyfmu_wrapper.physics.params.TMDParams` that fails (:data:`TMD_CHECKS`; the single-field
  ranges are declared and enforced by the stub);
- ``outputs(reals, ints, z, p, u, t) -> int32``: the outputs at the current inputs (the slave's
  ``update_outputs``), written into the value buffers;
- ``derivative(reals, ints, z, p, u, t, direction, dy) -> int32``: d outputs along ``direction`` in
  the inputs, by the complex step of the slave's ``directional_derivative``.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc, types

from ..physics import kernels as kn
from ..physics import registry
from ..physics.params import N_PARAMS, BaseParams, TMDParams, pack
from .contract import NATIVE_OK
from .native import B_NVR, T_NVR, write_outputs
from .outputs import BASE_OUT_INT, BASE_OUT_VR, TMD_OUT_INT, TMD_OUT_VR, base_outputs, tmd_outputs
from .slave import _CSTEP
from .variables import BASE_OSCILLATOR, TMD_INERTER
from .varspec import FmuSpec

F64P, I32P = types.CPointer(types.float64), types.CPointer(types.int32)
CONFIGURE_SIG = types.int32(F64P, I32P, F64P, F64P, F64P)
OUTPUTS_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64)
DERIVATIVE_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64, F64P, F64P)

#: the cross-field checks of TMDParams, in the order configure numbers them (1, 2, ...)
TMD_CHECKS = (
    "inertance must be 0 when inerter is 'none'",
    "inertance must be > 0 for an inerter (ideal or with play)",
    "mass + inertance (m + I) must be > 0",
    "mass (m) must be > 0 unless the inerter is ideal (the TMD node would be massless)",
)


def pack_table(spec: FmuSpec, subsystem: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per slot of the packed parameters: source (0: the constant, 1: a Real variable, 2: an Integer
    variable), its value reference, the constant. The slots of ``subsystem`` come from the FMU's
    variables, the others hold what ``pack`` puts there (the defaults of the other subsystem, and
    omega = 0 for the TMD)."""
    const = pack(BaseParams(), TMDParams(), 0.0)
    src = np.zeros(N_PARAMS, dtype=np.int64)
    vr = np.zeros(N_PARAMS, dtype=np.int64)
    for i, par in enumerate(registry.PARAMETERS):
        if par.subsystem == subsystem:
            v = spec.by_name(par.fmu_name)
            src[i] = 1 if v.type == "Real" else 2
            vr[i] = v.vr
    return src, vr, const


B_SRC, B_VR, B_CONST = pack_table(BASE_OSCILLATOR, "base")
T_SRC, T_VR, T_CONST = pack_table(TMD_INERTER, "tmd")
B_Z0 = np.array([BASE_OSCILLATOR.vr(n) for n in ("x0", "xd0")], dtype=np.int64)
T_Z0 = np.array([TMD_INERTER.vr(n) for n in ("y0", "yd0", "d0", "dd0")], dtype=np.int64)
B_FLINK = BASE_OSCILLATOR.vr("f_link")
T_IN = np.array([TMD_INERTER.vr(n) for n in ("x", "xd", "xdd")], dtype=np.int64)
T_KAPPA, T_I, T_m, T_MODEL = (TMD_INERTER.vr(n) for n in ("base_compliance", "I", "m", "inerter"))
B_NOUT, T_NOUT = BASE_OUT_VR.size, TMD_OUT_VR.size
NU_TMD = kn.U_KAPPA + 1
NP = N_PARAMS


def _pack(src: Any, vr: Any, const: Any, reals: Any, ints: Any, p: Any) -> None:
    for i in range(NP):
        if src[i] == 1:
            p[i] = reals[vr[i]]
        elif src[i] == 2:
            p[i] = float(ints[vr[i]])
        else:
            p[i] = const[i]


@functools.cache
def base_functions() -> dict[str, Any]:
    """The BaseOscillator's configure, outputs and derivative cfuncs (compiled on first use)."""
    from numba import njit

    pack_ = njit(_pack)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (B_NVR,)), carray(ints_p, (B_NVR,))
        p, z = carray(p_p, (NP,)), carray(z_p, (2,))
        pack_(B_SRC, B_VR, B_CONST, reals, ints, p)
        z[0] = reals[B_Z0[0]]
        z[1] = reals[B_Z0[1]]
        return NATIVE_OK

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        n = B_NVR
        reals, ints, z, p = carray(reals_p, (n,)), carray(ints_p, (n,)), carray(z_p, (2,)), carray(p_p, (NP,))
        out = np.empty(B_NOUT)
        base_outputs(z, t, reals[B_FLINK], p, out)
        write_outputs(out, BASE_OUT_VR, BASE_OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        n = B_NVR
        reals, z, p = carray(reals_p, (n,)), carray(z_p, (2,)), carray(p_p, (NP,))
        direction, dy = carray(d_p, (1,)), carray(dy_p, (B_NOUT,))
        out = np.empty(B_NOUT, dtype=np.complex128)
        base_outputs(z, t, reals[B_FLINK] + 1j * _CSTEP * direction[0], p, out)
        for j in range(B_NOUT):
            dy[j] = 0.0 + out[j].imag / _CSTEP
        return NATIVE_OK

    return {"configure": configure, "outputs": outputs, "derivative": derivative}


@functools.cache
def tmd_functions() -> dict[str, Any]:
    """The TMDInerter's configure, outputs and derivative cfuncs (compiled on first use)."""
    from numba import njit

    pack_ = njit(_pack)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        n = T_NVR
        reals, ints, p, z, u = (
            carray(reals_p, (n,)), carray(ints_p, (n,)), carray(p_p, (NP,)), carray(z_p, (4,)), carray(u_p, (NU_TMD,))
        )  # fmt: skip
        model, inertance, mass = ints[T_MODEL], reals[T_I], reals[T_m]
        if model == 0 and inertance != 0.0:
            return 1
        if model != 0 and inertance <= 0.0:
            return 2
        if mass + inertance <= 0.0:
            return 3
        if mass <= 0.0 and model != 1:
            return 4
        pack_(T_SRC, T_VR, T_CONST, reals, ints, p)
        u[kn.U_KAPPA] = reals[T_KAPPA]
        for i in range(4):
            z[i] = reals[T_Z0[i]]
        return NATIVE_OK

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        n = T_NVR
        reals, ints, z, p = carray(reals_p, (n,)), carray(ints_p, (n,)), carray(z_p, (4,)), carray(p_p, (NP,))
        u = carray(u_p, (NU_TMD,))
        out = np.empty(T_NOUT)
        tmd_outputs(z, reals[T_IN[0]], reals[T_IN[1]], reals[T_IN[2]], u[kn.U_KAPPA], p, out)
        write_outputs(out, TMD_OUT_VR, TMD_OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        n = T_NVR
        reals, z, p, u = carray(reals_p, (n,)), carray(z_p, (4,)), carray(p_p, (NP,)), carray(u_p, (NU_TMD,))
        direction, dy = carray(d_p, (3,)), carray(dy_p, (T_NOUT,))
        x = reals[T_IN[0]] + 1j * _CSTEP * direction[0]
        xd = reals[T_IN[1]] + 1j * _CSTEP * direction[1]
        xdd = reals[T_IN[2]] + 1j * _CSTEP * direction[2]
        out = np.empty(T_NOUT, dtype=np.complex128)
        tmd_outputs(z, x, xd, xdd, u[kn.U_KAPPA], p, out)
        for j in range(T_NOUT):
            dy[j] = 0.0 + out[j].imag / _CSTEP
        return NATIVE_OK

    return {"configure": configure, "outputs": outputs, "derivative": derivative}


#: model -> the factory of its functions
FUNCTIONS = {"BaseOscillator": base_functions, "TMDInerter": tmd_functions}
