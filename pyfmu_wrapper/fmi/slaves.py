"""Python co-simulation slaves run by the C stub (``fmu/src/pyfmu_stub.c``).

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
never raises: an exception is caught by :func:`_guarded`, its full traceback is kept in
``last_error`` and the stub forwards it to the FMI logger.

The physics is not restated here: parameters go through :func:`~pyfmu_wrapper.physics.params.pack`,
a step is one call of the subsystem's integrator (:mod:`.integrators`) on the subsystem kernels
(``SYS_BASE``, ``SYS_TMD``), outputs come from the kernels.
"""

from __future__ import annotations

import functools
import math
import traceback

import numpy as np

from ..physics import kernels as kn
from ..physics import registry
from ..physics.params import N_PARAMS, BaseParams, P_s, ParameterError, TMDParams, pack
from ..solvers.rodas import STAT_STEPS, failure_message
from .contract import MAX_INTEGRATOR_STEPS, NATIVE_MAX_STEP
from .integrators import BASE_MODEL, TMD_MODEL, integrate_base, integrate_tmd
from .variables import BASE_OSCILLATOR, BOOLEAN, INTEGER, TMD_INERTER, TRIVIAL, FmuSpec

OK, WARNING, ERROR, FATAL = 0, 1, 3, 4
_CSTEP = 1e-30
#: A doStep is integrated in pieces of at most this length [s] (the native step's longest step) and
#: fails when it needs more integrator steps than MAX_INTEGRATOR_STEPS; the step itself (finite,
#: 0 < h <= MAX_STEP, on the FMU's time within TIME_SLACK h) is checked by the C stub before Python
#: is entered: fmi/contract.py.
CHUNK = NATIVE_MAX_STEP


class FmuStepError(RuntimeError):
    """The integrator failed inside doStep, or doStep was called inconsistently."""


class InjectedError(RuntimeError):
    """Raised on purpose when the debug_raise parameter is set (tests of error reporting)."""


def _guarded(method):
    @functools.wraps(method)
    def wrapper(self, *args):
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

    def __init__(self, reals, ints, derivs, scratch, instance_name="", resources=""):
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

    def native(self):
        """Addresses for the stub's native step (:mod:`.native`): the C function and the arrays it
        updates in place, as 8 native-endian uint64; empty bytes when this slave has none."""
        step = self._native_step()
        if step is None:
            return b""
        self._native_ref = step  # keep the compiled function alive with the slave
        # z and the integrator counters at the start of the native step (put back if it raised)
        self._native_backup = np.zeros(self.n_state + self.stats.size)
        arrays = (self.z, self.p, self.stats, self._th, self._u, self._atol, self._native_backup)
        return np.array([step.address] + [a.ctypes.data for a in arrays], dtype=np.uint64).tobytes()

    @_guarded
    def native_restore(self):
        """The compiled step raised (numba printed the exception and returned 0): put z and the
        counters back to where the step started, so the Python path retakes the same step."""
        b = self._native_backup
        self.z[:] = b[: self.n_state]
        self.stats[:] = b[self.n_state :].astype(np.int64)

    def _native_step(self):
        return None

    # --- helpers --------------------------------------------------------------------------
    def _start_values(self):
        for v in self.spec.variables:
            if v.start is None:
                continue
            if v.type in (INTEGER, BOOLEAN):
                self.i[v.vr] = int(v.start)
            else:
                self.r[v.vr] = float(v.start)
        self.du[:] = 0.0

    def _registry_values(self, subsystem):
        """Field name -> value of the subsystem's registry parameters, read from the FMU buffers."""
        return {p.name: self.val(p.fmu_name) for p in registry.fields(subsystem)}

    def val(self, name):
        v = self.spec.by_name(name)
        return int(self.i[v.vr]) if v.type in (INTEGER, BOOLEAN) else float(self.r[v.vr])

    def _taylor_inputs(self, t):
        """Input polynomials about t: u = [t, value, d/dt, d2/dt2, ...] (kernels' layout)."""
        u = self._u
        u[0] = t
        for k, vr in enumerate(self._input_vr):
            u[1 + 3 * k] = self.r[vr]
            u[2 + 3 * k] = self.du[vr, 0]
            u[3 + 3 * k] = self.du[vr, 1]
        return u

    def _inputs_at(self, t):
        u = self._u
        return np.array([kn.input_value(u, k, t) for k in range(len(self._input_vr))])

    def _current_inputs(self):
        return np.array([self.r[vr] for vr in self._input_vr])

    # --- model hooks -----------------------------------------------------------------------
    def configure(self):
        """Read parameters from the buffers, validate and pack them, set the initial state."""

    def outputs(self, inputs):
        """Output values (in the order of spec.of('output')) for the current state and inputs.

        Must accept complex inputs (directional derivatives by complex step)."""
        raise NotImplementedError

    def advance(self, t, h, u):
        """Integrate the state over [t, t + h] with input polynomials u."""

    # --- stub entry points -----------------------------------------------------------------
    @_guarded
    def setup_experiment(self, tolerance_defined, tolerance, t_start, stop_defined, t_stop):
        if not np.isfinite(t_start):
            raise FmuStepError(f"setupExperiment: startTime must be finite, got {t_start!r}")
        if tolerance_defined and not (np.isfinite(tolerance) and tolerance > 0):
            raise FmuStepError(f"setupExperiment: tolerance must be finite and > 0, got {tolerance!r}")
        self.t = float(t_start)
        if tolerance_defined and tolerance > 0 and "rtol" in {v.name for v in self.spec.variables}:
            self.r[self.spec.vr("rtol")] = tolerance

    @_guarded
    def enter_initialization(self):
        pass

    @_guarded
    def update_outputs(self, initializing):
        if initializing:
            self.configure()
        self._write_outputs(self.outputs(self._current_inputs()))

    @_guarded
    def exit_initialization(self):
        self.configure()
        self.h = 0.0
        self._write_outputs(self.outputs(self._current_inputs()))

    @_guarded
    def do_step(self, t, h, no_set_prior):
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

    @_guarded
    def reset(self):
        self._start_values()
        self.t = 0.0
        self.h = 0.0
        self.z[:] = 0.0
        self.stats[:] = 0

    @_guarded
    def terminate(self):
        pass

    def get_state(self):
        """Whole internal state as bytes (the stub saves its value buffers itself)."""
        try:
            return np.concatenate(([self.t, self.h], self.p, self.z, self.stats.astype(np.float64))).tobytes()
        except Exception:  # noqa: BLE001
            self.last_error = traceback.format_exc()
            return None

    @_guarded
    def set_state(self, data):
        a = np.frombuffer(data, dtype=np.float64)
        n = 2 + self.p.size + self.n_state + 4
        if a.size != n:
            raise ValueError(f"FMU state has {a.size} values, expected {n}")
        self.t, self.h = float(a[0]), float(a[1])
        self.p[:] = a[2 : 2 + self.p.size]
        k = 2 + self.p.size
        self.z[:] = a[k : k + self.n_state]
        self.stats[:] = a[k + self.n_state :].astype(np.int64)

    @_guarded
    def directional_derivative(self, n_unknown, n_known, initializing=0):
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
        params = {}
        for vr, dv in zip(vk, seed):
            vr = int(vr)
            if vr in in_index:
                direction[in_index[vr]] += dv
            elif initializing and vr in self._real_params:
                params[vr] = params.get(vr, 0.0) + dv
        dy = np.zeros(len(self._outputs))
        if np.any(direction != 0.0):
            y = self.outputs(self._current_inputs() + 1j * _CSTEP * direction)
            dy += np.array([np.imag(complex(v)) for v in y]) / _CSTEP
        for vr, dv in params.items():
            dy += dv * self._parameter_sensitivity(vr)
        res = s[n_unknown + 2 * n_known : 2 * n_unknown + 2 * n_known]
        for j, vr in enumerate(vu):
            vr = int(vr)
            if vr in out_index:
                res[j] = dy[out_index[vr]]
            else:
                res[j] = float(np.sum(seed[vk == vr]))

    def _parameter_sensitivity(self, vr):
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

    def _write_outputs(self, values):
        for v, val in zip(self._outputs, values, strict=True):
            if v.type in (INTEGER, BOOLEAN):
                self.i[v.vr] = int(np.real(val))
            else:
                self.r[v.vr] = float(np.real(val))

    def _integrate(self, system, t, h, u):
        integrate, model = (integrate_base, BASE_MODEL) if system == kn.SYS_BASE else (integrate_tmd, TMD_MODEL)
        tol_vr = getattr(self, "_tol_vr", None)
        if tol_vr is None:  # value references of rtol/atol, resolved once
            tol_vr = self._tol_vr = (self.spec.by_name("rtol").vr, self.spec.by_name("atol").vr)
        from .native import fill_atol  # atol, the gear chain's rate atol x sqrt(ki/I)

        rtol = float(self.r[tol_vr[0]])
        fill_atol(system, float(self.r[tol_vr[1]]), self.p, self._atol)
        band = 1.0 / self.p[P_s] if self.p[P_s] > 0 else 1e-6
        n = 1 if h <= CHUNK else int(np.ceil(h / CHUNK))  # long steps in pieces, within a budget of steps
        start = int(self.stats[STAT_STEPS])
        hn = self.h
        for k in range(n):
            a, b = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
            hn, _, status, tf = integrate(
                self.z,
                a,
                b,
                self.p,
                u,
                rtol,
                self._atol,
                hn,
                h if n == 1 else b - a,
                self._empty_t,
                self._empty_s,
                band,
                self.stats,
                MAX_INTEGRATOR_STEPS,
            )
            if status != 0:
                raise FmuStepError(
                    f"doStep from t = {t:.16g} s: "
                    + failure_message(status, model, tf, self.z, self.p, self._atol, band, MAX_INTEGRATOR_STEPS)
                )
            if self.stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
                raise FmuStepError(
                    f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} "
                    "integrator steps; use shorter communication steps"
                )
        self.h = hn


class BaseOscillatorSlave(Slave):
    """Base oscillator alone: state [x, xd], input f_link (force of the TMD links, in -x)."""

    spec = BASE_OSCILLATOR
    n_state = 2

    def configure(self):
        base = BaseParams(**self._registry_values("base"), source=f"FMU {self.instance_name}")
        self.p[:] = pack(base, TMDParams(), self.val(registry.get("base", "omega").fmu_name))
        self.z[:] = (self.val("x0"), self.val("xd0"))

    def outputs(self, inputs):
        x, xd = self.z[0], self.z[1]
        fexc = kn.excitation(self.t, self.p)
        xdd = kn.base_acceleration(x, xd, inputs[0], 0.0, fexc, self.p)
        return [x, xd, xdd, fexc, kn.base_acceleration(x, xd, 0.0, 0.0, fexc, self.p)]

    def advance(self, t, h, u):
        self._integrate(kn.SYS_BASE, t, h, u)

    def _native_step(self):
        from .native import base_step

        return base_step()


class TMDInerterSlave(Slave):
    """TMD subsystem alone: state [y, yd, d, dd], inputs x, xd, xdd of the base."""

    spec = TMD_INERTER
    n_state = 4

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._u = np.zeros(kn.U_KAPPA + 1)  # the input polynomials, then the mounting compliance

    def configure(self):
        tmd = TMDParams(**self._registry_values("tmd"), source=f"FMU {self.instance_name}")
        kappa = self.val("base_compliance")
        if not (math.isfinite(kappa) and kappa >= 0.0):
            raise ParameterError(
                f"FMU {self.instance_name}: base_compliance = {kappa!r} 1/kg: must be finite "
                "and >= 0 (1/M of the body the TMD is mounted on, 0: off)"
            )
        self.p[:] = pack(BaseParams(), tmd, 0.0)
        self._u[kn.U_KAPPA] = kappa
        self.z[:] = (self.val("y0"), self.val("yd0"), self.val("d0"), self.val("dd0"))

    def outputs(self, inputs):
        x, xd, xdd = inputs[0], inputs[1], inputs[2]
        force, chain, contact = kn.tmd_outputs(self.z, x, xd, xdd, self._u[kn.U_KAPPA], self.p)
        return [force, self.z[0], self.z[1], chain, contact]

    def advance(self, t, h, u):
        self._integrate(kn.SYS_TMD, t, h, u)

    def _native_step(self):
        from .native import tmd_step

        return tmd_step()


class TrivialSlave(Slave):
    """y = gain * u; a step only advances time (measures the stub's own overhead)."""

    spec = TRIVIAL
    n_state = 0

    def outputs(self, inputs):
        return [self.r[0] * inputs[0]]

    @_guarded
    def do_step(self, t, h, no_set_prior):
        self.t = t + h
        self.r[2] = self.r[0] * self.r[1]


def create(slave_path: str, reals, ints, derivs, scratch, instance_name="", resources=""):
    """Instantiate the slave class named "module:Class" (called by the FMU's resources/model.py)."""
    import importlib

    mod, _, cls = slave_path.partition(":")
    return getattr(importlib.import_module(mod), cls)(reals, ints, derivs, scratch, instance_name, resources)
