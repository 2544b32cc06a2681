"""The native model functions of the paper's two FMUs besides their steps (configure, outputs, derivative,
sensitivity), as numba cfuncs, and their tables for the native build.

What they compute and why the numbers are the slave's: :mod:`pyfmu_wrapper.fmi.native_model`. The packed
parameters come from :func:`~pyfmu_wrapper.physics.params.pack`'s slots, as a table generated from the
registry (the slot of each registry parameter is read from its FMU variable, the other subsystem's slots
hold the defaults ``pack`` puts there); the TMD's cross-field checks are those of
:class:`~pyfmu_wrapper.physics.params.TMDParams` (:data:`~pyfmu_wrapper.physics.params.TMD_CHECKS`, by the
same compiled :func:`~pyfmu_wrapper.physics.params.tmd_check`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc

from ...._jit import njit
from ....fmi.contract import NATIVE_OK
from ....fmi.native import write_outputs
from ....fmi.native_model import (
    CONFIGURE_SIG,
    DERIVATIVE_SIG,
    KAPPA_CODE,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    check_fields,
    field_checks,
    field_messages,
    pack_slots,
    pack_table,
    parameter_sensitivity,
)
from ....physics import kernels as kn
from ....physics import models
from ....physics.jacobians import CSTEP
from ....physics.params import N_PARAMS, TMD_CHECKS, tmd_check
from .integrators import BASE_U_SIZE
from .native import B_NVR, T_NVR
from .outputs import BASE_OUT_INT, BASE_OUT_VR, TMD_OUT_INT, TMD_OUT_VR, base_outputs, tmd_outputs
from .variables import BASE_OSCILLATOR, TMD_INERTER

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
B_ON, B_LO, B_STRICT = field_checks("base")
T_ON, T_LO, T_STRICT = field_checks("tmd")


@functools.cache
def base_functions() -> dict[str, Any]:
    """The BaseOscillator's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    pack_, fields_, sens_ = njit(pack_slots), njit(check_fields), njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        pack_(B_SRC, B_VR, B_CONST, reals, ints, p)
        rc = fields_(B_ON, B_LO, B_STRICT, p)
        if rc != NATIVE_OK:
            return rc
        z[0] = reals[B_Z0[0]]
        z[1] = reals[B_Z0[1]]
        return NATIVE_OK

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        base_outputs(z, t, reals[B_FLINK], p, out)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (B_NVR,)), carray(ints_p, (B_NVR,))
        return configure_(reals, ints, carray(p_p, (NP,)), carray(z_p, (2,)), carray(u_p, (BASE_U_SIZE,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints = carray(reals_p, (B_NVR,)), carray(ints_p, (B_NVR,))
        out = np.empty(B_NOUT)
        outputs_(reals, carray(z_p, (2,)), carray(p_p, (NP,)), carray(u_p, (BASE_U_SIZE,)), t, out)
        write_outputs(out, BASE_OUT_VR, BASE_OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        reals, z, p = carray(reals_p, (B_NVR,)), carray(z_p, (2,)), carray(p_p, (NP,))
        direction, dy = carray(d_p, (1,)), carray(dy_p, (B_NOUT,))
        out = np.empty(B_NOUT, dtype=np.complex128)
        base_outputs(z, t, reals[B_FLINK] + 1j * CSTEP * direction[0], p, out)
        for j in range(B_NOUT):
            dy[j] = 0.0 + out[j].imag / CSTEP
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (B_NVR,)), carray(ints_p, (B_NVR,))
        z, p, u = carray(z_p, (2,)), carray(p_p, (NP,)), carray(u_p, (BASE_U_SIZE,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (B_NOUT,)))

    return {"configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity}


@functools.cache
def tmd_functions() -> dict[str, Any]:
    """The TMDInerter's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    pack_, fields_, sens_ = njit(pack_slots), njit(check_fields), njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        model, inertance, mass = ints[T_MODEL], reals[T_I], reals[T_m]
        pack_(T_SRC, T_VR, T_CONST, reals, ints, p)
        rc = fields_(T_ON, T_LO, T_STRICT, p)
        if rc != NATIVE_OK:
            return rc
        check = tmd_check(mass, inertance, model)
        if check != 0:
            return check
        kappa = reals[T_KAPPA]
        if not (np.isfinite(kappa) and kappa >= 0.0):
            return KAPPA_CODE
        u[kn.U_KAPPA] = kappa
        for i in range(4):
            z[i] = reals[T_Z0[i]]
        return NATIVE_OK

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        tmd_outputs(z, reals[T_IN[0]], reals[T_IN[1]], reals[T_IN[2]], u[kn.U_KAPPA], p, out)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (T_NVR,)), carray(ints_p, (T_NVR,))
        return configure_(reals, ints, carray(p_p, (NP,)), carray(z_p, (4,)), carray(u_p, (NU_TMD,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints = carray(reals_p, (T_NVR,)), carray(ints_p, (T_NVR,))
        out = np.empty(T_NOUT)
        outputs_(reals, carray(z_p, (4,)), carray(p_p, (NP,)), carray(u_p, (NU_TMD,)), t, out)
        write_outputs(out, TMD_OUT_VR, TMD_OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        reals, z, p, u = carray(reals_p, (T_NVR,)), carray(z_p, (4,)), carray(p_p, (NP,)), carray(u_p, (NU_TMD,))
        direction, dy = carray(d_p, (3,)), carray(dy_p, (T_NOUT,))
        x = reals[T_IN[0]] + 1j * CSTEP * direction[0]
        xd = reals[T_IN[1]] + 1j * CSTEP * direction[1]
        xdd = reals[T_IN[2]] + 1j * CSTEP * direction[2]
        out = np.empty(T_NOUT, dtype=np.complex128)
        tmd_outputs(z, x, xd, xdd, u[kn.U_KAPPA], p, out)
        for j in range(T_NOUT):
            dy[j] = 0.0 + out[j].imag / CSTEP
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (T_NVR,)), carray(ints_p, (T_NVR,))
        z, p, u = carray(z_p, (4,)), carray(p_p, (NP,)), carray(u_p, (NU_TMD,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (T_NOUT,)))

    return {"configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity}


def base_table() -> dict[str, Any]:
    """The BaseOscillator's table for ``pyfmu_native_model.h`` (:class:`~pyfmu_wrapper.fmi.fmumodel.NativeFmu`)."""
    return dict(
        nstate=2, np=N_PARAMS, nu=BASE_U_SIZE, states=models.BASE.state_names, checks=(),
        fields=field_messages("base"), check_vars=(),
    )  # fmt: skip


def tmd_table() -> dict[str, Any]:
    """The TMDInerter's table for ``pyfmu_native_model.h``: its cross-field checks are TMDParams' (physics.params)."""
    return dict(
        nstate=4, np=N_PARAMS, nu=kn.U_KAPPA + 1, states=models.TMD.state_names, checks=TMD_CHECKS,
        fields=field_messages("tmd"), check_vars=("m", "I", "inerter"),
    )  # fmt: skip
