"""The coupling-error check of a co-simulated steady state: step doubling.

The amplitude A_N found with N communication steps per forcing period is held against the
amplitude of the same steady state with N/2 steps (or with the N of the previous, coarser try).
Their gap, relative to max(A_N, :data:`AMPLITUDE_FLOOR` |F|/K) (an antiresonance whose amplitude
is zero to rounding has no relative error), is the estimate of the relative error of A_N: the
error of A_N itself for a method of order p is gap / (2^p - 1), so the gap over-estimates it for
every p >= 1 (the impulse coupling of order 2 measures p = 1.6-2.7 on light bases, where the
Richardson divisor 2^2 - 1 of its nominal order would under-estimate: docs/cosimulation.md).

* Smooth configurations (Newton shooting): the N/2 steady state by Newton from the converged
  orbit with the Jacobian of the N run (:func:`coarse_amplitude`): one or two periods at N/2 (the
  Newton correction, times :data:`START_SENSITIVITY`, is added to the estimate when it stops early).
* The play model (the gear chain's states are not FMU outputs, no shooting), where its rattle
  error model was calibrated (:func:`check_mode`: the paper's inerter-to-base mass ratios, I/M <=
  :data:`PLAY_CALIBRATED_RATIO`; a step the structure makes finer than the model's only helps the
  rattle): the coupling error of its
  smooth companion (the same links with an ideal inerter; the coupling, the structure and the
  step are the same, the rattle is what the play model adds and its error model covers, see
  :func:`~pyfmu_wrapper.cosim.settings.steps_for_accuracy`), by shooting at N and N/2
  (:func:`companion_error`; the gap relative to the play model's amplitude), computed before the play run so that the master stands at the end
  of the play run afterwards. Outside it (a light base under a rattling inerter: 0.1 kg under
  Case 1's 1 kg inerter was 1.4 % off with a companion 5e-5 off) the play run itself at N/2 and
  N, the costly check.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..master.master import Master
from ..physics.params import InerterModel, TMDParams
from ..solvers.shooting import shoot
from .periods import CosimSteadyState, Periods, can_shoot, run_steady, shot_index, start, start_state, state_of
from .settings import CosimSettings
from .system import CosimSystem

#: the largest inerter-to-base mass ratio I/M of the configurations the play model's rattle error
#: model was fitted on (the paper's Cases 1-3 on the 100 kg base: 0.01-0.09)
PLAY_CALIBRATED_RATIO = 0.1
#: amplitudes below this fraction of the static deflection |F|/K count as this much in the relative
#: error (the undamped antiresonance is zero to rounding)
AMPLITUDE_FLOOR = 1e-4


def check_mode(system: CosimSystem, settings: CosimSettings) -> str:
    """How a point's coupling error is estimated (module doc): "own" (shooting, smooth
    configurations), "companion" (the play model where its error model holds) or "doubling" (the
    play run itself at N/2 and N)."""
    tmd = system.tmd
    if can_shoot(system) and settings.window_for(tmd) == 1:
        return "own"
    if float(tmd.inertance) / float(system.reaction_mass()) <= PLAY_CALIBRATED_RATIO:
        return "companion"
    return "doubling"


def relative_gap(fine: float, coarse: float, base: Any, amplitude: float | None = None) -> float:
    """The estimated relative error of ``fine`` from its gap to ``coarse`` (half the steps), relative
    to ``amplitude`` (default ``fine``) or the floor of the structure ``base`` (:data:`AMPLITUDE_FLOOR` |F|/K)."""
    amp = fine if amplitude is None else amplitude
    if not (math.isfinite(fine) and math.isfinite(coarse) and math.isfinite(amp)):
        return math.inf
    scale = max(abs(amp), AMPLITUDE_FLOOR * abs(base.force_amplitude) / base.stiffness)
    if scale == 0.0:
        return 0.0 if fine == coarse else math.inf
    return abs(fine - coarse) / scale


#: bound on |A* - A_1| / (A_N |delta|) (A_1: the period's maximum from a start whose Newton
#: correction to the coarse orbit is delta, relative; A*: the coarse orbit's): measured at most
#: 1.54 over Case 1 (c = 0, 15, df = 10) and a 0.001 kg base, 15-25 rad/s, taken with a margin
START_SENSITIVITY = 4.0
#: Newton on the coarse period map stops when the estimate (gap plus the bound above) is within this
#: fraction of the tolerance: the point passes, and the estimate it reports stays informative
DECIDED = 0.2


def coarse_amplitude(
    master: Master,
    system: CosimSystem,
    omega: float,
    ss: CosimSteadyState,
    settings: CosimSettings,
    jacobian: np.ndarray | None,
    n: int,
    tol: float = 0.0,
) -> tuple[float, float]:
    """The steady-state amplitude with ``n`` steps per period, found from the steady state ``ss`` (of
    another step count) by Newton on the period map with ``jacobian`` (D - I of the ``ss`` run), or
    by :func:`~pyfmu_wrapper.solvers.shooting.shoot` with finite differences when there is none;
    and a bound on how far it may be from the coarse orbit's (:data:`START_SENSITIVITY` times the
    last Newton correction). Newton stops as soon as the gap to ``ss.amplitude`` plus that bound is
    within :data:`DECIDED` ``tol`` (relative) or the correction is within 1 % of
    ``coupling_tol``. (NaN, 0) when Newton fails."""
    T = 2.0 * math.pi / omega
    base = system.structure
    run = Periods(master, n, T, system.observed)
    idx = shot_index(system)
    m = idx.size
    full = np.array(ss.state, dtype=float)
    z = full[idx]
    zs = system.shooting_scale(z, omega)

    def period_map(zz: np.ndarray) -> tuple[np.ndarray, float]:
        full[idx] = zz
        start(master, system, omega, full, settings)
        a = run.period()
        return state_of(system, master, full)[idx], a

    if jacobian is None or np.shape(jacobian) != (m, m):
        res = shoot(period_map, z, zs, settings.tol, settings.max_newton, None)
        return (math.nan, 0.0) if res is None else (float(res.amplitude), 0.0)
    enough = max(10.0 * settings.tol, 1e-2 * settings.coupling_tol)
    fine = abs(ss.amplitude)
    a = u = math.nan
    for _ in range(4):
        zT, a = period_map(z)
        try:
            delta = -np.linalg.solve(jacobian, zT - z)
        except np.linalg.LinAlgError:
            return math.nan, 0.0
        if not np.all(np.isfinite(delta)):
            return math.nan, 0.0
        d = float(np.max(np.abs(delta) / np.maximum(np.abs(z), zs)))
        u = START_SENSITIVITY * d * fine
        if d <= enough or relative_gap(ss.amplitude, a, base) + u / max(fine, 1e-300) <= DECIDED * tol:
            return float(a), u
        z = z + delta
    return float(a), u


def own_error(
    master: Master,
    system: CosimSystem,
    omega: float,
    ss: CosimSteadyState,
    settings: CosimSettings,
    hint: dict,
    previous: tuple[int, float] | None,
    restart: bool = True,
) -> float:
    """Step-doubling estimate of a smooth steady state's coupling error (module doc); ``previous``:
    (steps, amplitude) of a run with half the steps, if there was one. With ``restart`` the master
    is left re-initialised at ``ss.state`` (the fine orbit, for a time series that follows)."""
    n = ss.steps_per_period
    base = system.structure
    if previous is not None and previous[0] * 2 == n:
        return relative_gap(ss.amplitude, previous[1], base)
    tol = settings.coupling_tolerance(system.tmd)
    a, u = coarse_amplitude(master, system, omega, ss, settings, hint.get("A"), max(n // 2, 4), tol)
    if restart:
        start(master, system, omega, ss.state, settings)
    floor = AMPLITUDE_FLOOR * abs(base.force_amplitude) / base.stiffness
    return relative_gap(ss.amplitude, a, base) + u / max(abs(ss.amplitude), floor, 1e-300)


def companion(tmd: TMDParams) -> TMDParams:
    """The smooth companion of a play model: the same links with an ideal inerter."""
    return replace(tmd, inerter=InerterModel.IDEAL, play_gap=0.0)


def companion_error(
    master: Master,
    system: CosimSystem,
    omega: float,
    settings: CosimSettings,
    hint: dict,
    n: int,
) -> tuple[float, float]:
    """The smooth companion of a play model at ``n`` steps per period and at n/2 (shooting at n, then
    n/2 from its orbit): its two amplitudes, whose gap the caller holds against the play model's
    own amplitude (the companion's antiresonance, zero to rounding, is not the play model's: it
    rattles there). The companion's orbit and Jacobian are carried along a sweep in
    ``hint['companion_cosim']``."""
    ideal = system.with_tmd(companion(system.tmd))
    sub: dict[str, Any] = hint.setdefault("companion_cosim", {})
    z0 = sub.get("z")
    if z0 is None or sub.get("omega") is None:
        z = start_state(ideal, omega)
    else:
        z = np.asarray(z0, float) + start_state(ideal, omega) - start_state(ideal, sub["omega"])
    smooth = replace(settings, window=1, shooting=True)
    ss = run_steady(master, ideal, omega, z, smooth, sub, n)
    sub["z"], sub["omega"] = ss.state.copy(), float(omega)
    coarse, u = coarse_amplitude(master, ideal, omega, ss, smooth, sub.get("A"), max(n // 2, 4))
    return ss.amplitude, coarse + math.copysign(u, coarse - ss.amplitude)
