"""diagnose: attribution on synthetic data with withheld effects, the benchmark, and the BRFD data."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pyfmu_wrapper.cli.diagnose import main_diagnose
from pyfmu_wrapper.diagnose.link.benchmark import make_benchmark, make_dataset, score
from pyfmu_wrapper.diagnose.run import run_diagnosis

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "effect,value,key,tol",
    [
        ("play", 1e-3, "play.play_gap", 0.05),
        ("friction", 6.0, "friction.friction_force", 0.05),
        ("cubic", 2e5, "cubic.cubic_stiffness", 0.15),
    ],
)
def test_link_hidden_effect_ranks_first(tmp_path, effect, value, key, tol):
    make_dataset(tmp_path, {effect: value}, seed=11)
    res = run_diagnosis(tmp_path)
    assert res["attribution"]["effects"] == [effect]
    assert res["candidates"][0]["effects"] == [effect]
    assert abs(res["attribution"]["params"][key] - value) <= tol * value
    assert res["held_out"]["gap_closed"] > 0.9


def test_clean_link_data_no_structural_effect(tmp_path):
    make_dataset(tmp_path, {}, seed=12)
    res = run_diagnosis(tmp_path)
    assert res["attribution"]["effects"] == []
    assert res["attribution"]["verdict"].startswith("No structural effect")


def test_two_hidden_effects_found_as_a_pair(tmp_path):
    make_dataset(tmp_path, {"viscous": 8.0, "bias": 1e-3}, seed=13)
    res = run_diagnosis(tmp_path)
    assert sorted(res["attribution"]["effects"]) == ["bias", "viscous"]
    where = dict(zip(res["attribution"]["effects"], res["attribution"]["elements"]))
    assert where == {"bias": "channel d", "viscous": "tmd link"}  # the displacement sensor, the link
    assert abs(res["attribution"]["params"]["viscous.delta_damping"] - 8.0) < 0.8


def test_small_link_benchmark_meets_goals(tmp_path):
    make_benchmark(tmp_path, n=12, seed=2, pair_fraction=0.0)
    s = score(tmp_path)["summary"]
    assert s["n_clean"] >= 0.25 * s["n_datasets"]
    assert s["top1_accuracy"] >= 0.9
    assert s["false_positive_rate"] <= 0.1
    assert s["gap_closed_median"] >= 0.8
    assert s["param_rel_error_median"] < 0.05
    assert not any("manifest" in str(p) for p in (tmp_path / "ds000").iterdir())


def test_brfd_attributed_to_backlash(tmp_path):
    out = tmp_path / "out"
    assert main_diagnose([str(ROOT / "data" / "brfd_link"), "--out", str(out)]) == 0
    res = json.loads((out / "diagnosis.json").read_text())
    for f in ("report.md", "where.png", "loops.png", "candidates.png"):
        assert (out / f).is_file()
    a, h = res["attribution"], res["held_out"]
    assert a["effects"][0] == "play"
    assert 1e-3 < a["params"]["play.play_gap"] < 4e-3  # half-gap; measured ~2.3 mm
    assert h["gap_closed"] > 0.85  # measured 92 %
    assert h["nrmse_after"] < 0.35 * h["nrmse_before"]
    friction = next(c for c in res["candidates"] if c["effects"] == ["friction"])
    assert friction["gap_closed"] < 0.6  # refitted Coulomb friction alone cannot reproduce the loop
    singles = {c["effects"][0]: c for c in res["candidates"] if len(c["effects"]) == 1}
    # the gap matters: play beats friction with contact compliance but no gap on held-out BIC
    assert singles["play"]["bic_test"] < singles["compliant_friction"]["bic_test"] - 20
    assert set(res["split"]["test"]) == {"0.25Hz_1in.csv", "0.5Hz_1in.csv", "1Hz_1in.csv", "2Hz_0.5in.csv"}
    assert "low relative speed" in res["where"]["summary"]


def test_frc_viscous(tmp_path):
    import numpy as np
    import yaml

    from pyfmu_wrapper.models.solve import exact_amplitude
    from pyfmu_wrapper.physics.params import BaseParams, paper_case

    w = np.linspace(15, 25, 31)
    x = exact_amplitude(BaseParams(), paper_case(1, damping=55.0), w) + np.random.default_rng(0).normal(0, 2e-5, w.size)
    (tmp_path / "frc.csv").write_text("omega,force_amplitude,x_max\n" + "\n".join(f"{a},200,{b}" for a, b in zip(w, x)))
    nom = {
        "base": {"mass": 100.0, "stiffness": 4e4, "damping": 100.0, "force_amplitude": 200.0},
        "tmd": {"mass": 9.0, "stiffness": 4e3, "damping": 40.0, "inertance": 1.0, "inerter": "ideal"},
    }
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": "system", "nominal": nom, "records": ["frc.csv"]}))
    res = run_diagnosis(tmp_path, out=tmp_path / "out")
    assert res["attribution"]["effects"] == ["viscous"]
    assert abs(res["attribution"]["params"]["viscous.delta_damping"] - 15.0) < 1.0
    assert (tmp_path / "out" / "frc.png").is_file()


def test_model_override_scenario_and_nominal_yaml(tmp_path):
    import yaml

    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset

    data = tmp_path / "data"
    make_system_dataset(data, {}, seed=15, case=1, frc=False)  # generated with c = 15 N s/m
    model = tmp_path / "model.yaml"
    nom = yaml.safe_load((data / "dataset.yaml").read_text())["nominal"]
    nom["tmd"]["damping"] = 0.0  # the engineer's model forgot the damper
    model.write_text(yaml.safe_dump({"nominal": nom}))
    res = run_diagnosis(data, model=str(model))
    assert res["verdict"]["effects"] == ["viscous"]
    assert abs(res["verdict"]["parameters"]["viscous.delta_damping"]["value"] - 15.0) < 0.3
    scen = ROOT / "scenarios" / "paper" / "fig3_case1.yaml"  # Case 1, c = 0: same answer from a scenario
    if scen.is_file():
        res = run_diagnosis(data, model=str(scen))
        assert res["verdict"]["effects"] == ["viscous"]
