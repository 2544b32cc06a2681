"""Start states and tolerances shared by both engines (the monolithic solver and the co-simulation).

* :func:`initial_guess`: the exact steady state of the nearest linear configuration;
* :func:`companion_start`: the start of a windowed (play) solve, the periodic orbit of the smooth
  companion with the gear chain at its contact (computed by the monolithic solver);
* :func:`play_atol`: the absolute tolerance on the gear-chain deflection of the play model, used by
  the monolithic integrator and the TMD FMU alike.
"""
from __future__ import annotations

import math

import numpy as np

from ..physics.kernels import NSTATE, inerter_force, rhs
from ..physics.params import BaseParams, InerterModel, TMDParams, pack


def play_atol(base: BaseParams, tmd: TMDParams) -> float:
    """Absolute tolerance [m] on the gear-chain deflection d of the play model, shared by both
    engines (the monolithic integrator and the TMD FMU): the gear penetration is ~ F / ki, so
    resolve it, not just the gap: 1e-3 of the larger of gap and penetration, plus the penetration."""
    pen = max(abs(base.force_amplitude) / tmd.mesh_stiffness, 1e-12)
    return 1e-3 * max(tmd.play_gap, pen) + pen


def companion_start(base: BaseParams, tmd: TMDParams, omega: float, settings,
                    hint: dict | None = None) -> np.ndarray:
    """Start state for the play model: the periodic orbit of its smooth companion (the same
    links with an ideal inerter), with the gear chain at the contact the ideal inerter force
    asks for (d = sign(P) (eps + |P| / ki), dd = 0).

    The play response differs from the companion's only by the rattling, so the windowed
    steady state settles in about two windows from here, where a start from the previous
    frequency's state drags a transient that decays with the 2.5 %-damped base (~100 periods).
    With ``hint`` (carried along a sweep) the companion orbit itself is continued.
    """
    from dataclasses import replace

    from .monolithic import steady_state  # the monolithic engine computes the companion orbit

    ideal = replace(tmd, inerter=InerterModel.IDEAL, play_gap=0.0)
    sub = None if hint is None else hint.setdefault("companion", {})
    z0 = None if sub is None else sub.get("z")
    ss = steady_state(base, ideal, omega, z0, replace(settings, window=1), sub)
    z = ss.state.copy() if ss.converged else initial_guess(base, ideal, omega)
    if sub is not None and ss.converged:
        sub["z"] = ss.state.copy()
    p = pack(base, ideal, omega)
    f = np.empty(NSTATE)
    rhs(0.0, z, p, f)
    P = inerter_force(z, f[1], p)
    z[4] = math.copysign(tmd.play_gap + abs(P) / tmd.mesh_stiffness, P)
    z[5] = 0.0
    return z


def initial_guess(base: BaseParams, tmd: TMDParams, omega: float) -> np.ndarray:
    """A starting state: the exact steady state of the nearest linear configuration (friction and
    gap removed), which is the right answer in the linear case and a close one otherwise."""
    from dataclasses import replace

    from .frequency_response import exact_state

    # (exact_response itself handles an undamped companion exactly at a resonance)
    return exact_state(base, replace(tmd, friction_force=0.0, play_gap=0.0, cubic_stiffness=0.0), omega)
