"""The LinearTMD FMU's native (compiled) functions: its doStep, configure, outputs, derivative and
sensitivity as numba cfuncs, and its table for the native build.

The contract of a native step and of the model functions is :mod:`pyfmu_wrapper.fmi.native`'s and
:mod:`pyfmu_wrapper.fmi.native_model`'s. The step is :func:`.step.advance_linear`, the outputs are
:func:`.step.linear_outputs`, configure restates the checks of
:class:`~pyfmu_wrapper.models.linear_tmd.LinearTMDParams` on the model's rows (finite, and their bounds) and
the packing of :func:`~pyfmu_wrapper.models.linear_tmd.packing.linear_tmd_pack` over the FMU's value
buffers; both step paths are bit-identical.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc

from ...._jit import njit
from ....fmi.contract import NATIVE_OK, backup_size
from ....fmi.native import SIGNATURE, record_failure, write_outputs
from ....fmi.native_model import (
    CONFIGURE_SIG,
    DERIVATIVE_SIG,
    FIELD_CODE,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    parameter_sensitivity,
)
from ....physics.jacobians import CSTEP
from ....physics.kernels import input_value
from ....physics.params import P_F, P_W
from ..equations import L_AT, N_PACKED
from ..params import PARAMETERS
from .step import OUT_INT, OUT_VR, U_SIZE, advance_linear, linear_outputs
from .variables import LINEAR_TMD_FMU

NVR = max(v.vr for v in LINEAR_TMD_FMU.variables) + 1
NOUT = OUT_VR.size
BACKUP = backup_size(4)
V_F, V_W = LINEAR_TMD_FMU.vr("f_ext"), LINEAR_TMD_FMU.vr("w")
V_Z0 = np.array([LINEAR_TMD_FMU.vr(n) for n in ("x0", "xd0", "y0", "yd0")], dtype=np.int64)
V_RTOL, V_ATOL = LINEAR_TMD_FMU.vr("rtol"), LINEAR_TMD_FMU.vr("atol")

#: per declared row: its slot of the packed array (linear_tmd_pack's), its FMU variable, its bound (NaN:
#: none) and strictness
_SLOTS = {"force_amplitude": P_F} | {
    n: L_AT + i
    for i, n in enumerate(("mass", "stiffness", "damping", "absorber_mass", "absorber_stiffness", "absorber_damping"))
}
ROW_SLOT = np.array([_SLOTS[p.name] for p in PARAMETERS], dtype=np.int64)
ROW_VR = np.array([p.fmu_vr for p in PARAMETERS], dtype=np.int64)
ROW_LO = np.array([np.nan if p.minimum is None else p.minimum for p in PARAMETERS])
ROW_STRICT = np.array([p.strict for p in PARAMETERS], dtype=np.bool_)


def field_messages() -> list[str]:
    """The message of configure's code FIELD_CODE + slot (the words of LinearTMDParams' errors)."""
    out = [""] * N_PACKED
    for p, slot in zip(PARAMETERS, ROW_SLOT):
        bound = "" if p.minimum is None else (f" > {p.minimum:g}" if p.strict else f" >= {p.minimum:g}")
        out[int(slot)] = f"{p.label} must be a finite number{bound} [{p.unit}]"
    return out


@njit(cache=True)
def linear_configure(reals: Any, ints: Any, p: Any, z: Any) -> int:
    """The slave's ``configure``: the model's rows checked in their declared order (FIELD_CODE + slot, the
    value then in p[slot]), the packed array and the start state."""
    for k in range(ROW_SLOT.shape[0]):
        v = reals[ROW_VR[k]]
        ok = np.isfinite(v)
        if ok and not np.isnan(ROW_LO[k]):
            ok = v > ROW_LO[k] if ROW_STRICT[k] else v >= ROW_LO[k]
        if not ok:
            p[ROW_SLOT[k]] = v
            return FIELD_CODE + ROW_SLOT[k]
    for i in range(p.shape[0]):
        p[i] = 0.0
    for k in range(ROW_SLOT.shape[0]):
        p[ROW_SLOT[k]] = reals[ROW_VR[k]]
    p[P_W] = reals[V_W]
    for i in range(4):
        z[i] = reals[V_Z0[i]]
    return NATIVE_OK


@functools.cache
def linear_step() -> Any:
    """The LinearTMD step (compiled on first use, cached on disk): :func:`.step.advance_linear`."""

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
        u = carray(u_p, (U_SIZE,))
        atol = carray(atol_p, (4,))
        backup = carray(backup_p, (BACKUP,))
        backup[4 + 4] = 0.0
        for i in range(4):
            backup[i] = z[i]
        for i in range(4):
            backup[4 + i] = stats[i]
        u[0] = t
        u[1] = reals[V_F]
        u[2] = derivs[2 * V_F]
        u[3] = derivs[2 * V_F + 1]
        for i in range(4):
            atol[i] = reals[V_ATOL]
        code, hn, tf = advance_linear(z, t, h, p, u, reals[V_RTOL], atol, th[1], stats)
        if code != 0:  # back to the start of the step, with why, when and where it stopped
            record_failure(backup, z, code, tf)
            return 1
        th[1] = hn
        t1 = t + h
        th[0] = t1
        out = np.empty(NOUT)
        linear_outputs(z, t1, input_value(u, 0, t1), p, u, out)
        write_outputs(out, OUT_VR, OUT_INT, reals, ints)
        derivs[2 * V_F] = 0.0
        derivs[2 * V_F + 1] = 0.0
        return NATIVE_OK

    return step


@functools.cache
def linear_functions() -> dict[str, Any]:
    """The LinearTMD's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    sens_ = njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        return linear_configure(reals, ints, p, z)

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        linear_outputs(z, t, reals[V_F], p, u, out)

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
        direction, dy = carray(d_p, (1,)), carray(dy_p, (NOUT,))
        out = np.empty(NOUT, dtype=np.complex128)
        linear_outputs(z, t, reals[V_F] + 1j * CSTEP * direction[0], p, u, out)
        for j in range(NOUT):
            dy[j] = 0.0 + out[j].imag / CSTEP
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (NVR,)), carray(ints_p, (NVR,))
        z, p, u = carray(z_p, (4,)), carray(p_p, (N_PACKED,)), carray(u_p, (U_SIZE,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (NOUT,)))

    return {"configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity}


def linear_table() -> dict[str, Any]:
    """The LinearTMD's table for ``pyfmu_native_model.h``: no cross-field checks, the row checks' messages."""
    return dict(
        nstate=4, np=N_PACKED, nu=U_SIZE, states=("x", "xd", "y", "yd"), checks=(),
        fields=field_messages(), check_vars=(),
    )  # fmt: skip
