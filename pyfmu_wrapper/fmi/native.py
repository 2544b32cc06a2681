"""Native-speed doStep: the step of a slave as a C-callable function (numba ``cfunc``).

The C stub calls it directly for an ordinary step (h <= :data:`~.contract.NATIVE_MAX_STEP`), so a step enters
neither the interpreter nor the Python slave: it reads the inputs and their derivatives from the
stub's value buffers, advances the subsystem over [t, t + h] with the same compiled step the Python
path calls (:mod:`.integrators`: the TMD's RODAS4 integrator built by
:func:`~pyfmu_wrapper.solvers.rodas.make_integrator`, the base's exact step), writes the outputs at t + h
with the same compiled outputs function (:mod:`.outputs`), so the numbers are bit-identical, and clears
the input derivatives. Python is entered only to instantiate, to set up, for long steps, and on errors.

C signature (all pointers to the slave's own arrays, which keep their address for its life)::

    int32 step(double *reals, int32 *ints, double *derivs, double *z, double *p, int64 *stats,
               double *th /* [t, suggested h] */, double *u, double *atol, double *backup,
               double t, double h)

Returns :data:`NATIVE_OK` on success, 1 to ask the stub for the Python path: ``debug_raise`` is
set (the Python slave raises with a traceback), or the step failed (a state not finite, a step
size underflow, more than :data:`~.contract.MAX_INTEGRATOR_STEPS` steps in one call or in one
doStep): the state is put back to the start of the step and the tail of ``backup`` says why
(:data:`~.contract.FAIL_NOT_FINITE` ... :data:`~.contract.FAIL_BUDGET`), the time reached and the state there, which a
native FMU's stub turns into its message; the Python-hosted FMU retakes the step in Python, which
fails the same way and names it (:func:`~pyfmu_wrapper.solvers.rodas.failure_message`).

A step longer than :data:`~.slave.CHUNK` is taken in pieces exactly as the Python slave takes it
(:meth:`~.slaves.TMDInerterSlave.advance`), so a native FMU takes steps of any length.

An exception inside the compiled code (e.g. a ZeroDivisionError) cannot leave a ``cfunc``: numba
prints it to stderr and the function returns 0, the null value of its return type. That is why
success is :data:`NATIVE_OK` and never 0: the stub reads 0 as "the compiled step raised", puts the
state back from ``backup`` (z and the integrator counters as they were at the start of the step,
saved there before integrating; :meth:`~.slave.Slave.native_restore`) and retakes the step in
Python, which raises the same exception with its traceback: fmi2Error, with the message sent to
the FMI logger. ``debug_raise`` = 2 raises inside the compiled step (a test of that path).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import carray, cfunc, types
from numpy.typing import NDArray

from .._jit import njit
from ..physics import kernels as kn
from ..physics.params import N_PARAMS, P_s
from ..solvers.rodas import STAT_STEPS
from .contract import FAIL_BUDGET, FAIL_NOT_FINITE, MAX_INTEGRATOR_STEPS, NATIVE_MAX_STEP, NATIVE_OK, backup_size
from .frame_step import FRAME_OUT_INT, FRAME_OUT_VR, FRAME_U_SIZE, NP_FRAME, NS_MAX, advance_frame, frame_outputs
from .frame_variables import SHEAR_FRAME
from .integrators import BASE_U_SIZE, advance_base, fill_atol, integrate_tmd
from .outputs import BASE_OUT_INT, BASE_OUT_VR, TMD_OUT_INT, TMD_OUT_VR, base_outputs, tmd_outputs
from .variables import BASE_OSCILLATOR, TMD_INERTER

SIGNATURE = types.int32(
    types.CPointer(types.float64),
    types.CPointer(types.int32),
    types.CPointer(types.float64),
    types.CPointer(types.float64),
    types.CPointer(types.float64),
    types.CPointer(types.int64),
    types.CPointer(types.float64),
    types.CPointer(types.float64),
    types.CPointer(types.float64),
    types.CPointer(types.float64),
    types.float64,
    types.float64,
)
#: debug_raise value that makes the compiled step itself raise
DEBUG_RAISE_NATIVE = 2

NP = N_PARAMS
# value references (frozen into the compiled code)
B_NVR = max(v.vr for v in BASE_OSCILLATOR.variables) + 1
B_FLINK = BASE_OSCILLATOR.vr("f_link")
B_DEBUG = BASE_OSCILLATOR.vr("debug_raise")
B_NOUT, T_NOUT = BASE_OUT_VR.size, TMD_OUT_VR.size
T_NVR = max(v.vr for v in TMD_INERTER.variables) + 1
T_X, T_XD, T_XDD = (TMD_INERTER.vr(n) for n in ("x", "xd", "xdd"))
T_RTOL, T_ATOL, T_DEBUG = (TMD_INERTER.vr(n) for n in ("rtol", "atol", "debug_raise"))
SYS_BASE, SYS_TMD, U_KAPPA = kn.SYS_BASE, kn.SYS_TMD, kn.U_KAPPA
MAX_STEPS = MAX_INTEGRATOR_STEPS
CHUNK = NATIVE_MAX_STEP
B_BACKUP, T_BACKUP = backup_size(2), backup_size(4)
F_NVR = max(v.vr for v in SHEAR_FRAME.variables) + 1
F_FLINK, F_FINER = SHEAR_FRAME.vr("f_link"), SHEAR_FRAME.vr("f_inerter")
F_NOUT, F_BACKUP = FRAME_OUT_VR.size, backup_size(NS_MAX)


@njit(cache=True)
def record_failure(backup: NDArray[np.float64], z: NDArray[np.float64], code: int, tf: float) -> None:
    """The tail of ``backup`` after a failed step: its code, the time reached, the state there; then z
    is put back to the start of the step (the head of ``backup``)."""
    n = z.shape[0]
    backup[n + 4] = code
    backup[n + 5] = tf
    for i in range(n):
        backup[n + 6 + i] = z[i]
        z[i] = backup[i]


@njit(cache=True)
def write_outputs(
    out: NDArray[np.float64],
    vr: NDArray[np.int64],
    is_int: NDArray[np.bool_],
    reals: NDArray[np.float64],
    ints: NDArray[np.int32],
) -> None:
    """The outputs computed by :mod:`.outputs` into the stub's value buffers (Integer and Boolean
    outputs into the int32 buffer)."""
    for j in range(out.shape[0]):
        if is_int[j]:
            ints[vr[j]] = np.int32(out[j])
        else:
            reals[vr[j]] = out[j]


@functools.cache
def base_step() -> Any:
    """The BaseOscillator step (compiled on first use, cached on disk): exact (:func:`.integrators.advance_base`)."""

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
        reals = carray(reals_p, (B_NVR,))
        ints = carray(ints_p, (B_NVR,))
        derivs = carray(derivs_p, (2 * B_NVR,))
        z = carray(z_p, (2,))
        p = carray(p_p, (NP,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (BASE_U_SIZE,))  # the input polynomial, then the exact step's cache
        backup = carray(backup_p, (B_BACKUP,))
        backup[2 + 4] = 0.0
        for i in range(2):
            backup[i] = z[i]
        for i in range(4):
            backup[2 + i] = stats[i]
        if ints[B_DEBUG] == DEBUG_RAISE_NATIVE:
            raise ZeroDivisionError("debug_raise = 2: exception injected in the compiled step")
        if ints[B_DEBUG] != 0:
            return 1
        u[0] = t
        u[1] = reals[B_FLINK]
        u[2] = derivs[2 * B_FLINK]
        u[3] = derivs[2 * B_FLINK + 1]
        if advance_base(z, t, h, p, u, stats) != 0:  # not finite: z is at the start of the step
            backup[2 + 4] = FAIL_NOT_FINITE
            backup[2 + 5] = t + h
            return 1
        th[1] = h
        t1 = t + h
        th[0] = t1
        out = np.empty(B_NOUT)
        base_outputs(z, t1, kn.input_value(u, 0, t1), p, out)
        write_outputs(out, BASE_OUT_VR, BASE_OUT_INT, reals, ints)
        derivs[2 * B_FLINK] = 0.0
        derivs[2 * B_FLINK + 1] = 0.0
        return NATIVE_OK

    return step


@functools.cache
def tmd_step() -> Any:
    """The TMDInerter step (compiled on first use, cached on disk)."""

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
        reals = carray(reals_p, (T_NVR,))
        ints = carray(ints_p, (T_NVR,))
        derivs = carray(derivs_p, (2 * T_NVR,))
        z = carray(z_p, (4,))
        p = carray(p_p, (NP,))
        stats = carray(stats_p, (4,))
        th = carray(th_p, (2,))
        u = carray(u_p, (U_KAPPA + 1,))  # u[U_KAPPA]: the mounting compliance, set by configure
        atol = carray(atol_p, (4,))
        backup = carray(backup_p, (T_BACKUP,))
        backup[4 + 4] = 0.0
        for i in range(4):
            backup[i] = z[i]
        for i in range(4):
            backup[4 + i] = stats[i]
        if ints[T_DEBUG] == DEBUG_RAISE_NATIVE:
            raise ZeroDivisionError("debug_raise = 2: exception injected in the compiled step")
        if ints[T_DEBUG] != 0:
            return 1
        u[0] = t
        u[1] = reals[T_X]
        u[2] = derivs[2 * T_X]
        u[3] = derivs[2 * T_X + 1]
        u[4] = reals[T_XD]
        u[5] = derivs[2 * T_XD]
        u[6] = derivs[2 * T_XD + 1]
        u[7] = reals[T_XDD]
        u[8] = derivs[2 * T_XDD]
        u[9] = derivs[2 * T_XDD + 1]
        fill_atol(SYS_TMD, reals[T_ATOL], p, atol)
        band = 1.0 / p[P_s] if p[P_s] > 0 else 1e-6
        n = 1 if h <= CHUNK else int(math.ceil(h / CHUNK))  # long steps in pieces, as the Python slave
        start = stats[STAT_STEPS]
        hn = th[1]
        no_t, no_s = np.zeros(0), np.zeros((0, 4))
        for k in range(n):
            a, b = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
            hn, _, status, tf = integrate_tmd(
                z, a, b, p, u, reals[T_RTOL], atol, hn, h if n == 1 else b - a, no_t, no_s, band, stats, MAX_STEPS
            )
            if status != 0:  # back to the start of the step, with why, when and where it stopped
                record_failure(backup, z, 1 + status, tf)
                return 1
            if stats[STAT_STEPS] - start > MAX_STEPS:
                record_failure(backup, z, FAIL_BUDGET, b)
                return 1
        th[1] = hn
        t1 = t + h
        th[0] = t1
        x = kn.input_value(u, 0, t1)
        xd = kn.input_value(u, 1, t1)
        xdd = kn.input_value(u, 2, t1)
        out = np.empty(T_NOUT)
        tmd_outputs(z, x, xd, xdd, u[U_KAPPA], p, out)
        write_outputs(out, TMD_OUT_VR, TMD_OUT_INT, reals, ints)
        for vr in (T_X, T_XD, T_XDD):
            derivs[2 * vr] = 0.0
            derivs[2 * vr + 1] = 0.0
        return NATIVE_OK

    return step


@functools.cache
def frame_step() -> Any:
    """The ShearFrame step (compiled on first use, cached on disk): exact (:func:`.frame_step.advance_frame`)."""

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
