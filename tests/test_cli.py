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

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models.solve import exact_amplitude
from pyfmu_wrapper.physics.params import BaseParams, TMDParams
from pyfmu_wrapper.scenario import plots

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
    files = ["frc.csv", "frc.png", "map.csv", "map.png", "phase.csv", "phase.png", "summary.json", "summary.md"]
    assert names == [".run-scenario.json"] + files
    marker = json.loads((linear_run / ".run-scenario.json").read_text())  # what marks the folder as ours
    assert marker["tool"] == "run-scenario" and marker["kind"] == "result" and marker["scenario"] == "fig2_small"
    assert sorted(marker["files"]) == files and all(len(h) == 64 for h in marker["files"].values())  # with hashes
    for png in ("frc.png", "map.png", "phase.png"):
        assert (linear_run / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # no temporary folders left beside it
    assert sorted(p.name for p in linear_run.parent.iterdir()) == ["out", "scn.yaml"]


def test_csv_matches_exact_amplitude(linear_run):
    t = pd.read_csv(linear_run / "frc.csv")
    base = BaseParams()
    for label, tmd in (
        ("Iratio = 0", TMDParams(mass=10, inertance=0, inerter="none")),
        ("Iratio = 1", TMDParams(mass=0, inertance=10)),
    ):
        c = t[t["curve"] == label]
        assert len(c) == 101 and c["converged"].all() and set(c["method"]) == {"exact"}
        np.testing.assert_allclose(c["amplitude"], exact_amplitude(base, tmd, c["omega"].to_numpy()), rtol=1e-8)
    m = pd.read_csv(linear_run / "map.csv")
    assert sorted(m["value"].unique()) == pytest.approx([0.0, 0.3, 0.6, 0.9])
    row = m[np.isclose(m["value"], 0.3)]
    np.testing.assert_allclose(
        row["amplitude"], exact_amplitude(base, TMDParams(mass=7, inertance=3), row["omega"].to_numpy()), rtol=1e-8
    )


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
    text = text.replace(
        '- {label: "Iratio = 1", tmd: {inertance_ratio: 1.0}}',
        '- {label: "df = 10", tmd: {case: 1, friction_force: 10.0}}',
    )
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


# --- progress, closing lines, the parallelism switch ----------------------------------------------

PLAY = """\
schema_version: 2
name: irr
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: play, play_gap: 1.0e-4, stiffness: 4000.0, damping: 0.0, mesh_stiffness: 2.0e7,
      mesh_damping: 0.01}
frequencies: [19.5, 20.0]
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "play eps = 1e-4"}
"""


def test_progress_lines_and_closing_lines_when_not_on_a_terminal(tmp_path):
    """stderr to a pipe: plain progress lines (no bar, no carriage returns) per point with an ETA; at
    the end one line per study naming the irregular / unconverged points, the same as the CSV's flags.
    The play model at its antiresonance (20 rad/s) rattles: an irregular point (paper Sect. 6)."""
    p = write(tmp_path, PLAY)
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "pyfmu_wrapper.cli.run_scenario",
        str(p),
        "--out",
        str(out),
        "--executor",
        "sequential",
        "--progress-every",
        "0.5",
    ]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    assert "\r" not in r.stderr and "it/s" not in r.stderr  # no tqdm bar in a log
    import re

    prog = [
        re.match(
            r"run-scenario: irr: (\d+)/(\d+) points \((\d+) %\), (.+) elapsed, (about (.+) left|"
            r"estimating the time left)$",
            ln,
        )
        for ln in r.stderr.splitlines()
        if "points (" in ln
    ]
    assert len(prog) >= 2 and all(prog)
    done = [int(m.group(1)) for m in prog]
    assert done == sorted(done) and done[-1] == 2 and {int(m.group(2)) for m in prog} == {2}
    assert prog[-1].group(6) == "0 s"
    t = pd.read_csv(out / "frc.csv")
    closing = [ln for ln in r.stdout.splitlines() if ln.startswith("run-scenario: frc:")]
    assert len(closing) == 1
    irregular = t[t["irregular"]]["omega"].tolist()
    unconverged = t[~t["converged"]]["omega"].tolist()
    assert irregular == [20.0]  # the premise: the rattling antiresonance point
    assert f"{len(unconverged)} of 2 points not converged, 1 irregular" in closing[0]
    assert "irregular at 20 rad/s (window scatter" in closing[0]
    assert ("not converged)" in closing[0]) == (20.0 in unconverged)


def test_progress_eta_is_the_speed_of_the_points_computed(monkeypatch):
    """ETA = points left x (time so far / points computed); points read back from checkpoints
    (skip) count as done but not in the speed. 50 skipped, 10 computed in 20 s, 40 left: 80 s."""
    from pyfmu_wrapper.cli import progress as rs

    now = [1000.0]
    monkeypatch.setattr(rs.time, "monotonic", lambda: now[0])
    bar = rs.Progress(100, "x", enabled=False)
    assert bar.eta() is None and "estimating" in bar.line()
    bar.skip(50)
    assert bar.eta() is None  # nothing computed yet: no speed
    now[0] += 20.0
    bar(10)
    assert bar.eta() == pytest.approx(80.0)
    assert bar.line() == "run-scenario: x: 60/100 points (60 %), 20 s elapsed, about 1 min 20 s left"
    # points known to cost nothing (a sweep repeated from an earlier study) are not work left
    bar = rs.Progress(100, "x", enabled=False, instant=30)
    now[0] += 10.0
    bar(10)
    assert bar.eta() == pytest.approx(60 * 10.0 / 10)
    bar.skip(30)  # they come: nothing changes in the estimate but the count
    assert bar.eta() == pytest.approx(60 * 10.0 / 10)


def test_one_parallelism_switch_recorded_as_used(tmp_path, capsys):
    """--workers N is the number of processes the sweeps use, and summary.json says how many did;
    the numbers do not depend on it (each sweep is one strict continuation in one process)."""
    text = (
        LINEAR.replace("count: 101}", "count: 4}")
        .split("  - kind: map")[0]
        .replace("schema_version: 1", "schema_version: 2")
    )
    text = text.replace(
        '- {label: "Iratio = 0", tmd: {inertance_ratio: 0.0}}',
        '- {label: "df = 10", tmd: {case: 1, friction_force: 10.0}}',
    )
    text = text.replace(
        '- {label: "Iratio = 1", tmd: {inertance_ratio: 1.0}}',
        '- {label: "df = 20", tmd: {case: 1, friction_force: 20.0}}',
    )
    p = write(tmp_path, text)
    runs = {}
    for n in (1, 2):
        out = tmp_path / f"w{n}"
        assert (
            main([str(p), "--out", str(out), "--quiet", "--engine", "monolithic", "--workers", str(n), "--no-resume"])
            == 0
        )
        s = json.loads((out / "summary.json").read_text())
        assert s["workers"] == n and s["executor"]["processes_used"] == n
        assert s["executor"]["processes_requested"] == n
        runs[n] = pd.read_csv(out / "frc.csv")
    pd.testing.assert_series_equal(runs[1]["amplitude"], runs[2]["amplitude"])  # bit-identical
    # --jobs: a deprecated alias, said so
    assert main([str(p), "--out", str(tmp_path / "j"), "--quiet", "--engine", "monolithic", "--jobs", "1"]) == 0
    assert "--jobs is deprecated" in capsys.readouterr().err
    assert json.loads((tmp_path / "j" / "summary.json").read_text())["workers"] == 1
    # a number that would not be used is refused, not recorded
    for opt, msg in (
        (["--executor", "sequential", "--workers", "2"], "--workers 2 would not be used"),
        (["--jobs", "2", "--workers", "3"], "disagree"),
        (["--workers", "-1"], "--workers must be >= 0"),
    ):
        assert main([str(p), "--out", str(tmp_path / "bad"), "--quiet"] + opt) == 2
        assert msg in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_engine_both_headlines_the_regular_points_only(tmp_path, capsys):
    """--engine both: the headline max |difference| is over the regular points; the irregular play
    point at the antiresonance (no single amplitude: its windows scatter) is listed apart with the
    window scatter of each engine, in summary.json, on the console and in the figure's title."""
    p = write(tmp_path, PLAY.replace("frequencies: [19.5, 20.0]", "frequencies: [19.0, 19.5, 20.0]"))
    out = tmp_path / "out"
    assert main([str(p), "--out", str(out), "--quiet", "--engine", "both", "--executor", "sequential"]) == 0
    t = pd.read_csv(out / "frc.csv")
    irr = t["irregular"].astype(bool) | (t["reference_irregular"] == 1)
    assert irr.tolist() == [False, False, True]  # the premise: 20 rad/s rattles
    reg = t[~irr]
    d = json.loads((out / "summary.json").read_text())["studies"][0]["curves"][0]["directions"]["up"]
    assert d["regular_points"] == 2
    assert d["max_abs_difference"] == pytest.approx(np.abs(reg["amplitude"] / reg["reference"] - 1).max(), rel=1e-6)
    assert d["max_abs_difference"] <= 5e-3  # README: within 0.5 % of the monolithic solver
    (ip,) = d["irregular_points"]
    row = t[irr].iloc[0]
    assert ip["omega"] == 20.0 and ip["scatter"] == pytest.approx(row["change"], rel=1e-8)
    assert ip["reference_scatter"] == pytest.approx(row["reference_change"], rel=1e-8)
    assert ip["difference"] == pytest.approx(row["amplitude"] / row["reference"] - 1, rel=1e-6)
    console = capsys.readouterr().out
    assert (
        f"max |difference| = {100 * d['max_abs_difference']:.3g} % over the 2 points both engines call regular"
        in console
    )
    assert "irregular points (not in that maximum): 20 rad/s" in console


@pytest.mark.parametrize("both", [False, True])
def test_frc_plot_every_curve_visible_units_and_notes_outside(both):
    """Six curves, two of them identical (curve 1 of full_frc.png lay hidden under curve 2): every
    curve gets its own (line style, marker) pair, the legend (with the units of the parameters the
    labels name, and the x / o notes) sits outside the axes, so nothing is drawn over the data."""
    from pyfmu_wrapper.physics.params import TMDParams as T
    from pyfmu_wrapper.scenario.runner import FRCData
    from pyfmu_wrapper.scenario.schema import Curve, FRCStudy

    w = np.linspace(15.0, 25.0, 41)
    labels = ["1: c = 0", "2: eps = 1e-4", "3: c = 10", "4: df = 10", "5: full", "6: c = 15"]
    study = FRCStudy("frc", "t", w, tuple(Curve(lb, T(damping=float(k))) for k, lb in enumerate(labels)))
    rows = []
    for k, lb in enumerate(labels):
        amp = exact_amplitude(BaseParams(), T(damping=10.0 if k != 1 else 10.0), w)  # curves 1 and 2 identical
        rows.append(
            pd.DataFrame(
                dict(
                    curve=lb,
                    direction="up",
                    omega=w,
                    amplitude=amp,
                    converged=True,
                    irregular=w == 20.0,
                    change=0.1,
                    reference=amp if both else np.nan,
                    difference=0.0 if both else np.nan,
                    reference_irregular=0.0,
                )
            )
        )
    fig = plots.frc_plot(FRCData(study, pd.concat(rows, ignore_index=True), {}))
    ax = fig.axes[0]
    curves = [ln for ln in ax.get_lines() if ln.get_label() in labels]
    assert [ln.get_label() for ln in curves] == labels
    styles = {(str(ln.get_linestyle()), ln.get_marker()) for ln in curves}
    assert len(styles) == 6  # each curve distinct in both line style and marker
    assert len({ln.get_marker() for ln in curves}) == 6
    assert curves[0].get_linewidth() > curves[1].get_linewidth()  # the one underneath is wider
    leg = ax.get_legend()
    assert "c [N s/m]" in leg.get_title().get_text() and "df [N]" in leg.get_title().get_text()
    assert "eps [m]" in leg.get_title().get_text()
    texts = [t.get_text() for t in leg.get_texts()]
    assert any(t.startswith("not converged") for t in texts) and any(t.startswith("irregular") for t in texts)
    fig.canvas.draw()
    lb, axb = leg.get_window_extent(), ax.get_window_extent()
    assert lb.x0 >= axb.x1  # the legend and its notes lie outside the data area
    assert not any(t.get_position()[1] < 0.05 and t.get_text().startswith("x:") for t in ax.texts)


def test_phase_portrait_tick_labels_do_not_overlap():
    """play_phase.png: two narrow panels of a +-6.5 mm orbit; the x tick labels used to run into
    each other ('-0.00500.0025...'). Their boxes must be apart, on both axes, in every panel."""
    from pyfmu_wrapper.scenario.engines import TimeSeries
    from pyfmu_wrapper.scenario.runner import PhaseData
    from pyfmu_wrapper.scenario.schema import Curve, PhasePortraitStudy

    study = PhasePortraitStudy(
        "phase", "Case 1", (21.0, 19.0), (Curve("eps = 0", TMDParams()), Curve("eps = 1e-3", TMDParams()))
    )
    data = PhaseData(study)
    t = np.linspace(0.0, 2 * np.pi / 20.0, 400)
    for w in study.omegas:
        for c in study.curves:
            x = 6.5e-3 * np.cos(w * t)
            data.series[(w, c.label)] = TimeSeries(
                t, np.column_stack([x, -w * 6.5e-3 * np.sin(w * t)] + [x * 0] * 4), "m", True, 1, 0.0, 6.5e-3
            )
    fig = plots.phase_portrait_plot(data)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            boxes = [
                lb.get_window_extent(renderer) for lb in axis.get_ticklabels() if lb.get_visible() and lb.get_text()
            ]
            assert len(boxes) >= 3
            for a, b in zip(boxes, boxes[1:]):
                assert not a.overlaps(b), [lb.get_text() for lb in axis.get_ticklabels()]
