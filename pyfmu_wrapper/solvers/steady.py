"""The steady-state definition shared by both engines: its settings and the window criterion.

:class:`SteadySettings` holds the settings every engine's steady state reads (tolerances, the
window, period bounds, the play start, shooting) and validates them in one place;
:class:`~pyfmu_wrapper.solvers.monolithic.SolverSettings` (the monolithic engine) and
:class:`~pyfmu_wrapper.cosim.settings.CosimSettings` (the co-simulation engine) extend it with
their own accuracy settings. :func:`default_window` and :class:`WindowCriterion` are the rule
both engines apply to the per-period maxima of |x| (see the module doc of
:mod:`pyfmu_wrapper.solvers.monolithic`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from ..physics.params import TMDParams, has_gap
from . import settings_table as _table
from .harmonic import periodic_max
from .settings_table import MONO

#: where a windowed solve starts (SteadySettings.play_start)
PLAY_STARTS = ("companion", "previous")


class SettingsError(InputError):
    """A settings value out of its range: ``field`` names it, ``value`` is the value, ``reason`` says why."""

    def __init__(self, owner: str, field: str, value: Any, reason: str) -> None:
        super().__init__(f"{owner}.{field} = {value!r}: {reason}")
        self.owner, self.field, self.value, self.reason = owner, field, value, reason


def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)


class Checks:
    """Range checks of one settings object; each failure raises :class:`SettingsError` naming the field."""

    def __init__(self, obj: Any) -> None:
        self.obj, self.owner = obj, type(obj).__name__

    def fail(self, name: str, reason: str) -> NoReturn:
        raise SettingsError(self.owner, name, getattr(self.obj, name), reason)

    def number(self, name: str, positive: bool = False, optional: bool = False) -> None:
        v = getattr(self.obj, name)
        if optional and v is None:
            return
        if not _is_number(v) or v < 0 or (positive and v == 0):
            self.fail(name, "must be a finite number " + ("> 0" if positive else ">= 0"))

    def integer(self, name: str, minimum: int, optional: bool = False) -> None:
        v = getattr(self.obj, name)
        if optional and v is None:
            return
        if not _is_int(v) or v < minimum:
            self.fail(name, f"must be an integer >= {minimum}")

    def choice(self, name: str, choices: Iterable[Any]) -> None:
        if getattr(self.obj, name) not in choices:
            self.fail(name, f"must be one of {', '.join(map(str, choices))}")

    def boolean(self, name: str) -> None:
        if not isinstance(getattr(self.obj, name), (bool, np.bool_)):
            self.fail(name, "must be true or false")


def default_window(tmd: TMDParams, window: int | None = None) -> int:
    """Periods per steady-state window: ``window`` if given, else 20 for the play model with a gap
    (never exactly periodic) and 1 otherwise (periodic). Shared by every engine."""
    if window is not None:
        return int(window)
    return 20 if has_gap(tmd) else 1


@dataclass(frozen=True)
class SteadySettings:
    """Steady-state settings shared by both engines (validated on construction).

    tol: steady-state tolerance of a periodic response (window 1: Newton correction or distance
    to the orbit, relative); tol_window: agreement of two window maxima (window > 1); window: periods
    per window (None: :func:`default_window`); min_periods / max_periods: bounds per frequency;
    scatter_tol: the largest scatter of the window maxima an irregular response may have and
    still count as converged; play_start: where a windowed solve starts, "companion" (the
    periodic orbit of the same system with an ideal inerter, gear chain at its contact) or
    "previous" (the previous frequency's state); shooting / max_newton: Newton shooting for
    window 1 and its iteration cap. Each engine's settings class sets its own defaults.
    """

    tol: float = _table.default("tol", MONO)
    tol_window: float = _table.default("tol_window", MONO)
    window: int | None = _table.default("window", MONO)
    min_periods: int = _table.default("min_periods", MONO)
    max_periods: int = _table.default("max_periods", MONO)
    scatter_tol: float = _table.default("scatter_tol", MONO)
    play_start: str = _table.default("play_start", MONO)
    shooting: bool = _table.default("shooting", MONO)
    max_newton: int = _table.default("max_newton", MONO)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`SettingsError` on the first value out of range: the rule of every field is
        its row of :data:`~pyfmu_wrapper.solvers.settings_table.SETTINGS` (subclasses included),
        plus max_periods >= min_periods."""
        c = Checks(self)
        names = [f.name for f in fields(self)]
        for name in names:
            setting = _table.BY_NAME.get(name)
            if setting is None:
                raise TypeError(f"{type(self).__name__}.{name} is not declared in solvers/settings_table.py")
            why = setting.problem(getattr(self, name))
            if why is not None:
                c.fail(name, why)
            if (
                name == "max_periods"
                and "min_periods" in names
                and _table.BY_NAME["min_periods"].problem(self.min_periods) is None
                and self.max_periods < self.min_periods
            ):
                c.fail("max_periods", f"must be >= min_periods = {self.min_periods}")

    def window_for(self, tmd: TMDParams) -> int:
        return default_window(tmd, self.window)

    @classmethod
    def shared_fields(cls) -> tuple[str, ...]:
        """Names of the fields every engine's settings have."""
        return tuple(f.name for f in fields(SteadySettings))


class WindowCriterion:
    """The steady-state test on per-period maxima of |x| (module doc), shared by every engine.

    Feed it A_k with :meth:`add` (True when the run may stop); :meth:`result` gives (amplitude,
    converged, change) and :attr:`irregular` tells a response that settled into irregular motion.

    * W = 1 (periodic response): with the base state at each period start (``state`` = x, xd)
      the distance to the periodic orbit is estimated from the residual r_k = max(|dx|, |dxd|/w)
      / A_k between consecutive period starts and its contraction rho (the largest of the last
      three ratios r_k / r_k-1): est = r_k rho / (1 - rho). A beating transient, whose amplitude
      differences change sign, cannot fool it; modes that do not move the base (the offset of a
      TMD stuck by friction) do not hold it up. Without ``state`` the same rule is applied to
      the amplitudes A_k. Converged when est <= tol.
    * W > 1 (windows of W periods, W_j = max A_k in window j): regular when two consecutive
      windows agree, |W_j - W_j-1| <= tol W_j. Otherwise, once three windows after the first
      exist, the run stops when the running maximum of the windows after the first has not
      grown by more than tol for two windows: the amplitude is that maximum and ``change`` the
      scatter (max - min) / max of those windows. The point counts as converged when the
      scatter is within ``scatter_tol`` (an amplitude known to that fraction), else it is
      flagged irregular and not converged. There is no absolute tolerance: a tiny amplitude
      must settle relative to itself.

    With each period's x sampled at n uniform phases (``add(..., samples=...)``), :meth:`periodic`
    gives the **periodic amplitude**: :func:`~.harmonic.periodic_max` of the mean of those samples
    over the periods of the windows after the first (W > 1: the least-squares harmonic series of x
    over the windows the amplitude is taken from) or of the last period (W = 1), i.e. max |x - mean|
    of the response's periodic part, as the diagnosis takes a steady record's amplitude. For a
    periodic response it is the amplitude (to the series' truncation); a rattling play chain's
    non-periodic part averages out of it.
    """

    def __init__(
        self,
        window: int,
        tol: float,
        *,
        min_periods: int = 3,
        max_periods: int = 3000,
        scatter_tol: float = 5e-3,
        omega: float | None = None,
    ) -> None:
        self.W, self.tol = int(window), float(tol)
        self.min_periods, self.max_periods = int(min_periods), int(max_periods)
        self.scatter_tol, self.omega = float(scatter_tol), omega
        self.period_max: list[float] = []
        self.wins: list[float] = []
        self.diffs: list[float] = []
        self.res: list[float] = []
        self._z_prev: np.ndarray | None = None
        self.converged = False
        self.irregular = False
        self.change = math.inf
        self._stopped = False
        self._stable = 0
        self.floor = 0.0
        self._sync: NDArray[np.float64] | None = None  #: the sum of the sampled periods' x (periodic)
        self._sync_n = 0

    @classmethod
    def from_settings(
        cls, settings: SteadySettings, window: int, base: Any, omega: float | None = None
    ) -> WindowCriterion:
        """From an engine's settings (:class:`SteadySettings`; ``max_periods_window``, which only
        the monolithic engine has, bounds the windowed run when present)."""
        if window == 1:
            c = cls(1, settings.tol, min_periods=settings.min_periods, max_periods=settings.max_periods, omega=omega)
            # resolution floor of the W = 1 residual: 1e-9 of the static deflection F/K (an orbit
            # with a zero amplitude, an undamped antiresonance, has only round-off to settle)
            c.floor = 1e-9 * abs(base.force_amplitude) / max(base.stiffness, 1e-300)
            return c
        mp = min(settings.max_periods, getattr(settings, "max_periods_window", settings.max_periods))
        return cls(
            window,
            settings.tol_window,
            min_periods=settings.min_periods,
            max_periods=mp,
            scatter_tol=settings.scatter_tol,
            omega=omega,
        )

    def _contraction(self, r: float, scale: float) -> float:
        self.res.append(r)
        if len(self.res) < 3:
            return math.inf
        ratios = [
            self.res[i] / self.res[i - 1] if self.res[i - 1] > 0 else 0.0
            for i in range(max(1, len(self.res) - 3), len(self.res))
        ]
        rho = min(max(ratios), 0.999)
        return r * rho / (1.0 - rho) if rho > 0 else r

    def add(
        self,
        a: float,
        state: Sequence[float] | NDArray[np.float64] | None = None,
        samples: NDArray[np.float64] | None = None,
    ) -> bool:
        """A_k = ``a`` of the next period; ``state``: x, xd at its end (W = 1); ``samples``: its x at n
        uniform phases from its start (:meth:`periodic`). True when the run may stop."""
        self.period_max.append(float(a))
        k = len(self.period_max)
        W = self.W
        if samples is not None and (W == 1 or k > W):
            x = np.asarray(samples, dtype=float)
            if W == 1 or self._sync is None or self._sync.shape != x.shape:
                self._sync, self._sync_n = x.copy(), 1
            else:
                self._sync += x
                self._sync_n += 1
        if W == 1:
            scale = max(abs(a), self.floor, 1e-300)
            if state is not None and self.omega:
                z = np.array([state[0], state[1] / self.omega], dtype=float)
                if self._z_prev is None:
                    self._z_prev = z
                    return False
                r = float(np.max(np.abs(z - self._z_prev))) / scale
                self._z_prev = z
            else:
                if k < 2:
                    return False
                r = abs(self.period_max[-1] - self.period_max[-2]) / scale
            self.wins.append(float(a))
            self.change = self._contraction(r, scale)
            if k >= self.min_periods and self.change <= self.tol:
                self.converged = True
            return self.converged
        if k % W:
            return False
        wins = self.wins
        wins.append(max(self.period_max[-W:]))
        if len(wins) < 2:
            return False
        d = wins[-1] - wins[-2]
        self.diffs.append(d)
        scale = max(abs(wins[-1]), 1e-300)
        self.change = abs(d) / scale
        if k >= self.min_periods and self.change <= self.tol:
            self.converged = True
            return True
        tail = wins[1:]
        if len(tail) >= 3:
            grew = max(tail) - max(tail[:-1])
            self._stable = self._stable + 1 if grew <= self.tol * max(tail) else 0
            if self._stable >= 2 and k >= self.min_periods:
                scatter = (max(tail) - min(tail)) / max(max(tail), 1e-300)
                self.converged = scatter <= self.scatter_tol
                self.irregular = not self.converged
                self._stopped = True
                return True
        return False

    def result(self) -> tuple[float, bool, float]:
        wins = self.wins
        amplitude = wins[-1] if wins else (max(self.period_max) if self.period_max else float("nan"))
        change = self.change
        if self.W > 1 and len(wins) >= 3 and (self._stopped or not self.converged):
            tail = wins[1:]
            amplitude = max(tail)
            change = (max(tail) - min(tail)) / max(max(tail), 1e-300)
        return amplitude, self.converged, change

    def periodic(self) -> float:
        """The periodic amplitude (class doc); NaN when no period was sampled."""
        if self._sync is None or self._sync_n == 0:
            return math.nan
        return periodic_max(self._sync / self._sync_n)
