"""Communication step control: fixed or adaptive step, the coupling error estimate, rollback.

Fixed (``run(t_end, step=h)``): the interval is divided into equal steps of about h.
Adaptive (``run(t_end, tol=...)``): the error estimate of a step is the difference between the
extrapolated input at t_n+1 and the source output actually found there (after the loop solve),
the local error of the coupling, O(h^(order+1)). A step whose scaled estimate exceeds 1 is
rejected and redone from the saved FMU states (``fmi2GetFMUstate`` / ``fmi2SetFMUstate``,
:class:`Rollback`); the next step is h (1/err)^(1/(order+1)) times a safety factor of 0.9, within
[0.2 h, 2 h]. The scale of a signal is ``atol + rtol * max|signal|`` seen so far.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .instance import MasterError, free_states, get_states, set_states

if TYPE_CHECKING:
    from .state import MasterState


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


class ErrorEstimate:
    """Scaled local coupling error of the last step: max |extrapolated - found| / (atol + rtol
    max|signal|), the maximum of |signal| taken over every step estimated so far."""

    def __init__(self) -> None:
        self.ymax: np.ndarray | None = None

    def __call__(self, pred: np.ndarray, y: np.ndarray, rtol: float, atol: float) -> float:
        self.ymax = np.maximum(np.abs(y) if self.ymax is None else self.ymax, np.abs(y))
        return float(np.max(np.abs(pred - y) / (atol + rtol * self.ymax)))


class Rollback:
    """Everything a step changes, saved before it: the FMU states and the master's own state
    (time, signals, history, counters, rate-connection memory). :meth:`restore` puts it back;
    :meth:`free` releases the FMU states (call it exactly once)."""

    def __init__(self, master: MasterState) -> None:
        m = master
        self.m = m
        self.states = get_states(m.stepper.inst_list)
        self.t, self.y, self.steps = m.t, m.y.copy(), m.steps
        self.hist = m.history.snapshot()
        self.rate = [(ins.rate_prev.copy(), ins.rate_ready) for ins in m.stepper.inst_list]
        self.h_prev = m.stepper.h_prev

    def restore(self) -> None:
        m = self.m
        set_states(m.stepper.inst_list, self.states)
        m.t, m.steps = self.t, self.steps
        m.y[:] = self.y
        m.history.restore(self.hist)
        for ins, (rp, rr) in zip(m.stepper.inst_list, self.rate):
            ins.rate_prev, ins.rate_ready = rp, rr
        m.stepper.h_prev = self.h_prev

    def free(self) -> None:
        free_states(self.m.stepper.inst_list, self.states)


def run(
    master: MasterState,
    t_end: float,
    step: float | None = None,
    tol: float | None = None,
    atol: float = 1e-9,
    h0: float | None = None,
    h_max: float | None = None,
) -> Result:
    """Step ``master`` from its current time to t_end [s]; fixed ``step`` or adaptive with relative
    ``tol`` and absolute ``atol`` (module doc). Returns the recorded communication points."""
    m = master
    t0w = time.perf_counter()
    ts, ys = [m.t], [m.y.copy()]
    if tol is None:
        if step is None:
            raise ValueError("give a fixed step or a tolerance")
        n = max(1, int(round((t_end - m.t) / step)))
        h = (t_end - m.t) / n
        t_rec = np.empty(n + 1)
        y_rec = np.empty((n + 1, m.nsig))
        t_rec[0], y_rec[0] = m.t, m.y
        m.advance(n, h, t_rec[1:], y_rec[1:])  # preallocated: no per-step Python objects
        return Result(t_rec, y_rec, list(m.signals), m.steps, m.rejected, time.perf_counter() - t0w)
    else:
        if m.scheme == "gauss-seidel" or m.wiring.rate:
            # with rate connections the destination's outputs jump at step-size changes (the
            # piecewise-linear mean reconstruction), which this estimate cannot tell from error
            raise ValueError(
                "the adaptive step is implemented for the jacobi and loop schemes with value connections only"
            )
        if not m.stepper.can_rollback:
            raise MasterError("the adaptive step needs fmi2GetFMUstate/fmi2SetFMUstate in every FMU")
        h = h0 or (t_end - m.t) / 1000
        h_max = h_max or (t_end - m.t) / 10
        p = m.order + 1
        while m.t < t_end - 1e-12 * max(1.0, abs(t_end)):
            h = min(h, t_end - m.t, h_max)
            saved = Rollback(m)
            m.step(h)
            err = m.error_estimate(tol, atol) if saved.hist[2] > m.order else 0.0
            if err > 1.0 and h > 1e-12:
                saved.restore()
                saved.free()
                m.rejected += 1
                h *= max(0.2, 0.9 * err ** (-1.0 / p))
                continue
            saved.free()
            ts.append(m.t)
            ys.append(m.y.copy())
            h *= min(2.0, max(0.2, 0.9 * max(err, 1e-10) ** (-1.0 / p)))
    return Result(np.array(ts), np.array(ys), list(m.signals), m.steps, m.rejected, time.perf_counter() - t0w)
