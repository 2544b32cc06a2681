"""A co-simulation master for FMI 2.0 co-simulation FMUs, built on fmpy's FMU API.

Give it FMUs (instance name -> path), a connection list (``"a.y -> b.u"``) and parameter values;
it reads every ``modelDescription.xml``, builds the connection graph
(:mod:`pyfmu_wrapper.master.graph`), finds the algebraic loops from the declared direct
dependencies and steps the system with one of the schemes below. See ``docs/cosimulation.md``.

Schemes (``scheme=``)
---------------------
All schemes hand each FMU its inputs at the communication point t_n as a Taylor polynomial of
degree ``order`` (``fmi2SetRealInputDerivatives``; the FMU must declare ``canInterpolateInputs``),
obtained from the polynomial through the last ``order + 1`` communication points of the source
output (extrapolation). ``order = 0`` is the zero-order hold.

* ``"jacobi"``: every FMU steps from t_n to t_n+1 with extrapolated inputs, in parallel; the
  outputs read after the step are used as they are. Algebraic loops are ignored: an output with
  direct feed-through is evaluated with the *extrapolated* input, so the loop is closed with a
  one-step lag (the naive scheme). Global error O(h^(order+1)) for systems without loops.
* ``"gauss-seidel"``: FMUs step one after the other in the order of the graph condensation; an
  FMU whose source has already stepped gets the interpolating polynomial through the new point
  instead of an extrapolation. Loops are again closed with a lag. Same order as Jacobi, smaller
  constant; sequential by nature.
* ``"loop"`` (default): Jacobi stepping, and at every communication point the coupling equations
  u = G(u) (every connected input equals its source output, the outputs depending directly on
  the inputs as declared in the ModelStructure) are solved by Newton's method with the Jacobian
  dG/du from ``fmi2GetDirectionalDerivative`` (finite differences if an FMU does not provide it).
  The Jacobian is reused while the iteration contracts (chord Newton); for a linear feed-through
  (the ideal inerter) one correction is exact. The values handed to the next step are then
  consistent, and the scheme keeps the order of the extrapolation: O(h^(order+1)).

Communication step
------------------
Fixed (``run(t_end, step=h)``) or adaptive (``run(t_end, tol=...)``): the error estimate of a step
is the difference between the extrapolated input at t_n+1 and the source output actually found
there (after the loop solve): the local error of the coupling, O(h^(order+1)). A step whose
scaled estimate exceeds 1 is rejected and redone from the saved FMU states
(``fmi2GetFMUstate`` / ``fmi2SetFMUstate``); the next step is h (1/err)^(1/(order+1)) times a safety
factor. The scale of a signal is ``atol + rtol * max|signal|`` seen so far.

The stepping loop is lean: value references and ctypes pointers are resolved once, values live
in numpy arrays, the raw fmi2 functions are called without fmpy's per-call wrappers.
"""
from __future__ import annotations

import ctypes
import shutil
import tempfile
import time
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from .graph import Connection, ConnectionGraph, build_graph

SCHEMES = ("jacobi", "gauss-seidel", "loop")

_DBL = ctypes.POINTER(ctypes.c_double)
_UINT = ctypes.POINTER(ctypes.c_uint)
_INT = ctypes.POINTER(ctypes.c_int)


class MasterError(RuntimeError):
    """An FMI call failed or the coupling could not be solved."""


def _ptr(a: np.ndarray, kind):
    return a.ctypes.data_as(kind)


class _Instance:
    """One FMU instance: its slave, value references and pre-allocated exchange buffers."""

    def __init__(self, name: str, path: Path, md, unzipdir: str):
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
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=cs.modelIdentifier,
                               instanceName=name)
        self.last_error = ""
        self.slave.instantiate(callbacks=self._callbacks())
        f = self.slave._functions
        self._c = self.slave.component
        self._set_real = f["fmi2SetReal"]
        self._get_real = f["fmi2GetReal"]
        self._set_der = f["fmi2SetRealInputDerivatives"] if "fmi2SetRealInputDerivatives" in f else None
        self._do_step = f["fmi2DoStep"]
        self.initialized = False
        self.inputs: list[str] = []  # connected inputs, in order
        self.outputs: list[str] = []  # outputs the master reads, in order

    def finalize_ports(self):
        self.in_vr = np.array([self.vars[n].valueReference for n in self.inputs], dtype=np.uint32)
        self.out_vr = np.array([self.vars[n].valueReference for n in self.outputs], dtype=np.uint32)
        self.in_val = np.zeros(len(self.inputs))
        self.out_val = np.zeros(len(self.outputs))
        ni = len(self.inputs)
        self.der_vr = np.concatenate([self.in_vr, self.in_vr]).astype(np.uint32)
        self.der_order = np.array([1] * ni + [2] * ni, dtype=np.int32)
        self.der_val = np.zeros(2 * ni)
        self.p_in_vr, self.p_in_val = _ptr(self.in_vr, _UINT), _ptr(self.in_val, _DBL)
        self.p_out_vr, self.p_out_val = _ptr(self.out_vr, _UINT), _ptr(self.out_val, _DBL)
        self.p_der_vr, self.p_der_order = _ptr(self.der_vr, _UINT), _ptr(self.der_order, _INT)
        self.p_der_val = _ptr(self.der_val, _DBL)
        self.n_in, self.n_out = ni, len(self.outputs)

    # --- lean calls -------------------------------------------------------------------------
    def set_inputs(self):
        if self.n_in and self._set_real(self._c, self.p_in_vr, self.n_in, self.p_in_val) > 1:
            raise MasterError(f"{self.name}: fmi2SetReal failed")

    def set_derivatives(self, n_orders: int):
        if self.n_in and n_orders and self._set_der is not None:
            n = self.n_in * n_orders
            if self._set_der(self._c, self.p_der_vr, n, self.p_der_order, self.p_der_val) > 1:
                raise MasterError(f"{self.name}: fmi2SetRealInputDerivatives failed")

    def get_outputs(self):
        if self.n_out and self._get_real(self._c, self.p_out_vr, self.n_out, self.p_out_val) > 1:
            raise MasterError(f"{self.name}: fmi2GetReal failed")

    def _callbacks(self):
        """FMI callbacks whose logger prints as fmpy's does and keeps the last error message, so
        that a failed call raises an error saying what the FMU said (e.g. where its integrator
        stopped, in which state and mode)."""
        from fmpy.fmi2 import (calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free, printLogMessage)

        def logger(env, instance, status, category, message):
            if status > 1:
                self.last_error = (message or b"").decode(errors="replace")
            printLogMessage(env, instance, status, category, message)

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb_keep = (cb, logger)  # the FMU holds pointers to these: keep them alive
        return cb

    def do_step(self, t: float, h: float):
        st = self._do_step(self._c, t, h, 0)
        if st > 1:
            said = self.last_error.strip().splitlines()
            said = f": {said[-1]}" if said else ""
            raise MasterError(f"{self.name}: fmi2DoStep failed at t = {t:.16g} s, h = {h:.6g} s (status {st}){said}")

    # --- parameters -------------------------------------------------------------------------
    def set_value(self, name: str, value):
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

    def get_real(self, names) -> list[float]:
        return self.slave.getReal([self.vars[n].valueReference for n in names])


@dataclass
class Result:
    """Recorded communication points: t [s] and one column per recorded port."""

    t: np.ndarray
    values: np.ndarray
    names: list[str]
    steps: int
    rejected: int
    wall_time: float

    def __getitem__(self, name: str) -> np.ndarray:
        return self.values[:, self.names.index(name)]


def _lagrange_weights(s: np.ndarray):
    """Weights (d1, d2): first and second derivative at s = 0 of the polynomial through s."""
    n = len(s)
    d1 = np.zeros(n)
    d2 = np.zeros(n)
    if n == 1:
        return d1, d2
    for i in range(n):
        others = [s[j] for j in range(n) if j != i]
        den = np.prod([s[i] - o for o in others])
        if n == 2:
            d1[i] = 1.0 / den
        else:  # n == 3
            d1[i] = (-others[0] - others[1]) / den
            d2[i] = 2.0 / den
    return d1, d2


class Master:
    """Co-simulation of FMI 2.0 co-simulation FMUs coupled by a connection list.

    fmus: instance name -> FMU path; connections: ``"a.y -> b.u"`` strings or (src, dst) pairs;
    parameters: ``"instance.variable" -> value`` start values; scheme: see the module doc;
    order: degree of the input extrapolation (0, 1 or 2; capped at 0 for FMUs that cannot
    interpolate inputs); record: extra ports to record (all connected outputs are recorded).
    """

    def __init__(self, fmus: dict[str, str | Path], connections, parameters: dict | None = None,
                 scheme: str = "loop", order: int = 2, record=(), loop_tol: float = 1e-10, max_loop_iter: int = 20,
                 startup_iterations: int = 2):
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
        if order not in (0, 1, 2):
            raise ValueError("order must be 0, 1 or 2")
        self.scheme, self.order = scheme, int(order)
        self.loop_tol, self.max_loop_iter = loop_tol, max_loop_iter
        self.startup_iterations = int(startup_iterations)
        self._tmp = tempfile.mkdtemp(prefix="pyfmu_master_")
        self._cleanup = weakref.finalize(self, shutil.rmtree, self._tmp, True)  # also if close() is never called
        self.instances: dict[str, _Instance] = {}
        mds = {}
        for name, path in fmus.items():
            md = read_model_description(str(path))
            mds[name] = md
            unzip = extract(str(path), unzipdir=str(Path(self._tmp) / name))
            self.instances[name] = _Instance(name, Path(path), md, unzip)
        self.graph: ConnectionGraph = build_graph(mds, connections)
        self.parameters = dict(parameters or {})
        self._wire(list(record))
        self.t = 0.0
        self.steps = 0
        self.rejected = 0

    # --- set-up -----------------------------------------------------------------------------
    def _wire(self, record):
        conns = self.graph.connections
        # one signal per distinct source port, plus recorded ports
        self.signals: list[str] = []
        for c in conns:
            if c.src not in self.signals:
                self.signals.append(c.src)
            for extra in (c.init_src, c.integral_src):
                if extra is not None and extra not in self.signals:
                    self.signals.append(extra)
        for r in record:
            if r not in self.signals:
                self.signals.append(r)
        sig_index = {s: i for i, s in enumerate(self.signals)}
        for s in self.signals:
            inst, var = s.split(".", 1)
            if inst not in self.instances or var not in self.instances[inst].vars:
                raise MasterError(f"unknown port {s!r}")
            self.instances[inst].outputs.append(var)
        for c in conns:
            self.instances[c.dst_instance].inputs.append(c.dst_variable)
        for ins in self.instances.values():
            ins.finalize_ports()
            ins.sig_out = np.array([sig_index[f"{ins.name}.{o}"] for o in ins.outputs], dtype=np.int64)
            src = {c.dst_variable: sig_index[c.src] for c in conns if c.dst_instance == ins.name}
            ins.sig_in = np.array([src[i] for i in ins.inputs], dtype=np.int64)
            ins.order = self.order if ins.can_interpolate else 0
        self.nsig = len(self.signals)
        self.y = np.zeros(self.nsig)  # current source values (consistent at t after a loop solve)
        self.hist_y = np.zeros((3, self.nsig))  # values at the last three points, oldest first
        self.hist_t = np.zeros(3)
        self.n_hist = 0
        # coupling unknowns: every connection, u_j = value of input dst_j
        self.conn_sig = np.array([sig_index[c.src] for c in conns], dtype=np.int64)
        self.order_gs = self.graph.instance_order()
        self.has_loops = bool(self.graph.loops)
        self._jac = None
        self._wcache: dict = {}
        self._inst_list = list(self.instances.values())
        self._can_rollback = all(ins.can_state for ins in self._inst_list)
        for ins in self._inst_list:
            ins.n_orders = min(ins.order, 2)
            ins.conn_idx = np.array([next(k for k, c in enumerate(conns) if c.dst == f"{ins.name}.{i}")
                                     for i in ins.inputs], dtype=np.int64)
            rate = [(j, conns[k]) for j, k in enumerate(ins.conn_idx) if conns[k].kind == "rate"]
            ins.rate_pos = np.array([j for j, _ in rate], dtype=np.int64)
            ins.rate_src = np.array([sig_index[c.src] for _, c in rate], dtype=np.int64)
            ins.rate_gain = np.array([c.gain for _, c in rate], dtype=float)
            ins.rate_init = [None if c.init_src is None else sig_index[c.init_src] for _, c in rate]
            ins.rate_int = np.array([-1 if c.integral_src is None else sig_index[c.integral_src] for _, c in rate],
                                    dtype=np.int64)
            ins.rate_has_int = ins.rate_int >= 0
            ins.rate_prev = np.zeros(len(rate))  # mean of the previous step (for the slope)
            ins.rate_ready = False
            ins.rate_orders = max(ins.n_orders, 1) if ins.can_interpolate else 0
        self._rate = any(len(ins.rate_pos) for ins in self._inst_list)
        if self._rate:
            self._phase1 = [i for i in self._inst_list if not len(i.rate_pos)]
            self._phase2 = [i for i in self._inst_list if len(i.rate_pos)]
            srcs2 = {s for i in self._phase2 for s in i.rate_src}
            if any(s in srcs2 for i in self._phase2 for s in i.sig_out):
                raise MasterError("an instance fed by a rate connection cannot be the source of one")
            if self.has_loops and self.scheme == "loop":
                raise MasterError("algebraic loops and rate connections together are not supported "
                                  "by the 'loop' scheme")

    def set_order(self, order: int):
        """Change the degree of the input extrapolation (0, 1 or 2)."""
        if order not in (0, 1, 2):
            raise ValueError("order must be 0, 1 or 2")
        self.order = int(order)
        for ins in self._inst_list:
            ins.order = self.order if ins.can_interpolate else 0
            ins.n_orders = min(ins.order, 2)
            ins.rate_orders = max(ins.n_orders, 1) if ins.can_interpolate else 0
        self._wcache.clear()

    def set_parameters(self, values: dict):
        self.parameters.update(values)

    # --- initialisation ---------------------------------------------------------------------
    def initialize(self, t0: float = 0.0, parameters: dict | None = None, tol: float | None = None):
        """(Re-)initialise all FMUs at t0 with the stored parameters updated by ``parameters``."""
        if parameters:
            self.parameters.update(parameters)
        for ins in self.instances.values():
            if ins.initialized:
                ins.slave.reset()
        for key, val in self.parameters.items():
            inst, var = key.split(".", 1)
            if inst not in self.instances:
                raise MasterError(f"parameter {key!r}: unknown instance {inst!r}")
            self.instances[inst].set_value(var, val)
        for ins in self.instances.values():
            ins.slave.setupExperiment(tolerance=tol, startTime=t0)
            ins.slave.enterInitializationMode()
        # propagate the connections in initialisation mode (fixed-point / Newton on the loops)
        for ins in self.instances.values():
            ins.get_outputs()
            self.y[ins.sig_out] = ins.out_val
        self._jac = None
        self._startup_probe = False
        self._h_prev = 0.0
        for ins in self._inst_list:
            ins.rate_prev = np.zeros(len(ins.rate_pos))
            ins.rate_ready = False
            ins.rate_orders = max(ins.n_orders, 1) if ins.can_interpolate else 0
        if self._rate:
            self._init_rate_inputs()
        else:
            self._solve_coupling(initial=True)
        for ins in self.instances.values():
            ins.slave.exitInitializationMode()
            ins.initialized = True
        for ins in self.instances.values():
            ins.get_outputs()
            self.y[ins.sig_out] = ins.out_val
        if self.has_loops and self.scheme == "loop":
            self._solve_coupling()
        self.t = float(t0)
        self.steps = 0
        self.rejected = 0
        self.n_hist = 0
        self._push_history(self.t)

    def _push_history(self, t):
        self.hist_y[:-1] = self.hist_y[1:]
        self.hist_t[:-1] = self.hist_t[1:]
        self.hist_y[-1] = self.y
        self.hist_t[-1] = t
        self.n_hist = min(self.n_hist + 1, 3)

    def _init_rate_inputs(self, iterations: int = 50, tol: float = 1e-12):
        """Initialisation with rate connections: value inputs from their sources, rate inputs from
        their ``init_src`` ports, by fixed-point iteration."""
        for _ in range(iterations):
            before = self.y.copy()
            for ins in self._inst_list:
                if ins.n_in:
                    ins.in_val[:] = self.y[ins.sig_in]
                    for j, (pos, isrc) in enumerate(zip(ins.rate_pos, ins.rate_init)):
                        ins.in_val[pos] = 0.0 if isrc is None else self.y[isrc]
                    ins.set_inputs()
            self._read_all()
            if np.all(np.abs(self.y - before) <= tol * (np.abs(self.y) + 1e-300)):
                return
        # not converged: accept (the rate inputs are recomputed at the first step anyway)

    # --- coupling equations -----------------------------------------------------------------
    def _coupling_jacobian(self) -> np.ndarray:
        """dG/du over the connections: d(source output of i)/d(input of j), from the FMUs'
        directional derivatives restricted to the declared direct dependencies."""
        conns = self.graph.connections
        n = len(conns)
        J = np.zeros((n, n))
        feed = self.graph.feedthrough
        for i, ci in enumerate(conns):
            deps = feed.get(ci.src, ())
            for j, cj in enumerate(conns):
                if cj.dst not in deps:
                    continue
                ins = self.instances[ci.src_instance]
                vu = ins.vars[ci.src_variable].valueReference
                vk = ins.vars[cj.dst_variable].valueReference
                if ins.can_dd:
                    J[i, j] = ins.slave.getDirectionalDerivative([vu], [vk], [1.0])[0]
                else:  # central finite difference on the input
                    u0 = ins.slave.getReal([vk])[0]
                    du = 1e-6 * max(1.0, abs(u0))
                    ins.slave.setReal([vk], [u0 + du])
                    yp = ins.slave.getReal([vu])[0]
                    ins.slave.setReal([vk], [u0 - du])
                    ym = ins.slave.getReal([vu])[0]
                    ins.slave.setReal([vk], [u0])
                    J[i, j] = (yp - ym) / (2 * du)
        return J

    def _set_all_inputs(self, u: np.ndarray):
        for ins in self.instances.values():
            if ins.n_in:
                ins.in_val[:] = u[ins.conn_idx]
                ins.set_inputs()

    def _read_all(self):
        for ins in self.instances.values():
            ins.get_outputs()
            self.y[ins.sig_out] = ins.out_val

    def _solve_coupling(self, initial: bool = False, u0: np.ndarray | None = None) -> int:
        """Solve u = G(u) at the current point (Newton with a reused Jacobian). Returns iterations.

        Without loops a single pass (set inputs, read outputs) in topological order is exact."""
        if not self.has_loops:
            for name in self.order_gs:
                ins = self.instances[name]
                if ins.n_in:
                    ins.in_val[:] = self.y[ins.sig_in]
                    ins.set_inputs()
                ins.get_outputs()
                self.y[ins.sig_out] = ins.out_val
            return 1
        u = self.y[self.conn_sig].copy() if u0 is None else u0.copy()
        if self._jac is None:
            self._set_all_inputs(u)
            self._jac = np.eye(len(u)) - self._coupling_jacobian()
            self._jac_lu = np.linalg.inv(self._jac)
        self._uscale = np.abs(u) + 1e-300
        scale = 1e-300 + np.abs(u)
        g = None
        for it in range(1, self.max_loop_iter + 1):
            self._set_all_inputs(u)
            self._read_all()
            g = self.y[self.conn_sig]
            r = g - u
            err = np.max(np.abs(r) / (self.loop_tol * np.maximum(scale, np.abs(g)) + 1e-300))
            if err <= 1.0 or not np.any(r):
                return it
            u = u + self._jac_lu @ r
            if it == 3:  # slow: refresh the Jacobian
                self._jac = np.eye(len(u)) - self._coupling_jacobian()
                self._jac_lu = np.linalg.inv(self._jac)
        raise MasterError(f"coupling equations did not converge at t = {self.t:.16g} s")

    # --- stepping ---------------------------------------------------------------------------
    def _weights(self, k: int):
        """Cached derivative weights at t of the polynomial through the last k points."""
        ht, t = self.hist_t, self.t
        if k == 3:
            key = (3, round(float(ht[0]) - t, 13), round(float(ht[1]) - t, 13))
        elif k == 2:
            key = (2, round(float(ht[1]) - t, 13))
        else:
            key = (k,)
        w = self._wcache.get(key)
        if w is None:
            w = _lagrange_weights(ht[3 - k:] - t)
            if len(self._wcache) > 64:
                self._wcache.clear()
            self._wcache[key] = w
        return w

    def step(self, h: float):
        """One communication step of size h with the chosen scheme.

        While fewer than ``order + 1`` points are known (right after :meth:`initialize`) and the
        FMUs can roll back, the step is iterated (``startup_iterations`` times): taken with the
        extrapolation the known points allow, rolled back, and taken again with the polynomial
        through the known points and the point just found. The start-up then has the accuracy of
        the full order, so a run restarted from a state (shooting) equals a continued one."""
        t = self.t
        k = min(self.n_hist, self.order + 1)
        hy = self.hist_y[3 - k:]
        w1, w2 = self._weights(k)
        d1 = w1 @ hy
        d2 = w2 @ hy
        if self.scheme == "gauss-seidel":
            self._step_gs(t, h, d1, d2)
        elif k <= self.order and self.startup_iterations and self._can_rollback:
            saved = self._get_states()
            y0 = self.y.copy()
            try:
                for it in range(self.startup_iterations + 1):
                    if it:
                        ynew = self.y.copy()
                        self._set_states(saved)
                        self.y[:] = y0
                        s_pts = np.concatenate([self.hist_t[3 - k:] - t, [h]])[-(self.order + 1):]
                        pts = np.vstack([hy, ynew[None, :]])[-(self.order + 1):]
                        v1, v2 = _lagrange_weights(s_pts)
                        d1, d2 = v1 @ pts, v2 @ pts
                    self._startup_probe = it < self.startup_iterations
                    self._advance(t, h, d1, d2)
            finally:
                self._startup_probe = False
                self._free_states(saved)
        else:
            self._advance(t, h, d1, d2)
        self.t = t + h
        self.steps += 1
        self._push_history(self.t)

    def _advance(self, t, h, d1, d2):
        if self._rate:
            return self._advance_rate(t, h, d1, d2)
        y = self.y
        for ins in self._inst_list:
            if ins.n_in:
                src = ins.sig_in
                ins.in_val[:] = y[src]
                nd = ins.n_in
                ins.der_val[:nd] = d1[src]
                ins.der_val[nd:] = d2[src]
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
        for ins in self._inst_list:
            ins.do_step(t, h)
        pred = y + h * d1 + (0.5 * h * h) * d2  # extrapolated sources at t + h
        for ins in self._inst_list:
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val
        if self.scheme == "loop" and self.has_loops:
            self._loop_correct(pred[self.conn_sig])
        self._pred = pred

    def _set_extrapolated(self, ins, d1, d2):
        y = self.y
        src = ins.sig_in
        ins.in_val[:] = y[src]
        nd = ins.n_in
        ins.der_val[:nd] = d1[src]
        ins.der_val[nd:] = d2[src]

    def _advance_rate(self, t, h, d1, d2):
        """Two phases: the sources of rate connections step first (extrapolated inputs); the
        destinations then get the mean rate over the step (exact increment of the source), as a
        linear polynomial whose mean is that rate and whose slope comes from the previous mean
        (or from the exact first moment when the connection names an ``integral_src``)."""
        y = self.y
        y0 = y.copy()
        for ins in self._phase1:
            if ins.n_in:
                src = ins.sig_in
                ins.in_val[:] = y0[src]
                ins.der_val[:ins.n_in] = d1[src]
                ins.der_val[ins.n_in:] = d2[src]
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
            ins.do_step(t, h)
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val
        for ins in self._phase2:
            src = ins.sig_in
            ins.in_val[:] = y0[src]
            nd = ins.n_in
            ins.der_val[:nd] = d1[src]
            ins.der_val[nd:] = d2[src]
            rs = ins.rate_src
            s1 = y[rs]
            mean = ins.rate_gain * (s1 - y0[rs]) / h
            if ins.rate_has_int.any():  # exact first moment: slope from it
                k = ins.rate_has_int
                ii = ins.rate_int[k]
                i0 = mean[k] * h
                i1 = ins.rate_gain[k] * (h * s1[k] - (y[ii] - y0[ii]))
                slope = np.where(k, 0.0, (mean - ins.rate_prev) / (0.5 * (h + self._h_prev)))
                slope[k] = 12.0 * (i1 - 0.5 * h * i0) / h ** 3
            elif self.order >= 1 and ins.rate_ready:
                slope = (mean - ins.rate_prev) / (0.5 * (h + self._h_prev))
            else:
                slope = 0.0 * mean
            if not self._startup_probe:
                ins.rate_prev = mean
                ins.rate_ready = True
            pos = ins.rate_pos
            ins.in_val[pos] = mean - 0.5 * h * slope
            ins.der_val[pos] = slope
            ins.der_val[nd + pos] = 0.0
            ins.set_inputs()
            ins.set_derivatives(ins.rate_orders)
            ins.do_step(t, h)
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val
        self._h_prev = h
        self._pred = y0 + h * d1 + (0.5 * h * h) * d2

    def _loop_correct(self, u: np.ndarray):
        """After a step taken with inputs u (extrapolated), outputs G(u) are in y: chord Newton
        corrections u <- u + (I - dG/du)^-1 (G(u) - u) until the coupling equations hold."""
        y = self.y
        g = y[self.conn_sig]
        for it in range(self.max_loop_iter):
            r = g - u
            u = u + self._jac_lu @ r
            for ins in self._inst_list:
                if ins.n_in:
                    ins.in_val[:] = u[ins.conn_idx]
                    ins.set_inputs()
            for ins in self._inst_list:
                ins.get_outputs()
                y[ins.sig_out] = ins.out_val
            g = y[self.conn_sig]
            sc = self._uscale
            np.maximum(sc, np.abs(g), out=sc)
            if np.all(np.abs(g - u) <= self.loop_tol * sc):
                return it + 1
            if it == 2:
                self._jac = np.eye(len(u)) - self._coupling_jacobian()
                self._jac_lu = np.linalg.inv(self._jac)
        raise MasterError(f"coupling equations did not converge at t = {self.t:.16g} s")

    def _step_gs(self, t, h, d1, d2):
        stepped = np.zeros(self.nsig, dtype=bool)
        ynew = self.y.copy()
        kk = min(self.n_hist, self.order)  # old points used besides the new one
        s_i = np.concatenate([self.hist_t[3 - kk:] - t, [h]]) if kk > 0 else np.array([h])
        hy_old = self.hist_y[3 - kk:] if kk > 0 else self.hist_y[:0]
        v1, v2 = _lagrange_weights(s_i) if len(s_i) > 1 else (np.zeros(1), np.zeros(1))
        for name in self.order_gs:
            ins = self.instances[name]
            if ins.n_in:
                src = ins.sig_in
                e1, e2 = d1[src].copy(), d2[src].copy()
                new = stepped[src]
                if np.any(new) and len(s_i) > 1:
                    pts = np.vstack([hy_old[:, src], ynew[src][None, :]])
                    e1 = np.where(new, v1 @ pts, e1)
                    e2 = np.where(new, v2 @ pts, e2)
                ins.in_val[:] = self.y[src]
                ins.der_val[:ins.n_in] = e1
                ins.der_val[ins.n_in:] = e2
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
            ins.do_step(t, h)
            ins.get_outputs()
            ynew[ins.sig_out] = ins.out_val
            stepped[ins.sig_out] = True
        self._pred = self.y + h * d1 + 0.5 * h * h * d2
        self.y[:] = ynew

    def error_estimate(self, rtol: float, atol: float) -> float:
        """Scaled local coupling error of the last step: |extrapolated - found| at the new point."""
        y = self.y
        self._ymax = np.maximum(getattr(self, "_ymax", np.abs(y)), np.abs(y))
        return float(np.max(np.abs(self._pred - y) / (atol + rtol * self._ymax)))

    def _get_states(self):
        return [ins.slave.getFMUstate() for ins in self.instances.values()]

    def _set_states(self, states):
        for ins, s in zip(self.instances.values(), states):
            ins.slave.setFMUstate(s)

    def _free_states(self, states):
        for ins, s in zip(self.instances.values(), states):
            ins.slave.freeFMUstate(s)

    # --- runs -------------------------------------------------------------------------------
    def run(self, t_end: float, step: float | None = None, tol: float | None = None, atol: float = 1e-9,
            h0: float | None = None, h_max: float | None = None, callback=None) -> Result:
        """Step from the current time to t_end; fixed ``step`` or adaptive with relative ``tol``.

        Returns the communication points and the recorded signals (every connected output and
        the ``record`` ports)."""
        t0w = time.perf_counter()
        ts, ys = [self.t], [self.y.copy()]
        if tol is None:
            if step is None:
                raise ValueError("give a fixed step or a tolerance")
            n = max(1, int(round((t_end - self.t) / step)))
            h = (t_end - self.t) / n
            for _ in range(n):
                self.step(h)
                ts.append(self.t)
                ys.append(self.y.copy())
        else:
            if self.scheme == "gauss-seidel" or self._rate:
                # with rate connections the destination's outputs jump at step-size changes (the
                # piecewise-linear mean reconstruction), which this estimate cannot tell from error
                raise ValueError("the adaptive step is implemented for the jacobi and loop schemes with value "
                                 "connections only")
            if not all(ins.can_state for ins in self.instances.values()):
                raise MasterError("the adaptive step needs fmi2GetFMUstate/fmi2SetFMUstate in every FMU")
            h = h0 or (t_end - self.t) / 1000
            h_max = h_max or (t_end - self.t) / 10
            p = self.order + 1
            while self.t < t_end - 1e-12 * max(1.0, abs(t_end)):
                h = min(h, t_end - self.t, h_max)
                saved = self._get_states()
                snap = (self.t, self.y.copy(), self.hist_y.copy(), self.hist_t.copy(), self.n_hist, self.steps)
                rate_snap = [(ins.rate_prev.copy(), ins.rate_ready) for ins in self._inst_list], self._h_prev
                self.step(h)
                err = self.error_estimate(tol, atol) if snap[4] > self.order else 0.0
                if err > 1.0 and h > 1e-12:
                    self._set_states(saved)
                    self._free_states(saved)
                    self.t, y, hy, ht, self.n_hist, self.steps = snap
                    self.y[:], self.hist_y[:], self.hist_t[:] = y, hy, ht
                    for ins, (rp, rr) in zip(self._inst_list, rate_snap[0]):
                        ins.rate_prev, ins.rate_ready = rp, rr
                    self._h_prev = rate_snap[1]
                    self.rejected += 1
                    h *= max(0.2, 0.9 * err ** (-1.0 / p))
                    continue
                self._free_states(saved)
                ts.append(self.t)
                ys.append(self.y.copy())
                h *= min(2.0, max(0.2, 0.9 * max(err, 1e-10) ** (-1.0 / p)))
        return Result(np.array(ts), np.array(ys), list(self.signals), self.steps, self.rejected,
                      time.perf_counter() - t0w)

    def value(self, port: str) -> float:
        """Current value of a recorded port."""
        return float(self.y[self.signals.index(port)])

    def get(self, port: str) -> float:
        inst, var = port.split(".", 1)
        return self.instances[inst].get_real([var])[0]

    def close(self):
        for ins in self.instances.values():
            try:
                ins.slave.terminate()
            except Exception:  # noqa: BLE001
                pass
            try:
                ins.slave.freeInstance()
            except Exception:  # noqa: BLE001
                pass
        self.instances = {}
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
