"""The native (compiled) doSteps of the paper's two FMUs, BaseOscillator and TMDInerter (numba ``cfunc``).

The contract every native step keeps (signature, return codes, the backup of a failed step) is
:mod:`pyfmu_wrapper.fmi.native`'s. The base is stepped exactly (:func:`.integrators.advance_base`), the TMD by
its RODAS4 integrator (:func:`.integrators.integrate_tmd`), long steps in pieces exactly as the Python slave
takes them (:meth:`.slaves.TMDInerterSlave.advance`); the outputs are :mod:`.outputs`', so both step paths
are bit-identical.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import carray, cfunc

from ....fmi.contract import FAIL_BUDGET, FAIL_NOT_FINITE, MAX_INTEGRATOR_STEPS, NATIVE_MAX_STEP, NATIVE_OK, backup_size
from ....fmi.native import DEBUG_RAISE_NATIVE, SIGNATURE, record_failure, write_outputs
from ....physics import kernels as kn
from ....physics.params import N_PARAMS, P_s
from ....solvers.rodas import STAT_STEPS
from .integrators import BASE_U_SIZE, advance_base, fill_atol, integrate_tmd
from .outputs import BASE_OUT_INT, BASE_OUT_VR, TMD_OUT_INT, TMD_OUT_VR, base_outputs, tmd_outputs
from .variables import BASE_OSCILLATOR, TMD_INERTER

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
