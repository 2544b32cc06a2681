"""The machinery of the Python co-simulation slaves run by the C stub (``fmu/src/``): buffers, start values,
time keeping, FMU state, directional derivatives, the guard that turns exceptions into statuses. The
slaves of the FMUs (:mod:`.slaves`) add their configuration, outputs and step.

Contract with the stub
----------------------
The stub owns the value buffers and shares them with the slave as writable memoryviews: one
float64 buffer and one int32 buffer indexed by value reference (fmi2Boolean is stored as int32),
a float64 ``(nvr, 2)`` buffer of input derivatives (orders 1 and 2, set by
fmi2SetRealInputDerivatives) and a float64 scratch buffer for directional derivatives. fmi2Get/
SetReal never enter Python; the stub calls :meth:`Slave.update_outputs` only when an input or
parameter changed since the outputs were last computed.

Ordinary steps do not come here: :meth:`Slave.native` hands the stub a compiled step
(:mod:`.native`) and the addresses of the arrays it updates in place (``z``, ``p``, ``stats``,
``[t, h]``, the input polynomials, ``atol``); those arrays keep their address for the life of the
slave (they are only ever written in place). :meth:`Slave.do_step` runs for long steps (> CHUNK),
when ``debug_raise`` is set, and when the stub runs without native steps (``PYFMU_NATIVE=0``).

Every method called by the stub returns an int status (0 ok, 1 warning, 3 error, 4 fatal) and
never raises: an exception is caught by :func:`guarded`, its full traceback is kept in
``last_error`` and the stub forwards it to the FMI logger.

"""

from __future__ import annotations

import functools
import traceback
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..physics import kernels as kn
from ..physics import registry
from ..physics.jacobians import CSTEP
from ..physics.params import N_PARAMS
from .contract import NATIVE_MAX_STEP, backup_size
from .varspec import BOOLEAN, INTEGER, FmuSpec

OK, WARNING, ERROR, FATAL = 0, 1, 3, 4
#: A doStep is integrated in pieces of at most this length [s] (the native step's longest step) and
#: fails when it needs more integrator steps than MAX_INTEGRATOR_STEPS; the step itself (finite,
#: 0 < h <= MAX_STEP, on the FMU's time within TIME_SLACK h) is checked by the C stub before Python
#: is entered: fmi/contract.py.
CHUNK = NATIVE_MAX_STEP
FloatArray = NDArray[np.float64]
#: what the stub hands over: its value buffers as writable memoryviews, a state as bytes
Buffer = memoryview | bytes


class FmuStepError(RuntimeError):
    """The integrator failed inside doStep, or doStep was called inconsistently."""


class InjectedError(RuntimeError):
    """Raised on purpose when the debug_raise parameter is set (tests of error reporting)."""


def guarded(method: Callable[..., int | None]) -> Callable[..., int]:
    @functools.wraps(method)
    def wrapper(self: Slave, *args: Any) -> int:
        try:
            r = method(self, *args)
            return OK if r is None else r
        except Exception:  # noqa: BLE001 - every exception becomes fmi2Error with its traceback
            self.last_error = traceback.format_exc()
            return ERROR

    return wrapper


class Slave:
    """Common machinery: buffers, start values, time keeping, state (de)serialisation."""

    spec: FmuSpec  #: set by each FMU's subclass
    n_state = 0

    def __init__(
        self, reals: Buffer, ints: Buffer, derivs: Buffer, scratch: Buffer, instance_name: str = "", resources: str = ""
    ) -> None:
        self.r = np.frombuffer(reals, dtype=np.float64)
        self.i = np.frombuffer(ints, dtype=np.int32)
        self.du = np.frombuffer(derivs, dtype=np.float64).reshape(-1, 2)
        self.scratch = np.frombuffer(scratch, dtype=np.float64)
        self.instance_name = instance_name
        self.resources = resources
        self.last_error = ""
        # [time, step size suggested by the integrator] (part of the state: exact restore); an
        # array, like p, z, stats, u and atol, so that the native step (.native) updates them in place
        self._th = np.zeros(2)
        self._atol = np.zeros(max(self.n_state, 1))
        self.p = np.zeros(N_PARAMS)
        self.z = np.zeros(self.n_state)
        self.stats = np.zeros(4, dtype=np.int64)
        self._empty_t = np.zeros(0)
        self._empty_s = np.zeros((0, max(self.n_state, 1)))
        self._inputs = [v for v in self.spec.of("input")]
        self._input_vr = np.array([v.vr for v in self._inputs], dtype=np.int64)
        self._u = np.zeros(1 + 3 * len(self._inputs))
        self._outputs = [v for v in self.spec.of("output")]
        self._debug_vr = next((v.vr for v in self.spec.variables if v.name == "debug_raise"), None)
        self._real_params = {
            v.vr for v in self.spec.variables if v.causality == "parameter" and v.type not in (INTEGER, BOOLEAN)
        }
        self._start_values()

    t = property(lambda self: float(self._th[0]), lambda self, v: self._th.__setitem__(0, v))
    h = property(lambda self: float(self._th[1]), lambda self, v: self._th.__setitem__(1, v))

    def native(self) -> bytes:
        """Addresses for the stub's native step (:mod:`.native`): the C function and the arrays it
        updates in place, as 8 native-endian uint64; empty bytes when this slave has none."""
        step = self._native_step()
        if step is None:
            return b""
        self._native_ref = step  # keep the compiled function alive with the slave
        # z and the integrator counters at the start of the native step (put back if it raised)
        self._native_backup = np.zeros(backup_size(self.n_state))
        arrays = (self.z, self.p, self.stats, self._th, self._u, self._atol, self._native_backup)
        return np.array([step.address] + [a.ctypes.data for a in arrays], dtype=np.uint64).tobytes()

    @guarded
    def native_restore(self) -> None:
        """The compiled step raised (numba printed the exception and returned 0): put z and the
        counters back to where the step started, so the Python path retakes the same step."""
        b = self._native_backup
        self.z[:] = b[: self.n_state]
        self.stats[:] = b[self.n_state : self.n_state + self.stats.size].astype(np.int64)

    def _native_step(self) -> Any:
        return None

    # --- helpers --------------------------------------------------------------------------
    def _start_values(self) -> None:
        for v in self.spec.variables:
            if v.start is None:
                continue
            if v.type in (INTEGER, BOOLEAN):
                self.i[v.vr] = int(v.start)
            else:
                self.r[v.vr] = float(v.start)
        self.du[:] = 0.0

    def _registry_values(self, subsystem: str) -> dict[str, Any]:
        """Field name -> value of the subsystem's registry parameters, read from the FMU buffers."""
        return {p.name: self.val(p.fmu_name) for p in registry.fields(subsystem)}

    def val(self, name: str) -> float:
        v = self.spec.by_name(name)
        return int(self.i[v.vr]) if v.type in (INTEGER, BOOLEAN) else float(self.r[v.vr])

    def _taylor_inputs(self, t: float) -> FloatArray:
        """Input polynomials about t: u = [t, value, d/dt, d2/dt2, ...] (kernels' layout)."""
        u = self._u
        u[0] = t
        for k, vr in enumerate(self._input_vr):
            u[1 + 3 * k] = self.r[vr]
            u[2 + 3 * k] = self.du[vr, 0]
            u[3 + 3 * k] = self.du[vr, 1]
        return u

    def _inputs_at(self, t: float) -> FloatArray:
        u = self._u
        return np.array([kn.input_value(u, k, t) for k in range(len(self._input_vr))])

    def _current_inputs(self) -> FloatArray:
        return np.array([self.r[vr] for vr in self._input_vr])

    # --- model hooks -----------------------------------------------------------------------
    def configure(self) -> None:
        """Read parameters from the buffers, validate and pack them, set the initial state."""

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        """Output values (in the order of spec.of('output')) for the current state and inputs.

        Must accept complex inputs (directional derivatives by complex step)."""
        raise NotImplementedError

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """Integrate the state over [t, t + h] with input polynomials u."""

    # --- stub entry points -----------------------------------------------------------------
    @guarded
    def setup_experiment(
        self, tolerance_defined: int, tolerance: float, t_start: float, stop_defined: int, t_stop: float
    ) -> None:
        if not np.isfinite(t_start):
            raise FmuStepError(f"setupExperiment: startTime must be finite, got {t_start!r}")
        if tolerance_defined and not (np.isfinite(tolerance) and tolerance > 0):
            raise FmuStepError(f"setupExperiment: tolerance must be finite and > 0, got {tolerance!r}")
        self.t = float(t_start)
        if tolerance_defined and tolerance > 0 and "rtol" in {v.name for v in self.spec.variables}:
            self.r[self.spec.vr("rtol")] = tolerance

    @guarded
    def enter_initialization(self) -> None:
        pass

    @guarded
    def update_outputs(self, initializing: int) -> None:
        if initializing:
            self.configure()
        self._write_outputs(self.outputs(self._current_inputs()))

    @guarded
    def exit_initialization(self) -> None:
        self.configure()
        self.h = 0.0
        self._write_outputs(self.outputs(self._current_inputs()))

    @guarded
    def do_step(self, t: float, h: float, no_set_prior: int) -> None:
        # (t, h) were checked by the C stub, the one guard of the doStep contract (fmi/contract.py)
        if self._debug_vr is not None and self.i[self._debug_vr]:
            raise InjectedError(
                f"debug_raise = {self.i[self._debug_vr]} is set: exception injected at t = {t:.16g}"
                + (" (in the compiled step, then again here)" if self.i[self._debug_vr] == 2 else "")
            )
        u = self._taylor_inputs(t)
        self.advance(t, h, u)
        self.t = t + h
        self._write_outputs(self.outputs(self._inputs_at(self.t)))
        self.du[self._input_vr] = 0.0  # input derivatives are valid for one step only

    @guarded
    def reset(self) -> None:
        self._start_values()
        self.t = 0.0
        self.h = 0.0
        self.z[:] = 0.0
        self.stats[:] = 0

    @guarded
    def terminate(self) -> None:
        pass

    def get_state(self) -> bytes | None:
        """Whole internal state as bytes (the stub saves its value buffers itself)."""
        try:
            return np.concatenate(([self.t, self.h], self.p, self.z, self.stats.astype(np.float64))).tobytes()
        except Exception:  # noqa: BLE001
            self.last_error = traceback.format_exc()
            return None

    @guarded
    def set_state(self, data: Buffer) -> None:
        a = np.frombuffer(data, dtype=np.float64)
        n = 2 + self.p.size + self.n_state + 4
        if a.size != n:
            raise ValueError(f"FMU state has {a.size} values, expected {n}")
        self.t, self.h = float(a[0]), float(a[1])
        self.p[:] = a[2 : 2 + self.p.size]
        k = 2 + self.p.size
        self.z[:] = a[k : k + self.n_state]
        self.stats[:] = a[k + self.n_state :].astype(np.int64)

    @guarded
    def directional_derivative(self, n_unknown: int, n_known: int, initializing: int = 0) -> None:
        """Scratch layout: [vUnknown (nu), vKnown (nk), dvKnown (nk)] -> dvUnknown after them.

        Knowns may be any variable (FMI 2.0 allows masters to pass others than inputs; OMSimulator
        does by default). Inputs enter by complex step through :meth:`outputs`; in initialisation
        mode a Real parameter enters by a central difference through :meth:`configure`; any other
        known (a fixed parameter after initialisation, an output, an Integer or Boolean) cannot
        change continuously and contributes zero. An unknown that is not an output has derivative
        1 with respect to itself and 0 otherwise.
        """
        s = self.scratch
        vu = s[:n_unknown].astype(np.int64)
        vk = s[n_unknown : n_unknown + n_known].astype(np.int64)
        seed = s[n_unknown + n_known : n_unknown + 2 * n_known]
        in_index = {int(vr): k for k, vr in enumerate(self._input_vr)}
        out_index = {v.vr: j for j, v in enumerate(self._outputs) if v.type not in (INTEGER, BOOLEAN)}
        direction = np.zeros(len(in_index))
        params: dict[int, float] = {}
        for vr, dv in zip(vk, seed):
            vr = int(vr)
            if vr in in_index:
                direction[in_index[vr]] += dv
            elif initializing and vr in self._real_params:
                params[vr] = params.get(vr, 0.0) + dv
        dy = np.zeros(len(self._outputs))
        if np.any(direction != 0.0):
            y = self.outputs(self._current_inputs() + 1j * CSTEP * direction)
            dy += np.array([np.imag(complex(v)) for v in y]) / CSTEP
        for vr, dv in params.items():
            dy += dv * self._parameter_sensitivity(vr)
        res = s[n_unknown + 2 * n_known : 2 * n_unknown + 2 * n_known]
        for j, vr in enumerate(vu):
            vr = int(vr)
            if vr in out_index:
                res[j] = dy[out_index[vr]]
            else:
                res[j] = float(np.sum(seed[vk == vr]))

    def _parameter_sensitivity(self, vr: int) -> FloatArray:
        """d outputs / d parameter vr in initialisation mode: a central difference through
        configure, one-sided at the edge of the parameter's domain (e.g. a play gap of 0)."""
        r0 = float(self.r[vr])
        d = 1e-6 * max(abs(r0), 1e-6)
        rows, errors = {}, []
        try:
            for v in (r0 + d, r0 - d, r0):
                self.r[vr] = v
                try:
                    self.configure()
                except Exception as e:  # noqa: BLE001 - this side leaves the parameter's domain
                    errors.append(str(e))
                    continue
                rows[v] = np.real(np.array(self.outputs(self._current_inputs()), dtype=complex))
        finally:
            self.r[vr] = r0
            self.configure()
        if r0 + d in rows and r0 - d in rows:
            return (rows[r0 + d] - rows[r0 - d]) / (2 * d)
        if r0 in rows and (r0 + d in rows or r0 - d in rows):
            v = r0 + d if r0 + d in rows else r0 - d
            return (rows[v] - rows[r0]) / (v - r0)
        raise FmuStepError(
            f"directional derivative with respect to parameter {vr} is not available at {r0!r}: " + "; ".join(errors)
        )

    def _write_outputs(self, values: Sequence[Any]) -> None:
        for v, val in zip(self._outputs, values, strict=True):
            if v.type in (INTEGER, BOOLEAN):
                self.i[v.vr] = int(np.real(val))
            else:
                self.r[v.vr] = float(np.real(val))
