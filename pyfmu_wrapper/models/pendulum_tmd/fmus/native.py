"""The PendulumTMD FMU's native (compiled) functions: its doStep, configure, outputs, derivative and
sensitivity as numba cfuncs, and its table for the native build.

The contract of a native step and of the model functions is :mod:`pyfmu_wrapper.fmi.native`'s and
:mod:`pyfmu_wrapper.fmi.native_model`'s. The step is :func:`.step.advance_pendulum`, the outputs are
:func:`.step.pendulum_outputs`, configure restates the checks of
:class:`~pyfmu_wrapper.models.pendulum_tmd.PendulumTMDParams` on the pendulum's rows (finite, and their
bounds) and the packing of :func:`~pyfmu_wrapper.models.pendulum_tmd.packing.pendulum_tmd_pack` over the
FMU's value buffers (the main mass's slots hold the defaults the slave packs); both step paths are
bit-identical.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc

from ...._jit import njit
from ....fmi.contract import NATIVE_OK, backup_size
from ....fmi.native import DEBUG_RAISE_NATIVE, SIGNATURE, record_failure, write_outputs
from ....fmi.native_model import (
    CONFIGURE_SIG,
    DERIVATIVE_SIG,
    FIELD_CODE,
    KAPPA_CODE,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    parameter_sensitivity,
)
from ....physics.jacobians import CSTEP
from ....physics.kernels import input_value
from ..equations import N_PACKED, Q_L, Q_cp, Q_m
from ..packing import pendulum_tmd_pack
from ..params import PendulumTMDParams
from .step import OUT_INT, OUT_VR, U_KAPPA, U_SIZE, advance_pendulum, fill_atol, pendulum_outputs
from .variables import PENDULUM_TMD_FMU, ROWS

NVR = max(v.vr for v in PENDULUM_TMD_FMU.variables) + 1
NOUT = OUT_VR.size
BACKUP = backup_size(4)
V_X, V_XD, V_XDD = (PENDULUM_TMD_FMU.vr(n) for n in ("x", "xd", "xdd"))
V_TH0, V_THD0, V_KAPPA = (PENDULUM_TMD_FMU.vr(n) for n in ("th0", "thd0", "base_compliance"))
V_RTOL, V_ATOL, V_DEBUG = (PENDULUM_TMD_FMU.vr(n) for n in ("rtol", "atol", "debug_raise"))

#: the packed array of the slave's configure with the default pendulum: the main mass's slots and the rest
CONST = pendulum_tmd_pack(PendulumTMDParams(), None, 0.0)
#: per pendulum row: its slot of the packed array, its FMU variable, its bound (NaN: none) and strictness
_SLOTS = {"pendulum_mass": Q_m, "length": Q_L, "pivot_damping": Q_cp}
ROW_SLOT = np.array([_SLOTS[p.name] for p in ROWS], dtype=np.int64)
ROW_VR = np.array([p.fmu_vr for p in ROWS], dtype=np.int64)
ROW_LO = np.array([np.nan if p.minimum is None else p.minimum for p in ROWS])
ROW_STRICT = np.array([p.strict for p in ROWS], dtype=np.bool_)


def field_messages() -> list[str]:
    """The message of configure's code FIELD_CODE + slot (the words of PendulumTMDParams' errors)."""
    out = [""] * N_PACKED
    for p, slot in zip(ROWS, ROW_SLOT):
        bound = "" if p.minimum is None else (f" > {p.minimum:g}" if p.strict else f" >= {p.minimum:g}")
        out[int(slot)] = f"{p.label} must be a finite number{bound} [{p.unit}]"
    return out


@njit(cache=True)
def pendulum_configure(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
    """The slave's ``configure``: the pendulum's rows checked (FIELD_CODE + slot, the value then in p[slot]),
    the compliance (KAPPA_CODE), the packed array and the start state."""
    for k in range(ROW_SLOT.shape[0]):
        v = reals[ROW_VR[k]]
        ok = np.isfinite(v)
        if ok and not np.isnan(ROW_LO[k]):
            ok = v > ROW_LO[k] if ROW_STRICT[k] else v >= ROW_LO[k]
        if not ok:
            p[ROW_SLOT[k]] = v
            return FIELD_CODE + ROW_SLOT[k]
    kappa = reals[V_KAPPA]
    if not (np.isfinite(kappa) and kappa >= 0.0):
        return KAPPA_CODE
    for i in range(p.shape[0]):
        p[i] = CONST[i]
    for k in range(ROW_SLOT.shape[0]):
        p[ROW_SLOT[k]] = reals[ROW_VR[k]]
    u[U_KAPPA] = kappa
    z[0] = reals[V_X]
    z[1] = reals[V_XD]
    z[2] = reals[V_TH0]
    z[3] = reals[V_THD0]
    return NATIVE_OK


@functools.cache
def pendulum_step() -> Any:
    """The PendulumTMD step (compiled on first use, cached on disk): :func:`.step.advance_pendulum`."""

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
        reals = carray(reals_p, (NVR,))
        ints = carray(ints_p, (NVR,))
        derivs = carray(derivs_p, (2 * NVR,))
        z = carray(z_p, (4,))
        p = carray(p_p, (N_PACKED,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (U_SIZE,))  # u[U_KAPPA]: the compliance, set by configure
        atol = carray(atol_p, (4,))
        backup = carray(backup_p, (BACKUP,))
        backup[4 + 4] = 0.0
        for i in range(4):
            backup[i] = z[i]
        for i in range(4):
            backup[4 + i] = stats[i]
        if ints[V_DEBUG] == DEBUG_RAISE_NATIVE:
            raise ZeroDivisionError("debug_raise = 2: exception injected in the compiled step")
        if ints[V_DEBUG] != 0:
            return 1
        u[0] = t
        u[1] = reals[V_X]
        u[2] = derivs[2 * V_X]
        u[3] = derivs[2 * V_X + 1]
        u[4] = reals[V_XD]
        u[5] = derivs[2 * V_XD]
        u[6] = derivs[2 * V_XD + 1]
        u[7] = reals[V_XDD]
        u[8] = derivs[2 * V_XDD]
        u[9] = derivs[2 * V_XDD + 1]
        fill_atol(reals[V_ATOL], p, atol)
        code, hn, tf = advance_pendulum(z, t, h, p, u, reals[V_RTOL], atol, th[1], stats)
        if code != 0:  # back to the start of the step, with why, when and where it stopped
            record_failure(backup, z, code, tf)
            return 1
        th[1] = hn
        t1 = t + h
        th[0] = t1
        out = np.empty(NOUT)
        pendulum_outputs(z, input_value(u, 2, t1), u[U_KAPPA], p, out)
        write_outputs(out, OUT_VR, OUT_INT, reals, ints)
        for vr in (V_X, V_XD, V_XDD):
            derivs[2 * vr] = 0.0
            derivs[2 * vr + 1] = 0.0
        return NATIVE_OK

    return step


@functools.cache
def pendulum_functions() -> dict[str, Any]:
    """The PendulumTMD's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    sens_ = njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        return pendulum_configure(reals, ints, p, z, u)

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        pendulum_outputs(z, reals[V_XDD], u[U_KAPPA], p, out)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (NVR,)), carray(ints_p, (NVR,))
        return configure_(reals, ints, carray(p_p, (N_PACKED,)), carray(z_p, (4,)), carray(u_p, (U_SIZE,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints = carray(reals_p, (NVR,)), carray(ints_p, (NVR,))
        out = np.empty(NOUT)
        outputs_(reals, carray(z_p, (4,)), carray(p_p, (N_PACKED,)), carray(u_p, (U_SIZE,)), t, out)
        write_outputs(out, OUT_VR, OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        reals, z, p, u = carray(reals_p, (NVR,)), carray(z_p, (4,)), carray(p_p, (N_PACKED,)), carray(u_p, (U_SIZE,))
        direction, dy = carray(d_p, (3,)), carray(dy_p, (NOUT,))
        out = np.empty(NOUT, dtype=np.complex128)
        pendulum_outputs(z, reals[V_XDD] + 1j * CSTEP * direction[2], u[U_KAPPA], p, out)
        for j in range(NOUT):
            dy[j] = 0.0 + out[j].imag / CSTEP
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (NVR,)), carray(ints_p, (NVR,))
        z, p, u = carray(z_p, (4,)), carray(p_p, (N_PACKED,)), carray(u_p, (U_SIZE,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (NOUT,)))

    return {"configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity}


def pendulum_table() -> dict[str, Any]:
    """The PendulumTMD's table for ``pyfmu_native_model.h``: no cross-field checks, the row checks' messages."""
    return dict(
        nstate=4, np=N_PACKED, nu=U_SIZE, states=("x", "xd", "th", "thd"), checks=(),
        fields=field_messages(), check_vars=(),
    )  # fmt: skip
