"""Stepping schemes: one communication step of all FMUs from t_n to t_n + h.

All schemes hand each FMU its inputs at t_n as a Taylor polynomial of degree ``order``
(``fmi2SetRealInputDerivatives``), from the polynomial through the last ``order + 1``
communication points of the source output (:mod:`.extrapolation`).

* ``"jacobi"``: every FMU steps with extrapolated inputs, in parallel; the outputs read after the
  step are used as they are (loops closed with a one-step lag).
* ``"gauss-seidel"``: FMUs step one after the other in the order of the graph condensation; an
  FMU whose source has already stepped gets the interpolating polynomial through the new point.
* ``"loop"``: Jacobi stepping, then the coupling equations solved at the new point
  (:class:`~.loop.CouplingSolver`).
* rate connections (with ``"jacobi"``): two phases, the sources first, then the destinations
  with the mean rate over the step (:meth:`Stepper.advance_rate`).

:class:`Stepper` also iterates the start-up steps (fewer known points than ``order + 1``) with
FMU state rollback. See the module doc of :mod:`.master` for orders and use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .extrapolation import History, combine, lagrange_weights
from .instance import free_states, get_states, set_states
from .loop import CouplingSolver
from .wiring import Wiring

if TYPE_CHECKING:
    from numpy import ndarray

SCHEMES = ("jacobi", "gauss-seidel", "loop")


class Stepper:
    """Takes communication steps of the wired instances.

    y: the master's signal array (updated in place to the values at t + h); after a step
    ``pred`` holds the sources extrapolated to t + h (for the error estimate)."""

    def __init__(
        self,
        instances: dict,
        wiring: Wiring,
        loop: CouplingSolver,
        y: np.ndarray,
        history: History,
        scheme: str,
        order: int,
        startup_iterations: int,
    ) -> None:
        self.instances = instances
        self.inst_list = list(instances.values())
        self.wiring = wiring
        self.loop = loop
        self.y = y
        self.history = history
        self.scheme, self.order = scheme, order
        self.startup_iterations = int(startup_iterations)
        self.can_rollback = all(ins.can_state for ins in self.inst_list)
        self.pred: np.ndarray | None = None  #: the sources extrapolated to t + h (None before a step)
        self.reset()

    def reset(self) -> None:
        """State of a fresh start (no previous step)."""
        self.startup_probe = False  # a start-up step that will be rolled back
        self.h_prev = 0.0  # previous step size (slope of the rate reconstruction)

    def step(self, t: float, h: float) -> None:
        """One communication step from t to t + h with the chosen scheme.

        While fewer than ``order + 1`` points are known (right after initialisation) and the
        FMUs can roll back, the step is iterated (``startup_iterations`` times): taken with the
        extrapolation the known points allow, rolled back, and taken again with the polynomial
        through the known points and the point just found. The start-up then has the accuracy of
        the full order, so a run restarted from a state (shooting) equals a continued one."""
        hist = self.history
        k = min(hist.n, self.order + 1)
        hy = hist.y[3 - k :]
        w1, w2 = hist.weights(k, t)
        d1 = combine(w1, hy)
        d2 = combine(w2, hy)
        if self.scheme == "gauss-seidel":
            self.step_gauss_seidel(t, h, d1, d2)
        elif k <= self.order and self.startup_iterations and self.can_rollback:
            saved = get_states(self.inst_list)
            y0 = self.y.copy()
            try:
                for it in range(self.startup_iterations + 1):
                    if it:
                        ynew = self.y.copy()
                        set_states(self.inst_list, saved)
                        self.y[:] = y0
                        s_pts = np.concatenate([hist.t[3 - k :] - t, [h]])[-(self.order + 1) :]
                        pts = np.vstack([hy, ynew[None, :]])[-(self.order + 1) :]
                        v1, v2 = lagrange_weights(s_pts)
                        d1, d2 = combine(v1, pts), combine(v2, pts)
                    self.startup_probe = it < self.startup_iterations
                    self.advance(t, h, d1, d2)
            finally:
                self.startup_probe = False
                free_states(self.inst_list, saved)
        else:
            self.advance(t, h, d1, d2)

    def advance(self, t: float, h: float, d1: ndarray, d2: ndarray) -> None:
        """Jacobi step (and, with the loop scheme, the coupling solved at t + h); d1, d2: input
        derivatives at t of every signal."""
        if self.wiring.rate:
            return self.advance_rate(t, h, d1, d2)
        y = self.y
        for ins in self.inst_list:
            if ins.n_in:
                src = ins.sig_in
                ins.in_val[:] = y[src]
                nd = ins.n_in
                ins.der_val[:nd] = d1[src]
                ins.der_val[nd:] = d2[src]
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
        for ins in self.inst_list:
            ins.do_step(t, h)
        pred = y + h * d1 + (0.5 * h * h) * d2  # extrapolated sources at t + h
        for ins in self.inst_list:
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val
        if self.scheme == "loop" and self.wiring.has_loops:
            self.loop.correct(pred[self.wiring.conn_sig], t)
        self.pred = pred

    def advance_rate(self, t: float, h: float, d1: ndarray, d2: ndarray) -> None:
        """Two phases: the sources of rate connections step first (extrapolated inputs); the
        destinations then get the mean rate over the step (exact increment of the source), as a
        linear polynomial whose mean is that rate and whose slope comes from the previous mean
        (or from the exact first moment when the connection names an ``integral_src``)."""
        y = self.y
        y0 = y.copy()
        for ins in self.wiring.phase1:
            if ins.n_in:
                src = ins.sig_in
                ins.in_val[:] = y0[src]
                ins.der_val[: ins.n_in] = d1[src]
                ins.der_val[ins.n_in :] = d2[src]
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
            ins.do_step(t, h)
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val
        for ins in self.wiring.phase2:
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
                slope = np.where(k, 0.0, (mean - ins.rate_prev) / (0.5 * (h + self.h_prev)))
                slope[k] = 12.0 * (i1 - 0.5 * h * i0) / h**3
            elif self.order >= 1 and ins.rate_ready:
                slope = (mean - ins.rate_prev) / (0.5 * (h + self.h_prev))
            else:
                slope = 0.0 * mean
            if not self.startup_probe:
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
        self.h_prev = h
        self.pred = y0 + h * d1 + (0.5 * h * h) * d2

    def step_gauss_seidel(self, t: float, h: float, d1: ndarray, d2: ndarray) -> None:
        """Sequential step in the order of the graph condensation; inputs whose source has
        already stepped get the polynomial through the new point."""
        y = self.y
        hist = self.history
        stepped = np.zeros(len(y), dtype=bool)
        ynew = y.copy()
        kk = min(hist.n, self.order)  # old points used besides the new one
        s_i = np.concatenate([hist.t[3 - kk :] - t, [h]]) if kk > 0 else np.array([h])
        hy_old = hist.y[3 - kk :] if kk > 0 else hist.y[:0]
        v1, v2 = lagrange_weights(s_i) if len(s_i) > 1 else (np.zeros(1), np.zeros(1))
        for name in self.wiring.order_gs:
            ins = self.instances[name]
            if ins.n_in:
                src = ins.sig_in
                e1, e2 = d1[src].copy(), d2[src].copy()
                new = stepped[src]
                if np.any(new) and len(s_i) > 1:
                    pts = np.vstack([hy_old[:, src], ynew[src][None, :]])
                    e1 = np.where(new, combine(v1, pts), e1)
                    e2 = np.where(new, combine(v2, pts), e2)
                ins.in_val[:] = y[src]
                ins.der_val[: ins.n_in] = e1
                ins.der_val[ins.n_in :] = e2
                ins.set_inputs()
                ins.set_derivatives(ins.n_orders)
            ins.do_step(t, h)
            ins.get_outputs()
            ynew[ins.sig_out] = ins.out_val
            stepped[ins.sig_out] = True
        self.pred = y + h * d1 + 0.5 * h * h * d2
        y[:] = ynew

    def init_rate_inputs(self, iterations: int = 50, tol: float = 1e-12) -> None:
        """Initialisation with rate connections: value inputs from their sources, rate inputs from
        their ``init_src`` ports, by fixed-point iteration (if it does not converge the values
        are kept: the rate inputs are recomputed at the first step anyway)."""
        y = self.y
        for _ in range(iterations):
            before = y.copy()
            for ins in self.inst_list:
                if ins.n_in:
                    ins.in_val[:] = y[ins.sig_in]
                    for pos, isrc in zip(ins.rate_pos, ins.rate_init):
                        ins.in_val[pos] = 0.0 if isrc is None else y[isrc]
                    ins.set_inputs()
            for ins in self.inst_list:
                ins.get_outputs()
                y[ins.sig_out] = ins.out_val
            if np.all(np.abs(y - before) <= tol * (np.abs(y) + 1e-300)):
                return
