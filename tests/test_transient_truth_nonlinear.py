"""The transient suite's truths of the paper's two nonlinearities (issue 41): play in the inerter's gear
(a contact law outside a gap of +-eps) and dry friction with a true stick phase (event by event), checked
against their limits -- eps -> 0 is the ideal inerter, df -> 0 the viscous link -- against the static
condition of a stuck link, and by an energy balance."""

from __future__ import annotations

import numpy as np
import pytest

from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 10.0, "inertance": 1.0}


def _sweep(T: float) -> object:
    return force_signal("sweep_lin", np.random.default_rng(0), T, 150.0, f0=2.0, f1=4.0)


def test_play_with_a_vanishing_gap_is_the_ideal_inerter_and_a_real_gap_rattles():
    """eps -> 0: the contact never opens, the chain is the inerter behind the gear's 2e7 N/m (its mode
    at ~700 Hz, a 1e-5 change at 3 Hz): x, y within 1e-4 of the stroke of the ideal inerter's. A gap
    of 0.3 mm (the paper's size) keeps the displacements near (lost motion of 0.3 mm on a ~50 mm
    stroke) but its impacts put a rattle into the TMD's acceleration well above 1 % noise."""
    T = 2.0
    t = np.arange(0.0, T, 5e-4)
    F = _sweep(T)
    ideal = Truth(BASE, TMD, T).simulate(F, t)
    tiny = Truth(BASE, TMD, T, eps=1e-9).simulate(F, t)
    stroke = np.max(np.abs(ideal["x"] - ideal["y"]))
    for ch in ("x", "y"):
        assert np.max(np.abs(tiny[ch] - ideal[ch])) < 1e-4 * stroke
    assert np.std(tiny["ydd"] - ideal["ydd"]) < 1e-3 * np.std(ideal["ydd"])
    gap = Truth(BASE, TMD, T, eps=3e-4).simulate(F, t)
    assert np.max(np.abs(gap["y"] - ideal["y"])) < 0.05 * stroke
    assert np.std(gap["ydd"] - ideal["ydd"]) > 0.02 * np.std(ideal["ydd"])


def test_friction_with_a_vanishing_force_is_the_viscous_link():
    """df -> 0: the stick-slip truth (events at every v = 0, a stick phase where |Ff_req| <= df)
    tends to the truth without friction, to O(df / force)."""
    T = 5.0
    t = np.arange(0.0, T, 5e-4)
    F = _sweep(T)
    lin = Truth(BASE, TMD, T).simulate(F, t)
    fr = Truth(BASE, TMD, T, df=1e-4).simulate(F, t)
    for ch in ("x", "y"):
        assert np.max(np.abs(fr[ch] - lin[ch])) < 1e-5 * np.max(np.abs(lin[ch]))


def test_stuck_link_has_no_relative_velocity_and_holds_the_static_condition():
    """A 15 N friction under a sweep sticks for a share of the record: over each stick phase the
    stroke x - y is constant (to rounding), the two accelerations are equal, and the friction force
    that holds the link stuck stays within +-df; while slipping the relative velocity has the
    mode's sign. A free decay ends stuck for good, at rest with |Ff_req| <= df."""
    T = 6.0
    t = np.arange(0.0, T, 5e-4)
    tr = Truth(BASE, TMD, T, df=15.0)
    F = _sweep(T)
    s = tr.simulate(F, t)
    mode = s["mode"]
    stuck = mode == 0
    assert 0.05 < stuck.mean() < 0.9 and tr.segments > 10
    u = s["x"] - s["y"]
    runs = np.split(np.arange(t.size), np.flatnonzero(np.diff(stuck.astype(int))) + 1)
    n_runs = 0
    for r in runs:
        if stuck[r[0]] and r.size > 3:
            n_runs += 1
            assert np.ptp(u[r]) < 1e-12
            np.testing.assert_allclose(s["xdd"][r], s["ydd"][r], rtol=0, atol=1e-12)
    assert n_runs >= 4
    # the static condition, from the states: the force keeping the link stuck within +-df
    z = np.vstack([s["x"], np.gradient(s["x"], t), s["y"], np.gradient(s["x"], t)])
    _, ff = tr._stuck(t[stuck], z[:, stuck], F)
    assert np.max(np.abs(ff)) <= 15.0 * (1 + 1e-6)
    # slipping: v has the mode's sign (v from the slip-phase accelerations' integral: y's derivative)
    v = np.gradient(u, t)
    same = np.r_[True, mode[1:] == mode[:-1]] & np.r_[mode[:-1] == mode[1:], True]  # (differences inside a phase)
    slip = (~stuck) & same & (np.abs(v) > 1e-4)
    assert np.all(np.sign(v[slip]) == mode[slip])

    dec = Truth(BASE, TMD, 8.0, df=15.0).simulate(
        lambda tt: 0.0 * np.asarray(tt, float), np.arange(0, 8.0, 1e-3), np.array([0.004, 0.0, 0.012, 0.0])
    )
    assert dec["mode"][-1] == 0 and np.all(dec["mode"][-500:] == 0)
    assert np.ptp((dec["x"] - dec["y"])[-500:]) < 1e-12


def test_stick_slip_truth_balances_its_energy():
    """Work of the force = change of the energy (kinetic with the inerter's I v^2 / 2, both springs)
    + the dissipation C xd^2 + c v^2 + df |v|: the stick phases dissipate nothing, the slip phases
    df |v|; on a 20 kHz grid the trapezoid rule closes the balance to 1e-4 of the work."""
    T = 4.0
    t = np.arange(0.0, T, 5e-5)
    F = _sweep(T)
    tr = Truth(BASE, TMD, T, df=8.0)
    s = tr.simulate(F, t)
    # velocities from the accelerations (the truth's own xdd, ydd), integrated by trapezoid
    xd = np.concatenate([[0.0], np.cumsum(0.5 * (s["xdd"][1:] + s["xdd"][:-1]) * np.diff(t))])
    yd = np.concatenate([[0.0], np.cumsum(0.5 * (s["ydd"][1:] + s["ydd"][:-1]) * np.diff(t))])
    x, y, v = s["x"], s["y"], xd - yd
    M, m, I, K, k, C, c = tr.M, tr.m, tr.I, tr.K, tr.k, tr.C, tr.c
    E = 0.5 * M * xd**2 + 0.5 * m * yd**2 + 0.5 * I * v**2 + 0.5 * K * x**2 + 0.5 * k * (x - y) ** 2

    def integral(f: np.ndarray) -> float:
        return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))

    work = integral(s["force"] * xd)
    lost = integral(C * xd**2 + c * v**2 + tr.df * np.abs(v))
    assert E[-1] - E[0] == pytest.approx(work - lost, abs=1e-4 * work)
    assert integral(tr.df * np.abs(v)) > 0.01 * work  # the friction's share is not negligible


def test_suite_draws_play_and_can_be_restricted_to_effects():
    """make-benchmark --suite transient: play is an in-vocabulary truth (its half gap eps 0.1-1 mm);
    ``effects`` draws the singles from those effects only, and an unknown one is refused."""
    from pyfmu_wrapper.diagnose.system.transient_suite import IN_VOCAB, make_transient_benchmark, plan

    assert IN_VOCAB["play"] == ("eps", (1e-4, 1e-3), False)
    items = plan(np.random.default_rng(0), 6, 0, 0, 0, ["play", "friction"])
    drawn = [next(iter(h)) for _, h, _ in items]
    assert sorted(drawn) == ["friction"] * 3 + ["play"] * 3
    assert all(1e-4 <= h["play"] <= 1e-3 for _, h, _ in items if "play" in h)
    with pytest.raises(ValueError, match="draws"):
        make_transient_benchmark(None, n=1, n_clean=0, n_pair=0, n_oov=0, effects=["backlash"])  # type: ignore[arg-type]


@pytest.mark.slow
def test_stick_slip_friction_is_named_from_a_sweep_and_random_force(tmp_path):
    """End to end (issue 41): a 5 N stick-slip truth, an up-sweep and a random force of 20 s at 1 kHz,
    no filter: named alone, df within 1 %, explained to the noise (before the stick check the
    regularised law at its slope bound of 5000 s/m left z = 19: `unexplained`). ~40 s CPU."""
    from test_diagnose_transient import RANDOM, SWEEP_UP, make

    from pyfmu_wrapper.diagnose.run import run_diagnosis

    make(tmp_path / "ds", {"df": 5.0}, [SWEEP_UP, RANDOM], fs=1000.0, T=20.0, acq={})
    v = run_diagnosis(tmp_path / "ds", out=tmp_path / "out")["verdict"]
    assert v["effects"] == ["friction"] and not v["unexplained"], v["text"]
    assert abs(v["parameters"]["friction.friction_force"]["value"] - 5.0) < 0.05
