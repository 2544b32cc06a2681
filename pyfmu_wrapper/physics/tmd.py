"""The paper's TMD-inerter as an element that any structure carries: the absolute tolerance of its play
chain (shared by the monolithic integrator and the TMD FMU), whether it floats, and the states a period
map's Newton iteration moves when a structure carries it at z[2:6]."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._jit import njit
from .params import P_F, P_I, P_MODEL, InerterModel, P_eps, P_ki, TMDParams, has_gap

_PLAY = int(InerterModel.PLAY)


@njit(cache=True)
def chain_tolerance(force_amplitude: float, mesh_stiffness: float, play_gap: float) -> float:
    """Absolute tolerance [m] on the gear-chain deflection d of the play model, shared by both
    engines (the monolithic integrator and the TMD FMU): the gear penetration is ~ F / ki, so
    resolve it, not just the gap: 1e-3 of the larger of gap and penetration, plus the penetration."""
    pen = max(abs(force_amplitude) / mesh_stiffness, 1e-12)
    return 1e-3 * max(play_gap, pen) + pen


def chain_atol(force_amplitude: float, tmd: TMDParams) -> float:
    """:func:`chain_tolerance` of a TMD."""
    return float(chain_tolerance(float(force_amplitude), float(tmd.mesh_stiffness), float(tmd.play_gap)))


def tmd_atol(atol: NDArray[np.float64], force_amplitude: float, tmd: TMDParams) -> None:
    """Tighten the chain's entries atol[4], atol[5] for the play model with a gap (in place)."""
    if has_gap(tmd):
        atol[4] = min(atol[4], chain_atol(force_amplitude, tmd))
        atol[5] = atol[4] * math.sqrt(tmd.mesh_stiffness / tmd.inertance)


@njit(cache=True)
def packed_tmd_atol(p: NDArray[np.float64], atol: NDArray[np.float64]) -> None:
    """:func:`tmd_atol` on the packed parameters (the compiled tolerances of a structure carrying the TMD at
    z[2:6]: the FMUs' integrators and nominal values)."""
    if int(p[P_MODEL]) == _PLAY and p[P_eps] > 0.0:
        atol[4] = min(atol[4], chain_tolerance(p[P_F], p[P_ki], p[P_eps]))
        atol[5] = atol[4] * math.sqrt(p[P_ki] / p[P_I])


def detached(tmd: TMDParams) -> bool:
    """The TMD has no link to the structure (no spring, damper, friction or inerter): it floats."""
    return (
        tmd.stiffness == 0.0
        and tmd.cubic_stiffness == 0.0
        and tmd.damping == 0.0
        and tmd.friction_force == 0.0
        and tmd.inertance == 0.0
    )


def active_states(tmd: TMDParams, n: int) -> list[int]:
    """The states the shooting moves: all with the play chain, else all but the chain's d, dd; a
    detached TMD's none of z[2:6] (it floats: its period map has the eigenvalue 1, no fixed point to
    solve for, and the structure does not feel it)."""
    if detached(tmd):
        return [i for i in range(n) if not 2 <= i < 6]
    return list(range(n)) if tmd.inerter == InerterModel.PLAY else [i for i in range(n) if i not in (4, 5)]


def tmd_companion(structure: Any, tmd: TMDParams) -> tuple[Any, TMDParams]:
    """The linear configuration nearest a structure with the paper's TMD: the TMD without friction, play
    gap and cubic spring (the start of its periodic solutions)."""
    return structure, replace(tmd, friction_force=0.0, play_gap=0.0, cubic_stiffness=0.0)
