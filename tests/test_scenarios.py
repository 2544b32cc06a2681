"""Scenario files: every committed file loads; every kind of bad file is refused with a message that
names the file, the line, the key path and the value."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from pyfmu_wrapper.physics.params import CASES, InerterModel
from pyfmu_wrapper.scenario import FRCStudy, MapStudy, PhasePortraitStudy, ScenarioError, load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = sorted((ROOT / "scenarios").glob("*.yaml"))

GOOD = """\
schema_version: 2
name: small
base:
  mass: 100.0
  stiffness: 40000.0
  damping: 100.0
  force_amplitude: 200.0
tmd:
  case: 1
  damping: 0.0
frequencies: {start: 15.0, stop: 25.0, count: 11}
sweep:
  direction: up
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "no TMD", without_tmd: true}
      - {label: "c = 10", tmd: {damping: 10.0}}
  - kind: map
    name: map
    parameter: damping
    values: [0.0, 10.0, 20.0, 30.0]
"""


def write(tmp_path, text, name="s.yaml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def error_for(tmp_path, text) -> ScenarioError:
    p = write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    msg = str(info.value)
    assert str(p) in msg, msg
    return info.value


# --- committed files -----------------------------------------------------------------------------


def test_every_paper_study_has_a_file():
    names = {p.stem for p in SCENARIOS}
    expected = {"iratio"} | {f"{s}_case{c}" for s in ("viscous", "friction", "play", "full") for c in (1, 2, 3)}
    assert expected <= names


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.name)
def test_committed_scenario_loads(path):
    scn = load_scenario(path)
    assert scn.schema_version == 2
    assert scn.name == path.stem  # the default results folder is results/<file stem>
    assert scn.studies
    if not path.stem.startswith(
        "frame"
    ):  # the paper's base: sqrt(K/M) = 20 rad/s (frames: tests/test_frame_scenarios.py)
        assert scn.base.natural_frequency == pytest.approx(20.0)
    for st in scn.studies:
        assert np.all(st.omegas > 0) if not isinstance(st, PhasePortraitStudy) else all(w > 0 for w in st.omegas)


def test_full_case1_is_the_papers_fig6a():
    scn = load_scenario(ROOT / "scenarios" / "full_case1.yaml")
    frc = scn.studies[0]
    assert isinstance(frc, FRCStudy)
    assert frc.omegas[0] == 15.0 and frc.omegas[-1] == 25.0 and len(frc.omegas) >= 41
    full = [c.tmd for c in frc.curves if c.label.startswith("5")][0]
    assert (full.mass, full.inertance) == (9.0, 1.0)
    assert (full.damping, full.friction_force, full.play_gap) == (10.0, 10.0, 1e-4)
    assert full.inerter == InerterModel.PLAY and full.mesh_stiffness == 2e7 and full.mesh_damping == 0.01
    simple = [c.tmd for c in frc.curves if c.label.startswith("6")][0]
    assert simple.damping == 15.0 and simple.is_linear and simple.inerter == InerterModel.IDEAL


def test_progress_units_of_command_1():
    """README command 1: 6 + 2 curves x 41 frequencies, sweep up = 328 points, of which the 2 x 41
    of the second study repeat curves 5 and 6 of the first (computed once): the ETA leaves them
    out of the work to do. With the monolithic engine the three linear curves (1, 3, 6; exact
    response) cost nothing too: 3 x 41 more (curve 6 counted once)."""
    from pyfmu_wrapper.scenario.engines import RunSettings
    from pyfmu_wrapper.scenario.runner import instant_units, work_units

    scn = load_scenario(ROOT / "scenarios" / "full_case1.yaml")
    co = RunSettings.for_scenario(scn, engine="cosim")
    assert work_units(scn, co) == (6 + 2) * 41 and instant_units(scn, co) == 2 * 41
    mono = RunSettings.for_scenario(scn, engine="monolithic")
    assert instant_units(scn, mono) == (2 + 3) * 41


@pytest.mark.parametrize("case,c_opt,df_opt", [(1, 56.38, 45.78), (2, 31.73, 37.65), (3, 6.45, 15.44)])
def test_optimised_values_of_the_paper(case, c_opt, df_opt):
    v = load_scenario(ROOT / "scenarios" / f"viscous_case{case}.yaml")
    f = load_scenario(ROOT / "scenarios" / f"friction_case{case}.yaml")
    for scn in (v, f):
        assert (scn.tmd.mass, scn.tmd.inertance) == (CASES[case]["mass"], CASES[case]["inertance"])
    frc_v = [s for s in v.studies if s.kind == "frc"][0]
    frc_f = [s for s in f.studies if s.kind == "frc"][0]
    assert {c.tmd.damping for c in frc_v.curves} >= {0.0, 10.0, c_opt, 90.0}
    assert {c.tmd.friction_force for c in frc_f.curves} >= {0.0, 10.0, df_opt, 90.0}
    m = [s for s in v.studies if s.kind == "map"][0]
    assert m.parameter == "damping" and m.values[0] == 0.0 and m.values[-1] == 100.0


def test_play_and_iratio_files():
    p = load_scenario(ROOT / "scenarios" / "play_case2.yaml")
    m = [s for s in p.studies if isinstance(s, MapStudy)][0]
    assert m.parameter == "play_gap" and m.values[-1] == pytest.approx(2e-3)
    assert all(t.mesh_stiffness == 2e7 and t.mesh_damping == 0.01 for t in m.tmds)
    ph = [s for s in p.studies if isinstance(s, PhasePortraitStudy)][0]
    assert set(ph.omegas) == {19.0, 21.0}
    assert [c.tmd.play_gap for c in ph.curves] == [0.0, 5e-5, 1e-4, 1e-3]
    r = load_scenario(ROOT / "scenarios" / "iratio.yaml")
    m = r.studies[0]
    assert m.parameter == "inertance_ratio" and m.values[0] == 0.0 and m.values[-1] < 1.0
    assert m.tmds[0].inerter == InerterModel.NONE and m.tmds[1].inerter == InerterModel.IDEAL
    assert all(t.inertia == pytest.approx(10.0) for t in m.tmds)
    ratios = [c.tmd.inertance_ratio for c in r.studies[1].curves if not c.without_tmd]
    assert ratios == pytest.approx([0.0, 0.1, 0.5, 0.9, 1.0])


def test_good_small_scenario(tmp_path):
    scn = load_scenario(write(tmp_path, GOOD))
    assert [s.kind for s in scn.studies] == ["frc", "map"]
    assert scn.studies[0].curves[1].tmd.damping == 10.0
    assert scn.studies[0].curves[0].tmd.stiffness == 0.0  # detached
    assert [t.damping for t in scn.studies[1].tmds] == [0.0, 10.0, 20.0, 30.0]


def test_yaml12_floats_are_numbers(tmp_path):
    scn = load_scenario(
        write(tmp_path, GOOD.replace("damping: 0.0\nfreq", "damping: 0.0\n  mesh_stiffness: 3e7\nfreq"))
    )
    assert scn.tmd.mesh_stiffness == 3e7


# --- bad files -----------------------------------------------------------------------------------


def test_unknown_key(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  damping: 0.0\nfreq", "  dampnig: 0.0\nfreq"))
    assert "tmd.dampnig" in str(e) and "unknown key" in str(e) and ":10:" in str(e)
    assert "friction_force" in str(e)  # the allowed keys are listed


def test_unknown_top_level_key(tmp_path):
    e = error_for(tmp_path, GOOD + "plots: yes\n")
    assert "plots" in str(e) and "unknown key" in str(e)


def test_wrong_type(tmp_path):
    e = error_for(tmp_path, GOOD.replace("stiffness: 40000.0", "stiffness: stiff"))
    assert "base.stiffness" in str(e) and "'stiff'" in str(e) and ":5:" in str(e)


def test_wrong_type_bool_count(tmp_path):
    e = error_for(tmp_path, GOOD.replace("count: 11", "count: 11.5"))
    assert "frequencies.count" in str(e) and "11.5" in str(e) and "integer" in str(e)


def test_missing_field(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  force_amplitude: 200.0\n", ""))
    assert "base.force_amplitude" in str(e) and "missing" in str(e)
    e = error_for(tmp_path, GOOD.replace("    parameter: damping\n", ""))
    assert "studies[1].parameter" in str(e) and "missing" in str(e)


def test_negative_mass(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  mass: 100.0", "  mass: -100.0"))
    assert "base.mass" in str(e) and "-100" in str(e) and ":4:" in str(e)


def test_negative_tmd_friction(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  damping: 0.0\nfreq", "  friction_force: -3.0\nfreq"))
    assert "tmd.friction_force" in str(e) and "-3" in str(e) and ":10:" in str(e)


def test_bad_map_value_names_its_index(tmp_path):
    e = error_for(
        tmp_path,
        GOOD.replace(
            "values: [0.0, 10.0, 20.0, 30.0]", "values:\n      - 0.0\n      - 10.0\n      - 20.0\n      - -5.0"
        ),
    )
    assert "studies[1].values[3]" in str(e) and "-5" in str(e) and ":27:" in str(e)
    assert e.path == "studies[1].values[3]" and e.value == -5.0


def test_bad_curve_value(tmp_path):
    e = error_for(tmp_path, GOOD.replace("tmd: {damping: 10.0}", "tmd: {damping: -10.0}"))
    assert "studies[0].curves[1].tmd.damping" in str(e) and "-10" in str(e) and ":19:" in str(e)


def test_inertance_with_no_inerter(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  case: 1\n", "  case: 1\n  inerter: none\n"))
    assert "inertance" in str(e) and "none" in str(e)


def test_non_physical_frequencies(tmp_path):
    e = error_for(tmp_path, GOOD.replace("start: 15.0, stop: 25.0", "start: -15.0, stop: 25.0"))
    assert "frequencies.start" in str(e) and "-15" in str(e)
    e = error_for(tmp_path, GOOD.replace("start: 15.0, stop: 25.0", "start: 25.0, stop: 15.0"))
    assert "frequencies.stop" in str(e)


def test_bad_choice_and_version(tmp_path):
    e = error_for(tmp_path, GOOD.replace("direction: up", "direction: sideways"))
    assert "sweep.direction" in str(e) and "'sideways'" in str(e) and "both" in str(e)
    e = error_for(tmp_path, GOOD.replace("schema_version: 2", "schema_version: 3"))
    assert "schema_version" in str(e) and "3" in str(e)
    e = error_for(tmp_path, GOOD.replace("case: 1", "case: 4"))
    assert "tmd.case" in str(e) and "4" in str(e)


def test_duplicate_key(tmp_path):
    e = error_for(tmp_path, GOOD.replace("  damping: 0.0\nfreq", "  damping: 0.0\n  damping: 1.0\nfreq"))
    assert "duplicate key 'damping'" in str(e) and ":11" in str(e)


def test_malformed_yaml(tmp_path):
    e = error_for(tmp_path, GOOD.replace("count: 11}", "count: 11"))
    assert "not valid YAML" in str(e) and e.line is not None


def test_python_object_tag_is_refused(tmp_path):
    marker = tmp_path / "pwned"
    e = error_for(tmp_path, GOOD.replace("name: small", f"name: !!python/object/apply:os.system ['touch {marker}']"))
    assert "python/object/apply:os.system" in str(e) and ":2:" in str(e)
    assert not marker.exists()


def test_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match="nope.yaml.*cannot read"):
        load_scenario(tmp_path / "nope.yaml")


def test_empty_and_non_mapping(tmp_path):
    assert "empty" in str(error_for(tmp_path, ""))
    assert "mapping" in str(error_for(tmp_path, "- 1\n- 2\n"))


# --- settings blocks: one meaning per key --------------------------------------------------------


def test_settings_blocks_per_engine(tmp_path):
    text = GOOD.replace(
        "sweep:\n  direction: up\n",
        "sweep: {direction: both, continuation: false}\n"
        "solver: {rtol: 1.0e-7, window: 4, linear: simulate}\n"
        "cosim: {accuracy: 1.0e-4, coupling: force, window: 7, shooting: false, "
        "interface_jacobian: false}\n",
    )
    scn = load_scenario(write(tmp_path, text))
    assert (scn.sweep.direction, scn.sweep.continuation) == ("both", False)
    assert scn.solver.settings().rtol == 1e-7 and scn.solver.settings().window == 4 and scn.solver.linear == "simulate"
    cs = scn.cosim.settings()
    assert (cs.accuracy, cs.coupling, cs.window, cs.shooting, cs.interface_jacobian) == (1e-4, "force", 7, False, False)
    from pyfmu_wrapper.cosim.settings import CosimSettings

    assert cs.tol_window == CosimSettings().tol_window  # not taken from solver:


@pytest.mark.parametrize(
    "block,key,value,hint",
    [
        ("solver", "direction", "up", "sweep.direction"),
        ("solver", "continuation", "false", "sweep.continuation"),
        ("solver", "accuracy", "1.0e-4", "cosim.accuracy"),
        ("solver", "coupling", "force", "cosim.coupling"),
        ("cosim", "rtol", "1.0e-6", "solver.rtol"),
        ("cosim", "atol_scale", "1.0e-6", "solver.atol_scale"),
        ("cosim", "linear", "exact", "solver.linear"),
        ("cosim", "direction", "up", "sweep.direction"),
        ("sweep", "rtol", "1.0e-6", "solver.rtol"),
        ("sweep", "accuracy", "1.0e-3", "cosim.accuracy"),
        ("cosim", "bogus", "1", "unknown key"),
    ],
)
def test_inapplicable_settings_are_refused(tmp_path, block, key, value, hint):
    text = GOOD.replace("sweep:\n  direction: up\n", f"{block}:\n  {key}: {value}\n")
    e = error_for(tmp_path, text)
    assert f"{block}.{key}" in str(e) and hint in str(e) and ":13:" in str(e), str(e)
    assert e.path == f"{block}.{key}" and e.line == 13


def test_schema1_files(tmp_path):
    """Schema 1 files are read only without a solver block (the block whose meaning changed)."""
    v1 = GOOD.replace("schema_version: 2", "schema_version: 1")
    e = error_for(tmp_path, v1.replace("sweep:", "solver:"))
    assert "schema_version 1" in str(e) and "solver" in str(e) and "sweep:" in str(e)
    scn = load_scenario(write(tmp_path, v1.replace("sweep:\n  direction: up\n", "")))
    assert scn.sweep.direction == "up" and scn.schema_version == 1


def test_bad_cosim_values(tmp_path):
    e = error_for(tmp_path, GOOD.replace("sweep:\n  direction: up\n", "cosim:\n  coupling: spring\n"))
    assert "cosim.coupling" in str(e) and "'spring'" in str(e)
    e = error_for(tmp_path, GOOD.replace("sweep:\n  direction: up\n", "cosim:\n  accuracy: -1.0\n"))
    assert "cosim.accuracy" in str(e) and "-1" in str(e)
    e = error_for(tmp_path, GOOD.replace("sweep:\n  direction: up\n", "cosim: {min_periods: 9, max_periods: 4}\n"))
    assert "cosim.max_periods" in str(e) and "min_periods = 9" in str(e)
    # the same rule (SteadySettings, shared by both engines) refuses it in the monolithic block, at its line
    e = error_for(tmp_path, GOOD.replace("sweep:\n  direction: up\n", "solver:\n  min_periods: 9\n  max_periods: 4\n"))
    assert (e.path, e.line, e.value) == ("solver.max_periods", 14, 4) and "min_periods = 9" in str(e)


def test_settings_used_by_each_engine(tmp_path):
    """summary.json records the settings the engine used: its blocks only, fully resolved."""
    from pyfmu_wrapper.cosim.settings import CosimSettings
    from pyfmu_wrapper.scenario.engines import RunSettings

    text = GOOD.replace(
        "sweep:\n  direction: up\n", "sweep: {direction: down}\nsolver: {rtol: 1.0e-7}\ncosim: {accuracy: 1.0e-4}\n"
    )
    scn = load_scenario(write(tmp_path, text))
    mono = RunSettings.for_scenario(scn, engine="monolithic").used()
    co = RunSettings.for_scenario(scn, engine="cosim").used()
    both = RunSettings.for_scenario(scn, engine="both").used()
    assert mono["engine"] == "monolithic" and mono["solver"]["rtol"] == 1e-7 and "cosim" not in mono
    assert co["engine"] == "cosim" and co["cosim"]["accuracy"] == 1e-4 and "solver" not in co
    assert both["solver"]["rtol"] == 1e-7 and both["cosim"]["accuracy"] == 1e-4
    for u in (mono, co, both):
        assert u["sweep"] == {"direction": "down", "continuation": True}
    assert co["cosim"]["tol_window"] == CosimSettings().tol_window  # defaults filled in
    assert co["cosim"]["max_periods"] > 0
    assert RunSettings.for_scenario(scn, engine="cosim").directions() == ["down"]
    with pytest.raises(ValueError):
        RunSettings.for_scenario(scn, engine="nope")


# --- checkpoint keys: code version and every setting that changes a number ----------------------

from pyfmu_wrapper.physics.params import BaseParams, paper_case  # noqa: E402
from pyfmu_wrapper.scenario.engines import RunSettings  # noqa: E402
from pyfmu_wrapper.scenario.schema import SolverConfig, SweepConfig  # noqa: E402
from pyfmu_wrapper.scenario.tasks import Checkpoint, SweepTask  # noqa: E402

BASE = BaseParams(mass=100.0, stiffness=4.0e4, damping=100.0, force_amplitude=200.0)


def _fake_table(task):
    import pandas as pd

    from pyfmu_wrapper.scenario.sweeptable import SWEEP_COLUMNS

    n = task.units()
    return pd.DataFrame(
        {c: (["x"] * n if c in ("engine", "method", "direction") else np.arange(n, dtype=float)) for c in SWEEP_COLUMNS}
    ).astype(dict(periods=int, steps=int, rejected=int, converged=bool))


def test_checkpoint_key_follows_every_setting(tmp_path):
    from dataclasses import replace

    from pyfmu_wrapper.cosim.settings import CosimSettings

    w = np.array([18.0, 20.0, 22.0])
    tmd = paper_case(1, friction_force=20.0)
    mono = RunSettings(engine="monolithic", solver=SolverConfig())
    co = RunSettings(engine="cosim", cosim=CosimSettings())
    ck = Checkpoint(tmp_path / "ck")
    for rs in (mono, co):
        t = SweepTask(BASE, tmd, w, rs)
        ck.save(t, _fake_table(t))
        assert ck.load(SweepTask(BASE, tmd, w.copy(), rs)) is not None  # same inputs: reused
    changed = {
        "solver.rtol": replace(mono, solver=SolverConfig(rtol=1e-7)),
        "solver.tol": replace(mono, solver=SolverConfig(tol=1e-5)),
        "solver.window": replace(mono, solver=SolverConfig(window=5)),
        "solver.tol_window": replace(mono, solver=SolverConfig(tol_window=1e-3)),
        "solver.max_periods": replace(mono, solver=SolverConfig(max_periods=100)),
        "solver.linear": replace(mono, solver=SolverConfig(linear="simulate")),
        "sweep.direction": replace(mono, sweep=SweepConfig(direction="down")),
        "sweep.continuation": replace(mono, sweep=SweepConfig(continuation=False)),
        "engine": replace(mono, engine="both", cosim=CosimSettings()),
        "cosim.accuracy": replace(co, cosim=CosimSettings(accuracy=1e-4)),
        "cosim.coupling": replace(co, cosim=CosimSettings(coupling="force")),
        "cosim.tol_window": replace(co, cosim=CosimSettings(tol_window=2e-3)),
        "cosim.fmu_rtol": replace(co, cosim=CosimSettings(fmu_rtol=1e-9)),
    }
    for what, rs in changed.items():
        assert ck.load(SweepTask(BASE, tmd, w, rs)) is None, what
    assert ck.load(SweepTask(BASE, replace(tmd, friction_force=20.5), w, mono)) is None  # a parameter
    assert ck.load(SweepTask(replace(BASE, damping=101.0), tmd, w, mono)) is None
    assert ck.load(SweepTask(BASE, tmd, w + 1e-12, mono)) is None  # a frequency
    # settings the engine does not read do not invalidate it: the monolithic engine and the cosim block
    assert ck.load(SweepTask(BASE, tmd, w, replace(mono, cosim=CosimSettings(accuracy=1e-4)))) is not None
    assert ck.load(SweepTask(BASE, tmd, w, replace(co, solver=SolverConfig(rtol=1e-7)))) is not None


def test_checkpoint_key_follows_the_code(tmp_path, monkeypatch):
    import shutil

    from pyfmu_wrapper.scenario import tasks

    w = np.array([18.0, 22.0])
    task = SweepTask(BASE, paper_case(1, friction_force=20.0), w, RunSettings())
    ck = Checkpoint(tmp_path / "ck")
    ck.save(task, _fake_table(task))
    assert ck.load(task) is not None
    assert task.key_payload()["code"] == tasks.numbers_hash(tasks.PACKAGE_DIR)[:16]
    # a copy of the package (and of the FMU stub beside it) with one kernel line changed has another hash ...
    same, edited = tmp_path / "same" / "pkg", tmp_path / "edited" / "pkg"
    for d in (same, edited):
        shutil.copytree(tasks.PACKAGE_DIR, d, ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.pyc"))
        shutil.copytree(tasks.PACKAGE_DIR.parent / "fmu" / "src", d.parent / "fmu" / "src")
    assert tasks.numbers_hash(same) == tasks.numbers_hash(tasks.PACKAGE_DIR)
    kern = edited / "physics" / "kernels.py"
    kern.write_text(kern.read_text() + "\n# edited\n")
    other = tasks.numbers_hash(edited)[:16]
    assert other != tasks.code_version()
    # ... and a checkpoint written by the old code is not read back by the new one
    monkeypatch.setattr(tasks, "code_version", lambda: other)
    assert ck.load(task) is None
