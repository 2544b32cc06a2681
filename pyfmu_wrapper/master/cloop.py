"""The compiled stepping loop: fixed communication steps in C, calling the FMUs' fmi2 functions
through their C function pointers.

``cloop.c`` (beside this file) takes blocks of fixed steps of the Jacobi scheme, the two-phase
stepping with rate connections (the impulse coupling) and Gauss-Seidel, with exactly the
arithmetic of the Python reference path (:mod:`.schemes`): the two agree bit for bit (tested).
It is compiled at first use and loaded with ctypes by :mod:`.cloop_lib`; the call releases the GIL
while it runs, as every ctypes call does.

The loop returns to Python at the end of a block (the caller records in preallocated arrays),
when it meets history time offsets whose extrapolation weights it has not been given (the master's
own :meth:`~.extrapolation.History.weights`, so the cache behaves as on the Python path) and on an
FMU error (status > fmi2Warning: the master raises the same :class:`~.instance.MasterError`
with the FMU's own message as the Python path). The start-up steps after an initialisation (fewer known points than order + 1) are
iterated with rollback there as well (fmi2GetFMUstate / fmi2SetFMUstate), as
:meth:`.schemes.Stepper.step` does. What it does not cover stays in Python: the ``loop`` scheme on
a system with algebraic loops (Newton with directional derivatives), adaptive steps.

It also measures, per FMU, the time spent inside its fmi2 calls (``timing``).
"""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING, Any

import numpy as np

from .instance import MasterError, address_of

if TYPE_CHECKING:
    from .instance3 import Instance3
    from .state import MasterState

from .cloop_lib import DONE, NEED_WEIGHTS, SCHEME_CODE, Ctx, Fmi3, Inst, library


def _addr(a: np.ndarray) -> int:
    return a.ctypes.data


def scheme_of(master: MasterState) -> str | None:
    """The compiled scheme that takes the master's fixed steps, or None if they stay in Python."""
    st = master.stepper
    if st.scheme == "gauss-seidel":
        return "gauss-seidel"
    if master.wiring.rate:
        return "rate"
    if st.scheme == "loop" and master.wiring.has_loops:
        return None  # Newton on the coupling equations: Python
    return "jacobi"


class CompiledLoop:
    """The C structures of one master (built once; the arrays they point to are the master's own
    buffers, kept alive here)."""

    MAX_WEIGHTS = 64

    def __init__(self, master: MasterState) -> None:
        self.lib = library()
        m = master
        self.m = m
        inst = m.stepper.inst_list
        self.index = {id(ins): i for i, ins in enumerate(inst)}
        n = len(inst)
        self.insts = (Inst * n)()
        self._keep = []
        nsig = m.nsig
        phase2 = {id(i) for i in m.wiring.phase2}
        self.rate_prev = []
        for k, ins in enumerate(inst):
            s = self.insts[k]
            if getattr(ins, "fmi_version", 2) == 3:
                self._fmi3_adapter(s, ins)
            else:
                s.comp = ins._c
                s.set_real = ins.raw_address("fmi2SetReal")
                s.get_real = ins.raw_address("fmi2GetReal")
                s.set_der = ins.raw_address("fmi2SetRealInputDerivatives")
                s.do_step = ins.raw_address("fmi2DoStep")
                states = ins.state_addresses()
                if states is not None:
                    s.get_state, s.set_state, s.free_state = states
            s.n_in, s.n_out = ins.n_in, ins.n_out
            arrays = dict(
                in_vr=ins.in_vr,
                out_vr=ins.out_vr,
                der_vr=ins.der_vr,
                der_order=ins.der_order,
                in_val=ins.in_val,
                out_val=ins.out_val,
                der_val=ins.der_val,
                sig_in=np.ascontiguousarray(ins.sig_in, np.int64),
                sig_out=np.ascontiguousarray(ins.sig_out, np.int64),
                rate_pos=np.ascontiguousarray(ins.rate_pos, np.int64),
                rate_src=np.ascontiguousarray(ins.rate_src, np.int64),
                rate_int=np.ascontiguousarray(ins.rate_int, np.int64),
                rate_gain=np.ascontiguousarray(ins.rate_gain, float),
            )
            rp = np.zeros(max(1, len(ins.rate_pos)))
            arrays.update(rate_prev=rp, slope=np.zeros(max(1, len(ins.rate_pos))))
            self.rate_prev.append(rp)
            for name, a in arrays.items():
                self._keep.append(a)
                setattr(s, name, _addr(a) if a.size else None)  # empty: never read (its count is 0)
            s.n_rate = len(ins.rate_pos)
            s.any_int = int(bool(np.any(ins.rate_has_int))) if len(ins.rate_pos) else 0
            s.phase = 2 if id(ins) in phase2 else 1
        c = self.ctx = Ctx()
        c.n_inst, c.nsig = n, nsig
        #: the start-up steps roll back in C when every FMU gives its state functions
        self.can_rollback = all(bool(self.insts[k].get_state) for k in range(n))
        self.work = {k: np.zeros(max(1, nsig)) for k in ("y0", "d1", "d2", "pred", "ynew", "ysave", "yit")}
        self.stepped = np.zeros(max(1, nsig), dtype=np.uint8)
        for name, a in self.work.items():
            setattr(c, name, _addr(a))
        c.stepped = _addr(self.stepped)
        self.gs_order = np.array([self.index[id(m.instances[nm])] for nm in m.wiring.order_gs], dtype=np.int64)
        c.gs_order = _addr(self.gs_order)
        c.y = _addr(m.y)
        c.hist_y, c.hist_t = _addr(m.history.y), _addr(m.history.t)
        self.w_key = np.zeros((self.MAX_WEIGHTS, 3))
        self.w_val = np.zeros((self.MAX_WEIGHTS, 6))
        c.w_key, c.w_val, c.max_w, c.n_w = _addr(self.w_key), _addr(self.w_val), self.MAX_WEIGHTS, 0
        self.generation = m.history.generation
        self.timing = True

    def _fmi3_adapter(self, s: Any, ins: Instance3) -> Any:
        """Point the loop's calls of an FMI 3.0 instance at the adapters of cloop.c."""
        f = Fmi3()
        f.inst = ins._c
        f.set64, f.get64, f.step = (ins.raw3_address(n) for n in ("fmi3SetFloat64", "fmi3GetFloat64", "fmi3DoStep"))
        der = np.ascontiguousarray(ins.der3_vr, np.uint32)
        zeros = np.zeros(max(1, len(der)))
        f.n_der = len(der)
        f.der_vr = _addr(der) if der.size else None
        f.zeros = _addr(zeros)
        self._keep += [f, der, zeros]
        s.comp = ctypes.addressof(f)
        lib = self.lib
        if ins.can_state:
            try:
                f.getst, f.setst, f.freest = (address_of(getattr(ins.slave.dll, n)) for n in ins.STATE_CALLS)
            except (AttributeError, MasterError):
                pass
            else:
                s.get_state, s.set_state, s.free_state = (
                    ctypes.cast(getattr(lib, n), ctypes.c_void_p).value
                    for n in ("cl_f3_get_state", "cl_f3_set_state", "cl_f3_free_state")
                )
        s.set_real = ctypes.cast(lib.cl_f3_set_real, ctypes.c_void_p).value
        s.get_real = ctypes.cast(lib.cl_f3_get_real, ctypes.c_void_p).value
        s.set_der = ctypes.cast(lib.cl_f3_set_der, ctypes.c_void_p).value if der.size else None
        s.do_step = ctypes.cast(lib.cl_f3_do_step, ctypes.c_void_p).value

    def _check_buffers(self) -> None:
        m = self.m
        c = self.ctx
        # the master's arrays are updated in place everywhere; guard against a replaced one
        if c.y != _addr(m.y) or c.hist_y != _addr(m.history.y) or c.hist_t != _addr(m.history.t):
            raise MasterError("internal: the master's signal or history arrays were replaced")

    def _add_weights(self, k: int, x0: float, x1: float) -> None:
        hist = self.m.history
        w1, w2 = hist.weights(int(k), self.ctx.t)
        if hist.generation != self.generation or self.ctx.n_w >= self.MAX_WEIGHTS:
            self.ctx.n_w = 0  # the Python cache was emptied: forget what was copied from it
            self.generation = hist.generation
        e = self.ctx.n_w
        self.w_key[e] = (k, x0, x1)
        self.w_val[e] = 0.0
        self.w_val[e, : len(w1)] = w1
        self.w_val[e, 3 : 3 + len(w2)] = w2
        self.ctx.n_w = e + 1

    def run(self, n: int, h: float, rec_t: np.ndarray | None = None, rec_y: np.ndarray | None = None) -> int:
        """Take n steps of size h [s] from the master's state; record t and the signals after every
        step in rec_t[:n], rec_y[:n] (C-contiguous float arrays) if given. Updates the master's
        time, signals, history, step count, rate memory and ``stepper.pred``."""
        m = self.m
        st = m.stepper
        self._check_buffers()
        c = self.ctx
        if m.history.generation != self.generation:
            c.n_w = 0
            self.generation = m.history.generation
        scheme = scheme_of(m)
        if scheme is None:
            raise MasterError(
                "the compiled loop cannot take these steps (Newton on the coupling equations runs in Python)"
            )
        c.scheme = SCHEME_CODE[scheme]
        c.order = st.order
        c.startup_iters = st.startup_iterations if (st.can_rollback and self.can_rollback) else 0
        c.probe = 0
        c.timing = int(self.timing)
        c.t, c.h, c.h_prev = m.t, h, st.h_prev
        c.half_h, c.hh2, c.h3 = 0.5 * h, 0.5 * h * h, h**3
        c.hist_n = m.history.n
        c.steps = m.steps
        inst = st.inst_list
        for k, ins in enumerate(inst):
            self.insts[k].n_orders, self.insts[k].rate_orders = ins.n_orders, ins.rate_orders
            if len(ins.rate_pos):
                self.rate_prev[k][:] = ins.rate_prev
                self.insts[k].rate_ready = int(ins.rate_ready)
        if (rec_t is None) != (rec_y is None):
            raise ValueError("rec_t and rec_y are given together or not at all")
        if rec_t is not None and rec_y is not None:
            assert rec_t.flags.c_contiguous and rec_y.flags.c_contiguous and rec_y.shape[1] == m.nsig
        done = 0
        try:
            while done < n:
                pt = None if rec_t is None else _addr(rec_t) + 8 * done
                py = None if rec_y is None else _addr(rec_y) + 8 * m.nsig * done
                r = self.lib.cl_run(ctypes.byref(c), self.insts, n - done, pt, py)
                done += c.steps_done
                if r == DONE:
                    break
                if r == NEED_WEIGHTS:
                    m.history.n = c.hist_n
                    self._add_weights(c.need_k, c.need_x0, c.need_x1)
                    continue
                ins = inst[c.err_inst]
                raise ins.failure(ins.LEAN_CALLS[c.err_func], c.err_status, c.t, h)
        finally:
            m.t = c.t
            m.steps = c.steps
            m.history.n = c.hist_n
            st.h_prev = c.h_prev
            st.pred = self.work["pred"][: m.nsig].copy()
            for k, ins in enumerate(inst):
                if len(ins.rate_pos):
                    ins.rate_prev = self.rate_prev[k][: len(ins.rate_pos)].copy()
                    ins.rate_ready = bool(self.insts[k].rate_ready)
        return done

    def fmu_times(self) -> dict:
        """Seconds inside each FMU's fmi2 calls and number of calls, since the loop was built."""
        return {
            ins.name: dict(seconds=self.insts[k].time_in, calls=int(self.insts[k].calls))
            for k, ins in enumerate(self.m.stepper.inst_list)
        }

    @property
    def loop_seconds(self) -> float:
        """Seconds spent in the compiled loop (inside the FMUs and the master's own work)."""
        return self.ctx.loop_time

    def plain(self, n: int, h: float) -> float:
        """Benchmark baseline: n steps of a plain C loop (fmi2SetReal, fmi2DoStep, fmi2GetReal of
        every FMU, no coupling arithmetic) on the same instances from the master's time; returns
        the wall time [s]. The master's time moves on with the FMUs' (its history does not: the
        next extrapolation spans the gap)."""
        import time

        m = self.m
        t = time.perf_counter()
        if self.lib.cl_plain(self.insts, len(m.stepper.inst_list), m.t, h, n):
            raise MasterError("an FMU failed in the plain loop")
        wall = time.perf_counter() - t
        for _ in range(n):  # the same additions as the C loop
            m.t = m.t + h
        return wall
