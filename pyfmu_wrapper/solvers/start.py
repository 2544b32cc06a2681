"""Start states and tolerances shared by both engines (the monolithic solver and the co-simulation).

The start of a windowed (play) solve, :func:`~.monolithic.companion_start`, runs the monolithic solver and
lives there (the co-simulation imports it from the monolithic engine).

* :func:`initial_guess`: the exact steady state of the nearest linear configuration;
* :func:`play_atol`: the absolute tolerance on the gear-chain deflection of the play model, used by
  the monolithic integrator and the TMD FMU alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..physics.params import BaseParams, TMDParams
from ..physics.tmd import chain_atol


def play_atol(base: BaseParams, tmd: TMDParams) -> float:
    """Absolute tolerance [m] on the gear-chain deflection d of the play model, shared by both
    engines (the monolithic integrator and the TMD FMU): :func:`~pyfmu_wrapper.physics.tmd.chain_atol`."""
    return chain_atol(base.force_amplitude, tmd)


def initial_guess(base: Any, tmd: TMDParams, omega: float) -> np.ndarray:
    """A starting state: the exact steady state of the nearest linear configuration (friction and
    gap removed), which is the right answer in the linear case and a close one otherwise."""
    from dataclasses import replace

    from .frequency_response import exact_state

    # (exact_response itself handles an undamped companion exactly at a resonance)
    return exact_state(base, replace(tmd, friction_force=0.0, play_gap=0.0, cubic_stiffness=0.0), omega)
