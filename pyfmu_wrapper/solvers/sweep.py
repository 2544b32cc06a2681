"""Frequency sweeps up and down with continuation.

Each frequency starts from the steady state of the previous one (the state at phase w t = 0,
which is continuous in w), so the transient to settle is short, and the branch followed depends on
the direction, as in a stepped-sine test. ``direction='both'`` runs up and then down. For the play
model (windowed steady state) the continued state is that of the smooth companion (ideal
inerter) and each point starts from it (``SolverSettings.play_start``; "previous" restores a
plain continuation of the play state).

``workers > 1`` splits the frequency list into that many contiguous pieces, each swept with
continuation in its own process; the first point of each piece starts from the linear initial
guess instead of its neighbour. Where the response is multistable this can pick another branch
at a piece boundary than a single sequential sweep would: use ``workers=1`` for strict
stepped-sine semantics.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from functools import partial
from typing import Any, Protocol

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from ..physics.params import TMDParams
from ..physics.unit import ModelUnit
from .monolithic import SolverSettings, SteadyState, steady_state


@dataclass
class SweepResult:
    """Table with one row per (direction, omega): amplitude [m], periods, converged, irregular
    (settled into irregular motion; ``change`` is then the scatter of its window maxima), change,
    steps, rejected, wall_time."""

    table: pd.DataFrame
    final_states: dict[str, Any]


class ProgressQueue(Protocol):
    """Where a sweep piece reports each finished frequency (a multiprocessing queue or a callback)."""

    def put(self, n: int) -> None: ...


def _sweep_piece(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    seq: Sequence[float] | NDArray[np.float64],
    d: str,
    settings: SolverSettings,
    z0: ArrayLike | None,
    queue: ProgressQueue | None = None,
) -> tuple[list[dict[str, Any]], NDArray[np.float64] | None]:
    rows: list[dict[str, Any]] = []
    z = None if z0 is None else np.array(z0, dtype=float)
    hint: dict = {}
    # windowed (play) points start from their smooth companion's orbit, continued via hint
    companion = settings.window_for(tmd) > 1 and settings.play_start == "companion"
    w_prev = None
    for w in seq:
        ss = steady_state(unit, base, tmd, float(w), None if companion else z, settings, hint)
        if not ss.converged and not companion and z is not None and w_prev is not None:
            ss = refine(unit, base, tmd, w_prev, float(w), z, settings, ss)
        z = ss.state if ss.converged or z is None else z  # a failed point hands on the last converged state
        w_prev = float(w) if ss.converged else w_prev
        rows.append(
            dict(
                direction=d,
                omega=float(w),
                amplitude=ss.amplitude,
                amplitude_periodic=ss.amplitude_periodic,
                periods=ss.periods,
                converged=ss.converged,
                irregular=ss.irregular,
                change=ss.change,
                steps=ss.steps,
                rejected=ss.rejected,
                wall_time=ss.wall_time,
                reason=ss.reason,
            )
        )
        if queue is not None:
            queue.put(1)
    return rows, z


#: the continuation steps a point that failed from its neighbour's state is approached by
REFINE_STEPS = 4


def refine(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    w_prev: float,
    w: float,
    z_prev: NDArray[np.float64],
    settings: SolverSettings,
    failed: SteadyState,
) -> SteadyState:
    """A point that did not converge from the previous point's state (a jump of the continuation too
    large for Newton), approached again in :data:`REFINE_STEPS` smaller steps from ``w_prev``, each from
    the last; returns the point at ``w`` if that converges, else ``failed`` with the reason extended (the
    sweep goes on either way)."""
    z = np.array(z_prev, dtype=float)
    spent = failed.wall_time
    for k in range(1, REFINE_STEPS + 1):
        wk = w_prev + (w - w_prev) * k / REFINE_STEPS
        ss = steady_state(unit, base, tmd, wk, z, settings)
        spent += ss.wall_time
        if not ss.converged:
            why = f"{failed.reason}; refined in {REFINE_STEPS} steps from {w_prev:.6g} rad/s: failed at {wk:.6g} rad/s"
            return replace(failed, reason=why, wall_time=spent)
        z = ss.state
    return replace(ss, wall_time=spent)


def sweep(
    unit: ModelUnit,
    base: Any,
    tmd: TMDParams,
    omegas: ArrayLike,
    direction: str = "up",
    settings: SolverSettings | None = None,
    progress: Callable[[int], Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int = 1,
) -> SweepResult:
    """Steady-state amplitude of the base at each omega [rad/s], sweeping up, down or both.

    settings: the solver settings (default ``SolverSettings()``).
    progress: optional callable(n_done) called after every frequency (e.g. tqdm.update).
    workers: processes to use (0 or None: all cores); see the module doc.
    """
    settings = SolverSettings() if settings is None else settings
    rows, finals = run_sweep_pieces(
        partial(_sweep_piece, unit), base, tmd, omegas, direction, settings, progress, z0, workers
    )
    return SweepResult(pd.DataFrame(rows), finals)


def run_sweep_pieces(
    piece: Callable[..., tuple[list[dict[str, Any]], Any]],
    base: Any,
    tmd: TMDParams,
    omegas: ArrayLike,
    direction: str,
    settings: Any,
    progress: Callable[[int], Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int | None = 1,
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Drive a continuation sweep, up, down or both, over ``workers`` processes (module doc).

    piece(base, tmd, seq, direction, settings, z0, queue) -> (rows, final_state) sweeps one
    contiguous piece and calls queue.put(1) after every frequency; any engine's sweep can use this
    driver. Returns (rows of every piece, {direction: final state of the last piece}).
    """
    omegas = np.sort(np.asarray(omegas, dtype=float))
    if direction not in ("up", "down", "both"):
        raise ValueError(f"direction must be 'up', 'down' or 'both', got {direction!r}")
    if not workers:
        workers = os.cpu_count() or 1
    rows: list[dict[str, Any]] = []
    finals: dict[str, Any] = {}
    for d in ["up", "down"] if direction == "both" else [direction]:
        seq = omegas if d == "up" else omegas[::-1]
        nw = max(1, min(int(workers), len(seq) // 2))
        if nw == 1:
            r, z = piece(base, tmd, seq, d, settings, z0, None if progress is None else _CallbackQueue(progress))
            rows += r
            finals[d] = z
            continue
        import multiprocessing as mp

        pieces = np.array_split(seq, nw)
        with mp.Manager() as mgr, ProcessPoolExecutor(max_workers=nw) as ex:
            q = mgr.Queue()
            futs = [
                ex.submit(piece, base, tmd, part, d, settings, z0 if i == 0 else None, q)
                for i, part in enumerate(pieces)
            ]
            done = 0
            while done < len(seq):
                if all(f.done() for f in futs) and q.empty():
                    break
                try:
                    q.get(timeout=0.2)
                except Exception:  # noqa: BLE001 - queue.Empty from the manager proxy
                    continue
                done += 1
                if progress is not None:
                    progress(1)
            results = [f.result() for f in futs]
        for r, _ in results:
            rows += r
        finals[d] = results[-1][1]
    return rows, finals


class _CallbackQueue:
    def __init__(self, cb: Callable[[int], Any]) -> None:
        self.cb = cb

    def put(self, n: int) -> None:
        self.cb(n)
