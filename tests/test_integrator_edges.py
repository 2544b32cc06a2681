"""Edges of the RODAS4 integrator: a grazing gear contact, the step cap, the stuck pair.

The grazing state is the one where the monolithic solver used to stall:
``run-scenario scenarios/full_case3.yaml --engine monolithic`` at 15.5 rad/s, curve 5 (Case 3,
c = 5, df = 5, eps = 1e-4): the TMD moves with the base (xd - yd = -1.4e-6 m/s) and the play chain
rests on its contact, d + eps = -1.4e-20 (below the float resolution of d ~ 1e-4). With the step
size it had reached there (2.5e-11 s), each step crossed the surface, was retaken to land on it,
landed on the same side, and the next step did it again: ~1e-9 s of progress per 10,000 steps.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pyfmu_wrapper.models.solve import simulate, steady_state
from pyfmu_wrapper.physics.models import COUPLED
from pyfmu_wrapper.physics.params import BaseParams, pack, paper_case
from pyfmu_wrapper.solvers.monolithic import SolverError, SolverSettings
from pyfmu_wrapper.solvers.rodas import OK, STAT_STEPS, STEP_CAP, failure_message, make_integrator

integrate = make_integrator(COUPLED)

pytestmark = pytest.mark.timeout(120)

BASE = BaseParams()
OMEGA = 15.5
T = 2.0 * math.pi / OMEGA
TMD3 = paper_case(3, damping=5.0, friction_force=5.0, inerter="play", play_gap=1e-4)
#: the state where the stall began (printed by an instrumented run of the former code)
T_GRAZE = 0.006670307692610001
Z_GRAZE = np.array(
    [
        0.012649324581685674,
        -0.0010192285832326259,
        0.012649325046447692,
        -0.0010178161357253979,
        -0.00010000000000000002,
        5.204494799144315e-10,
    ]
)
#: the monolithic solver's absolute tolerances at this point (solvers.monolithic.integrator_atol)
ATOL = np.array([5e-09, 1e-07, 5e-09, 1e-07, 5e-09, 7.453559924999298e-06])
BAND = 1.0 / TMD3.friction_slope


def _period(z0, h0=2.5e-11, max_steps=20000):
    """One forcing period from the grazing time; returns (z, xmax, status, t, steps)."""
    z = np.array(z0, dtype=float)
    p = pack(BASE, TMD3, OMEGA)
    stats = np.zeros(4, dtype=np.int64)
    args = (
        z,
        T_GRAZE,
        T_GRAZE + T,
        p,
        np.zeros(1),
        1e-8,
        ATOL,
        h0,
        T / 20,
        np.zeros(0),
        np.zeros((0, 6)),
        BAND,
        stats,
        max_steps,
    )
    h, xmax, status, t = integrate(*args)
    return z, xmax, status, t, int(stats[STAT_STEPS]), p


def test_grazing_state_is_the_one_described():
    """The reproducer's state really grazes: the chain on its contact to ~1e-20 m, the pair stuck."""
    eps = TMD3.play_gap
    assert abs(Z_GRAZE[4] + eps) < 1e-18
    assert abs(Z_GRAZE[1] - Z_GRAZE[3]) < 2e-6


@pytest.mark.parametrize("h0", [2.5e-11, T / 200])
def test_grazing_state_integrates_over_a_period_in_bounded_steps(h0):
    """From the grazing state, one period completes in a few hundred steps (not ~1e10), whatever
    step size it inherits, and matches runs with the contact offset by +-1e-12 m (engaged / free
    side of the surface) to 1e-9 in max |x| and in the end state x, xd, y, yd (an offset of 1e-12 m
    changes the chain force by at most ki 1e-12 = 2e-5 N)."""
    z, xmax, status, t, steps, _ = _period(Z_GRAZE, h0=h0)
    assert status == OK and t == pytest.approx(T_GRAZE + T, abs=1e-15)
    assert steps < 2000
    for off in (1e-12, -1e-12):
        z1 = Z_GRAZE.copy()
        z1[4] += off
        zo, xo, so, _, steps_o, _ = _period(z1, h0=h0)
        assert so == OK and steps_o < 2000
        assert xo == pytest.approx(xmax, rel=1e-9)
        np.testing.assert_allclose(zo[:4], z[:4], rtol=0, atol=1e-9 * np.max(np.abs(z[:4])))
        # the chain coasts freely after leaving the surface: the 1e-12 m offset pushes it off with
        # dd changed by ~5e-10 m/s, which carries d by ~4e-10 m over the period (4e-6 of the gap)
        assert abs(zo[4] - z[4]) <= 1e-5 * TMD3.play_gap


def test_the_step_cap_ends_a_call_with_a_status_naming_it():
    """A cap smaller than the steps a period needs ends the call there: a status naming the cap,
    the time and the state, never a hang."""
    z, _, status, t, steps, p = _period(Z_GRAZE, max_steps=50)
    assert status == STEP_CAP and steps <= 50
    assert T_GRAZE < t < T_GRAZE + T  # stopped inside the period
    msg = failure_message(status, COUPLED, t, z, p, ATOL, BAND, 50)
    assert "cap of 50 steps" in msg and f"t = {t:.12g}" in msg and "d = " in msg and "mode: " in msg


def test_step_cap_ends_a_steady_state_not_converged_and_a_simulation_with_a_solver_error():
    """A cap too small for a period: the steady state is a point not converged whose reason names omega,
    the time reached, the state and the mode (a sweep goes on past it); simulate raises a SolverError
    naming the same."""
    ss = steady_state(BASE, TMD3, OMEGA, settings=SolverSettings(max_steps=50))
    assert not ss.converged and np.isnan(ss.amplitude)
    assert re.search(
        r"integrator failed: omega = 15\.5 rad/s.*stopped at t = .*cap of 50 steps.*state x = .*mode: ", ss.reason
    )
    with pytest.raises(SolverError, match=r"cap of 30 steps.*mode: .*gear"):
        simulate(BASE, TMD3, OMEGA, 2 * T, max_steps=30)


def test_a_solver_error_inside_shooting_ends_the_point_not_the_sweep():
    """Newton shooting's period map (a smooth configuration, window 1) meets the integrator's step cap: the
    error does not escape shoot() or the sweep; every point is reported not converged with the
    integrator's reason (omega, the cap), and a generous cap on the same sweep converges every point to
    the exact response (1e-5): the failure was the cap's, not the sweep's."""
    from pyfmu_wrapper.models.solve import exact_amplitude, sweep

    tmd = paper_case(1, damping=10.0)
    omegas = [18.0, 19.0, 20.0]
    capped = sweep(BASE, tmd, omegas, "up", SolverSettings(max_steps=20)).table
    assert not capped["converged"].any() and capped["amplitude"].isna().all()
    assert all(re.search(r"integrator failed: omega = .* cap of 20 steps", r) for r in capped["reason"])
    fine = sweep(BASE, tmd, omegas, "up", SolverSettings()).table
    assert fine["converged"].all() and fine["reason"].eq("").all()
    exact = exact_amplitude(BASE, tmd, omegas)
    assert np.max(np.abs(fine["amplitude"].to_numpy() / exact - 1)) < 1e-5


def test_stuck_pair_closed_form_monolithic():
    """df = 45.78 (Case 1, c = 0, ideal inerter) at 25 rad/s keeps the TMD stuck to the base: the
    pair moves as one body of mass M + m (an ideal inerter between two bodies moving together
    carries no force), so x has the amplitude F / |K - (M + m) w^2 + i C w| = 7.0832e-3 m for
    every stuck steady state, whatever the offset of the TMD spring."""
    tmd = paper_case(1, damping=0.0, friction_force=45.78)
    w = 25.0
    exact = BASE.force_amplitude / abs(BASE.stiffness - (BASE.mass + tmd.mass) * w**2 + 1j * BASE.damping * w)
    assert exact == pytest.approx(7.0832e-3, abs=1e-7)
    for shooting in (True, False):
        ss = steady_state(BASE, tmd, w, settings=SolverSettings(shooting=shooting))
        assert ss.converged
        assert ss.amplitude == pytest.approx(exact, rel=2e-5), shooting


def test_stuck_pair_closed_form_cosimulation():
    """The same stuck pair co-simulated (default settings: Newton shooting, which the continuum of
    stuck offsets defeats, then period after period until the base orbit has settled): the
    amplitude is the closed form to 2e-5, not the unconverged 7.1176e-3 m reported before."""
    from pyfmu_wrapper.cosim.settings import CosimSettings
    from pyfmu_wrapper.models.base_tmd import UNIT
    from pyfmu_wrapper.models.base_tmd import cosim as cs
    from pyfmu_wrapper.models.base_tmd.cosim import make_master

    tmd = paper_case(1, damping=0.0, friction_force=45.78)
    w = 25.0
    exact = BASE.force_amplitude / abs(BASE.stiffness - (BASE.mass + tmd.mass) * w**2 + 1j * BASE.damping * w)
    m = make_master(BASE, tmd, coupling="impulse")
    try:
        ss = cs.steady_state(UNIT, m, BASE, tmd, w, None, CosimSettings())
    finally:
        m.close()
    assert ss.converged
    assert ss.amplitude == pytest.approx(exact, rel=2e-5)


def test_fmu_do_step_failure_names_time_state_and_mode():
    """The FMU's doStep uses the same integrator: when it cannot proceed (here tolerances of
    1e-30 / 1e-300 that no step can meet) the master raises an error carrying the FMU's own
    message: where the integrator stopped, why, the subsystem state and its mode."""
    from pyfmu_wrapper.master.master import MasterError
    from pyfmu_wrapper.models.base_tmd import cosim as cs
    from pyfmu_wrapper.models.solve import initial_guess

    tmd = paper_case(1, friction_force=10.0)
    m = cs.make_master(BASE, tmd, coupling="impulse", fmu_build="python")  # the reference build names the state
    try:
        p = cs.fmu_parameters(BASE, tmd, 20.0, initial_guess(BASE, tmd, 20.0), fmu_rtol=1e-30)
        p["tmd.atol"] = 1e-300
        m.initialize(0.0, p)
        with pytest.raises(
            MasterError,
            match=r"tmd: fmi2DoStep failed .*FmuStepError: doStep from t = 0 s: "
            r"integrator stopped at t = .* s: the step size fell below .*"
            r"state y = .*, yd = .*, d = .*, dd = .*; mode: ",
        ):
            m.step(1e-3)
    finally:
        m.close()
