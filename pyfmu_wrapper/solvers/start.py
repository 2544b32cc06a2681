"""Start states and tolerances shared by both engines (the monolithic solver and the co-simulation).

The start of a windowed (play) solve, :func:`~.monolithic.companion_start`, runs the monolithic solver and
lives there (the co-simulation imports it from the monolithic engine).

* :func:`initial_guess`: the start a model's unit declares (a linear companion's exact steady state, or the
  small-amplitude limit);
* :func:`play_atol`: the absolute tolerance on the gear-chain deflection of the play model, used by
  the monolithic integrator and the TMD FMU alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..physics.params import BaseParams, TMDParams
from ..physics.tmd import chain_atol
from ..physics.unit import ModelUnit, SmallForcing


def play_atol(base: BaseParams, tmd: TMDParams) -> float:
    """Absolute tolerance [m] on the gear-chain deflection d of the play model, shared by both
    engines (the monolithic integrator and the TMD FMU): :func:`~pyfmu_wrapper.physics.tmd.chain_atol`."""
    return chain_atol(base.force_amplitude, tmd)


def initial_guess(unit: ModelUnit, base: Any, tmd: TMDParams, omega: float) -> np.ndarray:
    """A starting state of a periodic solution at omega [rad/s], as the unit declares (``unit.start``):

    * :class:`~pyfmu_wrapper.physics.unit.LinearCompanion`: the exact steady state of the linear
      configuration nearest the model's (the paper's TMD without friction, gap and cubic term): the right
      answer in the linear case and a close one otherwise;
    * :class:`~pyfmu_wrapper.physics.unit.SmallForcing`: the exact steady state of the linearisation about
      rest, the small-amplitude limit (the monolithic solver then continues it from a small force to the
      structure's own, :func:`~pyfmu_wrapper.solvers.monolithic.steady_state`)."""
    from .frequency_response import exact_state

    start = unit.start
    if isinstance(start, SmallForcing):
        return exact_state(unit, base, tmd, omega, linearise=True)
    # (exact_response itself handles an undamped companion exactly at a resonance)
    structure, linear = start.companion(base, tmd)
    return exact_state(unit, structure, linear, omega)
