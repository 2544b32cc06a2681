"""A co-simulation master for FMI 2.0 and FMI 3.0 co-simulation FMUs, built on fmpy's FMU API.

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
in numpy arrays, the raw fmi2 functions are called without fmpy's per-call wrappers. Fixed steps
(:meth:`Master.advance`, :meth:`Master.run` with ``step=``) run in the compiled loop of
:mod:`.cloop` wherever it applies (Jacobi, Gauss-Seidel, rate connections), bit for bit the same
as the Python path of :mod:`.schemes`, which stays the reference and takes the rest.

Pieces
------
:class:`Master` is a facade over the pieces it composes, one module each:
:mod:`.instance` (an FMU instance over fmpy: ports, lean fmi2 calls, callbacks, FMU states),
:mod:`.wiring` (signals and the ports that read and write them), :mod:`.extrapolation` (input
polynomials from the history), :mod:`.schemes` (the stepping schemes), :mod:`.loop` (coupling
Jacobian and Newton on u = G(u)), :mod:`.stepcontrol` (fixed / adaptive step, error estimate,
rollback) and :mod:`.cloop` (the compiled stepping loop). It knows FMI and coupling only; the base + TMD application is
:mod:`pyfmu_wrapper.cosim`.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
import weakref
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy import extract, read_model_description

from . import cloop, stepcontrol
from .extrapolation import History
from .graph import ConnectionGraph, ConnectionLike, build_graph
from .instance import Instance, MasterError
from .instance3 import open_instance
from .loop import CouplingSolver
from .schemes import SCHEMES, Stepper
from .stepcontrol import ErrorEstimate, Result
from .wiring import reset_rate, wire

if TYPE_CHECKING:
    from .cloop import CompiledLoop

__all__ = ["Master", "MasterError", "Result", "SCHEMES"]


def _check_order(order: int) -> int:
    if order not in (0, 1, 2):
        raise ValueError("order must be 0, 1 or 2")
    return int(order)


class Master:
    """Co-simulation of FMI 2.0 or 3.0 co-simulation FMUs coupled by a connection list.

    fmus: instance name -> FMU path; connections: ``"a.y -> b.u"`` strings or (src, dst) pairs;
    parameters: ``"instance.variable" -> value`` start values; scheme: see the module doc;
    order: degree of the input extrapolation (0, 1 or 2; capped at 0 for FMUs that cannot
    interpolate inputs); record: extra ports to record (all connected outputs are recorded);
    loop_tol, max_loop_iter: the Newton solve of the coupling equations (:mod:`.loop`);
    startup_iterations: iterations of the first steps (:meth:`step`); compiled: take fixed steps
    (:meth:`advance`, :meth:`run`) in the compiled loop of :mod:`.cloop` where it applies (default:
    yes, unless the environment sets ``PYFMU_COMPILED_LOOP=0``); the results are the same bit for bit.

    ``y`` holds the current value of every signal (``signals``: every connected source and
    recorded port), ``t`` the current time [s].
    """

    def __init__(
        self,
        fmus: dict[str, str | Path],
        connections: Iterable[ConnectionLike],
        parameters: dict | None = None,
        scheme: str = "loop",
        order: int = 2,
        record: Iterable[str] = (),
        loop_tol: float = 1e-10,
        max_loop_iter: int = 20,
        startup_iterations: int = 2,
        compiled: bool | None = None,
    ) -> None:
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
        order = _check_order(order)
        self._tmp = tempfile.mkdtemp(prefix="pyfmu_master_")
        self._cleanup = weakref.finalize(self, shutil.rmtree, self._tmp, True)  # also if close() is never called
        self.instances: dict[str, Instance] = {}
        mds = {}
        for name, path in fmus.items():
            md = read_model_description(str(path))
            mds[name] = md
            unzip = extract(str(path), unzipdir=str(Path(self._tmp) / name))
            self.instances[name] = open_instance(name, Path(path), md, unzip)
        self.graph: ConnectionGraph = build_graph(mds, connections)
        self.parameters = dict(parameters or {})
        self.wiring = wire(self.instances, self.graph, list(record), scheme, order)
        self.signals: list[str] = self.wiring.signals
        self.nsig = self.wiring.nsig
        self.y = np.zeros(self.nsig)  # current source values (consistent at t after a loop solve)
        self.history = History(self.nsig)
        self.loop = CouplingSolver(
            self.graph,
            self.instances,
            self.y,
            self.wiring.conn_sig,
            self.wiring.order_gs,
            self.wiring.has_loops,
            loop_tol,
            max_loop_iter,
        )
        self.stepper = Stepper(
            self.instances, self.wiring, self.loop, self.y, self.history, scheme, order, startup_iterations
        )
        self._error = ErrorEstimate()
        if compiled is None:  # $PYFMU_COMPILED_LOOP=0: every step on the Python reference path
            compiled = os.environ.get("PYFMU_COMPILED_LOOP", "1") != "0"
        self.compiled = bool(compiled)  #: fixed steps in the compiled loop (:mod:`.cloop`) where it applies
        self._cloop: cloop.CompiledLoop | None = None
        self.python_seconds = 0.0  #: wall time of the steps taken on the Python path by :meth:`advance`
        self.t = 0.0
        self.steps = 0
        self.rejected = 0

    # --- settings ---------------------------------------------------------------------------
    @property
    def scheme(self) -> str:
        """The stepping scheme (:data:`SCHEMES`); may be changed between steps."""
        return self.stepper.scheme

    @scheme.setter
    def scheme(self, scheme: str) -> None:
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
        self.stepper.scheme = scheme

    @property
    def order(self) -> int:
        """Degree of the input extrapolation (change it with :meth:`set_order`)."""
        return self.stepper.order

    def set_order(self, order: int) -> None:
        """Change the degree of the input extrapolation (0, 1 or 2)."""
        order = _check_order(order)
        self.stepper.order = order
        for ins in self.stepper.inst_list:
            ins.set_order(order)
        self.history.clear_cache()

    def set_parameters(self, values: dict[str, Any]) -> None:
        self.parameters.update(values)

    # --- initialisation ---------------------------------------------------------------------
    def initialize(self, t0: float = 0.0, parameters: dict | None = None, tol: float | None = None) -> None:
        """(Re-)initialise all FMUs at t0 with the stored parameters updated by ``parameters``."""
        if parameters:
            self.parameters.update(parameters)
        inst = self.stepper.inst_list
        for ins in inst:
            if ins.initialized:
                ins.reset()
        by_instance: dict[str, dict[str, Any]] = {}
        for key, val in self.parameters.items():
            name, var = key.split(".", 1)
            if name not in self.instances:
                raise MasterError(f"parameter {key!r}: unknown instance {name!r}")
            by_instance.setdefault(name, {})[var] = val
        for name, values in by_instance.items():
            self.instances[name].set_values(values)
        for ins in inst:
            ins.enter_initialization(tol, t0)
        # propagate the connections in initialisation mode (fixed-point / Newton on the loops)
        self._read_all()
        self.loop.reset()
        self.stepper.reset()
        for ins in inst:
            reset_rate(ins)
        if self.wiring.rate:
            self.stepper.init_rate_inputs()
        else:
            self.loop.solve(t0)
        for ins in inst:
            ins.exit_initialization()
            ins.initialized = True
        self._read_all()
        if self.wiring.has_loops and self.scheme == "loop":
            self.loop.solve(t0)
        self.t = float(t0)
        self.steps = 0
        self.rejected = 0
        self.history.clear()
        self.history.push(self.t, self.y)

    def _read_all(self) -> None:
        for ins in self.stepper.inst_list:
            ins.get_outputs()
            self.y[ins.sig_out] = ins.out_val

    # --- stepping ---------------------------------------------------------------------------
    def step(self, h: float) -> None:
        """One communication step of size h [s] with the chosen scheme (:meth:`.schemes.Stepper.step`;
        the first steps after :meth:`initialize` are iterated to the full order when the FMUs can
        roll back)."""
        self.stepper.step(self.t, h)
        self.t = self.t + h
        self.steps += 1
        self.history.push(self.t, self.y)

    def _compiled_loop(self) -> CompiledLoop | None:
        """The compiled loop of this master, or None if its steps stay in Python (``compiled=False``,
        the ``loop`` scheme on algebraic loops)."""
        if not self.compiled or cloop.scheme_of(self) is None:
            return None
        if self._cloop is None:
            self._cloop = cloop.CompiledLoop(self)
        return self._cloop

    def _startup_step(self) -> bool:
        """Whether the next step is a start-up step iterated with rollback."""
        st = self.stepper
        k = min(self.history.n, st.order + 1)
        return st.scheme != "gauss-seidel" and k <= st.order and st.startup_iterations > 0 and st.can_rollback

    def advance(self, n: int, h: float, rec_t: np.ndarray | None = None, rec_y: np.ndarray | None = None) -> None:
        """n communication steps of size h [s], the same as n calls of :meth:`step` (bit for bit),
        in the compiled loop where it applies (its start-up steps included, when every FMU gives its
        state functions to the loop; else those stay in Python).
        rec_t, rec_y: if given, arrays of at least n rows (rec_y: C-contiguous, one column per
        signal) that receive t and the signals after every step."""
        n = int(n)
        if (rec_t is None) != (rec_y is None):
            raise ValueError("rec_t and rec_y are given together or not at all")
        i = 0
        loop = self._compiled_loop()
        while i < n and (loop is None or (self._startup_step() and not loop.can_rollback)):
            t0 = time.perf_counter()
            self.step(h)
            self.python_seconds += time.perf_counter() - t0
            if rec_t is not None and rec_y is not None:
                rec_t[i] = self.t
                rec_y[i] = self.y
            i += 1
        if i < n and loop is not None:  # (without a compiled loop, the Python steps above took all n)
            loop.run(n - i, h, None if rec_t is None else rec_t[i:], None if rec_y is None else rec_y[i:])

    def timing(self) -> dict[str, Any]:
        """Where the time of :meth:`advance` went: per FMU the seconds inside its fmi2 calls and
        their number (compiled loop), the seconds of the compiled loop in all, the master's own
        share of it (loop minus FMUs), and the seconds of steps taken on the Python path."""
        out: dict[str, Any] = dict(fmus={}, loop_seconds=0.0, master_seconds=0.0, python_seconds=self.python_seconds)
        if self._cloop is not None:
            out["fmus"] = self._cloop.fmu_times()
            out["loop_seconds"] = self._cloop.loop_seconds
            out["master_seconds"] = self._cloop.loop_seconds - sum(v["seconds"] for v in out["fmus"].values())
        return out

    def error_estimate(self, rtol: float, atol: float) -> float:
        """Scaled local coupling error of the last step: |extrapolated - found| at the new point."""
        pred = self.stepper.pred
        if pred is None:
            raise MasterError("no step taken yet: there is no coupling error to estimate")
        return self._error(pred, self.y, rtol, atol)

    def run(
        self,
        t_end: float,
        step: float | None = None,
        tol: float | None = None,
        atol: float = 1e-9,
        h0: float | None = None,
        h_max: float | None = None,
    ) -> Result:
        """Step from the current time to t_end [s]; fixed ``step`` or adaptive with relative ``tol``
        (:mod:`.stepcontrol`).

        Returns the communication points and the recorded signals (every connected output and
        the ``record`` ports)."""
        return stepcontrol.run(self, t_end, step, tol, atol, h0, h_max)

    # --- values -----------------------------------------------------------------------------
    def value(self, port: str) -> float:
        """Current value of a recorded port."""
        return float(self.y[self.signals.index(port)])

    def get(self, port: str) -> float:
        """Current value of any Real variable ``instance.variable``, read from the FMU."""
        inst, var = port.split(".", 1)
        return self.instances[inst].get_real([var])[0]

    def close(self) -> None:
        self._cloop = None
        for ins in self.instances.values():
            ins.close()
        self.instances = {}
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
