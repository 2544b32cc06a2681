"""The model functions a native FMU needs besides its step (:mod:`.native`), as numba cfuncs.

A native FMU (:mod:`.native_build`) runs with no Python: its stub calls these compiled functions
where the Python-hosted FMU calls its slave (:mod:`.slaves`). Each computes what the slave computes,
with the same compiled code, so the numbers are bit-identical (tests/test_native_fmu.py):

- ``configure(reals, ints, p, z, u) -> int32``: the slave's ``configure``: the packed parameters
  (:func:`~pyfmu_wrapper.physics.params.pack`, as a table generated from the registry: the slot of
  each registry parameter is read from its FMU variable, the other subsystem's slots hold the
  defaults ``pack`` puts there), the initial state and, for the TMD, the mounting compliance.
  Returns :data:`~.contract.NATIVE_OK`, or the number of the first cross-field check of
  :class:`~pyfmu_wrapper.physics.params.TMDParams` that fails (:data:`~pyfmu_wrapper.physics.params.TMD_CHECKS`, by the same compiled
  :func:`~pyfmu_wrapper.physics.params.tmd_check`; the single-field
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

from .._jit import njit
from ..physics import kernels as kn
from ..physics import registry
from ..physics.frame_model.equations import F_LOAD, F_N, F_TMD, F_TO, F_VALUES, storey_index
from ..physics.frame_model.params import MAX_STOREYS
from ..physics.jacobians import CSTEP
from ..physics.params import N_PARAMS, BaseParams, TMDParams, pack, tmd_check
from .contract import NATIVE_OK
from .frame_step import FRAME_OUT_INT, FRAME_OUT_VR, FRAME_U_SIZE, NP_FRAME, NS_MAX, frame_outputs
from .frame_variables import SHEAR_FRAME, VR_DAMPING, VR_MASS, VR_STIFFNESS, VR_X0, VR_XD0
from .integrators import BASE_U_SIZE
from .native import B_NVR, F_NVR, T_NVR, write_outputs
from .outputs import BASE_OUT_INT, BASE_OUT_VR, TMD_OUT_INT, TMD_OUT_VR, base_outputs, tmd_outputs
from .variables import BASE_OSCILLATOR, TMD_INERTER
from .varspec import FmuSpec

#: the ShearFrame's scalar variables configure reads: storeys, F, w, and the storeys of the force, the TMD
#: and the inerter's terminal
_FRAME_SCALARS = ("storeys", "F", "w", "force_storey", "tmd_storey", "inerter_to")
F64P, I32P = types.CPointer(types.float64), types.CPointer(types.int32)
CONFIGURE_SIG = types.int32(F64P, I32P, F64P, F64P, F64P)
OUTPUTS_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64)
DERIVATIVE_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64, F64P, F64P)
SENSITIVITY_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64, types.int32, F64P)


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


def field_checks(subsystem: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per slot of the packed parameters: checked (the subsystem's real registry fields, as
    ``physics.params._validate_fields`` checks them: finite, and the minimum), the minimum (NaN:
    none) and whether it is strict."""
    on = np.zeros(N_PARAMS, dtype=np.bool_)
    lo = np.full(N_PARAMS, np.nan)
    strict = np.zeros(N_PARAMS, dtype=np.bool_)
    for par in registry.fields(subsystem):
        if par.kind != "real":
            continue
        i = list(registry.PARAMETERS).index(par)
        on[i] = True
        lo[i] = np.nan if par.minimum is None else par.minimum
        strict[i] = par.strict
    return on, lo, strict


def field_messages(subsystem: str) -> list[str]:
    """The message of configure's code FIELD_CODE + slot (the wording of ``physics.params._check``)."""
    out = []
    for par in registry.PARAMETERS:
        name = f"{par.name} ({par.symbol})"
        if par.minimum is None:
            out.append(f"{name} must be finite")
        else:
            out.append(f"{name} must be finite and {'>' if par.strict else '>='} {par.minimum:g}")
    return out


#: configure's code of a field check that fails: FIELD_CODE + the slot; KAPPA_CODE: base_compliance
FIELD_CODE, KAPPA_CODE = 100, 99
B_ON, B_LO, B_STRICT = field_checks("base")
T_ON, T_LO, T_STRICT = field_checks("tmd")


def _pack(src: Any, vr: Any, const: Any, reals: Any, ints: Any, p: Any) -> None:
    for i in range(NP):
        if src[i] == 1:
            p[i] = reals[vr[i]]
        elif src[i] == 2:
            p[i] = float(ints[vr[i]])
        else:
            p[i] = const[i]


def _fields(on: Any, lo: Any, strict: Any, p: Any) -> int:
    for i in range(NP):
        if on[i]:
            v = p[i]
            if not np.isfinite(v):
                return FIELD_CODE + i
            if not np.isnan(lo[i]) and ((strict[i] and not v > lo[i]) or (not strict[i] and not v >= lo[i])):
                return FIELD_CODE + i
    return NATIVE_OK


def _sensitivity(
    configure: Any, outputs: Any, reals: Any, ints: Any, z: Any, p: Any, u: Any, t: float, vr: int, res: Any
) -> int:
    """The slave's ``_parameter_sensitivity``: d outputs / d parameter vr by a central difference
    through configure (one-sided at the edge of the parameter's domain); 1 if neither side works."""
    n = res.shape[0]
    r0 = reals[vr]
    d = 1e-6 * max(abs(r0), 1e-6)
    rows = np.zeros((3, n))
    ok = np.zeros(3, dtype=np.bool_)
    vals = (r0 + d, r0 - d, r0)
    for k in range(3):
        reals[vr] = vals[k]
        if configure(reals, ints, p, z, u) == NATIVE_OK:
            outputs(reals, z, p, u, t, rows[k])
            ok[k] = True
    reals[vr] = r0
    configure(reals, ints, p, z, u)
    if ok[0] and ok[1]:
        for j in range(n):
            res[j] = (rows[0, j] - rows[1, j]) / (2 * d)
        return NATIVE_OK
    if ok[2] and (ok[0] or ok[1]):
        k = 0 if ok[0] else 1
        v = vals[k]
        for j in range(n):
            res[j] = (rows[k, j] - rows[2, j]) / (v - r0)
        return NATIVE_OK
    return 1


@functools.cache
def base_functions() -> dict[str, Any]:
    """The BaseOscillator's configure, outputs, derivative and sensitivity cfuncs (compiled on first use)."""

    pack_, fields_, sens_ = njit(_pack), njit(_fields), njit(_sensitivity)

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

    pack_, fields_, sens_ = njit(_pack), njit(_fields), njit(_sensitivity)

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


#: the cross-field checks of the ShearFrame's configure, in the order it numbers them (1, 2, ...):
#: the words of :class:`~pyfmu_wrapper.physics.frame_model.FrameParams`' errors
FRAME_CHECKS = (
    f"storeys must be 1 to {MAX_STOREYS}",
    "force_storey must be an integer storey 0..storeys (0: the top)",
    "tmd_storey must be an integer storey 0..storeys (0: the top)",
    "inerter_to must be an integer storey -1..storeys (-1: the TMD's storey, 0: the ground)",
)
#: the variables a failed cross-field check of each model reports (name, value)
CHECK_VARIABLES = {
    "BaseOscillator": (),
    "TMDInerter": ("m", "I", "inerter"),
    "ShearFrame": ("storeys", "force_storey", "tmd_storey", "inerter_to"),
}
FR_N, FR_F, FR_W, FR_LOAD, FR_TMD, FR_TO = (SHEAR_FRAME.vr(n) for n in _FRAME_SCALARS)
FR_FLINK, FR_FINER = SHEAR_FRAME.vr("f_link"), SHEAR_FRAME.vr("f_inerter")
FR_NOUT = FRAME_OUT_VR.size


def frame_pack_table() -> tuple[np.ndarray, np.ndarray]:
    """The packed parameters of the paper's part that do not come from a frame's variables (the
    constants :func:`~pyfmu_wrapper.physics.frame_model.frame_pack` puts there: a default TMD) and,
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
    """The ShearFrame slave's ``configure``: the checks of :class:`~pyfmu_wrapper.physics.frame_model.FrameParams`
    (NATIVE_OK, a number of :data:`FRAME_CHECKS`, or FIELD_CODE + q of :func:`frame_field_messages`, the
    value then in p[q]), the packed array of :func:`~pyfmu_wrapper.physics.frame_model.frame_pack` (its
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

    sens_ = njit(_sensitivity)

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


#: model -> the factory of its functions
FUNCTIONS = {"BaseOscillator": base_functions, "TMDInerter": tmd_functions, "ShearFrame": frame_functions}
