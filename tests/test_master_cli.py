"""run-scenario with the co-simulation engine (the default) and with --engine both."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pandas as pd

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models.solve import exact_amplitude
from pyfmu_wrapper.physics.params import BaseParams, TMDParams

SCN = """\
schema_version: 1
name: cosim_small
description: two curves, three frequencies
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: ideal, stiffness: 4000.0, damping: 10.0}
frequencies: {start: 17.0, stop: 23.0, count: 3}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "c = 10"}
      - {label: "df = 10", tmd: {damping: 0.0, friction_force: 10.0}}
"""


def _write(tmp_path):
    p = tmp_path / "scn.yaml"
    p.write_text(textwrap.dedent(SCN))
    return p


def test_default_engine_is_cosim(tmp_path):
    out = tmp_path / "out"
    assert main([str(_write(tmp_path)), "--out", str(out), "--quiet", "--executor", "sequential"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["engine"] == "cosim"
    t = pd.read_csv(out / "frc.csv")
    assert set(t["engine"]) == {"cosim"} and t["converged"].all()
    lin = t[t["curve"] == "c = 10"]
    exact = exact_amplitude(BaseParams(), TMDParams(damping=10.0), lin["omega"].to_numpy())
    np.testing.assert_allclose(lin["amplitude"], exact, rtol=5e-3)


def test_engine_both_writes_the_difference(tmp_path):
    out = tmp_path / "out"
    assert (
        main([str(_write(tmp_path)), "--out", str(out), "--quiet", "--engine", "both", "--executor", "sequential"]) == 0
    )
    t = pd.read_csv(out / "frc.csv")
    assert np.isfinite(t["reference"]).all()
    np.testing.assert_allclose(t["difference"], t["amplitude"] / t["reference"] - 1, atol=1e-8)  # csv: 10 digits
    assert np.abs(t["difference"]).max() <= 5e-3
    s = json.loads((out / "summary.json").read_text())
    for c in s["studies"][0]["curves"]:
        d = c["directions"]["up"]
        assert d["max_abs_difference"] == max(abs(r["difference"]) for r in d["difference"]) <= 5e-3
        assert len(d["difference"]) == 3
    assert (out / "frc.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_engine_both_has_no_relative_difference_to_a_zero_reference(tmp_path):
    """The undamped ideal inerter's antiresonance (20 rad/s): the exact amplitude is zero to
    rounding (~1e-16 m), so the relative difference is NaN in the CSV and null in the summary,
    not ~1e10; the other point keeps its difference."""
    scn = SCN.replace("damping: 10.0}", "damping: 0.0}").replace(
        "{start: 17.0, stop: 23.0, count: 3}", "{start: 19.5, stop: 20.0, count: 2}"
    )
    scn = scn.replace('      - {label: "df = 10", tmd: {damping: 0.0, friction_force: 10.0}}\n', "")
    p = tmp_path / "scn.yaml"
    p.write_text(scn)
    out = tmp_path / "out"
    assert main([str(p), "--out", str(out), "--quiet", "--engine", "both", "--executor", "sequential"]) == 0
    t = pd.read_csv(out / "frc.csv").set_index("omega")
    exact = exact_amplitude(BaseParams(), TMDParams(damping=0.0), np.array([19.5, 20.0]))
    assert exact[1] < 1e-9 * exact[0]  # the premise: a zero of the exact response
    assert np.isnan(t.loc[20.0, "difference"]) and t.loc[20.0, "amplitude"] < 1e-3 * exact[0]
    assert abs(t.loc[19.5, "difference"]) <= 5e-3
    d = json.loads((out / "summary.json").read_text())["studies"][0]["curves"][0]["directions"]["up"]
    assert [r["difference"] is None for r in d["difference"]] == [False, True]
    assert d["max_abs_difference"] == abs(d["difference"][0]["difference"])
