"""The ShearFrame FMU's native (compiled) functions: its doStep, configure, outputs, derivative and
sensitivity as numba cfuncs, and its table for the native build.

The contract of a native step and of the model functions is :mod:`pyfmu_wrapper.fmi.native`'s and
:mod:`pyfmu_wrapper.fmi.native_model`'s. The step is exact (:func:`.step.advance_frame`), the outputs are
:func:`.step.frame_outputs`, configure restates the checks of
:class:`~pyfmu_wrapper.models.frame_model.FrameParams` and the packing of
:func:`~pyfmu_wrapper.models.frame_model.frame_pack` over the FMU's value buffers; both step paths are
bit-identical.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import carray, cfunc

from ...._jit import njit
from ....fmi.contract import FAIL_NOT_FINITE, NATIVE_OK, backup_size
from ....fmi.native import SIGNATURE, write_outputs
from ....fmi.native_model import (
    CONFIGURE_SIG,
    DERIVATIVE_SIG,
    FIELD_CODE,
    OUTPUTS_SIG,
    SENSITIVITY_SIG,
    field_messages,
    parameter_sensitivity,
)
from ....physics import kernels as kn
from ....physics import registry
from ....physics.jacobians import CSTEP
from ....physics.params import N_PARAMS, BaseParams, TMDParams, pack
from ..equations import F_LOAD, F_N, F_TMD, F_TO, F_VALUES, storey_index
from ..params import MAX_STOREYS
from .step import FRAME_OUT_INT, FRAME_OUT_VR, FRAME_U_SIZE, NP_FRAME, NS_MAX, advance_frame, frame_outputs
from .variables import SHEAR_FRAME, VR_DAMPING, VR_MASS, VR_STIFFNESS, VR_X0, VR_XD0

NP = N_PARAMS
F_NVR = max(v.vr for v in SHEAR_FRAME.variables) + 1
F_FLINK, F_FINER = SHEAR_FRAME.vr("f_link"), SHEAR_FRAME.vr("f_inerter")
F_NOUT, F_BACKUP = FRAME_OUT_VR.size, backup_size(NS_MAX)


@functools.cache
def frame_step() -> Any:
    """The ShearFrame step (compiled on first use, cached on disk): exact (:func:`.step.advance_frame`)."""

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
        reals = carray(reals_p, (F_NVR,))
        ints = carray(ints_p, (F_NVR,))
        derivs = carray(derivs_p, (2 * F_NVR,))
        z = carray(z_p, (NS_MAX,))
        p = carray(p_p, (NP_FRAME,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (FRAME_U_SIZE,))  # the input polynomials, then the exact step's cache
        backup = carray(backup_p, (F_BACKUP,))
        backup[NS_MAX + 4] = 0.0
        for i in range(NS_MAX):
            backup[i] = z[i]
        for i in range(4):
            backup[NS_MAX + i] = stats[i]
        u[0] = t
        u[1] = reals[F_FLINK]
        u[2] = derivs[2 * F_FLINK]
        u[3] = derivs[2 * F_FLINK + 1]
        u[4] = reals[F_FINER]
        u[5] = derivs[2 * F_FINER]
        u[6] = derivs[2 * F_FINER + 1]
        if advance_frame(z, t, h, p, u, stats) != 0:  # not finite: z is at the start of the step
            backup[NS_MAX + 4] = FAIL_NOT_FINITE
            backup[NS_MAX + 5] = t + h
            return 1
        th[1] = h
        t1 = t + h
        th[0] = t1
        out = np.empty(F_NOUT)
        frame_outputs(z, t1, kn.input_value(u, 0, t1), kn.input_value(u, 1, t1), p, out)
        write_outputs(out, FRAME_OUT_VR, FRAME_OUT_INT, reals, ints)
        for vr in (F_FLINK, F_FINER):
            derivs[2 * vr] = 0.0
            derivs[2 * vr + 1] = 0.0
        return NATIVE_OK

    return step


#: the ShearFrame's scalar variables configure reads: storeys, F, w, and the storeys of the force, the TMD
#: and the inerter's terminal
_FRAME_SCALARS = ("storeys", "F", "w", "force_storey", "tmd_storey", "inerter_to")

#: the cross-field checks of the ShearFrame's configure, in the order it numbers them (1, 2, ...):
#: the words of :class:`~pyfmu_wrapper.models.frame_model.FrameParams`' errors
FRAME_CHECKS = (
    f"storeys must be 1 to {MAX_STOREYS}",
    "force_storey must be an integer storey 0..storeys (0: the top)",
    "tmd_storey must be an integer storey 0..storeys (0: the top)",
    "inerter_to must be an integer storey -1..storeys (-1: the TMD's storey, 0: the ground)",
)
FR_N, FR_F, FR_W, FR_LOAD, FR_TMD, FR_TO = (SHEAR_FRAME.vr(n) for n in _FRAME_SCALARS)
FR_FLINK, FR_FINER = SHEAR_FRAME.vr("f_link"), SHEAR_FRAME.vr("f_inerter")
FR_NOUT = FRAME_OUT_VR.size


def frame_pack_table() -> tuple[np.ndarray, np.ndarray]:
    """The packed parameters of the paper's part that do not come from a frame's variables (the
    constants :func:`~pyfmu_wrapper.models.frame_model.frame_pack` puts there: a default TMD) and,
    per slot, the ShearFrame variable of the first storey's base slots (-1: none)."""
    const = pack(BaseParams(), TMDParams(), 0.0)
    src = np.full(N_PARAMS, -1, dtype=np.int64)
    fmu = {"mass": VR_MASS, "stiffness": VR_STIFFNESS, "damping": VR_DAMPING, "force_amplitude": FR_F, "omega": FR_W}
    for i, par in enumerate(registry.PARAMETERS):
        if par.subsystem == "base":
            src[i] = fmu[par.name]
    return const, src


FR_CONST, FR_SRC = frame_pack_table()


#: the per-storey fields configure checks: (kind, first value reference, > 0 strictly), their names
_STOREY_FIELDS = ((0, VR_MASS, True), (1, VR_STIFFNESS, True), (2, VR_DAMPING, False))
_STOREY_NAMES = (("mass", "m", "> 0"), ("stiffness", "k", "> 0"), ("damping", "c", ">= 0"))


def frame_field_messages() -> list[str]:
    """The message of the ShearFrame configure's code FIELD_CODE + q: q a slot of the paper's part, or
    F_VALUES + 20 kind + i for storey i + 1's mass, stiffness or damping (kind 0, 1, 2)."""
    out = field_messages("base") + [""] * (NP_FRAME - N_PARAMS)
    for kind, (name, sym, bound) in enumerate(_STOREY_NAMES):
        for i in range(1, MAX_STOREYS + 1):
            out[F_VALUES + MAX_STOREYS * kind + i - 1] = f"{name} of storey {i} ({sym}{i}) must be finite and {bound}"
    return out


@njit(cache=True)
def frame_configure(reals: Any, ints: Any, p: Any, z: Any) -> int:
    """The ShearFrame slave's ``configure``: the checks of :class:`~pyfmu_wrapper.models.frame_model.FrameParams`
    (NATIVE_OK, a number of :data:`FRAME_CHECKS`, or FIELD_CODE + q of :func:`frame_field_messages`, the
    value then in p[q]), the packed array of :func:`~pyfmu_wrapper.models.frame_model.frame_pack` (its
    head: the paper's array of the first storey and a default TMD) and the start state."""
    n = ints[FR_N]
    if not 1 <= n <= MAX_STOREYS:
        return 1
    load, at, to = ints[FR_LOAD], ints[FR_TMD], ints[FR_TO]
    if not 0 <= load <= n:
        return 2
    if not 0 <= at <= n:
        return 3
    if not -1 <= to <= n:
        return 4
    for kind, vr, strict in _STOREY_FIELDS:
        for i in range(n):
            v = reals[vr + i]
            if not np.isfinite(v) or (strict and not v > 0.0) or (not strict and not v >= 0.0):
                q = F_VALUES + MAX_STOREYS * kind + i
                p[q] = v
                return FIELD_CODE + q
    for i in range(N_PARAMS):
        if FR_SRC[i] >= 0 and not np.isfinite(reals[FR_SRC[i]]):
            p[i] = reals[FR_SRC[i]]
            return FIELD_CODE + i
    for i in range(p.shape[0]):
        p[i] = 0.0
    for i in range(N_PARAMS):
        p[i] = FR_CONST[i] if FR_SRC[i] < 0 else reals[FR_SRC[i]]
    at = at if at > 0 else n
    p[F_N] = n
    p[F_LOAD] = load if load > 0 else n
    p[F_TMD] = at
    p[F_TO] = at if to < 0 else to
    for i in range(n):
        p[F_VALUES + i] = reals[VR_MASS + i]
        p[F_VALUES + n + i] = reals[VR_STIFFNESS + i]
        p[F_VALUES + 2 * n + i] = reals[VR_DAMPING + i]
    for i in range(z.shape[0]):
        z[i] = 0.0
    for i in range(1, n + 1):
        ix = storey_index(i, n)
        z[ix] = reals[VR_X0 + i - 1]
        z[ix + 1] = reals[VR_XD0 + i - 1]
    return NATIVE_OK


@functools.cache
def frame_functions() -> dict[str, Any]:
    """The ShearFrame's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    sens_ = njit(parameter_sensitivity)

    @njit
    def configure_(reals: Any, ints: Any, p: Any, z: Any, u: Any) -> int:
        return frame_configure(reals, ints, p, z)

    @njit
    def outputs_(reals: Any, z: Any, p: Any, u: Any, t: float, out: Any) -> None:
        frame_outputs(z, t, reals[FR_FLINK], reals[FR_FINER], p, out)

    @cfunc(CONFIGURE_SIG)
    def configure(reals_p: Any, ints_p: Any, p_p: Any, z_p: Any, u_p: Any) -> int:
        reals, ints = carray(reals_p, (F_NVR,)), carray(ints_p, (F_NVR,))
        return configure_(reals, ints, carray(p_p, (NP_FRAME,)), carray(z_p, (NS_MAX,)), carray(u_p, (FRAME_U_SIZE,)))

    @cfunc(OUTPUTS_SIG)
    def outputs(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float) -> int:
        reals, ints = carray(reals_p, (F_NVR,)), carray(ints_p, (F_NVR,))
        out = np.empty(FR_NOUT)
        outputs_(reals, carray(z_p, (NS_MAX,)), carray(p_p, (NP_FRAME,)), carray(u_p, (FRAME_U_SIZE,)), t, out)
        write_outputs(out, FRAME_OUT_VR, FRAME_OUT_INT, reals, ints)
        return NATIVE_OK

    @cfunc(DERIVATIVE_SIG)
    def derivative(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, d_p: Any, dy_p: Any) -> int:
        reals, z, p = carray(reals_p, (F_NVR,)), carray(z_p, (NS_MAX,)), carray(p_p, (NP_FRAME,))
        direction, dy = carray(d_p, (2,)), carray(dy_p, (FR_NOUT,))
        out = np.empty(FR_NOUT, dtype=np.complex128)
        f = reals[FR_FLINK] + 1j * CSTEP * direction[0]
        P = reals[FR_FINER] + 1j * CSTEP * direction[1]
        frame_outputs(z, t, f, P, p, out)
        for j in range(FR_NOUT):
            dy[j] = 0.0 + out[j].imag / CSTEP
        return NATIVE_OK

    @cfunc(SENSITIVITY_SIG)
    def sensitivity(reals_p: Any, ints_p: Any, z_p: Any, p_p: Any, u_p: Any, t: float, vr: int, res_p: Any) -> int:
        reals, ints = carray(reals_p, (F_NVR,)), carray(ints_p, (F_NVR,))
        z, p, u = carray(z_p, (NS_MAX,)), carray(p_p, (NP_FRAME,)), carray(u_p, (FRAME_U_SIZE,))
        return sens_(configure_, outputs_, reals, ints, z, p, u, t, vr, carray(res_p, (FR_NOUT,)))

    return {"configure": configure, "outputs": outputs, "derivative": derivative, "sensitivity": sensitivity}


def frame_table() -> dict[str, Any]:
    """The ShearFrame's table for ``pyfmu_native_model.h``: the state of the largest frame (the top
    storey first, the TMD's four slots at rest, the other storeys down), its cross-field checks and messages."""
    storeys = [f"{x}{i}" for i in range(MAX_STOREYS, 0, -1) for x in ("x", "xd")]
    states = storeys[:2] + ["y", "yd", "d", "dd"] + storeys[2:]
    return dict(
        nstate=NS_MAX, np=NP_FRAME, nu=FRAME_U_SIZE, states=states, checks=FRAME_CHECKS,
        fields=frame_field_messages(), check_vars=("storeys", "force_storey", "tmd_storey", "inerter_to"),
    )  # fmt: skip
