"""FrameSystem's native functions: its doStep, configure, outputs, derivative, sensitivity and Model Exchange
functions as numba cfuncs, and its table for the native build.

The contract is :mod:`pyfmu_wrapper.fmi.native`'s and :mod:`pyfmu_wrapper.fmi.native_model`'s. The step is
:func:`.system.advance_frame_system` (the frame unit's integrator), the outputs :func:`.system.write_frame_system`,
as the Python slave takes and writes them. configure is ShearFrame's (:func:`.native.frame_configure`: the
frame's checks and packing) with the TMD's slots from its variables, their field checks and the TMD's cross-field
checks. Model Exchange: the derivatives are the unit's right-hand side, the event indicators its switching
functions, the nominal values its tolerance scales (:func:`..tolerances.frame_atol` at scale 1; 1 for the storeys
above the top), the Jacobian the unit's (complex step), on the FMU's state mapped onto the model's.
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
    FIELD_CODE,
    ME_SIG,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    check_fields,
    field_checks,
    parameter_sensitivity,
)
from ....physics import registry
from ....physics.jacobians import CSTEP
from ....physics.params import N_PARAMS, TMD_CHECKS, tmd_check
from ...base_tmd.fmus.variables import SYSTEM_TMD_VR
from ..equations import F_N, frame_jacobian, storey_index
from ..params import MAX_STOREYS
from ..tolerances import frame_atol
from .native import FRAME_CHECKS, frame_configure, frame_field_messages
from .step import NP_FRAME, NS_MAX
from .system import (
    FS_ATOL,
    FS_OUT_VR,
    FS_RTOL,
    N_SWITCH,
    advance_frame_system,
    frame_derivatives,
    frame_indicators,
    frame_system_outputs,
    model_index,
    to_model,
    write_frame_system,
)
from .system_variables import FRAME_SYSTEM, state_names

FS_NVR = max(v.vr for v in FRAME_SYSTEM.variables) + 1
FS_BACKUP = backup_size(NS_MAX)
FS_NOUT = FS_OUT_VR.size
#: the TMD's slots of the packed parameters: source (1 Real, 2 Integer, 0 none) and value reference
FS_TSRC = np.zeros(N_PARAMS, dtype=np.int64)
FS_TVR = np.zeros(N_PARAMS, dtype=np.int64)
for _i, _par in enumerate(registry.PARAMETERS):
    if _par.subsystem == "tmd":
        _v = next(v for v in FRAME_SYSTEM.variables if v.vr == SYSTEM_TMD_VR + _par.fmu_vr)
        FS_TSRC[_i], FS_TVR[_i] = (1 if _v.type == "Real" else 2), _v.vr
FS_T_ON, FS_T_LO, FS_T_STRICT = field_checks("tmd")
FS_Z0 = np.array([FRAME_SYSTEM.vr(n) for n in ("y0", "yd0", "d0", "dd0")], dtype=np.int64)
FS_X0, FS_XD0 = FRAME_SYSTEM.vr("x0_1"), FRAME_SYSTEM.vr("xd0_1")
FS_MODEL, FS_I, FS_m = (FRAME_SYSTEM.vr(n) for n in ("inerter", "I", "m"))
_check_fields = njit(check_fields)
#: configure's codes of the TMD's cross-field checks follow the frame's
TMD_CODE = len(FRAME_CHECKS)


@njit
def frame_system_configure(reals: Any, ints: Any, p: Any, z: Any) -> int:
    """ShearFrame's configure (the frame's checks, its packing), then the TMD's slots from its variables, their
    field checks, the TMD's cross-field checks (codes after the frame's), the FMU's start state."""
    zm = np.empty(NS_MAX)
    rc = frame_configure(reals, ints, p, zm)
    if rc != NATIVE_OK:
        return rc
    for i in range(N_PARAMS):
        if FS_TSRC[i] == 1:
            p[i] = reals[FS_TVR[i]]
        elif FS_TSRC[i] == 2:
            p[i] = float(ints[FS_TVR[i]])
    rc = _check_fields(FS_T_ON, FS_T_LO, FS_T_STRICT, p)
    if rc != NATIVE_OK:
        return rc
    check = tmd_check(reals[FS_m], reals[FS_I], ints[FS_MODEL])
    if check != 0:
        return TMD_CODE + check
    n = int(p[F_N])
    for k in range(z.shape[0]):
        z[k] = 0.0
    for i in range(1, n + 1):
        b = storey_index(i, MAX_STOREYS)
        z[b] = reals[FS_X0 + i - 1]
        z[b + 1] = reals[FS_XD0 + i - 1]
    for k in range(4):
        z[2 + k] = reals[FS_Z0[k]]
    return NATIVE_OK


@functools.cache
def frame_system_step() -> Any:
    """The FrameSystem step (compiled on first use, cached on disk): the frame's integrator."""

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
        reals = carray(reals_p, (FS_NVR,))
        ints = carray(ints_p, (FS_NVR,))
        z = carray(z_p, (NS_MAX,))
        p = carray(p_p, (NP_FRAME,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (1,))
        backup = carray(backup_p, (FS_BACKUP,))
        backup[NS_MAX + 4] = 0.0
        for i in range(NS_MAX):
            backup[i] = z[i]
        for i in range(4):
            backup[NS_MAX + i] = stats[i]
        hn, status, tf = advance_frame_system(z, t, h, p, u, reals[FS_RTOL], reals[FS_ATOL], th[1], stats)
        if status != 0:  # back to the start of the step, with why, when and where it stopped
            record_failure(backup, z, 1 + status, tf)
            return 1
        th[1] = hn
        th[0] = t + h
        write_frame_system(z, t + h, p, reals, ints)
        return NATIVE_OK

    return step


@functools.cache
def frame_system_functions() -> dict[str, Any]:
    """FrameSystem's configure, outputs, derivative, sensitivity and Model Exchange cfuncs (compiled on first use)."""

    sens_ = njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        return frame_system_configure(reals, ints, p, z)

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        n = int(p[F_N])
        zm = np.empty(2 * n + 4)
        to_model(z, n, zm)
        frame_system_outputs(zm, t, p, out)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (FS_NVR,)), carray(ints_p, (FS_NVR,))
        return configure_(reals, ints, carray(p_p, (NP_FRAME,)), carray(z_p, (NS_MAX,)), carray(u_p, (1,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints = carray(reals_p, (FS_NVR,)), carray(ints_p, (FS_NVR,))
        write_frame_system(carray(z_p, (NS_MAX,)), t, carray(p_p, (NP_FRAME,)), reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        dy = carray(dy_p, (FS_NOUT,))  # no inputs: the outputs do not move with any
        for j in range(FS_NOUT):
            dy[j] = 0.0
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (FS_NVR,)), carray(ints_p, (FS_NVR,))
        z, p, u = carray(z_p, (NS_MAX,)), carray(p_p, (NP_FRAME,)), carray(u_p, (1,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (FS_NOUT,)))

    @cfunc(ME_SIG)
    def me_derivatives(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        frame_derivatives(carray(z_p, (NS_MAX,)), t, carray(p_p, (NP_FRAME,)), carray(out_p, (NS_MAX,)))
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_indicators(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        p = carray(p_p, (NP_FRAME,))
        n = int(p[F_N])
        zm = np.empty(2 * n + 4)
        to_model(carray(z_p, (NS_MAX,)), n, zm)
        frame_indicators(zm, p, carray(out_p, (N_SWITCH,)))
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_nominals(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        p, nom = carray(p_p, (NP_FRAME,)), carray(out_p, (NS_MAX,))
        n = int(p[F_N])
        atol, idx = np.empty(2 * n + 4), np.empty(2 * n + 4, dtype=np.int64)
        frame_atol(p, 1.0, atol)
        model_index(n, idx)
        for k in range(NS_MAX):
            nom[k] = 1.0
        for k in range(2 * n + 4):
            nom[idx[k]] = atol[k]
        return NATIVE_OK

    @cfunc(ME_SIG)
    def me_jacobian(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, out_p: Any) -> int:
        z, p, u = carray(z_p, (NS_MAX,)), carray(p_p, (NP_FRAME,)), carray(u_p, (1,))
        jac = carray(out_p, (NS_MAX + FS_NOUT, NS_MAX))
        n = int(p[F_N])
        m = 2 * n + 4
        zm, idx = np.empty(m), np.empty(m, dtype=np.int64)
        to_model(z, n, zm)
        model_index(n, idx)
        J, ft = np.empty((m, m)), np.empty(m)
        zc, oc = np.empty(m, dtype=np.complex128), np.empty(m, dtype=np.complex128)
        frame_jacobian(t, zm, p, u, J, ft, zc, oc)
        for r in range(NS_MAX + FS_NOUT):
            for c in range(NS_MAX):
                jac[r, c] = 0.0
        out = np.empty(FS_NOUT, dtype=np.complex128)
        for j in range(m):
            for i in range(m):
                jac[idx[i], idx[j]] = J[i, j]
                zc[i] = zm[i]
            zc[j] += 1j * CSTEP
            frame_system_outputs(zc, t, p, out)
            for k in range(FS_NOUT):
                jac[NS_MAX + k, idx[j]] = out[k].imag / CSTEP
        return NATIVE_OK

    return {
        "configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity,
        "me_derivatives": me_derivatives, "me_indicators": me_indicators, "me_nominals": me_nominals,
        "me_jacobian": me_jacobian,
    }  # fmt: skip


def frame_system_table() -> dict[str, Any]:
    """FrameSystem's table for ``pyfmu_native_model.h``: the FMU's state (the layout for 20 storeys), the
    frame's cross-field checks then the TMD's, their messages."""
    return dict(
        nstate=NS_MAX, np=NP_FRAME, nu=1, states=state_names(), checks=FRAME_CHECKS + TMD_CHECKS,
        fields=frame_field_messages(),
        check_vars=("storeys", "force_storey", "tmd_storey", "inerter_to", "m", "I", "inerter"),
    )  # fmt: skip


assert FIELD_CODE > 0  # the field codes of both configures share FIELD_CODE + slot
