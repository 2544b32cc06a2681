"""summary.json's timing split of the co-simulation engine: the seconds inside each FMU, in the
compiled stepping loop, in Python steps and in the steady-state logic add up to the points' wall time."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pandas as pd

from pyfmu_wrapper.cli.run_scenario import main

SCENARIO = """\
schema_version: 2
name: timing
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: ideal, stiffness: 4000.0, damping: 10.0, friction_force: 5.0}
frequencies: {start: 17.0, stop: 21.0, count: 3}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "friction"}
"""


def test_summary_splits_cosim_time_inside_fmus_loop_and_logic(tmp_path):
    scn = tmp_path / "scn.yaml"
    scn.write_text(textwrap.dedent(SCENARIO))
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out), "--quiet", "--engine", "cosim", "--no-resume"]) == 0
    split = json.loads((out / "summary.json").read_text())["timings"]["cosim"]
    table = pd.read_csv(out / "frc.csv")
    assert split["points"] == len(table) == 3
    assert np.isclose(split["wall_time"], np.sum(table["wall_time"]), rtol=1e-9)  # the same seconds (CSV: 9 digits)
    parts = [split["fmus"]["base"], split["fmus"]["tmd"], split["master_loop"], split["python_steps"]]
    assert all(p >= 0.0 for p in parts) and split["fmus"]["tmd"] > 0.0 and split["fmus"]["base"] > 0.0
    # an accounting identity: the four parts and the logic add up to the wall time of the points
    assert abs(sum(parts) + split["steady_state_logic"] - split["wall_time"]) <= 1e-9 * split["wall_time"]
    assert split["steady_state_logic"] >= 0.0
    # the FRC table carries the same columns per point
    assert np.isclose(table["fmu_time_tmd"].sum(), split["fmus"]["tmd"], rtol=1e-9)


def test_monolithic_rows_carry_no_cosim_split(tmp_path):
    scn = tmp_path / "scn.yaml"
    scn.write_text(textwrap.dedent(SCENARIO))
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out), "--quiet", "--engine", "monolithic", "--no-resume"]) == 0
    assert json.loads((out / "summary.json").read_text())["timings"]["cosim"] is None
    assert pd.read_csv(out / "frc.csv")["fmu_time_tmd"].isna().all()


def test_the_split_names_the_fmus_by_their_role_not_their_instance():
    """The FMU seconds go to the columns by role, whatever a model names its instances: the structure's FMU
    (the instance of the observed displacement) to fmu_time_base, every other (the absorber) to fmu_time_tmd;
    the paper's pair's instances are those roles' names. Without the compiled loop (no FMU times) no column."""
    from pyfmu_wrapper.cosim.steady import _time_split

    def timing(frame: float, absorber: float) -> dict:
        fmus = {"frame": {"seconds": frame, "calls": 1}, "absorber": {"seconds": absorber, "calls": 1}}
        return {"fmus": fmus, "master_seconds": frame + absorber + 1.0, "python_seconds": 0.5}

    split = _time_split(timing(1.0, 2.0), timing(1.25, 2.5), "frame")
    assert split == {"fmu_time_base": 0.25, "fmu_time_tmd": 0.5, "master_loop_time": 0.75, "python_step_time": 0.0}
    none = {"fmus": {}, "master_seconds": 0.0, "python_seconds": 0.0}
    assert set(_time_split(none, none, "frame")) == {"master_loop_time", "python_step_time"}
