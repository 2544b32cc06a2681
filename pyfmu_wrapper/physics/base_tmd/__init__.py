"""The paper's model as a unit: the base oscillator with the TMD-inerter (Brzeski & Perlikowski 2017).

State z = [x, xd, y, yd, d, dd] (:mod:`~pyfmu_wrapper.physics.kernels`), parameters
:class:`~pyfmu_wrapper.physics.params.BaseParams` and :class:`~pyfmu_wrapper.physics.params.TMDParams`,
equations :data:`~pyfmu_wrapper.physics.models.COUPLED`, Modelica source and the paper's cases in
:mod:`.modelica`. Registered in :mod:`pyfmu_wrapper.physics.units`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .. import registry
from ..kernels import NSTATE, inerter_force, rhs
from ..models import COUPLED
from ..params import BaseParams, InerterModel, TMDParams, has_gap, pack
from ..unit import ModelUnit
from .modelica import MODELICA


def chain_atol(force_amplitude: float, tmd: TMDParams) -> float:
    """Absolute tolerance [m] on the gear-chain deflection d of the play model, shared by both
    engines (the monolithic integrator and the TMD FMU): the gear penetration is ~ F / ki, so
    resolve it, not just the gap: 1e-3 of the larger of gap and penetration, plus the penetration."""
    pen = max(abs(force_amplitude) / tmd.mesh_stiffness, 1e-12)
    return 1e-3 * max(tmd.play_gap, pen) + pen


def tmd_atol(atol: NDArray[np.float64], force_amplitude: float, tmd: TMDParams) -> None:
    """Tighten the chain's entries atol[4], atol[5] for the play model with a gap (in place)."""
    if has_gap(tmd):
        atol[4] = min(atol[4], chain_atol(force_amplitude, tmd))
        atol[5] = atol[4] * math.sqrt(tmd.mesh_stiffness / tmd.inertance)


def _atol(base: BaseParams, tmd: TMDParams, omega: float, atol_scale: float) -> NDArray[np.float64]:
    xs = abs(base.force_amplitude) / max(base.stiffness, 1e-300)
    xs = xs if xs > 0 else 1e-3
    wn = max(omega, base.natural_frequency, 1.0)
    a = atol_scale * xs
    atol = np.array([a, a * wn, a, a * wn, a, a * wn])
    tmd_atol(atol, base.force_amplitude, tmd)
    return atol


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


def _inerter_force(z: NDArray[np.float64], p: NDArray[np.float64]) -> float:
    f = np.empty(NSTATE)
    rhs(0.0, z, p, f)
    return float(inerter_force(z, f[1], p))


UNIT = ModelUnit(
    name="base_tmd",
    ode=COUPLED,
    structure=BaseParams,
    parameters=registry.of("base"),
    pack=pack,
    n_state=lambda base: NSTATE,
    atol=_atol,
    active=lambda base, tmd: active_states(tmd, NSTATE),
    inerter_force=_inerter_force,
    description="the paper's base oscillator with the TMD-inerter (one storey, one TMD)",
    cosim="pyfmu_wrapper.cosim.steady",
    fmus=("pyfmu_wrapper.physics.base_tmd.fmus.base_oscillator", "pyfmu_wrapper.physics.base_tmd.fmus.tmd_inerter"),
    example=BaseParams,
    modelica=MODELICA,
    scenario_block="base",
    scenario_reader="pyfmu_wrapper.scenario.loader:read_base",
)
