"""What every native-speed doStep shares: its C signature, and its helpers (a failed step recorded, outputs written).

Each FMU's step is a C-callable function (numba ``cfunc``) in its model's folder, whose factory its declaration holds
(:class:`~.fmumodel.NativeFmu`; the paper's pair: :mod:`pyfmu_wrapper.models.base_tmd.fmus.native`, the frame:
:mod:`pyfmu_wrapper.models.frame_model.fmus.native`).

The C stub calls it directly for an ordinary step (h <= :data:`~.contract.NATIVE_MAX_STEP`), so a step enters
neither the interpreter nor the Python slave: it reads the inputs and their derivatives from the
stub's value buffers, advances the subsystem over [t, t + h] with the same compiled step the Python
path calls (the paper's pair: :mod:`pyfmu_wrapper.models.base_tmd.fmus.integrators`: the TMD's RODAS4 integrator built by
:func:`~pyfmu_wrapper.solvers.rodas.make_integrator`, the base's exact step), writes the outputs at t + h
with the same compiled outputs function (its ``outputs`` function), so the numbers are bit-identical, and clears
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
(:meth:`~pyfmu_wrapper.models.base_tmd.fmus.slaves.TMDInerterSlave.advance`), so a native FMU takes steps of any length.

An exception inside the compiled code (e.g. a ZeroDivisionError) cannot leave a ``cfunc``: numba
prints it to stderr and the function returns 0, the null value of its return type. That is why
success is :data:`NATIVE_OK` and never 0: the stub reads 0 as "the compiled step raised", puts the
state back from ``backup`` (z and the integrator counters as they were at the start of the step,
saved there before integrating; :meth:`~.slave.Slave.native_restore`) and retakes the step in
Python, which raises the same exception with its traceback: fmi2Error, with the message sent to
the FMI logger. ``debug_raise`` = 2 raises inside the compiled step (a test of that path).
"""

from __future__ import annotations

import numpy as np
from numba import types
from numpy.typing import NDArray

from .._jit import njit

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
