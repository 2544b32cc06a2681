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
