"""What every native FMU's model functions share: their C signatures, and the compiled checks they are built from.

A native FMU (:mod:`pyfmu_wrapper.fmubuild.native_build`) runs with no Python: its stub calls compiled
functions where the Python-hosted FMU calls its slave. Each model's functions are numba cfuncs in its
folder, whose factories its declaration holds (:class:`~.fmumodel.NativeFmu`; the paper's pair:
:mod:`pyfmu_wrapper.models.base_tmd.fmus.native_model`, the frame:
:mod:`pyfmu_wrapper.models.frame_model.fmus.native`). Each computes what the slave computes, with the
same compiled code, so the numbers are bit-identical (tests/test_native_fmu.py):

- ``configure(reals, ints, p, z, u) -> int32``: the slave's ``configure``: the packed parameters (a table
  generated from the registry, :func:`pack_table`, read by :func:`pack_slots`), their field checks
  (:func:`check_fields`: code FIELD_CODE + slot), the model's cross-field checks (codes 1, 2, ...), the
  initial state. Returns :data:`~.contract.NATIVE_OK` or the code of the first check that fails;
- ``outputs(reals, ints, z, p, u, t) -> int32``: the outputs at the current inputs (the slave's
  ``update_outputs``), written into the value buffers;
- ``derivative(reals, ints, z, p, u, t, direction, dy) -> int32``: d outputs along ``direction`` in
  the inputs, by the complex step of the slave's ``directional_derivative``;
- ``sensitivity(reals, ints, z, p, u, t, vr, res) -> int32``: d outputs / d parameter vr (:func:`parameter_sensitivity`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import types

from ..physics import registry
from ..physics.params import N_PARAMS, BaseParams, TMDParams, pack
from .contract import NATIVE_OK
from .varspec import FmuSpec

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
NP = N_PARAMS


def pack_slots(src: Any, vr: Any, const: Any, reals: Any, ints: Any, p: Any) -> None:
    """p from the FMU's values by :func:`pack_table`'s table (to be compiled by the caller: ``njit(pack_slots)``)."""
    for i in range(NP):
        if src[i] == 1:
            p[i] = reals[vr[i]]
        elif src[i] == 2:
            p[i] = float(ints[vr[i]])
        else:
            p[i] = const[i]


def check_fields(on: Any, lo: Any, strict: Any, p: Any) -> int:
    """NATIVE_OK, or FIELD_CODE + the first slot of :func:`field_checks`' table whose value is refused."""
    for i in range(NP):
        if on[i]:
            v = p[i]
            if not np.isfinite(v):
                return FIELD_CODE + i
            if not np.isnan(lo[i]) and ((strict[i] and not v > lo[i]) or (not strict[i] and not v >= lo[i])):
                return FIELD_CODE + i
    return NATIVE_OK


def parameter_sensitivity(
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


#: Model Exchange (a native FMU whose table declares states, :meth:`~.varspec.FmuSpec.derivatives`): its
#: functions ``me_derivatives``, ``me_indicators``, ``me_nominals`` and ``me_jacobian``, each
#: ``f(reals, ints, z, p, u, t, out) -> int32`` (NATIVE_OK): the states' derivatives, the event indicators, the
#: states' nominal values, and [d derivatives / d z; d outputs / d z] (row-major, (nx + outputs) x nx)
ME_SIG = types.int32(F64P, I32P, F64P, F64P, F64P, types.float64, F64P)
#: the names of those functions in a model's functions dict (:data:`~pyfmu_wrapper.fmubuild.native_obj.ENTRIES`)
ME_FUNCTIONS = ("me_derivatives", "me_indicators", "me_nominals", "me_jacobian")
#: what an event indicator that is exactly 0 is reported as (:func:`away_from_zero`)
INDICATOR_ZERO = 2.2250738585072014e-308


def away_from_zero(g: Any) -> None:
    """The event indicators as reported (to be compiled by the caller, like :func:`pack_slots`): an indicator
    exactly 0 (a friction stuck to the last bit, xd == yd in floating point) becomes the smallest positive normal
    double. FMI hosts locate an event where an indicator changes sign, and CVODE stops with "Root found at and
    very near t" when one stays exactly 0 after an event; the event is still found where the sign first changed."""
    for k in range(g.shape[0]):
        if g[k] == 0.0:
            g[k] = INDICATOR_ZERO
