"""Frequency sweeps up and down with continuation.

Each frequency starts from the steady state of the previous one (the state at phase w t = 0,
which is continuous in w), so the transient to settle is short, and the branch followed depends on
the direction, as in a stepped-sine test. ``direction='both'`` runs up and then down.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..physics.params import BaseParams, TMDParams
from .monolithic import SolverSettings, steady_state


@dataclass
class SweepResult:
    """Table with one row per (direction, omega): amplitude [m], periods, converged, steps, wall_time."""

    table: pd.DataFrame
    final_states: dict


def sweep(base: BaseParams, tmd: TMDParams, omegas, direction: str = "up",
          settings: SolverSettings = SolverSettings(), progress=None, z0=None) -> SweepResult:
    """Steady-state amplitude of the base at each omega [rad/s], sweeping up, down or both.

    progress: optional callable(n_done) called after every frequency (e.g. tqdm.update).
    """
    omegas = np.sort(np.asarray(omegas, dtype=float))
    if direction not in ("up", "down", "both"):
        raise ValueError(f"direction must be 'up', 'down' or 'both', got {direction!r}")
    dirs = ["up", "down"] if direction == "both" else [direction]
    rows = []
    finals = {}
    for d in dirs:
        seq = omegas if d == "up" else omegas[::-1]
        z = None if z0 is None else np.array(z0, dtype=float)
        hint: dict = {}
        for w in seq:
            ss = steady_state(base, tmd, float(w), z, settings, hint)
            z = ss.state
            rows.append(dict(direction=d, omega=float(w), amplitude=ss.amplitude, periods=ss.periods,
                             converged=ss.converged, change=ss.change, steps=ss.steps,
                             rejected=ss.rejected, wall_time=ss.wall_time))
            if progress is not None:
                progress(1)
        finals[d] = z
    return SweepResult(pd.DataFrame(rows), finals)
