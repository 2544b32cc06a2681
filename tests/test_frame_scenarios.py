"""The frame scenarios of issue 29 (scenarios/frame3_tmdi.yaml, frame10_tmd.yaml, frame3_full.yaml):
read as written, run by run-scenario's monolithic engine, every linear curve held against the exact
response of the whole structure from its matrices (physics/frame.py), and the bad-input refusals."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models.frame_model import FrameParams
from pyfmu_wrapper.physics import frame as ref
from pyfmu_wrapper.scenario.engines import RunSettings
from pyfmu_wrapper.scenario.loader import load_scenario, parse_scenario
from pyfmu_wrapper.scenario.runner import curve_structure
from pyfmu_wrapper.scenario.schema import ScenarioError

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def _reference(frame: FrameParams, curve, omegas: np.ndarray) -> np.ndarray:
    """Top-storey amplitude of the curve's structure from its matrices (physics/frame.py)."""
    structure = ref.ShearFrame(
        frame.masses, frame.stiffnesses, frame.dampings, frame.force_amplitude, frame.loaded_storey
    )
    if curve.without_tmd:
        return ref.top_amplitude(structure, None, omegas)
    t = curve.tmd
    lin = ref.LinearTMD(frame.tmd_at, t.mass, t.stiffness, t.damping, t.inertance, inerter_to=frame.terminal)
    return ref.top_amplitude(structure, lin, omegas)


def test_the_frame_scenarios_read_as_the_issue_states():
    s3 = load_scenario(SCENARIOS / "frame3_tmdi.yaml")
    assert isinstance(s3.base, FrameParams) and s3.base.n == 3 and s3.base.masses == (100.0,) * 3
    assert s3.base.stiffnesses == (1.2e5,) * 3 and s3.base.dampings == (100.0,) * 3 and s3.base.loaded_storey == 3
    (study,) = s3.studies
    assert study.name == "frame3_frc" and len(study.omegas) == 61 and (study.omegas[0], study.omegas[-1]) == (10, 25)
    labels = [c.label for c in study.curves]
    assert labels == ["no TMD", "TMD-inerter", "TMDI"]
    frames = [curve_structure(s3, c) for c in study.curves]
    assert [(f.tmd_at, f.terminal) for f in frames[1:]] == [(3, 3), (3, 2)]
    assert (study.curves[2].tmd.mass, study.curves[2].tmd.inertance, study.curves[2].tmd.stiffness) == (10, 5, 3500)
    s10 = load_scenario(SCENARIOS / "frame10_tmd.yaml")
    assert s10.base.n == 10 and len(s10.studies[0].omegas) == 81 and s10.studies[0].name == "frame10_frc"
    full = load_scenario(SCENARIOS / "frame3_full.yaml")
    t = full.tmd
    assert (t.mass, t.inertance, t.stiffness, t.damping, t.friction_force, t.play_gap) == (9, 1, 4000, 10, 10, 1e-4)
    assert (t.mesh_stiffness, t.mesh_damping, full.base.terminal) == (2e7, 0.01, 3)
    assert full.studies[0].name == "frame3_full_frc" and len(full.studies[0].omegas) == 41


@pytest.mark.parametrize("name", ["frame3_tmdi", "frame10_tmd"])
@pytest.mark.parametrize("linear", ["exact", "simulate"])
def test_linear_frame_curves_are_the_structures_exact_response(name, linear, tmp_path):
    """run-scenario --engine monolithic: every curve to 1e-4 of (K - w^2 (M + B) + i w C) X = F; with
    solver.linear = simulate the curves are integrated to their steady states (not the exact path)."""
    text = (SCENARIOS / f"{name}.yaml").read_text()
    if linear == "simulate":
        text += "solver: {linear: simulate}\n"
        if name == "frame10_tmd":  # every 4th frequency: the integrated path, in a few seconds
            text = text.replace("count: 81", "count: 21")
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    assert main([str(path), "--out", str(tmp_path / "out"), "--engine", "monolithic", "--quiet"]) == 0
    scn = load_scenario(path)
    (study,) = scn.studies
    table = pd.read_csv(tmp_path / "out" / f"{study.name}.csv")
    assert list(table.columns[:4]) == ["curve", "engine", "method", "direction"]
    for curve in study.curves:
        rows = table[table["curve"] == curve.label]
        assert len(rows) == len(study.omegas) and rows["converged"].all()
        exact = _reference(curve_structure(scn, curve), curve, rows["omega"].to_numpy())
        err = np.max(np.abs(rows["amplitude"].to_numpy() / exact - 1))
        assert err < 1e-4, (curve.label, err)
        assert set(rows["method"]) == {"exact" if linear == "exact" else "steady_state"}


def test_tmdi_beats_the_tmd_inerter_and_both_beat_no_tmd():
    """The reason for the TMDI: with the inerter spanning two storeys the top storey's peak is lower
    (exact responses of the scenario's curves, from the structure's matrices)."""
    scn = load_scenario(SCENARIOS / "frame3_tmdi.yaml")
    w = np.linspace(10.0, 25.0, 3001)
    peaks = {c.label: _reference(curve_structure(scn, c), c, w).max() for c in scn.studies[0].curves}
    assert peaks["TMDI"] < peaks["TMD-inerter"] < peaks["no TMD"]


FRAME_DOC = """\
schema_version: 2
name: bad
frame: {storeys: 3, mass: 100.0, stiffness: 1.2e5, damping: 100.0, force_amplitude: 200.0}
tmd: {mass: 10.0, stiffness: 3500.0, inertance: 5.0}
frequencies: {start: 10.0, stop: 25.0, count: 5}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "a", tmd: {inerter_to: 2}}
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "inerter_to: 2",
            "inerter_to: 4",
            r"bad.yaml:10: studies\[0\].curves\[0\].tmd.inerter_to: must be a storey of the 3-storey frame, 1..3, or 0 for the ground \(got 4\)",
        ),
        ("storeys: 3", "storeys: 21", r"bad.yaml:3: frame.storeys: must be <= 20"),
        ("mass: 100.0,", "mass: [100.0, 100.0],", r"frame.mass: must be one number, or a list of one per storey \(3"),
        ("damping: 100.0", "damping: -1.0", r"frame.damping: must be >= 0"),
        ("frame: {", "base: {mass: 1.0, stiffness: 1.0, damping: 0.0, force_amplitude: 1.0}\nframe: {", "exactly one"),
    ],
)
def test_bad_frame_scenarios_are_refused_with_their_place(old, new, message):
    with pytest.raises(ScenarioError, match=message):
        parse_scenario(FRAME_DOC.replace(old, new), "bad.yaml")


def test_attachment_keys_need_a_frame():
    doc = FRAME_DOC.replace(
        "frame: {storeys: 3, mass: 100.0, stiffness: 1.2e5, damping: 100.0, force_amplitude: 200.0}",
        "base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}",
    )
    with pytest.raises(ScenarioError, match="needs a frame: block"):
        parse_scenario(doc, "bad.yaml")


def test_a_model_without_fmus_is_refused_by_the_cosim_engine_before_any_work(tmp_path, capsys, monkeypatch):
    """A registered model whose unit says it has no FMUs (cosim="") cannot run --engine cosim or
    both: one line naming the model, exit status 2, nothing written (the frame has FMUs: tests of its
    co-simulation in tests/test_frame_cosim.py)."""
    from dataclasses import replace

    from pyfmu_wrapper.models import MODELS

    monkeypatch.setitem(MODELS._units, "frame", replace(MODELS.get("frame"), cosim=""))
    path = tmp_path / "f.yaml"
    path.write_text(textwrap.dedent(FRAME_DOC))
    assert main([str(path), "--out", str(tmp_path / "out"), "--engine", "both"]) == 2
    err = capsys.readouterr().err
    assert "no FMUs of model 'frame' yet" in err and "--engine monolithic" in err
    assert not (tmp_path / "out").exists()
    with pytest.raises(Exception, match="no FMUs"):
        RunSettings.for_scenario(load_scenario(path), engine="cosim")
    assert RunSettings.for_scenario(load_scenario(path), engine="monolithic").engine == "monolithic"
