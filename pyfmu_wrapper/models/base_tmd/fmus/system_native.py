"""TMDSystem's native functions: its doStep, configure, outputs, derivative, sensitivity and Model Exchange
functions as numba cfuncs, and its table for the native build.

The contract of a native step and of the model functions is :mod:`pyfmu_wrapper.fmi.native`'s and
:mod:`pyfmu_wrapper.fmi.native_model`'s. The step is :func:`.system.advance_system` (the unit's coupled
integrator), the outputs :func:`.system.write_system`, as the Python slave takes and writes them. Model Exchange:
the derivatives are the unit's right-hand side (:func:`~pyfmu_wrapper.physics.models.coupled_rhs`), the event
indicators its switching functions (friction reversal xd - yd, gear contact d - eps and d + eps; 1 when
inactive), the nominal values of the states its absolute-tolerance scales (:func:`..tolerances.coupled_atol` at
scale 1), the Jacobian the unit's analytic one (:func:`~pyfmu_wrapper.physics.models.coupled_jac`) and the
outputs' by complex step.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc

from ...._jit import njit
from ....fmi.contract import NATIVE_OK, backup_size
from ....fmi.native import SIGNATURE, record_failure
from ....fmi.native_model import (
    CONFIGURE_SIG,
    DERIVATIVE_SIG,
    ME_SIG,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    check_fields,
    field_checks,
    field_messages,
    pack_slots,
    pack_table,
    parameter_sensitivity,
)
from ....physics.jacobians import CSTEP
from ....physics.models import coupled_jac, coupled_rhs
from ....physics.params import N_PARAMS, TMD_CHECKS, tmd_check
from ..tolerances import coupled_atol
from .system import (
    N_SWITCH,
    NSTATE,
    S_ATOL,
    S_RTOL,
    SYS_OUT_VR,
    SYSTEM_MODEL,
    advance_system,
    system_indicators,
    system_outputs,
    write_system,
)
from .variables import TMD_SYSTEM

NP = N_PARAMS
S_NVR = max(v.vr for v in TMD_SYSTEM.variables) + 1
S_BACKUP = backup_size(NSTATE)
S_NOUT = SYS_OUT_VR.size


def _system_pack_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~pyfmu_wrapper.fmi.native_model.pack_table` of both subsystems: every slot from a variable."""
    b_src, b_vr, const = pack_table(TMD_SYSTEM, "base")
    t_src, t_vr, _ = pack_table(TMD_SYSTEM, "tmd")
    return np.where(b_src > 0, b_src, t_src), np.where(b_src > 0, b_vr, t_vr), const


S_SRC, S_VR, S_CONST = _system_pack_table()
_B_ON, _B_LO, _B_STRICT = field_checks("base")
_T_ON, _T_LO, _T_STRICT = field_checks("tmd")
S_ON, S_LO, S_STRICT = _B_ON | _T_ON, np.where(_B_ON, _B_LO, _T_LO), _B_STRICT | _T_STRICT
S_Z0 = np.array([TMD_SYSTEM.vr(n) for n in ("x0", "xd0", "y0", "yd0", "d0", "dd0")], dtype=np.int64)
S_MODEL, S_I, S_m = (TMD_SYSTEM.vr(n) for n in ("inerter", "I", "m"))
_pack_slots, _check_fields = njit(pack_slots), njit(check_fields)


@functools.cache
def system_step() -> Any:
    """The TMDSystem step (compiled on first use, cached on disk): the coupled integrator."""

    @cfunc(SIGNATURE, cache=True)
    def step(  # the pointers' types: SIGNATURE
        reals_p: Any,
        ints_p: Any,
        derivs_p: Any,
        z_p: Any,
        p_p: Any,
        stats_p: Any,
        th_p: Any,
        u_p: Any,
        atol_p: Any,
        backup_p: Any,
        t: float,
        h: float,
    ) -> int:
        reals = carray(reals_p, (S_NVR,))
        ints = carray(ints_p, (S_NVR,))
        z = carray(z_p, (NSTATE,))
        p = carray(p_p, (NP,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (1,))
        atol = carray(atol_p, (NSTATE,))
        backup = carray(backup_p, (S_BACKUP,))
        backup[NSTATE + 4] = 0.0
        for i in range(NSTATE):
            backup[i] = z[i]
        for i in range(4):
            backup[NSTATE + i] = stats[i]
        hn, status, tf = advance_system(z, t, h, p, u, reals[S_RTOL], reals[S_ATOL], atol, th[1], stats)
        if status != 0:  # back to the start of the step, with why, when and where it stopped
            record_failure(backup, z, 1 + status, tf)
            return 1
        th[1] = hn
        th[0] = t + h
        write_system(z, t + h, p, reals, ints)
        return NATIVE_OK

    return step


@njit
def system_configure(reals: Any, ints: Any, p: Any, z: Any) -> int:
    """The slave's ``configure`` over the value buffers: the packed parameters, their field checks, the TMD's
    cross-field checks (:func:`~pyfmu_wrapper.physics.params.tmd_check`), the start state."""
    _pack_slots(S_SRC, S_VR, S_CONST, reals, ints, p)
    rc = _check_fields(S_ON, S_LO, S_STRICT, p)
    if rc != NATIVE_OK:
        return rc
    check = tmd_check(reals[S_m], reals[S_I], ints[S_MODEL])
    if check != 0:
        return check
    for i in range(NSTATE):
        z[i] = reals[S_Z0[i]]
    return NATIVE_OK


@functools.cache
def system_functions() -> dict[str, Any]:
    """TMDSystem's configure, outputs, derivative, sensitivity and Model Exchange cfuncs (compiled on first use)."""

    sens_ = njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        return system_configure(reals, ints, p, z)

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        system_outputs(z, t, p, out)

    def views(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any) -> Any:
        return carray(reals_p, (S_NVR,)), carray(ints_p, (S_NVR,)), carray(z_p, (NSTATE,)), carray(p_p, (NP,))

    views_ = njit(views)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (S_NVR,)), carray(ints_p, (S_NVR,))
        return configure_(reals, ints, carray(p_p, (NP,)), carray(z_p, (NSTATE,)), carray(u_p, (1,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints, z, p = views_(reals_p, ints_p, z_p, p_p)
        write_system(z, t, p, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        dy = carray(dy_p, (S_NOUT,))  # no inputs: the outputs do not move with any
        for j in range(S_NOUT):
            dy[j] = 0.0
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints, z, p = views_(reals_p, ints_p, z_p, p_p)
        return sens_(configure_, outputs_, reals, ints, z, p, carray(u_p, (1,)), t, vr, carray(res_p, (S_NOUT,)))

    @cfunc(ME_SIG)
    def me_derivatives(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        coupled_rhs(t, carray(z_p, (NSTATE,)), carray(p_p, (NP,)), carray(u_p, (1,)), carray(out_p, (NSTATE,)))
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_indicators(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        system_indicators(carray(z_p, (NSTATE,)), carray(p_p, (NP,)), carray(out_p, (N_SWITCH,)))
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_nominals(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        coupled_atol(carray(p_p, (NP,)), 1.0, carray(out_p, (NSTATE,)))
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_jacobian(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        z, p, u = carray(z_p, (NSTATE,)), carray(p_p, (NP,)), carray(u_p, (1,))
        jac = carray(out_p, (NSTATE + S_NOUT, NSTATE))
        J, ft = np.empty((NSTATE, NSTATE)), np.empty(NSTATE)
        zc, oc = np.empty(NSTATE, dtype=np.complex128), np.empty(NSTATE, dtype=np.complex128)
        coupled_jac(t, z, p, u, J, ft, zc, oc)
        out = np.empty(S_NOUT, dtype=np.complex128)
        for j in range(NSTATE):
            for i in range(NSTATE):
                jac[i, j] = J[i, j]
                zc[i] = z[i]
            zc[j] += 1j * CSTEP
            system_outputs(zc, t, p, out)
            for k in range(S_NOUT):
                jac[NSTATE + k, j] = out[k].imag / CSTEP
        return NATIVE_OK

    return {
        "configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity,
        "me_derivatives": me_derivatives, "me_indicators": me_indicators, "me_nominals": me_nominals,
        "me_jacobian": me_jacobian,
    }  # fmt: skip


def system_table() -> dict[str, Any]:
    """TMDSystem's table for ``pyfmu_native_model.h``: its cross-field checks are TMDParams' (physics.params)."""
    return dict(
        nstate=NSTATE, np=N_PARAMS, nu=1, states=SYSTEM_MODEL.state_names, checks=TMD_CHECKS,
        fields=field_messages("base"), check_vars=("m", "I", "inerter"),
    )  # fmt: skip
