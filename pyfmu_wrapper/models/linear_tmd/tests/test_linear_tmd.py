"""The plain linear TMD model (pyfmu_wrapper/models/linear_tmd/, added by following
docs/adding-a-model.md) against independent references: Den Hartog's closed form for an undamped main
mass (the two fixed points of equal height sqrt(1 + 2/mu) at the tuning f = 1/(1+mu)), the 2-DOF
matrices written here, the steady state integrated by shooting, and its scenario file run by
run-scenario --engine monolithic; bad input refused with its place."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.models.linear_tmd import UNIT, LinearTMDParams
from pyfmu_wrapper.models.solve import exact_response, steady_state
from pyfmu_wrapper.physics.params import ParameterError, TMDParams
from pyfmu_wrapper.scenario.loader import load_scenario, parse_scenario
from pyfmu_wrapper.scenario.runner import curve_structure
from pyfmu_wrapper.scenario.schema import ScenarioError
from pyfmu_wrapper.solvers.monolithic import SolverSettings

SCENARIO = Path(__file__).resolve().parents[4] / "scenarios" / "linear_tmd.yaml"  # the checkout's scenarios/
TMD = TMDParams()  # what the engines pass; the unit does not read it


def two_dof(s: LinearTMDParams, omegas: np.ndarray) -> np.ndarray:
    """(X, Y) per frequency from (K - w^2 M + i w C) [X, Y] = [F, 0], the matrices written out here."""
    M = np.diag([s.mass, s.absorber_mass])
    k, c = s.absorber_stiffness, s.absorber_damping
    K = np.array([[s.stiffness + k, -k], [-k, k]])
    C = np.array([[s.damping + c, -c], [-c, c]])
    return np.array([np.linalg.solve(K - w**2 * M + 1j * w * C, [s.force_amplitude, 0.0]) for w in omegas])


def den_hartog_ratio(g: np.ndarray, mu: float, f: float, zeta: float) -> np.ndarray:
    """|X| / (F/K) of an undamped main mass with an absorber (Den Hartog, Mechanical Vibrations, 3.7):
    g = w / sqrt(K/M), f = sqrt(k/m) / sqrt(K/M), zeta = c / (2 m sqrt(K/M))."""
    num = (2 * zeta * g) ** 2 + (g**2 - f**2) ** 2
    den = (2 * zeta * g) ** 2 * (g**2 - 1 + mu * g**2) ** 2 + (mu * f**2 * g**2 - (g**2 - 1) * (g**2 - f**2)) ** 2
    return np.sqrt(num / den)


def tuned(mu: float, c: float) -> LinearTMDParams:
    """Undamped main mass (M = 10 kg, K = 4000 N/m), absorber tuned to f = 1/(1+mu), damper c."""
    M, K = 10.0, 4000.0
    wa = math.sqrt(K / M) / (1 + mu)
    return LinearTMDParams(M, K, 0.0, 10.0, mu * M, mu * M * wa**2, c)


@pytest.mark.parametrize("mu", [0.02, 0.05, 0.2])
def test_den_hartog_fixed_points_have_equal_height_at_the_optimal_tuning(mu):
    """At f = 1/(1+mu) every damper gives the same |X| at the two fixed points
    g^2 = (1 -+ sqrt(mu/(2+mu)))/(1+mu), both sqrt(1 + 2/mu) times F/K; and the whole curve is Den
    Hartog's closed form."""
    wn = 20.0
    gP, gQ = (math.sqrt((1 + sg * math.sqrt(mu / (2 + mu))) / (1 + mu)) for sg in (-1, 1))
    height = math.sqrt(1 + 2 / mu)
    for c in (0.05, 1.0, 5.0, 40.0):
        s = tuned(mu, c)
        xs = s.force_amplitude / s.stiffness
        X = exact_response(s, TMD, [gP * wn, gQ * wn])[:, 0]
        assert np.allclose(np.abs(X) / xs, height, rtol=1e-9, atol=0), (c, np.abs(X) / xs, height)
        g = np.linspace(0.5, 1.5, 201)
        zeta = c / (2 * s.absorber_mass * wn)
        ours = np.abs(exact_response(s, TMD, g * wn)[:, 0]) / xs
        assert np.allclose(ours, den_hartog_ratio(g, mu, 1 / (1 + mu), zeta), rtol=1e-9, atol=0)


def test_den_hartog_optimum_puts_the_peak_at_the_fixed_points():
    """With Den Hartog's damping ratio sqrt(3 mu / (8 (1+mu)^3)) the peak of the curve lies within 2 %
    of the fixed points' height (his optimum levels the two peaks only approximately), and below every
    other damper's peak."""
    mu = 0.05
    s = LinearTMDParams.den_hartog(mu, damping=0.0)
    g = np.linspace(0.7, 1.3, 6001)
    peak = np.max(np.abs(exact_response(s, TMD, g * 20.0)[:, 0])) / (s.force_amplitude / s.stiffness)
    height = math.sqrt(1 + 2 / mu)
    assert height <= peak < 1.02 * height
    for c in (0.3 * s.absorber_damping, 3.0 * s.absorber_damping):
        other = tuned(mu, c)
        assert np.max(np.abs(exact_response(other, TMD, g * 20.0)[:, 0])) / (s.force_amplitude / s.stiffness) > peak


def test_exact_response_is_the_two_dof_matrices():
    """Every state: x, y and the velocities i w X, i w Y against the matrices, with a damped main mass."""
    s = LinearTMDParams(12.0, 5000.0, 6.0, 25.0, 0.9, 300.0, 3.5)
    w = np.linspace(5.0, 40.0, 71)
    Z = exact_response(s, TMD, w)
    ref = two_dof(s, w)
    want = np.column_stack([ref[:, 0], 1j * w * ref[:, 0], ref[:, 1], 1j * w * ref[:, 1]])
    assert np.max(np.abs(Z - want) / np.abs(want)) < 1e-12


@pytest.mark.parametrize("detached", [False, True])
def test_steady_state_by_shooting_is_the_exact_response(detached):
    """The monolithic solver's integrated periodic steady state (RODAS4 + shooting), within 1e-5 of the
    matrices' |X|; a detached absorber (k = c = 0) floats and the main mass settles alone."""
    s = LinearTMDParams.den_hartog(0.05, damping=2.0)
    if detached:
        s = LinearTMDParams(s.mass, s.stiffness, s.damping, s.force_amplitude, s.absorber_mass, 0.0, 0.0)
    for omega in (12.0, 18.5, 20.0, 26.0):
        ss = steady_state(s, TMD, omega, settings=SolverSettings())
        exact = abs(two_dof(s, [omega])[0, 0])
        assert ss.converged and abs(ss.amplitude / exact - 1) < 1e-5, (omega, ss.amplitude, exact)


def test_the_unit_is_registered_and_refuses_bad_parameters():
    assert MODELS.of(LinearTMDParams()) is UNIT and not UNIT.takes_tmd
    with pytest.raises(ParameterError, match=r"absorber_mass \(m\) must be a finite number > 0 \[kg\], got -1"):
        LinearTMDParams(absorber_mass=-1.0)
    with pytest.raises(ParameterError, match=r"damping \(C\) must be a finite number >= 0"):
        LinearTMDParams(damping=float("nan"))


def test_the_scenario_file_holds_den_hartogs_tuning():
    scn = load_scenario(SCENARIO)
    want = LinearTMDParams.den_hartog(0.05, mass=10.0, stiffness=4000.0, damping=2.0, force_amplitude=10.0)
    assert scn.base == want
    (study,) = scn.studies
    assert [c.label for c in study.curves] == ["no TMD", "Den Hartog", "light damping"]
    assert curve_structure(scn, study.curves[0]).detached
    assert curve_structure(scn, study.curves[2]).absorber_damping == 0.5


@pytest.mark.parametrize("linear", ["exact", "simulate"])
def test_scenario_run_by_the_monolithic_engine_is_the_matrices_response(linear, tmp_path):
    """run-scenario --engine monolithic: every curve within 1e-4 of the 2-DOF matrices; with
    solver.linear = simulate the points are integrated to their steady states."""
    text = SCENARIO.read_text()
    if linear == "simulate":
        text = text.replace("count: 81", "count: 21") + "solver: {linear: simulate}\n"
    path = tmp_path / "linear_tmd.yaml"
    path.write_text(text)
    assert main([str(path), "--out", str(tmp_path / "out"), "--engine", "monolithic", "--quiet"]) == 0
    scn = load_scenario(path)
    (study,) = scn.studies
    table = pd.read_csv(tmp_path / "out" / f"{study.name}.csv")
    peaks = {}
    for curve in study.curves:
        rows = table[table["curve"] == curve.label]
        assert len(rows) == len(study.omegas) and rows["converged"].all()
        w = rows["omega"].to_numpy()
        exact = np.abs(two_dof(curve_structure(scn, curve), w)[:, 0])
        assert np.max(np.abs(rows["amplitude"].to_numpy() / exact - 1)) < 1e-4, curve.label
        assert set(rows["method"]) == {"exact" if linear == "exact" else "steady_state"}
        peaks[curve.label] = rows["amplitude"].max()
    assert peaks["Den Hartog"] < peaks["light damping"] < peaks["no TMD"]


DOC = """\
schema_version: 2
name: bad
linear_tmd: {mass: 10.0, stiffness: 4000.0, damping: 2.0, force_amplitude: 10.0,
             absorber_mass: 0.5, absorber_stiffness: 181.0, absorber_damping: 2.4}
frequencies: [15.0, 20.0]
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "a", linear_tmd: {absorber_damping: 1.0}}
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "absorber_mass: 0.5",
            "absorber_mass: -0.5",
            r"bad.yaml:4: linear_tmd.absorber_mass: must be > 0 \(got -0.5\)",
        ),
        ("absorber_mass: 0.5,", "", r"bad.yaml:3: linear_tmd.absorber_mass: missing required key"),
        ("mass: 10.0,", "mass: 10.0, storeys: 3,", r"linear_tmd.storeys: unknown key 'storeys'"),
        (
            "{absorber_damping: 1.0}",
            "{absorber_damping: -1.0}",
            r"bad.yaml:10: studies\[0\].curves\[0\].linear_tmd.absorber_damping: must be >= 0",
        ),
        (
            "frequencies:",
            "tmd: {mass: 1.0}\nfrequencies:",
            r"bad.yaml:5: tmd: model 'linear_tmd' carries its own absorber and takes no tmd: block",
        ),
        (
            "linear_tmd: {absorber_damping: 1.0}}",
            "without_tmd: true}",
            r"curves\[0\].without_tmd: does not apply here: model 'linear_tmd' carries its own absorber",
        ),
        (
            'kind: frc\n    name: frc\n    curves:\n      - {label: "a", linear_tmd: {absorber_damping: 1.0}}',
            "kind: map\n    name: m\n    parameter: damping\n    values: [1.0, 2.0]",
            r"studies\[0\].kind: a map sweeps a TMD parameter; model 'linear_tmd' takes no TMD",
        ),
        (
            "\nlinear_tmd: {",
            "\nframe: {storeys: 1, mass: 1, stiffness: 1, damping: 0, force_amplitude: 1}\nlinear_tmd: {",
            "needs exactly one primary structure",
        ),
    ],
)
def test_bad_linear_tmd_scenarios_are_refused_with_their_place(old, new, message):
    assert old in DOC
    with pytest.raises(ScenarioError, match=message):
        parse_scenario(DOC.replace(old, new), "bad.yaml")


def test_a_scenario_of_the_paper_still_needs_its_tmd_block():
    doc = textwrap.dedent(
        """\
        schema_version: 2
        name: b
        base: {mass: 10.0, stiffness: 4000.0, damping: 2.0, force_amplitude: 10.0}
        frequencies: [15.0]
        studies: [{kind: frc, name: f, curves: [{label: a}]}]
        """
    )
    with pytest.raises(ScenarioError, match=r"bad.yaml:1: tmd: missing required key \(the TMD of model 'base_tmd'\)"):
        parse_scenario(doc, "bad.yaml")
