"""The pendulum TMD model (pyfmu_wrapper/models/pendulum_tmd/) against independent references: at small
swings the exact response of the equivalent linear TMD (mass m, k = m g / L, c = c_p / L^2; a 2x2
complex solve written here), at large swings a periodic orbit integrated here with scipy (DOP853, the
2x2 mass matrix solved by Cramer's rule, Newton on the period map; none of the package's kernels) and the
numbers of an independent long-time integration by another engineer (up and down sweeps to steady
state, DOP853 at rtol 1e-11, cross-checked by shooting, Floquet multipliers and a basin probe: one stable
periodic orbit at every frequency of 16-24 rad/s, no jump up vs down); its scenario file run by
run-scenario --engine monolithic; bad input refused with its place."""

from __future__ import annotations

import json
import math
import pickle
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.models.pendulum_tmd import UNIT, PendulumTMDParams
from pyfmu_wrapper.models.solve import periodic_time_series, steady_state, sweep
from pyfmu_wrapper.physics.params import ParameterError, TMDParams
from pyfmu_wrapper.scenario.loader import load_scenario, parse_scenario
from pyfmu_wrapper.scenario.schema import ScenarioError

SCENARIO = Path(__file__).resolve().parents[4] / "scenarios" / "pendulum_tmd.yaml"  # the checkout's scenarios/
TMD = TMDParams()  # what the engines pass; the unit does not read it
G = 9.81
#: scenarios/pendulum_tmd.yaml's pendulum (the F = 60 N curve)
BIG = PendulumTMDParams(100.0, 4.0e4, 100.0, 60.0, 5.0, 0.0270388, 0.0177228)
SMALL = PendulumTMDParams(100.0, 4.0e4, 100.0, 1.0, 5.0, 0.0270388, 0.0177228)
OMEGAS = np.linspace(16.0, 24.0, 33)

#: (w [rad/s], max |x| [m], max |th| [rad]) of the periodic orbit at F = 60 N, from the independent
#: long-time integration (up sweep; the down sweep agrees to 2.3e-10)
REFERENCE_F60 = (
    (16.00, 5.1817535099e-03, 0.3710108788),
    (16.25, 5.5866785147e-03, 0.4321076434),
    (16.50, 6.0194537717e-03, 0.5038582584),
    (16.75, 6.4443464338e-03, 0.5849293291),
    (17.00, 6.7945471644e-03, 0.6694109212),
    (17.25, 6.9941991359e-03, 0.7456331536),
    (17.50, 7.0269710945e-03, 0.8019675000),
    (17.75, 6.9626732456e-03, 0.8360529564),
    (18.00, 6.8922264106e-03, 0.8539645696),
    (18.25, 6.8806968796e-03, 0.8634183145),
    (18.50, 6.9716019516e-03, 0.8705873016),
    (18.75, 7.2037429008e-03, 0.8800526197),
    (19.00, 7.6272187704e-03, 0.8955574990),
    (19.25, 8.3249038994e-03, 0.9208370291),
    (19.50, 9.4538203328e-03, 0.9604239079),
    (19.75, 1.1304706337e-02, 1.0189380183),
    (20.00, 1.3873400492e-02, 1.0837771065),
    (20.25, 1.5025416729e-02, 1.0955969176),
    (20.50, 1.4138512727e-02, 1.0511158136),
    (20.75, 1.2664560338e-02, 0.9851334675),
    (21.00, 1.1241768425e-02, 0.9137689925),
    (21.25, 1.0009911525e-02, 0.8430292686),
    (21.50, 8.9674031353e-03, 0.7752096892),
    (21.75, 8.0831703898e-03, 0.7111856853),
    (22.00, 7.3261037553e-03, 0.6512760785),
    (22.25, 6.6711919985e-03, 0.5955811085),
    (22.50, 6.0995106819e-03, 0.5441090181),
    (22.75, 5.5968997258e-03, 0.4968151262),
    (23.00, 5.1526325540e-03, 0.4536075693),
    (23.25, 4.7583717908e-03, 0.4143448476),
    (23.50, 4.4074270150e-03, 0.3788362420),
    (23.75, 4.0942592626e-03, 0.3468483436),
    (24.00, 3.8141657921e-03, 0.3181166487),
)
REF = {w: (x, th) for w, x, th in REFERENCE_F60}
#: the default run's frequencies: both ends, the pendulum's own frequency and the peak
FEW = (16.0, 19.0, 20.25, 22.0)


# --- independent references --------------------------------------------------------------------


def linear_response(s: PendulumTMDParams, omegas: np.ndarray) -> np.ndarray:
    """|X| / F of the equivalent linear TMD: (K - w^2 M + i w C) [X, Y] = [F, 0] with the absorber's
    mass m, spring m g / L and damper c_p / L^2 (the bob's horizontal displacement y = x + L th to first
    order: m L th'' + m x'' = -(m g / L) (y - x) - (c_p / L^2) (y' - x'))."""
    m, k, c = s.pendulum_mass, s.pendulum_mass * G / s.length, s.pivot_damping / s.length**2
    Mm = np.diag([s.mass, m])
    Kk = np.array([[s.stiffness + k, -k], [-k, k]])
    Cc = np.array([[s.damping + c, -c], [-c, c]])
    return np.array([abs(np.linalg.solve(Kk - w**2 * Mm + 1j * w * Cc, [1.0, 0.0])[0]) for w in omegas])


def pendulum_rhs(t: float, Z: np.ndarray, s: PendulumTMDParams, w: float) -> np.ndarray:
    """The equations of motion for any number of stacked states [x, xd, th, thd, x, ...]:
    (M + m) x'' + m L (th'' cos th - th'^2 sin th) + C x' + K x = F cos(w t),
    m L^2 th'' + m L x'' cos th + c_p th' + m g L sin th = 0, the 2x2 mass matrix solved by Cramer's rule."""
    M, K, C, F, m, L, cp = (
        s.mass,
        s.stiffness,
        s.damping,
        s.force_amplitude,
        s.pendulum_mass,
        s.length,
        s.pivot_damping,
    )
    x, xd, th, thd = Z.reshape(-1, 4).T
    sn, cs = np.sin(th), np.cos(th)
    r1 = F * np.cos(w * t) - C * xd - K * x + m * L * thd**2 * sn
    r2 = -cp * thd - m * G * L * sn
    a11, a12, a22 = M + m, m * L * cs, m * L**2
    det = a11 * a22 - a12 * a12
    xdd = (a22 * r1 - a12 * r2) / det
    thdd = (a11 * r2 - a12 * r1) / det
    return np.column_stack([xd, xdd, thd, thdd]).ravel()


TIGHT = dict(method="DOP853", rtol=1e-11, atol=1e-13)


def reference_orbit(s: PendulumTMDParams, w: float) -> tuple[float, float]:
    """(max |x| [m], max |th| [rad]) over the periodic orbit at w: ten periods from rest, then Newton on
    the period map z -> z(T) (its Jacobian by finite differences, the five period maps integrated as one
    stacked system) until the correction is below 1e-10 of the state scales; the maxima at the extrema
    (events on x' = 0 and th' = 0, root-found on the dense output)."""
    T = 2.0 * math.pi / w
    z = solve_ivp(pendulum_rhs, (0.0, 10 * T), np.zeros(4), args=(s, w), **TIGHT).y[:, -1]
    xs = s.force_amplitude / s.stiffness
    scale = np.array([xs, xs * w, xs / s.length, xs / s.length * w])
    for _ in range(20):
        h = 1e-7 * np.maximum(np.abs(z), scale)
        starts = np.vstack([z, z + np.diag(h)])
        ends = solve_ivp(pendulum_rhs, (0.0, T), starts.ravel(), args=(s, w), **TIGHT).y[:, -1].reshape(5, 4)
        D = (ends[1:] - ends[0]).T / h  # the monodromy matrix, column j from the start displaced in z_j
        dz = np.linalg.solve(D - np.eye(4), z - ends[0])
        z = z + dz
        if np.max(np.abs(dz) / scale) < 1e-10:
            break
    else:
        raise AssertionError(f"reference: Newton did not converge at w = {w}")
    events = [lambda t, y, s, w: y[1], lambda t, y, s, w: y[3]]
    sol = solve_ivp(pendulum_rhs, (0.0, T), z, args=(s, w), events=events, **TIGHT)
    assert np.max(np.abs(sol.y[:, -1] - z) / scale) < 1e-8  # periodic
    x_max = max(abs(z[0]), float(np.max(np.abs(sol.y_events[0][:, 0]))))
    th_max = max(abs(z[2]), float(np.max(np.abs(sol.y_events[1][:, 2]))))
    return x_max, th_max


# --- the unit ------------------------------------------------------------------------------------


def test_the_unit_is_registered_pickled_by_reference_and_refuses_bad_parameters():
    assert MODELS.of(BIG) is UNIT and not UNIT.takes_tmd and not UNIT.is_linear(BIG, TMD)
    assert pickle.loads(pickle.dumps(UNIT)) is UNIT
    assert UNIT.example() == BIG  # the example is the scenario's pendulum
    with pytest.raises(ParameterError, match=r"length \(L\) must be a finite number > 0 \[m\], got 0.0"):
        PendulumTMDParams(length=0.0)
    with pytest.raises(ParameterError, match=r"pivot_damping \(c_p\) must be a finite number >= 0 \[N.m.s/rad\]"):
        PendulumTMDParams(pivot_damping=-1e-3)
    with pytest.raises(ParameterError, match=r"pendulum_mass \(m\) must be a finite number > 0"):
        PendulumTMDParams(pendulum_mass=float("inf"))


# --- (a) small swings: the equivalent linear TMD --------------------------------------------------


def test_small_swings_are_the_equivalent_linear_tmd():
    """F = 1 N: amplitude / F of the monolithic steady state (each point solved on its own, from the
    linearisation about rest continued in the force) within 1e-3 of the linear TMD at all 33 frequencies.
    The gap is the pendulum's own nonlinearity, not noise: 1.51e-4 at most, at 20.75 rad/s (an independent
    computation: it scales as F^2)."""
    lin = linear_response(SMALL, OMEGAS)
    amp = np.array([steady_state(SMALL, TMD, w).amplitude for w in OMEGAS])
    gap = np.abs(amp / SMALL.force_amplitude / lin - 1)
    assert np.max(gap) < 1e-3
    assert np.max(gap) == pytest.approx(1.51e-4, rel=0.02) and OMEGAS[np.argmax(gap)] == 20.75


# --- (b) large swings: an independent integration -------------------------------------------------


def test_reference_orbit_is_the_independent_long_time_integration():
    """The scipy orbit of this file at the default frequencies reproduces the other engineer's numbers
    (to 1e-7), and those numbers say what the issue's claim does not: at 19.0 rad/s the response is 1.167
    times the linear one with swings of 0.8956 rad, at 20.25 rad/s 2.25 times with 1.10 rad."""
    for w in FEW:
        x, th = reference_orbit(BIG, w)
        assert x == pytest.approx(REF[w][0], rel=1e-7) and th == pytest.approx(REF[w][1], rel=1e-7), w
    ratio = {w: REF[w][0] / (BIG.force_amplitude * linear_response(BIG, [w])[0]) for w in (19.0, 20.25)}
    assert ratio[19.0] == pytest.approx(1.167, abs=5e-4) and REF[19.0][1] == pytest.approx(0.8956, abs=5e-5)
    assert ratio[20.25] == pytest.approx(2.2495, abs=5e-4) and REF[20.25][1] == pytest.approx(1.0956, abs=5e-5)


@pytest.mark.parametrize("w", FEW)
def test_large_swings_agree_with_the_independent_integration(w):
    """F = 60 N: the monolithic steady state (solved on its own from small forcing) within 0.5 % of the
    reference's max |x|, and its swing max |th| (sampled 2000 times over the period) within 0.5 % too."""
    ss = steady_state(BIG, TMD, w)
    assert ss.converged and abs(ss.amplitude / REF[w][0] - 1) < 5e-3, (w, ss.amplitude, REF[w][0])
    _, z, _ = periodic_time_series(BIG, TMD, w, samples_per_period=2000)
    assert abs(np.max(np.abs(z[:, 2])) / REF[w][1] - 1) < 5e-3


@pytest.mark.slow
def test_the_whole_curve_agrees_with_the_independent_integration():
    """All 33 frequencies at F = 60 N swept up and down with continuation: one branch (up = down to
    1e-6), every point within 0.5 % of the other engineer's numbers and of this file's scipy orbit; the
    largest ratio to the linear response, 2.25, at 20.25 rad/s, where the pendulum swings 1.10 rad."""
    table = sweep(BIG, TMD, OMEGAS, direction="both").table
    assert table["converged"].all()
    up = table[table["direction"] == "up"].set_index("omega")["amplitude"]
    down = table[table["direction"] == "down"].set_index("omega")["amplitude"]
    assert np.max(np.abs(down[OMEGAS].to_numpy() / up[OMEGAS].to_numpy() - 1)) < 1e-6
    ref = np.array([REF[w][0] for w in OMEGAS])
    assert np.max(np.abs(up[OMEGAS].to_numpy() / ref - 1)) < 5e-3
    ours = np.array([reference_orbit(BIG, w) for w in OMEGAS])
    assert np.max(np.abs(ours[:, 0] / ref - 1)) < 1e-7
    assert np.max(np.abs(ours[:, 1] / np.array([REF[w][1] for w in OMEGAS]) - 1)) < 1e-7
    ratio = up[OMEGAS].to_numpy() / (BIG.force_amplitude * linear_response(BIG, OMEGAS))
    assert OMEGAS[np.argmax(ratio)] == 20.25 and np.max(ratio) == pytest.approx(2.2495, abs=5e-4)
    assert OMEGAS[np.argmax(ours[:, 1])] == 20.25 and np.max(ours[:, 1]) == pytest.approx(1.0956, abs=5e-5)


# --- (c) the scenario file -----------------------------------------------------------------------


def test_the_scenario_run_by_the_monolithic_engine(tmp_path):
    """run-scenario --engine monolithic on scenarios/pendulum_tmd.yaml: both curves at 33 points, the
    CSV columns of every model (curve, engine, omega, amplitude = max |x| [m]); F = 1 N within 1e-3 of
    the linear TMD, F = 60 N within 0.5 % of the reference; summary.json holds the pendulum's block
    and no tmd block."""
    scn = load_scenario(SCENARIO)
    assert scn.base == BIG and [c.label for c in scn.studies[0].curves] == ["F = 1 N", "F = 60 N"]
    out = tmp_path / "out"
    assert main([str(SCENARIO), "--out", str(out), "--engine", "monolithic", "--workers", "1", "--quiet"]) == 0
    table = pd.read_csv(out / "pendulum_frc.csv")
    assert {"curve", "engine", "omega", "amplitude"} <= set(table.columns) and set(table["engine"]) == {"monolithic"}
    small = table[table["curve"] == "F = 1 N"]
    big = table[table["curve"] == "F = 60 N"]
    assert len(small) == len(big) == 33 and table["converged"].all() and set(table["method"]) == {"steady_state"}
    assert np.allclose(small["omega"], OMEGAS) and np.allclose(big["omega"], OMEGAS)
    assert np.max(np.abs(small["amplitude"].to_numpy() / linear_response(SMALL, OMEGAS) - 1)) < 1e-3
    ref = np.array([REF[w][0] for w in OMEGAS])
    assert np.max(np.abs(big["amplitude"].to_numpy() / ref - 1)) < 5e-3
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["parameters"]) == {"pendulum_tmd"}
    assert summary["parameters"]["pendulum_tmd"]["length"] == BIG.length
    curves = summary["studies"][0]["curves"]
    assert all("tmd" not in c for c in curves) and curves[0]["pendulum_tmd"]["force_amplitude"] == 1.0


# --- (d) bad input ------------------------------------------------------------------------------

DOC = """\
schema_version: 2
name: bad
pendulum_tmd: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 60.0,
               pendulum_mass: 5.0, length: 0.0270388, pivot_damping: 0.0177228}
frequencies: [19.0, 20.0]
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "a", pendulum_tmd: {force_amplitude: 1.0}}
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("length: 0.0270388", "length: 0.0", r"bad.yaml:4: pendulum_tmd.length: must be > 0 \(got 0.0\)"),
        ("length: 0.0270388", "length: -0.03", r"bad.yaml:4: pendulum_tmd.length: must be > 0 \(got -0.03\)"),
        (
            "pivot_damping: 0.0177228",
            "pivot_damping: -1.0",
            r"bad.yaml:4: pendulum_tmd.pivot_damping: must be >= 0 \(got -1.0\)",
        ),
        ("length: 0.0270388, ", "", r"bad.yaml:3: pendulum_tmd.length: missing required key"),
        (
            "{force_amplitude: 1.0}",
            "{length: .nan}",
            r"bad.yaml:10: studies\[0\].curves\[0\].pendulum_tmd.length: must be finite \(got nan\)",
        ),
        (
            "frequencies:",
            "tmd: {mass: 1.0}\nfrequencies:",
            r"bad.yaml:5: tmd: model 'pendulum_tmd' carries its own absorber and takes no tmd: block",
        ),
    ],
)
def test_bad_pendulum_scenarios_are_refused_with_their_place(old, new, message):
    assert old in DOC
    with pytest.raises(ScenarioError, match=message):
        parse_scenario(DOC.replace(old, new), "bad.yaml")
