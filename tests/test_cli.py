"""run-scenario: results folder contents against exact values and the paper's Fig. 2; failures leave
nothing that looks complete; bad input exits 2."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest

from pyfmu_wrapper import plots
from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.physics.params import BaseParams, TMDParams
from pyfmu_wrapper.solvers.frequency_response import exact_amplitude

LINEAR = """\
schema_version: 1
name: fig2_small
description: Fig. 2b, two curves, c = 0
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {mass: 10.0, inertance: 0.0, inerter: none, stiffness: 4000.0, damping: 0.0}
frequencies: {start: 15.0, stop: 25.0, count: 101}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "Iratio = 0", tmd: {inertance_ratio: 0.0}}
      - {label: "Iratio = 1", tmd: {inertance_ratio: 1.0}}
  - kind: map
    name: map
    parameter: inertance_ratio
    values: {start: 0.0, stop: 0.9, count: 4}
    frequencies: {start: 15.0, stop: 25.0, count: 21}
  - kind: phase_portrait
    name: phase
    omegas: [19.0]
    samples_per_period: 64
    curves:
      - {label: "Iratio = 0", tmd: {inertance_ratio: 0.0}}
"""


def write(tmp_path, text, name="scn.yaml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


@pytest.fixture(scope="module")
def linear_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("linear")
    out = tmp / "out"
    rc = main([str(write(tmp, LINEAR)), "--out", str(out), "--quiet", "--engine", "monolithic"])
    assert rc == 0
    return out


def test_outputs_exist(linear_run):
    names = sorted(os.listdir(linear_run))
    files = ["frc.csv", "frc.png", "map.csv", "map.png", "phase.csv", "phase.png", "summary.json"]
    assert names == [".run-scenario.json"] + files
    marker = json.loads((linear_run / ".run-scenario.json").read_text())  # what marks the folder as ours
    assert marker["tool"] == "run-scenario" and marker["kind"] == "result" and marker["scenario"] == "fig2_small"
    assert marker["files"] == files
    for png in ("frc.png", "map.png", "phase.png"):
        assert (linear_run / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # no temporary folders left beside it
    assert sorted(p.name for p in linear_run.parent.iterdir()) == ["out", "scn.yaml"]


def test_csv_matches_exact_amplitude(linear_run):
    t = pd.read_csv(linear_run / "frc.csv")
    base = BaseParams()
    for label, tmd in (("Iratio = 0", TMDParams(mass=10, inertance=0, inerter="none")),
                       ("Iratio = 1", TMDParams(mass=0, inertance=10))):
        c = t[t["curve"] == label]
        assert len(c) == 101 and c["converged"].all() and set(c["method"]) == {"exact"}
        np.testing.assert_allclose(c["amplitude"], exact_amplitude(base, tmd, c["omega"].to_numpy()), rtol=1e-8)
    m = pd.read_csv(linear_run / "map.csv")
    assert sorted(m["value"].unique()) == pytest.approx([0.0, 0.3, 0.6, 0.9])
    row = m[np.isclose(m["value"], 0.3)]
    np.testing.assert_allclose(row["amplitude"], exact_amplitude(base, TMDParams(mass=7, inertance=3),
                                                                 row["omega"].to_numpy()), rtol=1e-8)


def test_summary_peaks_match_paper_fig2(linear_run):
    s = json.loads((linear_run / "summary.json").read_text())
    assert s["scenario"]["name"] == "fig2_small" and s["engine"] == "monolithic"
    assert s["parameters"]["base"]["mass"] == 100.0 and s["settings"]["sweep"]["direction"] == "up"
    assert s["timings"]["total"] > 0
    frc = {c["label"]: c["directions"]["up"] for c in s["studies"][0]["curves"]}
    # Iratio = 0, c = 0: two peaks at 17.08 and 23.41 rad/s of 0.1171 and 0.0854 m (paper Fig. 2b)
    peaks = frc["Iratio = 0"]["local_maxima"]
    assert [round(p["omega"], 2) for p in peaks] == [17.08, 23.41]
    assert [round(p["amplitude"], 4) for p in peaks] == [0.1171, 0.0854]
    assert frc["Iratio = 0"]["peak_amplitude"] == pytest.approx(0.11706, abs=1e-5)
    assert frc["Iratio = 0"]["all_converged"]
    # Iratio = 1 (m = 0): the TMD carries no force, a single 0.1 m peak at 20 rad/s (F / (C w_n))
    one = frc["Iratio = 1"]
    assert len(one["local_maxima"]) == 1
    assert one["peak_amplitude"] == pytest.approx(0.1, rel=1e-3)
    assert one["peak_omega"] == pytest.approx(20.0, abs=0.02)
    mp = s["studies"][1]
    assert mp["parameter"] == "inertance_ratio" and len(mp["peak_per_value"]) == 4
    ph = s["studies"][2]["portraits"][0]
    w = 19.0
    x0 = exact_amplitude(BaseParams(), TMDParams(mass=10, inertance=0, inerter="none"), [w])[0]
    assert ph["x_max"] == pytest.approx(x0, rel=1e-3) and ph["xd_max"] == pytest.approx(w * x0, rel=1e-3)


def test_nonlinear_and_simulated_linear_curves(tmp_path):
    """Friction goes through the steady-state solver; a linear curve with linear: simulate must
    reproduce the exact amplitude."""
    text = LINEAR.replace("count: 101}", "count: 5}").split("  - kind: map")[0]
    text = text.replace("schema_version: 1", "schema_version: 2")
    text = text.replace("studies:", "sweep: {direction: both}\nsolver: {linear: simulate}\nstudies:")
    text = text.replace('- {label: "Iratio = 1", tmd: {inertance_ratio: 1.0}}',
                        '- {label: "df = 10", tmd: {case: 1, friction_force: 10.0}}')
    out = tmp_path / "out"
    assert main([str(write(tmp_path, text)), "--out", str(out), "--quiet", "--engine", "monolithic"]) == 0
    t = pd.read_csv(out / "frc.csv")
    lin = t[t["curve"] == "Iratio = 0"]
    assert set(lin["method"]) == {"steady_state"} and set(lin["direction"]) == {"up", "down"}
    exact = exact_amplitude(BaseParams(), TMDParams(mass=10, inertance=0, inerter="none"), lin["omega"].to_numpy())
    np.testing.assert_allclose(lin["amplitude"], exact, rtol=1e-4, atol=1e-8)  # atol: the antiresonance at 20 rad/s
    fr = t[t["curve"] == "df = 10"]
    assert fr["converged"].all() and (fr["periods"] > 0).all()
    s = json.loads((out / "summary.json").read_text())
    d = s["studies"][0]["curves"][1]["directions"]
    assert set(d) == {"up", "down"} and d["up"]["all_converged"] and d["up"]["method"] == "steady_state"


def test_failed_run_leaves_no_results(tmp_path, monkeypatch, capsys):
    scn = write(tmp_path, LINEAR)
    out = tmp_path / "out"
    calls = []

    def broken_save(fig, path, dpi=120):
        calls.append(path)
        if len(calls) == 2:  # first study written completely, then a failure
            raise RuntimeError("disk full (simulated)")
        fig.savefig(path, dpi=dpi)

    monkeypatch.setattr(plots, "save_figure", broken_save)
    assert main([str(scn), "--out", str(out), "--quiet", "--engine", "monolithic"]) == 1
    err = capsys.readouterr().err
    assert "disk full (simulated)" in err and "no results were written" in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn.yaml"]  # no partial folder left

    # an earlier complete result is kept untouched by a failed re-run
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=120: fig.savefig(path, dpi=dpi))
    assert main([str(scn), "--out", str(out), "--quiet", "--engine", "monolithic"]) == 0
    before = (out / "summary.json").read_text()
    calls.clear()
    monkeypatch.setattr(plots, "save_figure", broken_save)
    assert main([str(scn), "--out", str(out), "--quiet", "--engine", "monolithic"]) == 1
    assert (out / "summary.json").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "scn.yaml"]


def test_missing_file_exits_2(tmp_path, capsys):
    assert main([str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err
    assert "missing.yaml" in err and "cannot read" in err


def test_invalid_scenario_exits_2(tmp_path, capsys):
    p = write(tmp_path, LINEAR.replace("damping: 100.0", "damping: -1.0"))
    assert main([str(p), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert str(p) in err and "base.damping" in err and "-1" in err
    assert not (tmp_path / "out").exists()


def test_unknown_engine_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main([str(write(tmp_path, LINEAR)), "--engine", "nonsense"])
    assert e.value.code == 2
    assert "nonsense" in capsys.readouterr().err


def test_console_script_missing_file(tmp_path):
    exe = shutil.which("run-scenario") or shutil.which("run-scenario", path=os.path.dirname(sys.executable))
    cmd = [exe] if exe else [sys.executable, "-m", "pyfmu_wrapper.cli.run_scenario"]
    r = subprocess.run(cmd + [str(tmp_path / "nope.yaml")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "nope.yaml" in r.stderr and "cannot read" in r.stderr


def test_cosim_options_refused_with_the_monolithic_engine(tmp_path, capsys):
    p = write(tmp_path, LINEAR)
    for opt in (["--accuracy", "1e-4"], ["--coupling", "force"]):
        assert main([str(p), "--out", str(tmp_path / "o"), "--quiet", "--engine", "monolithic"] + opt) == 2
        assert "co-simulation" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_summary_records_the_engine_settings(linear_run):
    s = json.loads((linear_run / "summary.json").read_text())
    assert s["settings"]["engine"] == "monolithic" and s["settings"]["solver"]["linear"] == "exact"
    assert "cosim" not in s["settings"] and len(s["code_version"]) == 16
