"""diagnose on system-level measurements as a rig gives them (x, y, xdd, ydd, force; no velocity;
per-channel noise): one dataset per hidden effect, a clean one and a pair, simulated with the
project's solver; each decision gate on its own."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pyfmu_wrapper.diagnose import gates
from pyfmu_wrapper.diagnose.run import run_diagnosis
from pyfmu_wrapper.diagnose.system import diagnosis as sysdiag
from pyfmu_wrapper.diagnose.system.bench import has_cubic, make_system_dataset
from pyfmu_wrapper.solvers.harmonic import estimate_omega, fit_series, fuse

CASES = {  # name: (hidden effects, paper case, parameter key, tolerance (relative))
    "clean": ({}, 1, None, None),
    "friction": ({"friction": 4.0}, 2, "friction.friction_force", 0.05),
    "viscous": ({"viscous": 4.0}, 1, "viscous.delta_damping", 0.05),
    "mass_split": ({"mass_split": -0.3}, 1, "mass_split.delta_inertance", 0.05),
    "force_error": ({"force_error": 0.04}, 2, "force_error.force_gain_error", 0.05),
    "sensor_offset": ({"sensor_offset": 8e-4}, 1, "sensor_offset.x_offset", 0.05),
    "play": ({"play": 2e-4}, 2, "play.play_gap", 0.25),
    "pair": ({"viscous": 6.0, "force_error": -0.05}, 2, "viscous.delta_damping", 0.05),
}
if has_cubic():
    CASES["cubic"] = ({"cubic": 1e5}, 1, "cubic.cubic_stiffness", 0.05)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("sysdiag")
    out = {}
    for k, (hidden, case, _, _) in CASES.items():
        make_system_dataset(root / k, hidden, seed=100 + len(out), case=case, frc=(k == "viscous"))
        out[k] = root / k
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_withheld_effect_named_with_its_parameter(data, name):
    hidden, _, key, tol = CASES[name]
    res = run_diagnosis(data[name])
    v = res["verdict"]
    assert sorted(v["effects"]) == sorted(hidden)
    if key:
        est = v["parameters"][key]["value"]
        assert abs(est - hidden[key.split(".")[0]]) <= tol * abs(hidden[key.split(".")[0]])
        assert v["held_out"]["gap_closed"] > 0.8
    else:
        assert v["text"].startswith("No structural effect")


def test_diagnosis_json_and_report(data, tmp_path):
    import json

    res = run_diagnosis(data["viscous"], out=tmp_path)
    j = json.loads((tmp_path / "diagnosis.json").read_text())
    v = j["verdict"]
    assert v["effects"] == ["viscous"] and v["sources"]["frc_records"] == ["frc.csv"]
    assert v["elements"] == ["tmd link"]  # where extra damping in c acts: between base and TMD
    p = v["parameters"]["viscous.delta_damping"]
    assert p["unit"] == "N s/m" and 0 < p["std"] < 0.05 * p["value"]
    assert v["held_out"]["gap_before"] > v["held_out"]["gap_after"] >= 0
    # the FRC records, predicted with the time-record parameters, agree (positive evidence)
    assert res["time_records"]["candidates"][0]["frc_evidence"] > 0
    assert (tmp_path / "report.md").read_text().count("extra viscous damping") >= 1


# --- each gate on its own -------------------------------------------------------------------------
def test_noise_gate_alone_stops_clean_data(data, monkeypatch):
    """With the evidence threshold removed, only the noise gate keeps clean data clean."""
    monkeypatch.setattr(gates, "EVIDENCE", -1e9)
    assert run_diagnosis(data["clean"])["verdict"]["effects"] == []
    assert sysdiag.noise_gate(200 + 3 * 20, 200) is False and sysdiag.noise_gate(200 + 6 * 20, 200) is True


def test_evidence_gate_alone_stops_clean_data(data, monkeypatch):
    """With the noise gate removed, only the held-out evidence keeps clean data clean; the same gate
    lets a real effect through."""
    monkeypatch.setattr(gates, "Z_NOISE", -1e9)
    assert run_diagnosis(data["clean"])["verdict"]["effects"] == []
    assert run_diagnosis(data["viscous"])["verdict"]["effects"] == ["viscous"]
    assert sysdiag.evidence_gate(100.0, 50.0, 1, 200) is True
    assert sysdiag.evidence_gate(100.0, 90.0, 1, 200) is False


def test_pair_gate():
    assert sysdiag.pair_gate(100.0, 10.0) is True
    assert sysdiag.pair_gate(100.0, 90.0) is False


def test_plausibility_gate():
    from pyfmu_wrapper.physics.params import paper_case

    tmd = paper_case(1, damping=15.0)
    motion = {"x": 0.03, "y": 0.1, "d": 0.08}
    ok = sysdiag.plausibility({"mass_split.delta_inertance": -0.5}, {"mass_split.delta_inertance": 0.01}, tmd, motion)
    assert ok == []
    assert "I < 0" in sysdiag.plausibility({"mass_split.delta_inertance": -9.0}, {}, tmd, motion)[0]
    assert "m < 0" in sysdiag.plausibility({"mass_split.delta_inertance": 9.5}, {}, tmd, motion)[0]
    assert (
        "damping"
        in sysdiag.plausibility({"viscous.delta_damping": -20.0}, {"viscous.delta_damping": 1.0}, tmd, motion)[0]
    )
    # within its uncertainty a slightly negative total is not rejected
    assert sysdiag.plausibility({"viscous.delta_damping": -15.5}, {"viscous.delta_damping": 1.0}, tmd, motion) == []
    assert "larger than" in sysdiag.plausibility({"play.play_gap": 0.1}, {}, tmd, motion)[0]
    assert "larger than" in sysdiag.plausibility({"sensor_offset.x_offset": 0.05}, {}, tmd, motion)[0]
    assert (
        "friction"
        in sysdiag.plausibility({"friction.friction_force": -5.0}, {"friction.friction_force": 0.1}, tmd, motion)[0]
    )


# --- derivatives and noise from the Fourier series -------------------------------------------------
def test_fourier_velocity_and_noise_per_channel():
    rng = np.random.default_rng(0)
    w = 17.3
    t = np.arange(0, 10 * 2 * math.pi / w, 1e-3)
    x = 0.02 * np.cos(w * t + 0.3) + 0.002 * np.cos(3 * w * t)
    xd = -0.02 * w * np.sin(w * t + 0.3) - 0.006 * w * np.sin(3 * w * t)
    xdd = -0.02 * w * w * np.cos(w * t + 0.3) - 0.018 * w * w * np.cos(3 * w * t)
    sx, sa = 0.02 * 0.0141, 0.01 * np.sqrt(np.mean(xdd**2))
    s = fit_series(t, {"x": x + rng.normal(0, sx, t.size), "xdd": xdd + rng.normal(0, sa, t.size)}, w)
    assert abs(s.noise["x"] / sx - 1) < 0.05 and abs(s.noise["xdd"] / sa - 1) < 0.05
    X, vX = fuse(s, "x", "xdd", 5)
    v = np.real(np.exp(1j * np.outer(w * t, np.arange(6))) @ (1j * np.arange(6) * w * X))
    err = np.sqrt(np.mean((v - xd) ** 2)) / np.sqrt(np.mean(xd**2))
    assert err < 0.005  # np.gradient of the noisy x gives ~30 % here
    assert np.sqrt(np.mean((np.gradient(x + rng.normal(0, sx, t.size), t) - xd) ** 2)) / np.sqrt(np.mean(xd**2)) > 0.1


def test_estimate_omega_positive_or_none():
    t = np.arange(0, 20, 1e-3)
    assert abs(estimate_omega(t, np.cos(18.7 * t + 1)) / 18.7 - 1) < 1e-3
    rng = np.random.default_rng(1)
    quake = np.cumsum(rng.normal(size=t.size)) * np.exp(-(((t - 5) / 3) ** 2))
    w = estimate_omega(t, quake)
    assert w is None or w > 0
    assert estimate_omega(t, np.zeros_like(t)) is None


def test_non_periodic_record_flagged_rest_still_runs(data, tmp_path):
    """An earthquake-like record gets no harmonic analysis (flagged, omega never <= 0); the
    periodic records still give the verdict."""
    import shutil

    import yaml

    from pyfmu_wrapper.diagnose.records import write_record

    d = tmp_path / "ds"
    shutil.copytree(data["viscous"], d)
    rng = np.random.default_rng(5)
    t = np.arange(0, 6.0, 1e-3)
    env = np.exp(-(((t - 2.0) / 1.0) ** 2))
    f = 300 * env * np.convolve(rng.normal(size=t.size), np.ones(40) / 40, "same")
    x = np.cumsum(np.cumsum(f)) * 1e-9
    write_record(
        d / "quake.csv",
        {
            "t": t,
            "force": f,
            "x": x,
            "y": 2 * x,
            "xdd": np.gradient(np.gradient(x, t), t),
            "ydd": np.gradient(np.gradient(2 * x, t), t),
        },
    )
    meta = yaml.safe_load((d / "dataset.yaml").read_text())
    meta["records"].append({"file": "quake.csv"})
    (d / "dataset.yaml").write_text(yaml.safe_dump(meta))
    res = run_diagnosis(d)
    assert [f["record"] for f in res["time_records"]["flagged"]] == ["quake.csv"]
    assert res["verdict"]["effects"] == ["viscous"]


def test_second_frc_at_half_the_force_is_half_the_amplitude_for_a_linear_truth(tmp_path):
    """make_system_dataset(n_frc=2) (the issue's speed shape: 6 steady records + 2 FRCs): the second
    FRC is taken at FRC_FORCE / 2, and for the linear clean truth (ideal inerter, no friction) its
    amplitudes are half the first's at every frequency (linearity), to the FRCs' 0.5 % noise."""
    import yaml

    make_system_dataset(tmp_path / "ds", {}, seed=7, case=1, n_records=1, frc=True, n_frc=2)
    files = [r["file"] for r in yaml.safe_load((tmp_path / "ds" / "dataset.yaml").read_text())["records"]]
    assert files[1:] == ["frc.csv", "frc_100N.csv"]
    a, b = (np.genfromtxt(tmp_path / "ds" / f, delimiter=",", names=True, comments="#") for f in files[1:])
    assert np.all(b["force_amplitude"] == 0.5 * a["force_amplitude"])
    assert np.allclose(b["x_max"] / a["x_max"], 0.5, rtol=0.03)
    assert np.std(b["x_max"] / a["x_max"] / 0.5 - 1) < 0.015
