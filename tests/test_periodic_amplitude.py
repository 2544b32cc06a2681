"""The periodic amplitude of a steady state (``amplitude_periodic`` of run-scenario's sweep table:
:meth:`pyfmu_wrapper.solvers.steady.WindowCriterion.periodic`), against independent references: a
closed-form series, the least-squares series of all the samples (:func:`~pyfmu_wrapper.solvers.harmonic.fit_series`,
the diagnosis's fit of a steady record), the exact steady state |H(w)| F of a linear model, and a
rattling play chain's window maximum (an upper bound)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pyfmu_wrapper.diagnose.system.bench import nominal, true_tmd
from pyfmu_wrapper.models.solve import exact_amplitude, steady_state
from pyfmu_wrapper.physics.params import BaseParams
from pyfmu_wrapper.scenario.engines import RunSettings, compute_sweep
from pyfmu_wrapper.solvers.harmonic import fit_series, fuse, periodic_max, series_max
from pyfmu_wrapper.solvers.monolithic import SolverSettings
from pyfmu_wrapper.solvers.steady import WindowCriterion

NOM = nominal(1)
BASE = BaseParams(**NOM["base"])
OMEGAS = [18.0, 20.0, 21.5]  #: below, between and above the two peaks of paper Case 1


def test_periodic_max_of_a_closed_form_series():
    n = 400
    th = 2 * np.pi * np.arange(n) / n
    # max of cos + 0.1 cos 3: 1.1 at theta = 0; a mean is dropped
    assert periodic_max(0.5 + np.cos(th) + 0.1 * np.cos(3 * th)) == pytest.approx(1.1, rel=1e-12)
    # a pure sine sampled off its maximum: the series finds the maximum between samples
    assert periodic_max(2.0 * np.sin(th + 0.3)) == pytest.approx(2.0, rel=1e-6)


def test_window_criterion_averages_the_windows_after_the_first_as_the_least_squares_series():
    """The mean of the sampled periods is the least-squares harmonic series of all their samples (the
    diagnosis's fit, :func:`fit_series`): a non-periodic part (an incommensurate tone) averages out of
    it the same way; the first window (the transient) is left out."""
    rng = np.random.default_rng(3)
    n, W, omega = 256, 5, 2 * np.pi  # period 1 s
    crit = WindowCriterion(W, 1e-12, max_periods=6 * W)
    t = np.arange(6 * W * n + 1) / n  # 6 W whole periods and the next one's first sample
    x = np.cos(omega * t) + 0.05 * np.cos(3 * omega * t + 0.4) + 0.02 * np.sin(1.37 * omega * t)
    x = x + 1e-3 * rng.normal(size=t.size)
    x[: W * n] *= 3.0  # the transient window: not in the periodic amplitude
    for k in range(6 * W):
        p = x[k * n : (k + 1) * n]
        crit.add(float(np.max(np.abs(p))), samples=p)
    s = fit_series(t[W * n :], {"x": x[W * n :]}, omega)  # the whole periods after the first window
    assert s.n == 5 * W * n
    X, _ = fuse(s, "x", None, s.H)
    assert crit.periodic() == pytest.approx(series_max(X), rel=1e-9)
    assert crit.periodic() < float(np.max(np.abs(x[W * n :])))


@pytest.mark.parametrize("hidden", [{}, {"viscous": 5.0}])
def test_linear_model_periodic_amplitude_is_the_exact_steady_amplitude(hidden):
    """|H(w)| F (closed form) against each engine's periodic amplitude, to the engine's accuracy: the
    monolithic solver (Newton shooting; and period after period without it) and the co-simulation."""
    tmd = true_tmd(NOM, hidden)
    exact = exact_amplitude(BASE, tmd, OMEGAS)
    for shooting in (True, False):
        st = SolverSettings(shooting=shooting)
        for w, a in zip(OMEGAS, exact, strict=True):
            ss = steady_state(BASE, tmd, w, settings=st)
            assert ss.converged
            assert ss.amplitude_periodic == pytest.approx(a, rel=1e-5)
    co = compute_sweep(BASE, tmd, OMEGAS, RunSettings(engine="cosim"))
    assert co["amplitude_periodic"].to_numpy() == pytest.approx(exact, rel=1e-3)  # the coupling tolerance
    # the series and the Hermite maximum of the same co-simulated orbit agree much closer than that
    assert co["amplitude_periodic"].to_numpy() == pytest.approx(co["amplitude"].to_numpy(), rel=1e-5)
    ex = compute_sweep(BASE, tmd, OMEGAS, RunSettings(engine="monolithic"))
    assert (ex["method"] == "exact").all()
    assert ex["amplitude_periodic"].to_numpy() == pytest.approx(exact, rel=1e-12)


def test_play_chain_periodic_amplitude_is_below_its_window_maximum():
    """A rattling play chain: its periodic part's max |x - mean| is at most the largest window maximum
    (which also holds the rattle) and close to it (the rattle moves the base little)."""
    tmd = true_tmd(NOM, {"play": 3e-4})
    for w in OMEGAS:
        ss = steady_state(BASE, tmd, w, settings=SolverSettings(max_periods_window=80))
        assert math.isfinite(ss.amplitude_periodic)
        assert ss.amplitude_periodic < ss.amplitude
        assert ss.amplitude_periodic >= 0.99 * ss.amplitude
