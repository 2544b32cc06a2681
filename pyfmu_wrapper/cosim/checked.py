"""The coupling-error check of a co-simulated steady state: step doubling.

The amplitude A_N found with N communication steps per forcing period is held against the
amplitude of the same steady state with N/2 steps (or with the N of the previous, coarser try).
Their gap, relative to max(A_N, :data:`AMPLITUDE_FLOOR` |F|/K) (an antiresonance whose amplitude
is zero to rounding has no relative error), is the estimate of the relative error of A_N: the
error of A_N itself for a method of order p is gap / (2^p - 1), so the gap over-estimates it for
every p >= 1 (the impulse coupling of order 2 measures p = 1.6-2.7 on light bases, where the
Richardson divisor 2^2 - 1 of its nominal order would under-estimate: docs/cosimulation.md).

* Smooth configurations (Newton shooting): the N/2 steady state by Newton from the converged
  orbit with the Jacobian of the N run (:func:`coarse_amplitude`): two periods at N/2, one period's
  cost at N.
* The play model (the gear chain's states are not FMU outputs, no shooting), where its rattle
  error model was calibrated (:func:`check_mode`: the paper's inerter-to-base mass ratios, I/M <=
  :data:`PLAY_CALIBRATED_RATIO`, and a step set by the accuracy model): the coupling error of its
  smooth companion (the same links with an ideal inerter; the coupling, the structure and the
  step are the same, the rattle is what the play model adds and its error model covers, see
  :func:`~pyfmu_wrapper.cosim.settings.steps_for_accuracy`), by shooting at N and N/2
  (:func:`companion_error`), computed before the play run so that the master stands at the end
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
from ..physics.params import BaseParams, InerterModel, TMDParams
from ..solvers.shooting import shoot
from ..solvers.start import initial_guess
from .periods import CosimSteadyState, Periods, can_shoot, run_steady, start, state_of
from .settings import CosimSettings

#: the largest inerter-to-base mass ratio I/M of the configurations the play model's rattle error
#: model was fitted on (the paper's Cases 1-3 on the 100 kg base: 0.01-0.09)
PLAY_CALIBRATED_RATIO = 0.1
#: amplitudes below this fraction of the static deflection |F|/K count as this much in the relative
#: error (the undamped antiresonance is zero to rounding)
AMPLITUDE_FLOOR = 1e-4


def check_mode(base: BaseParams, tmd: TMDParams, settings: CosimSettings, limited_by: str) -> str:
    """How a point's coupling error is estimated (module doc): "own" (shooting, smooth
    configurations), "companion" (the play model where its error model holds) or "doubling" (the
    play run itself at N/2 and N)."""
    if can_shoot(tmd) and settings.window_for(tmd) == 1:
        return "own"
    ratio = float(tmd.inertance) / float(base.mass)
    if limited_by == "accuracy" and ratio <= PLAY_CALIBRATED_RATIO:
        return "companion"
    return "doubling"


def relative_gap(fine: float, coarse: float, base: BaseParams) -> float:
    """The estimated relative error of ``fine`` from its gap to ``coarse`` (half the steps)."""
    if not (math.isfinite(fine) and math.isfinite(coarse)):
        return math.inf
    scale = max(abs(fine), AMPLITUDE_FLOOR * abs(base.force_amplitude) / base.stiffness)
    if scale == 0.0:
        return 0.0 if fine == coarse else math.inf
    return abs(fine - coarse) / scale


def coarse_amplitude(
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    ss: CosimSteadyState,
    settings: CosimSettings,
    jacobian: np.ndarray | None,
    n: int,
) -> float:
    """The steady-state amplitude with ``n`` steps per period, found from the steady state ``ss`` (of
    another step count) by Newton on the period map with ``jacobian`` (D - I of the ``ss`` run), or
    by :func:`~pyfmu_wrapper.solvers.shooting.shoot` with finite differences when there is none.
    NaN when Newton fails."""
    T = 2.0 * math.pi / omega
    run = Periods(master, n, T)
    z = np.array(ss.state[:4], dtype=float)
    tail = np.asarray(ss.state[4:6], dtype=float)
    scale = max(
        math.hypot(z[0], z[1] / omega),
        math.hypot(z[2], z[3] / omega),
        1e-6 * abs(base.force_amplitude) / base.stiffness,
    )
    zs = np.array([scale, scale * omega, scale, scale * omega])

    def period_map(zz: np.ndarray) -> tuple[np.ndarray, float]:
        start(master, base, tmd, omega, np.concatenate([zz, tail]), settings)
        a = run.period()
        return state_of(master, np.zeros(6))[:4], a

    if jacobian is None or np.shape(jacobian) != (4, 4):
        res = shoot(period_map, z, zs, settings.tol, settings.max_newton, None)
        return math.nan if res is None else float(res.amplitude)
    a = math.nan
    for _ in range(4):
        zT, a = period_map(z)
        g = zT - z
        if float(np.max(np.abs(g) / np.maximum(np.abs(z), zs))) <= 10.0 * settings.tol:
            return float(a)
        try:
            z = z - np.linalg.solve(jacobian, g)
        except np.linalg.LinAlgError:
            return math.nan
        if not np.all(np.isfinite(z)):
            return math.nan
    return float(a)


def own_error(
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    ss: CosimSteadyState,
    settings: CosimSettings,
    hint: dict,
    previous: tuple[int, float] | None,
) -> float:
    """Step-doubling estimate of a smooth steady state's coupling error (module doc); ``previous``:
    (steps, amplitude) of a run with half the steps, if there was one. The master is left
    re-initialised at ``ss.state`` (the fine orbit)."""
    n = ss.steps_per_period
    if previous is not None and previous[0] * 2 == n:
        return relative_gap(ss.amplitude, previous[1], base)
    a = coarse_amplitude(master, base, tmd, omega, ss, settings, hint.get("A"), max(n // 2, 4))
    start(master, base, tmd, omega, ss.state, settings)
    return relative_gap(ss.amplitude, a, base)


def companion(tmd: TMDParams) -> TMDParams:
    """The smooth companion of a play model: the same links with an ideal inerter."""
    return replace(tmd, inerter=InerterModel.IDEAL, play_gap=0.0)


def companion_error(
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    settings: CosimSettings,
    hint: dict,
    n: int,
) -> float:
    """Step-doubling estimate of the coupling error of the smooth companion of a play model at ``n``
    steps per period (shooting at n, then n/2 from its orbit). The companion's orbit and Jacobian
    are carried along a sweep in ``hint['companion_cosim']``."""
    ideal = companion(tmd)
    sub: dict[str, Any] = hint.setdefault("companion_cosim", {})
    z0 = sub.get("z")
    if z0 is None or sub.get("omega") is None:
        z = initial_guess(base, ideal, omega)
    else:
        z = np.asarray(z0, float) + initial_guess(base, ideal, omega) - initial_guess(base, ideal, sub["omega"])
    smooth = replace(settings, window=1, shooting=True)
    ss = run_steady(master, base, ideal, omega, z, smooth, sub, n)
    sub["z"], sub["omega"] = ss.state.copy(), float(omega)
    coarse = coarse_amplitude(master, base, ideal, omega, ss, smooth, sub.get("A"), max(n // 2, 4))
    return relative_gap(ss.amplitude, coarse, base)
