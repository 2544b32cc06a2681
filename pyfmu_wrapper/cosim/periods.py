"""The co-simulated steady state at one communication step: whole periods on the master, Newton
shooting on the co-simulated period map, the window criterion (the definition of
:mod:`pyfmu_wrapper.cosim.steady`, which checks the coupling error of what :func:`run_steady`
returns and refines the step).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..master.master import Master
from ..physics.params import InerterModel
from ..physics.unit import SmallForcing
from ..solvers.expm import expm
from ..solvers.harmonic import periodic_max
from ..solvers.hermite import hermite_absmax_series as _hermite_absmax  # the one Hermite maximum of both engines
from ..solvers.monolithic import SolverSettings, companion_start, small_forcing_start
from ..solvers.shooting import shoot
from ..solvers.start import initial_guess
from ..solvers.steady import WindowCriterion
from .settings import CosimSettings
from .system import CosimSystem


@dataclass
class CosimSteadyState:
    omega: float
    amplitude: float
    state: np.ndarray  #: the state at the end (the entries no FMU output shows, the play chain's d, dd: from the start)
    periods: int
    converged: bool
    change: float
    steps: int
    wall_time: float
    period_max: np.ndarray | None = field(repr=False, default=None)
    irregular: bool = False  #: settled into irregular motion; ``change`` is then its scatter
    reason: str = ""  #: why it is not converged ("" when converged)
    coupling_error: float = math.nan  #: estimated relative amplitude error of the coupling (step doubling)
    steps_per_period: int = 0  #: communication steps per forcing period of the reported amplitude
    amplitude_periodic: float = math.nan  #: max |x - mean| of the periodic part (WindowCriterion.periodic) [m]

    def row(self, direction: str) -> dict[str, Any]:
        """The point's row of a sweep table (scenario.sweeptable's columns)."""
        return dict(
            direction=direction,
            omega=float(self.omega),
            amplitude=self.amplitude,
            amplitude_periodic=self.amplitude_periodic,
            periods=self.periods,
            converged=self.converged,
            irregular=self.irregular,
            change=self.change,
            steps=self.steps,
            rejected=0,
            wall_time=self.wall_time,
            reason=self.reason,
            coupling_error=self.coupling_error,
            steps_per_period=self.steps_per_period,
        )


class Periods:
    """Runs whole periods on an initialised master and returns x, xd at the communication points.

    A period is one block of the master's :meth:`~pyfmu_wrapper.master.master.Master.advance`
    (the compiled loop: no Python work per step), recorded into preallocated arrays."""

    def __init__(self, master: Master, n: int, T: float, observed: tuple[str, str]):
        self.m, self.n, self.h = master, n, T / n
        self.ix, self.iv = master.signals.index(observed[0]), master.signals.index(observed[1])
        self.t_rec = np.zeros(n)
        self.y_rec = np.zeros((n + 1, master.nsig))

    def period(self, samples: np.ndarray | None = None) -> float:
        m = self.m
        rec = self.y_rec if samples is None else samples
        rec[0] = m.y
        m.advance(self.n, self.h, self.t_rec, rec[1:])
        self.x = np.ascontiguousarray(rec[:, self.ix])  # x, xd at the communication points of the period
        self.v = np.ascontiguousarray(rec[:, self.iv])
        return _hermite_absmax(self.x, self.v, self.h)


def shot_index(system: CosimSystem) -> np.ndarray:
    """The indices in the unit's state of the states the FMU outputs show (:attr:`~.system.CosimSystem.state_outputs`
    that are not None): the states Newton shooting moves."""
    return np.array([i for i, name in enumerate(system.state_outputs) if name is not None], dtype=np.int64)


def state_of(system: CosimSystem, master: Master, z_guess: np.ndarray) -> np.ndarray:
    """The system's state: the FMU outputs of :attr:`~.system.CosimSystem.state_outputs`, the rest from
    ``z_guess``."""
    s = master.signals
    y = master.y
    z = np.array(z_guess, dtype=float)
    for i, name in enumerate(system.state_outputs):
        if name is not None:
            z[i] = y[s.index(name)]
    return z


def companion_jacobian(system: CosimSystem, omega: float) -> np.ndarray | None:
    """A starting Jacobian D - I of the co-simulated period map at omega [rad/s] for a linear configuration: the
    monodromy matrix D = exp(A T) of the unit's own equations (A: :meth:`~pyfmu_wrapper.physics.unit.ModelUnit.linear_system`,
    exact for a linear configuration) over the shot states. The co-simulation's period map is affine with a D
    that differs from this one by the coupling error only, so Newton from it converges in two or three periods,
    where finite differences take one period per state (a 20-storey frame: 42) and the previous frequency's
    Jacobian, whose lightly damped modes turn with the period, stalls. None for a nonlinear configuration (its
    Jacobian from the previous frequency or finite differences)."""
    unit, structure, tmd = system.unit, system.structure, system.tmd
    if isinstance(unit.start, SmallForcing) or not unit.is_linear(structure, tmd):
        return None
    a, _ = unit.linear_system(structure, tmd)
    at = np.ascontiguousarray(a * (2.0 * math.pi / omega))
    d = np.empty_like(at)
    if expm(at, d) < 0:
        return None
    idx = shot_index(system)
    return d[np.ix_(idx, idx)] - np.eye(idx.size)


def can_shoot(system: CosimSystem) -> bool:
    """Shooting needs the whole state observable at the FMU outputs (not the play chain's d, dd)."""
    return system.tmd.inerter != InerterModel.PLAY


def start(master: Master, system: CosimSystem, omega: float, z: ArrayLike, settings: CosimSettings) -> None:
    master.initialize(0.0, system.parameters(omega, np.asarray(z, dtype=float), settings.fmu_rtol))


def _shoot(
    master: Master,
    system: CosimSystem,
    omega: float,
    z0: np.ndarray,
    settings: CosimSettings,
    run: Periods,
    hint: dict,
) -> Any:
    """Newton shooting (:func:`~pyfmu_wrapper.solvers.shooting.shoot`, the one shared with the
    monolithic solver) on the co-simulated period map z -> z(T) over the states the FMU outputs show
    (the pair's x, xd, y, yd); each evaluation re-initialises the FMUs from z. The Jacobian comes from
    the previous frequency of the sweep (``hint['A']``) or from finite differences. Returns the
    ShootingResult or None."""
    idx = shot_index(system)
    full = np.array(z0, dtype=float)
    z = full[idx]

    def period_map(zz: np.ndarray) -> tuple[np.ndarray, float]:
        full[idx] = zz
        start(master, system, omega, full, settings)
        a = run.period()
        return state_of(system, master, full)[idx], a

    jac = companion_jacobian(system, omega)
    jac = hint.get("A") if jac is None else jac
    res = shoot(period_map, z, system.shooting_scale(z, omega), settings.tol, settings.max_newton, jac)
    if res is None:
        hint.pop("A", None)
    else:
        hint["A"] = res.jacobian
    return res


def run_steady(
    master: Master,
    system: CosimSystem,
    omega: float,
    z0: ArrayLike | None,
    settings: CosimSettings,
    hint: dict | None,
    n: int,
) -> CosimSteadyState:
    """Co-simulated steady state at omega [rad/s] with ``n`` communication steps per period, no
    check of the coupling error (that is :func:`pyfmu_wrapper.cosim.steady.steady_state`).

    Window 1 without play: Newton shooting on the co-simulated period map (``settings.shooting``,
    :func:`~pyfmu_wrapper.solvers.shooting.shoot`, shared with the monolithic solver), the
    amplitude is max |x| over the period started from the converged state; otherwise
    (or if Newton fails) period after period until the window criterion holds.
    hint: a dict carried along a sweep (the shooting Jacobian)."""
    t_start = time.perf_counter()
    hint = {} if hint is None else hint
    unit, base, tmd = system.unit, system.structure, system.tmd
    W = settings.window_for(tmd)
    if W > 1 and settings.play_start == "companion":
        # the play model starts from the orbit of its smooth companion (ideal inerter), as in the
        # monolithic solver: the windows then settle in about two (see companion_start)
        z = companion_start(
            unit, base, tmd, omega, SolverSettings(rtol=1e-8, atol_scale=1e-8), hint.setdefault("monolithic", {})
        )
    else:
        if z0 is None:
            z = start_state(system, omega)
        else:  # the states no FMU output shows (the play chain's d, dd) from the start state
            z = np.array(z0, dtype=float)
            if tmd.inerter == InerterModel.PLAY:
                shown = shot_index(system)
                z = np.where(np.isin(np.arange(z.size), shown), z, start_state(system, omega))
    T = 2.0 * math.pi / omega
    run = Periods(master, n, T, system.observed)
    steps = 0
    if W == 1 and settings.shooting and can_shoot(system):
        res = _shoot(master, system, omega, z, settings, run, hint)
        if res is not None:  # the master stands at the end of the period from res.z
            return CosimSteadyState(
                omega=float(omega),
                amplitude=res.amplitude,
                state=state_of(system, master, z),
                periods=res.periods,
                converged=True,
                change=res.change,
                steps=res.periods * n,
                wall_time=time.perf_counter() - t_start,
                period_max=np.array([res.amplitude]),
                steps_per_period=n,
                amplitude_periodic=periodic_max(run.x[:-1]),  # the last map call was from res.z
            )
        steps = 0
    start(master, system, omega, z, settings)
    crit = WindowCriterion.from_settings(settings, W, base, omega)
    ix, iv = master.signals.index(system.observed[0]), master.signals.index(system.observed[1])
    if W == 1:
        crit.add(abs(master.y[ix]), (master.y[ix], master.y[iv]))  # the start, for the first residual
        crit.period_max.clear()
    k = 0
    while k < crit.max_periods:
        k += 1
        if crit.add(run.period(), (master.y[ix], master.y[iv]), run.x[:-1]):
            break
    amplitude, converged, change = crit.result()
    return CosimSteadyState(
        omega=float(omega),
        amplitude=amplitude,
        state=state_of(system, master, z),
        periods=k,
        converged=converged,
        change=change,
        steps=steps + k * n,
        wall_time=time.perf_counter() - t_start,
        period_max=np.array(crit.period_max),
        irregular=crit.irregular,
        reason=_window_reason(crit, k, converged, change),
        steps_per_period=n,
        amplitude_periodic=crit.periodic(),
    )


def start_state(system: CosimSystem, omega: float) -> np.ndarray:
    """The start of a periodic solution at omega [rad/s] with no better one at hand: the one the model's
    unit declares (:func:`~pyfmu_wrapper.solvers.start.initial_guess`: a linear companion's exact steady
    state; for a unit that continues from small forcing, the monolithic solver's continuation)."""
    unit = system.unit
    if isinstance(unit.start, SmallForcing):
        return small_forcing_start(
            unit, system.structure, system.tmd, omega, SolverSettings(rtol=1e-8, atol_scale=1e-8)
        )
    return initial_guess(unit, system.structure, system.tmd, omega)


def _window_reason(crit: WindowCriterion, periods: int, converged: bool, change: float) -> str:
    """Why a period-after-period run is not converged ("" when it is)."""
    if converged:
        return ""
    if crit.irregular:
        return f"irregular response: the window maxima scatter by {change:.3g} (more than scatter_tol)"
    return f"no steady state within max_periods = {periods} periods (last relative change {change:.3g})"
