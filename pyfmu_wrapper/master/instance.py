"""One FMU instance of the master: the fmpy slave, its ports and the lean fmi2 calls of the stepping loop.

The stepping loop calls four fmi2 functions (``fmi2SetReal``, ``fmi2GetReal``,
``fmi2SetRealInputDerivatives``, ``fmi2DoStep``) directly through ctypes with pre-allocated
numpy buffers, without fmpy's per-call wrappers (argument conversion, logging, status checks).
fmpy has no public accessor for the raw C functions; the one place that reaches below its
Python API is :func:`_raw_function`, which reads the symbol from the slave's public ``dll``
(the loaded ``ctypes.CDLL``) and gives it a prototype of its own (the FMI 2.0 signature), so
nothing depends on fmpy's private ``_functions`` table. Every other call (instantiate,
parameters, initialisation, FMU states, directional derivatives, terminate) goes through
fmpy's public :class:`fmpy.fmi2.FMU2Slave` methods.

FMI 3.0 FMUs go through the same choke point: :class:`~.instance3.Instance3` (made by
:func:`~.instance3.open_instance` when the model description says fmiVersion 3.0) maps the same lean calls onto ``fmi3SetFloat64``,
``fmi3GetFloat64`` and ``fmi3DoStep`` and the rest onto :class:`fmpy.fmi3.FMU3Slave`. FMI 3.0 has
no ``fmi3SetInputDerivatives``: an FMU that declares the input variables ``der(u)`` and
``der(u,2)`` for each continuous Float64 input ``u`` (as this project's FMI 3.0 FMUs do) gets the
input derivatives through them; one that does not gets inputs held constant over the step.
"""

from __future__ import annotations

import contextlib
import ctypes
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy.fmi2 import FMU2Slave

if TYPE_CHECKING:
    from ctypes import c_void_p

    from fmpy.fmi2 import fmi2CallbackFunctions
    from fmpy.model_description import ModelDescription
    from numpy import float64

DBL = ctypes.POINTER(ctypes.c_double)
UINT = ctypes.POINTER(ctypes.c_uint)
_INT = ctypes.POINTER(ctypes.c_int)

#: FMI 2.0 prototypes of the raw calls (fmi2Status f(fmi2Component, ...))
_PROTOTYPES = {
    "fmi2SetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, UINT, ctypes.c_size_t, DBL),
    "fmi2GetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, UINT, ctypes.c_size_t, DBL),
    "fmi2SetRealInputDerivatives": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, UINT, ctypes.c_size_t, _INT, DBL),
    "fmi2DoStep": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int),
}


class MasterError(RuntimeError):
    """An FMI call failed or the coupling could not be solved."""


def pointer_to(a: np.ndarray, kind: Any) -> Any:
    return a.ctypes.data_as(kind)


def _raw_function(slave: FMU2Slave, name: str, required: bool = True) -> Any:
    """The C function ``name`` of the FMU's shared library with its FMI 2.0 prototype (None if the
    library does not export it and ``required`` is False). The only access below fmpy's API."""
    try:
        sym = getattr(slave.dll, name)
    except AttributeError:
        if required:
            raise MasterError(f"{slave.instanceName}: the FMU does not export {name}") from None
        return None
    return _PROTOTYPES[name](address_of(sym))


def address_of(f: Any) -> int:
    """The address of a ctypes function (never NULL for a symbol the library exports)."""
    addr = ctypes.cast(f, ctypes.c_void_p).value
    if addr is None:
        raise MasterError(f"NULL address of {f!r}")
    return addr


class Instance:
    """One FMU instance: its slave, value references and pre-allocated exchange buffers.

    ``inputs`` / ``outputs`` are the connected inputs and the outputs the master reads, in order;
    :meth:`finalize_ports` allocates their buffers. The wiring (:mod:`.wiring`) sets the signal
    indices (``sig_in``, ``sig_out``, ``conn_idx``) and the rate-connection fields (``rate_*``).
    """

    #: the modelDescription's type of a double-precision variable (FMI 2.0: Real)
    REAL_TYPE = "Real"

    # set by the wiring (:func:`.wiring.wire`, :func:`.wiring.reset_rate`)
    sig_in: np.ndarray  #: signal index of each connected input
    sig_out: np.ndarray  #: signal index of each output read
    conn_idx: np.ndarray  #: connection index of each connected input
    rate_pos: np.ndarray  #: positions (in ``inputs``) of the rate inputs
    rate_src: np.ndarray  #: their source signals
    rate_gain: np.ndarray  #: their gains
    rate_init: list[int | None]  #: the signal giving each one's initial value (None: none)
    rate_int: np.ndarray  #: the signal of each one's exact integral (-1: none)
    rate_has_int: np.ndarray  #: rate_int >= 0
    rate_prev: np.ndarray  #: mean rate of the previous step
    rate_ready: bool  #: rate_prev holds a step

    def __init__(self, name: str, path: Path, md: ModelDescription, unzipdir: str) -> None:
        self.name = name
        self.path = Path(path)
        self.md = md
        self.unzipdir = unzipdir
        cs = md.coSimulation
        if cs is None:
            raise MasterError(f"{name}: {path} is not a co-simulation FMU")
        self.can_interpolate = bool(cs.canInterpolateInputs)
        self.can_state = bool(cs.canGetAndSetFMUstate)
        self.can_dd = bool(cs.providesDirectionalDerivative)
        self.vars = {v.name: v for v in md.modelVariables}
        self.slave = FMU2Slave(
            guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=cs.modelIdentifier, instanceName=name
        )
        self.last_error = ""
        self.slave.instantiate(callbacks=self._callbacks())
        self._c = self.slave.component
        self._set_real = _raw_function(self.slave, "fmi2SetReal")
        self._get_real = _raw_function(self.slave, "fmi2GetReal")
        self._set_der = _raw_function(self.slave, "fmi2SetRealInputDerivatives", required=False)
        self._do_step = _raw_function(self.slave, "fmi2DoStep")
        self.initialized = False
        self.inputs: list[str] = []  # connected inputs, in order
        self.outputs: list[str] = []  # outputs the master reads, in order
        self.order = 0  # degree of the input polynomial handed to this FMU
        self.n_orders = 0  # input derivatives set per step (value connections)
        self.rate_orders = 0  # input derivatives set per step when it has rate connections

    # --- life-cycle calls the master makes (FMI 2.0 here, FMI 3.0 in Instance3) -------------
    def enter_initialization(self, tol: float | None, t0: float) -> None:
        self.slave.setupExperiment(tolerance=tol, startTime=t0)
        self.slave.enterInitializationMode()

    def exit_initialization(self) -> None:
        self.slave.exitInitializationMode()

    def reset(self) -> None:
        self.slave.reset()

    def get_state(self) -> c_void_p:
        return self.slave.getFMUstate()

    def set_state(self, state: c_void_p) -> None:
        self.slave.setFMUstate(state)

    def free_state(self, state: c_void_p) -> None:
        self.slave.freeFMUstate(state)

    def finalize_ports(self) -> None:
        self.in_vr = np.array([self.vars[n].valueReference for n in self.inputs], dtype=np.uint32)
        self.out_vr = np.array([self.vars[n].valueReference for n in self.outputs], dtype=np.uint32)
        self.in_val = np.zeros(len(self.inputs))
        self.out_val = np.zeros(len(self.outputs))
        ni = len(self.inputs)
        self.der_vr = np.concatenate([self.in_vr, self.in_vr]).astype(np.uint32)
        self.der_order = np.array([1] * ni + [2] * ni, dtype=np.int32)
        self.der_val = np.zeros(2 * ni)
        self.p_in_vr, self.p_in_val = pointer_to(self.in_vr, UINT), pointer_to(self.in_val, DBL)
        self.p_out_vr, self.p_out_val = pointer_to(self.out_vr, UINT), pointer_to(self.out_val, DBL)
        self.p_der_vr, self.p_der_order = pointer_to(self.der_vr, UINT), pointer_to(self.der_order, _INT)
        self.p_der_val = pointer_to(self.der_val, DBL)
        self.n_in, self.n_out = ni, len(self.outputs)

    def set_order(self, order: int) -> None:
        """Degree of the input extrapolation (capped at 0 if the FMU cannot interpolate inputs)."""
        self.order = order if self.can_interpolate else 0
        self.n_orders = min(self.order, 2)
        self.rate_orders = max(self.n_orders, 1) if self.can_interpolate else 0

    # --- lean calls -------------------------------------------------------------------------
    #: the lean calls, in the numbering of the compiled loop's error report (:mod:`.cloop`)
    fmi_version = 2
    LEAN_CALLS = (
        "fmi2SetReal",
        "fmi2SetRealInputDerivatives",
        "fmi2DoStep",
        "fmi2GetReal",
        "fmi2GetFMUstate",
        "fmi2SetFMUstate",
    )
    STATE_CALLS = ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate")

    def state_addresses(self) -> tuple[int, int, int] | None:
        """Addresses of the FMU's get / set / free state functions (:data:`STATE_CALLS`), for the
        compiled loop's start-up rollback; None if the FMU cannot get and set its state."""
        if not self.can_state:
            return None
        try:
            got = tuple(address_of(getattr(self.slave.dll, n)) for n in self.STATE_CALLS)
        except (AttributeError, MasterError):
            return None
        return got[0], got[1], got[2]

    def failure(self, call: str, status: int = 3, t: float = 0.0, h: float = 0.0) -> MasterError:
        """The error of a failed lean call (status > fmi2Warning); a failed doStep says where and
        repeats the FMU's own last error message."""
        if call != self.LEAN_CALLS[2]:  # not the doStep
            return MasterError(f"{self.name}: {call} failed")
        lines = self.last_error.strip().splitlines()
        said = f": {lines[-1]}" if lines else ""
        return MasterError(f"{self.name}: {call} failed at t = {t:.16g} s, h = {h:.6g} s (status {status}){said}")

    def raw_address(self, name: str) -> int:
        """Address of the raw fmi2 function ``name`` (0 if the FMU does not export it), for the
        compiled loop."""
        f = {
            "fmi2SetReal": self._set_real,
            "fmi2GetReal": self._get_real,
            "fmi2SetRealInputDerivatives": self._set_der,
            "fmi2DoStep": self._do_step,
        }[name]
        return 0 if f is None else address_of(f)

    def set_inputs(self) -> None:
        if self.n_in and self._set_real(self._c, self.p_in_vr, self.n_in, self.p_in_val) > 1:
            raise self.failure("fmi2SetReal")

    def set_derivatives(self, n_orders: int) -> None:
        if self.n_in and n_orders and self._set_der is not None:
            n = self.n_in * n_orders
            if self._set_der(self._c, self.p_der_vr, n, self.p_der_order, self.p_der_val) > 1:
                raise self.failure("fmi2SetRealInputDerivatives")

    def get_outputs(self) -> None:
        if self.n_out and self._get_real(self._c, self.p_out_vr, self.n_out, self.p_out_val) > 1:
            raise self.failure("fmi2GetReal")

    def do_step(self, t: float, h: float) -> None:
        st = self._do_step(self._c, t, h, 0)
        if st > 1:
            raise self.failure("fmi2DoStep", st, t, h)

    def _callbacks(self) -> fmi2CallbackFunctions:
        """FMI callbacks whose logger prints as fmpy's does and keeps the last error message, so
        that a failed call raises an error saying what the FMU said (e.g. where its integrator
        stopped, in which state and mode)."""
        from fmpy.fmi2 import (
            calloc,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
            free,
            printLogMessage,
        )

        def logger(env: Any, instance: Any, status: int, category: bytes, message: bytes) -> None:
            if status > 1:
                self.last_error = (message or b"").decode(errors="replace")
            printLogMessage(env, instance, status, category, message)

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb_keep = (cb, logger)  # the FMU holds pointers to these: keep them alive
        return cb

    # --- parameters, partial derivatives ----------------------------------------------------
    def set_value(self, name: str, value: float | int | float64) -> None:
        v = self.vars.get(name)
        if v is None:
            raise MasterError(f"{self.name} has no variable {name!r}")
        if v.type == "Real":
            self.slave.setReal([v.valueReference], [float(value)])
        elif v.type in ("Integer", "Enumeration"):
            self.slave.setInteger([v.valueReference], [int(value)])
        elif v.type == "Boolean":
            self.slave.setBoolean([v.valueReference], [bool(value)])
        else:
            self.slave.setString([v.valueReference], [str(value)])

    def set_values(self, values: dict[str, Any]) -> None:
        """:meth:`set_value` of each ``name: value``, the real ones in one call (a restart sets every parameter
        again); on a failure they are set one by one, so that the error names the variable."""
        vrs: list[int] = []
        reals: list[float] = []
        others: list[tuple[str, Any]] = []
        for name, value in values.items():
            v = self.vars.get(name)
            if v is None:
                raise MasterError(f"{self.name} has no variable {name!r}")
            if v.type == self.REAL_TYPE:
                vrs.append(v.valueReference)
                reals.append(float(value))
            else:
                others.append((name, value))
        try:
            if vrs:
                self._set_reals(vrs, reals)
        except Exception:
            for name, value in values.items():
                if self.vars[name].type == self.REAL_TYPE:
                    self.set_value(name, value)
            raise
        for name, value in others:
            self.set_value(name, value)

    def _get_reals(self, vrs: list[int]) -> list[float]:
        return self.slave.getReal(vrs)

    def _set_reals(self, vrs: list[int], values: list[float]) -> None:
        self.slave.setReal(vrs, values)

    def get_real(self, names: list[str]) -> list[float]:
        return self._get_reals([self.vars[n].valueReference for n in names])

    def partial(self, output: str, input_: str) -> float:
        """d(output)/d(input) at the current point: the FMU's directional derivative, or a central
        finite difference on the input (step 1e-6 max(1, |u|)) if it provides none."""
        vu = self.vars[output].valueReference
        vk = self.vars[input_].valueReference
        if self.can_dd:
            return self.slave.getDirectionalDerivative([vu], [vk], [1.0])[0]
        u0 = self._get_reals([vk])[0]
        du = 1e-6 * max(1.0, abs(u0))
        self._set_reals([vk], [u0 + du])
        yp = self._get_reals([vu])[0]
        self._set_reals([vk], [u0 - du])
        ym = self._get_reals([vu])[0]
        self._set_reals([vk], [u0])
        return (yp - ym) / (2 * du)

    # --- life cycle -------------------------------------------------------------------------
    def close(self) -> None:
        """Terminate (if it was ever initialised: fmi2Terminate is not allowed in state Instantiated)
        and free the instance (errors of an FMU already in a failed state are ignored)."""
        if self.initialized:
            with contextlib.suppress(Exception):
                self.slave.terminate()
        with contextlib.suppress(Exception):
            self.slave.freeInstance()


# --- FMU states of a set of instances (rollback) ------------------------------------------------
def get_states(instances: list[Instance]) -> list[c_void_p]:
    return [ins.get_state() for ins in instances]


def set_states(instances: list[Instance], states: list[c_void_p]) -> None:
    for ins, s in zip(instances, states):
        ins.set_state(s)


def free_states(instances: list[Instance], states: list[c_void_p]) -> None:
    for ins, s in zip(instances, states):
        ins.free_state(s)
