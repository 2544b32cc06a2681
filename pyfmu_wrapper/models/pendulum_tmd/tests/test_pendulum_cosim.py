"""The pendulum TMD's FMU (PendulumTMD) and its co-simulation with the paper's BaseOscillator
(pyfmu_wrapper/models/pendulum_tmd/fmus/, cosim.py), held against independent references: the FMU's
equations with the interface Jacobian against the equations of motion written in test_pendulum_tmd.py (the
2x2 mass matrix by Cramer's rule), the FMU alone against scipy's integration of a free pendulum; the
co-simulated steady states at small forcing against the exact response of the equivalent linear TMD (mass m,
k = m g / L, c = c_p / L^2; 1e-3), at large forcing against the independent long-time integration of
test_pendulum_tmd.py (0.5 %), every point converged with its coupling-error estimate within coupling_tol;
the native FMUs against the Python-hosted ones (bit for bit); the scenario run by run-scenario on both
engines. The whole 33-point curves are marked slow; by default a handful of frequencies."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import fmpy
import numpy as np
import pandas as pd
import pytest
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp
from test_pendulum_tmd import BIG, FEW, OMEGAS, REF, SCENARIO, SMALL, TIGHT, linear_response, pendulum_rhs

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.cosim.settings import CosimSettings
from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.models import MODELS, catalog
from pyfmu_wrapper.models.base_tmd.fmus.variables import BASE_OSCILLATOR
from pyfmu_wrapper.models.pendulum_tmd import UNIT, PendulumTMDParams
from pyfmu_wrapper.models.pendulum_tmd.cosim import PendulumSystem, cosim_fmus, structure_frequencies
from pyfmu_wrapper.models.pendulum_tmd.fmus.step import U_KAPPA, U_SIZE, fmu_rhs, pendulum_outputs
from pyfmu_wrapper.models.pendulum_tmd.fmus.variables import PENDULUM_TMD_FMU
from pyfmu_wrapper.models.pendulum_tmd.params import PARAMETERS
from pyfmu_wrapper.physics.params import TMDParams

G = 9.81
TMD = TMDParams()  # the detached TMD the engines pass; the unit does not read it
COSIM = CosimSettings()
TOL = COSIM.coupling_tol  # 5e-3


def _fmu_inputs(s: PendulumTMDParams, w: float, t: float, z: np.ndarray, kappa: float) -> np.ndarray:
    """The PendulumTMD's input array at t coupled to the base: x, xd, and xdd_free = (F cos wt - K x - C xd)/M."""
    u = np.zeros(U_SIZE)
    u[0], u[1], u[4] = t, z[0], z[1]
    u[7] = (s.force_amplitude * math.cos(w * t) - s.stiffness * z[0] - s.damping * z[1]) / s.mass
    u[U_KAPPA] = kappa
    return u


# --- the FMU's equations ---------------------------------------------------------------------------


def test_with_the_base_compliance_the_fmu_is_the_coupled_system():
    """base_compliance = 1/M, xdd_free = (F cos wt - K x - C xd)/M: the FMU's rates (the 2x2 solve for the
    pivot's and the angle's accelerations) are those of the equations of motion of test_pendulum_tmd.py, and
    its force is the base's equation's: M x'' = F cos wt - K x - C xd - force (1e-12 of each rate's scale,
    300 random states with swings up to 3 rad and both forces)."""
    rng = np.random.default_rng(7)
    for s in (SMALL, BIG):
        p = UNIT.pack(s, TMD, 19.0)
        for _ in range(150):
            z = rng.normal(size=4) * np.array([1e-2, 0.2, 1.0, 10.0])
            t, w = rng.uniform(0.0, 2.0), 19.0
            ref = pendulum_rhs(t, z, s, w)
            got = np.empty(4)
            u = _fmu_inputs(s, w, t, z, 1.0 / s.mass)
            fmu_rhs(t, z, p, u, got)
            scale = np.array([1.0, 50.0, 10.0, 1e4]) * max(1.0, np.abs(ref).max())
            assert np.all(np.abs(got - ref) <= 1e-12 * scale), (z, got, ref)
            out = np.empty(5)
            pendulum_outputs(z, u[7], u[U_KAPPA], p, out)
            base = s.force_amplitude * math.cos(w * t) - s.stiffness * z[0] - s.damping * z[1] - out[0]
            assert abs(s.mass * ref[1] - base) <= 1e-11 * max(1.0, abs(base)), (s.mass * ref[1], base)
            # the outputs: the bob's horizontal position and velocity, the angle and its rate
            L = s.length
            assert np.allclose(out[1:], [z[0] + L * math.sin(z[2]), z[1] + L * math.cos(z[2]) * z[3], z[2], z[3]])


def test_without_the_compliance_the_pivot_is_prescribed():
    """base_compliance = 0: the input xdd is the pivot's acceleration, and the angle follows the pendulum's own
    equation L th'' = -(xdd cos th + g sin th) - c_p th' / (m L) (written here); the force is m y''."""
    rng = np.random.default_rng(3)
    s = BIG
    p = UNIT.pack(s, TMD, 0.0)
    m, L, cp = s.pendulum_mass, s.length, s.pivot_damping
    for _ in range(100):
        z = rng.normal(size=4) * np.array([1e-2, 0.2, 1.0, 10.0])
        a = rng.normal() * 10.0
        u = np.zeros(U_SIZE)
        u[7] = a
        got = np.empty(4)
        fmu_rhs(0.0, z, p, u, got)
        thdd = (-(a * math.cos(z[2]) + G * math.sin(z[2])) - cp * z[3] / (m * L)) / L
        assert got[0] == z[1] and abs(got[1] - a) <= 1e-13 * max(1.0, abs(a))
        assert abs(got[3] - thdd) <= 1e-11 * max(1.0, abs(thdd))
        out = np.empty(5)
        pendulum_outputs(z, a, 0.0, p, out)
        ydd = a + L * (thdd * math.cos(z[2]) - z[3] ** 2 * math.sin(z[2]))
        assert abs(out[0] - m * ydd) <= 1e-10 * max(1.0, abs(m * ydd))


# --- the unit's FMU --------------------------------------------------------------------------------


def test_the_unit_holds_its_fmu_and_its_co_simulation():
    """The unit gives its one FMU, PendulumTMD (gathered by the catalogue, with native functions); the
    co-simulation couples it to the BaseOscillator that base_tmd gives; the declared rows name the FMU
    variables they are set on (the pendulum's on PendulumTMD, the main mass's on BaseOscillator)."""
    (fmu,) = UNIT.fmus()
    assert fmu.name == "PendulumTMD" and fmu.native is not None and catalog.FMUS["PendulumTMD"] is fmu
    assert fmu.slave.__module__.endswith("models.pendulum_tmd.fmus.slave")
    base, pend = cosim_fmus()
    assert pend is fmu and base is catalog.FMUS["BaseOscillator"] and base in MODELS.get("base_tmd").fmus()
    assert UNIT.cosim is not None and UNIT.cosim().sweep is not None
    for p in PARAMETERS:
        owner, _, name = p.fmu_name.rpartition(".")
        spec = BASE_OSCILLATOR if owner == "BaseOscillator" else PENDULUM_TMD_FMU
        v = spec.by_name(name)
        assert v.vr == p.fmu_vr and v.causality == "parameter" and v.unit == p.unit, p.name
        if spec is PENDULUM_TMD_FMU:
            assert v.start == p.default and v.min == p.minimum and v.min_exclusive == p.strict
    md = fmpy.read_model_description(str(ensure_fmus((fmu,))["PendulumTMD"]))
    force = next(u for u in md.outputs if u.variable.name == "force")
    assert [d.name for d in force.dependencies] == ["xdd"]
    assert {u.variable.name: u.dependencies for u in md.outputs if u.variable.name != "force"} == {
        "y": [],
        "yd": [],
        "th": [],
        "thd": [],
    }


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_alone_is_a_free_pendulum(version):
    """fmpy runs the PendulumTMD alone on a pivot at rest from th0 = 1 rad for 1 s (100 steps): its angle and
    rate, the bob's position L sin th, and its force m y'' are scipy's integration of
    m L^2 th'' + c_p th' + m g L sin th = 0 (1e-7 of their scales); fmpy validates it."""
    path = ensure_fmus(UNIT.fmus(), fmi_version=version)["PendulumTMD"]
    assert validate_fmu(str(path)) == []
    s = BIG
    m, L, cp = s.pendulum_mass, s.length, s.pivot_damping
    r = fmpy.simulate_fmu(
        str(path),
        stop_time=1.0,
        step_size=0.01,
        output_interval=0.01,
        start_values=dict(th0=1.0, thd0=0.0, rtol=1e-11, atol=1e-14),
        output=["th", "thd", "y", "yd", "force"],
    )

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -(cp * y[1] + m * G * L * math.sin(y[0])) / (m * L * L)])

    sol = solve_ivp(rhs, (0.0, 1.0), [1.0, 0.0], t_eval=r["time"], **TIGHT)
    th, thd = sol.y
    assert np.max(np.abs(r["th"] - th)) < 1e-7 and np.max(np.abs(r["thd"] - thd)) < 1e-7 * 20
    assert np.max(np.abs(r["y"] - L * np.sin(th))) < 1e-7 * L
    thdd = np.array([rhs(0.0, v)[1] for v in sol.y.T])
    ydd = L * (thdd * np.cos(th) - thd**2 * np.sin(th))
    assert np.max(np.abs(r["force"] - m * ydd)) < 1e-7 * np.max(np.abs(m * ydd))


def test_the_time_scales_are_the_linearised_structure():
    """The coupled frequencies are the equivalent linear TMD's (the 2-DOF closed form written here); the base
    alone sqrt((K + m g/L)/M), the pendulum alone sqrt(g/L); 96 steps per period resolve them at 16 rad/s."""
    s = BIG
    M, K, m = s.mass, s.stiffness, s.pendulum_mass
    k = m * G / s.length
    # det([[K + k - M w2, -k], [-k, k - m w2]]) = 0: M m w2^2 - (M k + m (K + k)) w2 + K k = 0
    b, c = (M * k + m * (K + k)) / (M * m), K * k / (M * m)
    top = math.sqrt((b + math.sqrt(b * b - 4 * c)) / 2)
    scales = structure_frequencies(s)
    assert [sc.omega for sc in scales] == pytest.approx([top, math.sqrt((K + k) / M), math.sqrt(G / s.length)])
    assert 20.0 < max(sc.omega for sc in scales) < 22.0
    system = PendulumSystem(UNIT, s, TMD)
    assert UNIT.cosim().steps_at(s, TMD, 16.0, COSIM) == 96
    zs = system.shooting_scale(np.array([1e-3, 0.0, 0.5, 0.0]), 20.0)
    assert list(zs) == pytest.approx([1e-3, 2e-2, 0.5, 10.0])  # metres and radians, each its own scale


# --- the co-simulation -----------------------------------------------------------------------------


def _cosim(s: PendulumTMDParams, omegas, settings: CosimSettings = COSIM, direction: str = "up") -> pd.DataFrame:
    return UNIT.cosim().sweep(s, TMD, np.asarray(omegas, float), direction=direction, settings=settings)


def _checked(table: pd.DataFrame) -> None:
    """Every point converged, its coupling-error estimate within coupling_tol, no reason given."""
    assert table["converged"].all(), table[["omega", "reason"]]
    assert (table["coupling_error"] <= TOL).all() and not table["reason"].astype(object).fillna("").astype(bool).any()


def test_small_swings_are_the_equivalent_linear_tmd():
    """F = 1 N at a handful of frequencies: co-simulated amplitude / F within 1e-3 of the linear TMD."""
    table = _cosim(SMALL, FEW)
    _checked(table)
    gap = np.abs(table["amplitude"].to_numpy() / SMALL.force_amplitude / linear_response(SMALL, FEW) - 1)
    assert np.max(gap) < 1e-3, gap


def test_large_swings_agree_with_the_independent_integration():
    """F = 60 N at a handful of frequencies (swings up to 1.10 rad at 20.25 rad/s): within 0.5 % of the
    independent long-time integration; the co-simulated swing max |th| at the communication points too."""
    table = _cosim(BIG, FEW)
    _checked(table)
    ref = np.array([REF[w][0] for w in FEW])
    assert np.max(np.abs(table["amplitude"].to_numpy() / ref - 1)) < 5e-3
    t, z, ss = UNIT.cosim().periodic_time_series(BIG, TMD, 20.25, 1, None, COSIM)
    assert ss.converged and z.shape == (t.size, 4) and abs(ss.amplitude / REF[20.25][0] - 1) < 5e-3
    assert abs(np.max(np.abs(z[:, 2])) / REF[20.25][1] - 1) < 5e-3  # 96 samples: within 5.4e-4 of the peak


def test_native_fmus_give_the_python_hosted_numbers_bit_for_bit(monkeypatch):
    """The same sweep points on the native FMUs, on the Python-hosted ones, and on the Python-hosted ones with
    every step taken in Python (PYFMU_NATIVE=0): the same amplitudes, states and estimates, bit for bit."""
    ws = (19.0, 20.25)
    native = _cosim(BIG, ws, replace(COSIM, fmu_build="native"))
    hosted = _cosim(BIG, ws, replace(COSIM, fmu_build="python"))
    monkeypatch.setenv("PYFMU_NATIVE", "0")
    python = _cosim(BIG, ws, replace(COSIM, fmu_build="python"))
    for other in (hosted, python):
        for col in ("amplitude", "coupling_error", "periods", "steps"):
            assert np.array_equal(native[col].to_numpy(), other[col].to_numpy()), col


@pytest.mark.slow
def test_the_whole_curves_native_and_python_hosted():
    """Both curves at all 33 frequencies on the native and the Python-hosted FMUs: identical bit for bit; every
    point converged within coupling_tol; F = 1 N within 1e-3 of the linear TMD, F = 60 N within 0.5 % of the
    independent integration."""
    for s in (SMALL, BIG):
        native = _cosim(s, OMEGAS, replace(COSIM, fmu_build="native"))
        hosted = _cosim(s, OMEGAS, replace(COSIM, fmu_build="python"))
        assert np.array_equal(native["amplitude"].to_numpy(), hosted["amplitude"].to_numpy())
        assert np.array_equal(native["coupling_error"].to_numpy(), hosted["coupling_error"].to_numpy())
        _checked(native)
        amp = native["amplitude"].to_numpy()
        if s is SMALL:
            assert np.max(np.abs(amp / s.force_amplitude / linear_response(s, OMEGAS) - 1)) < 1e-3
        else:
            assert np.max(np.abs(amp / np.array([REF[w][0] for w in OMEGAS]) - 1)) < 5e-3


# --- the scenario file -----------------------------------------------------------------------------


@pytest.mark.slow
def test_the_scenario_run_by_both_engines_and_by_the_default_one(tmp_path):
    """run-scenario scenarios/pendulum_tmd.yaml --engine both, and with no --engine (the co-simulation): the
    CSV columns of every model (curve, engine, omega, amplitude = max |x| [m]); both curves at 33 points, every
    point converged with its coupling-error estimate within coupling_tol; F = 1 N within 1e-3 of the linear
    TMD, F = 60 N within 0.5 % of the independent integration, on both engines (the monolithic amplitude is
    the 'reference' column); no point called converged and more than 0.5 % off; the pendulum FMU's seconds
    in the timing split."""
    ref60 = np.array([REF[w][0] for w in OMEGAS])
    lin1 = linear_response(SMALL, OMEGAS)
    for engine, label in (("both", "both"), (None, "cosim")):
        out = tmp_path / label
        args = [str(SCENARIO), "--out", str(out), "--workers", "1", "--quiet"]
        assert main(args + (["--engine", engine] if engine else [])) == 0
        table = pd.read_csv(out / "pendulum_frc.csv")
        assert {"curve", "engine", "omega", "amplitude"} <= set(table.columns) and set(table["engine"]) == {label}
        small, big = table[table["curve"] == "F = 1 N"], table[table["curve"] == "F = 60 N"]
        assert len(small) == len(big) == 33 and np.allclose(big["omega"], OMEGAS)
        _checked(table)
        assert np.max(np.abs(small["amplitude"].to_numpy() / lin1 - 1)) < 1e-3
        assert np.max(np.abs(big["amplitude"].to_numpy() / ref60 - 1)) < 5e-3
        if engine == "both":
            assert np.max(np.abs(small["reference"].to_numpy() / lin1 - 1)) < 1e-3
            assert np.max(np.abs(big["reference"].to_numpy() / ref60 - 1)) < 5e-3
        summary = json.loads((out / "summary.json").read_text())
        assert set(summary["parameters"]) == {"pendulum_tmd"}
        # the pendulum FMU's seconds are the absorber's (the timing split by role), in the CSV and the summary
        fmus = summary["timings"]["cosim"]["fmus"]
        assert fmus["base"] > 0.0 and fmus["tmd"] > 0.0 and (table["fmu_time_tmd"] > 0.0).all()
