"""The steady-state rules and the event landing, each on its own, against hand-computed answers.

* The window criterion groups exactly W consecutive periods: a maximum in the first period of every
  window must be seen (a window one period short misses it), and two equal windows stop the run
  at exactly 2 W periods.
* Both engines' settings extend one SteadySettings: a shared field out of range is refused by
  both with the field named.
* The integrator lands on gear contacts: integrating the rattling play model over one period
  retakes steps onto the contact surfaces (event count > 0), and with that it agrees with a run at
  a 100x tighter tolerance.
"""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest

from pyfmu_wrapper.models.solve import initial_guess
from pyfmu_wrapper.physics.models import COUPLED
from pyfmu_wrapper.physics.params import BaseParams, pack, paper_case
from pyfmu_wrapper.solvers import rodas
from pyfmu_wrapper.solvers.monolithic import SolverSettings
from pyfmu_wrapper.solvers.steady import SettingsError, SteadySettings, WindowCriterion


@pytest.mark.parametrize("W", [2, 3, 20])
def test_window_holds_exactly_w_periods(W):
    crit = WindowCriterion(W, tol=1e-4)
    seq = ([5.0] + [1.0] * (W - 1)) * 4
    stop = next(k for k, a in enumerate(seq, start=1) if crit.add(a))
    amplitude, converged, change = crit.result()
    assert (stop, amplitude, converged, change) == (2 * W, 5.0, True, 0.0)
    assert crit.wins == [5.0, 5.0]


def test_window_scatter_flags_an_irregular_response():
    crit = WindowCriterion(2, tol=1e-4, scatter_tol=5e-3)
    seq = [1.0, 0.5, 1.10, 0.5, 1.00, 0.5, 1.05, 0.5, 1.02, 0.5, 1.08, 0.5, 1.03, 0.5, 1.01, 0.5]
    stop = next((k for k, a in enumerate(seq, start=1) if crit.add(a)), None)
    amplitude, converged, change = crit.result()
    assert stop is not None and not converged and crit.irregular
    assert amplitude == 1.10 and change == pytest.approx((1.10 - 1.00) / 1.10)


@pytest.mark.parametrize(
    "name,bad",
    [
        ("tol", -1e-6),
        ("tol_window", float("nan")),
        ("window", 0),
        ("min_periods", 0),
        ("max_periods", 2),
        ("scatter_tol", -5e-3),
        ("play_start", "middle"),
        ("shooting", "yes"),
        ("max_newton", 0),
    ],
)
def test_steady_settings_are_one_definition_for_both_engines(name, bad):
    """Both engines' settings are the shared SteadySettings (same fields, one validation): a value
    out of range is refused by both, naming the field (max_periods 2 < min_periods 3)."""
    from pyfmu_wrapper.cosim.settings import CosimSettings

    for cls in (SolverSettings, CosimSettings):
        assert issubclass(cls, SteadySettings)
        assert set(SteadySettings.shared_fields()) <= {f.name for f in fields(cls)}
        with pytest.raises(SettingsError) as e:
            cls(**{name: bad})
        assert e.value.field == name and str(e.value).startswith(f"{cls.__name__}.{name} = ")
    # the engines differ only in their own fields and in two defaults
    assert (SolverSettings().max_periods, CosimSettings().max_periods) == (3000, 240)
    assert (SolverSettings().max_newton, CosimSettings().max_newton) == (8, 12)


def test_integrator_lands_on_gear_contacts():
    base = BaseParams()
    tmd = paper_case(1, damping=10.0, inerter="play", play_gap=1e-4)
    w = 17.0
    T = 2 * math.pi / w
    z0 = initial_guess(base, tmd, w)
    z0[4] = tmd.play_gap * 1.5  # the chain engaged in compression
    p = pack(base, tmd, w)
    scale = np.array([5e-3, 0.1, 5e-3, 0.1, 1e-4, 0.1])
    runs = {}
    for rtol in (1e-8, 1e-10):
        z = z0.copy()
        stats = np.zeros(4, dtype=np.int64)
        res = rodas.make_integrator(COUPLED)(
            z,
            0.0,
            T,
            p,
            np.zeros(1),
            rtol,
            rtol * 1e-2 * scale,
            T / 200,
            T / 20,
            np.zeros(0),
            np.zeros((0, 6)),
            1.0 / tmd.friction_slope,
            stats,
        )
        assert res[2] == rodas.OK
        runs[rtol] = (z, stats.copy())
    z_lo, st = runs[1e-8]
    assert st[rodas.STAT_EVENTS] > 0  # contact switches were landed on
    assert abs(z_lo[0] - runs[1e-10][0][0]) <= 1e-6 * 5e-3
