"""Results that say what ran and plots for a report (issue 42): the plotted maximum of every curve is
its reported peak (held against a dense grid of the exact response), the y-label names the body, the
legend names each curve's attachment, summary.json and the CSV carry the attachment (no
``inerter_to: -1``), summary.md repeats summary.json's peaks, ``plot: {yscale: log}``, the ``--engine
both`` headline over the points both engines call regular; and diagnose's input checks against the
model (a time base in ms, a free decay said so), its progress and its worked example."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from pyfmu_wrapper.scenario import ScenarioError, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def frame_run(tmp_path_factory):
    """scenarios/frame3_tmdi.yaml on the monolithic engine (linear: the exact response, fast)."""
    from pyfmu_wrapper.scenario.engines import RunSettings
    from pyfmu_wrapper.scenario.output import run_scenario

    scn = load_scenario(ROOT / "scenarios" / "frame3_tmdi.yaml")
    out = tmp_path_factory.mktemp("frame") / "out"
    datas: list = []
    run_scenario(scn, out, RunSettings.for_scenario(scn, engine="monolithic", workers=1), collect=datas)
    return scn, out, datas


def test_the_plotted_maximum_is_the_reported_peak_and_the_exact_one(frame_run):
    from pyfmu_wrapper.models.solve import exact_amplitude
    from pyfmu_wrapper.scenario import plots

    scn, out, datas = frame_run
    summary = json.loads((out / "summary.json").read_text())
    fig = plots.frc_plot(datas[0])
    ax = fig.axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    for c, curve in zip(summary["studies"][0]["curves"], scn.studies[0].curves):
        peak = c["directions"]["up"]["peak_amplitude"]
        drawn = float(np.max(lines[c["label"]].get_ydata()))
        assert abs(drawn / peak - 1) <= 1e-3, (c["label"], drawn, peak)  # the issue's 0.1 %
        # the peak itself against the exact response on a grid 1000 times finer around it
        w0 = c["directions"]["up"]["peak_omega"]
        w = np.linspace(w0 - 0.25, w0 + 0.25, 20001)
        base = curve.structure if curve.structure is not None else scn.base
        dense = float(np.max(exact_amplitude(base, curve.tmd, w)))
        assert abs(peak / dense - 1) <= 1e-6, (c["label"], peak, dense)
    assert ax.get_ylabel() == "max |x| of the top storey [m]"
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(t.startswith("TMDI") and "storey 3, inerter to storey 2" in t for t in texts), texts
    assert any(t.startswith("TMD-inerter") and "storey 3, inerter to its own storey" in t for t in texts), texts


def test_summary_and_csv_say_where_each_tmd_was_attached(frame_run):
    scn, out, _ = frame_run
    summary = json.loads((out / "summary.json").read_text())
    frame = summary["parameters"]["frame"]
    assert frame["tmd_storey"] == 3 and frame["inerter_to"] == 3  # resolved: a value the tmd: keys accept
    curves = {c["label"]: c for c in summary["studies"][0]["curves"]}
    assert "attachment" not in curves["no TMD"]
    assert curves["TMD-inerter"]["attachment"]["storey"] == 3 and curves["TMD-inerter"]["attachment"]["inerter_to"] == 3
    assert curves["TMDI"]["attachment"]["inerter_to"] == 2 and curves["TMDI"]["frame"]["inerter_to"] == 2
    table = pd.read_csv(out / "frame3_frc.csv")
    by = table.groupby("curve")
    assert by.get_group("TMDI")["inerter_to"].eq(2).all() and by.get_group("TMDI")["tmd_storey"].eq(3).all()
    assert by.get_group("no TMD")["inerter_to"].isna().all()
    # the scenario reader takes the summary's attachment back: the same TMDI
    text = (ROOT / "scenarios" / "frame3_tmdi.yaml").read_text()
    again = parse_scenario(
        text.replace('{label: "TMDI", tmd: {inerter_to: 2}}', '{label: "TMDI", tmd: {inerter_to: 2, storey: 3}}')
    )
    assert again.studies[0].curves[2].structure.terminal == 2


def test_summary_md_repeats_the_peaks_reductions_and_timings(frame_run):
    _, out, _ = frame_run
    summary = json.loads((out / "summary.json").read_text())
    md = (out / "summary.md").read_text()
    curves = summary["studies"][0]["curves"]
    ref = curves[0]["directions"]["up"]["peak_amplitude"]
    for c in curves:
        p = c["directions"]["up"]
        assert f"| {c['label']} |" in md and f"{p['peak_amplitude']:.4g}" in md and f"{p['peak_omega']:.4g}" in md
        if not c["without_tmd"]:
            assert f"{100 * (1 - p['peak_amplitude'] / ref):.1f} %" in md
    assert "max |x| of the top storey" in md and "## Timings" in md
    assert f"{summary['timings']['compute']:.3g} s" in md


def test_plot_yscale_log_is_read_checked_and_drawn():
    from pyfmu_wrapper.scenario import plots
    from pyfmu_wrapper.scenario.runner import FRCData

    text = (ROOT / "scenarios" / "linear_tmd.yaml").read_text()
    scn = parse_scenario(text + "plot: {yscale: log}\n")
    assert scn.studies[0].yscale == "log"
    w = scn.studies[0].omegas
    tab = pd.DataFrame(
        [
            dict(curve=c.label, direction="up", omega=x, amplitude=1e-3 / (1 + (x - 20) ** 2), converged=True)
            for c in scn.studies[0].curves
            for x in w
        ]
    )
    fig = plots.frc_plot(FRCData(scn.studies[0], tab, {}))
    assert fig.axes[0].get_yscale() == "log"
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text + "plot: {yscale: logarithmic}\n", "s.yaml")
    assert "plot.yscale" in str(e.value) and "s.yaml:" in str(e.value)


def test_engine_both_headline_counts_only_points_both_engines_call_regular():
    from pyfmu_wrapper.scenario.sweeptable import engine_differences

    t = pd.DataFrame(
        dict(
            omega=[1.0, 2.0, 3.0, 4.0],
            amplitude=[1.0, 1.01, 1.5, 1.2],
            reference=[1.0, 1.0, 1.0, 1.0],
            difference=[0.0, 0.01, 0.5, 0.2],
            converged=[True, True, False, True],
            irregular=[False, False, False, True],
            change=[0.0, 0.0, 0.0, 0.3],
        )
    )
    d = engine_differences(t)
    assert d["regular_points"] == 2 and d["max_abs_difference"] == pytest.approx(0.01)
    assert d["not_converged_points"] == 1 and d["max_abs_difference_not_converged"] == pytest.approx(0.5)


# --- diagnose: the input against the model -------------------------------------------------------

NOMINAL = {
    "base": {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0},
    "tmd": {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"},
}


def _dataset(path: Path, t: np.ndarray, records: list[dict], columns: dict) -> Path:
    path.mkdir()
    for r in records:
        pd.DataFrame({"t": t, **columns}).to_csv(path / r["file"], index=False)
    (path / "dataset.yaml").write_text(yaml.safe_dump({"level": "system", "nominal": NOMINAL, "records": records}))
    return path


def test_a_time_base_in_ms_is_refused_with_the_numbers(tmp_path):
    from pyfmu_wrapper.diagnose.data import DataError, load_dataset

    rng = np.random.default_rng(1)
    t = np.arange(2000) / 256.0 * 1000.0  # 256 Hz written in ms
    cols = {"force": rng.normal(size=t.size), "x": rng.normal(size=t.size), "y": rng.normal(size=t.size)}
    ds = _dataset(tmp_path / "ds", t, [{"file": "r.csv", "kind": "transient"}], cols)
    with pytest.raises(DataError) as e:
        load_dataset(ds)
    msg = str(e.value)
    # the nominal's modes, from the 2x2 eigenproblem solved by hand (the quadratic in w^2)
    M, K, m, k, inert = 100.0, 4.0e4, 9.0, 4.0e3, 1.0
    a = (M + inert) * (m + inert) - inert**2
    b = -((M + inert) * k + (m + inert) * (K + k) - 2 * inert * k)
    c = (K + k) * k - k**2
    top = math.sqrt((-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)) / (2 * math.pi)
    assert f"{top:.4g} Hz" in msg and "0.256 Hz" in msg and "256 Hz: give t in seconds" in msg, msg
    assert "r.csv, column 't'" in msg


def test_a_free_decay_said_so_is_read_and_a_contradiction_refused(tmp_path):
    from pyfmu_wrapper.diagnose.data import DataError, load_dataset

    rng = np.random.default_rng(2)
    t = np.arange(2000) / 256.0
    resp = {"x": rng.normal(size=t.size), "y": rng.normal(size=t.size)}
    ds = load_dataset(_dataset(tmp_path / "a", t, [{"file": "r.csv", "kind": "decay"}], resp))
    assert ds.records[0].kind == "transient" and "force" not in ds.records[0].columns
    ds2 = load_dataset(_dataset(tmp_path / "b", t, [{"file": "r.csv", "kind": "transient", "free_decay": True}], resp))
    assert ds2.records[0].meta["free_decay"] is True
    with pytest.raises(DataError, match="column 'force'.*free decay"):
        load_dataset(
            _dataset(
                tmp_path / "c", t, [{"file": "r.csv", "kind": "decay"}], {**resp, "force": rng.normal(size=t.size)}
            )
        )


def test_diagnose_reports_stages_and_candidates_with_elapsed_time():
    from pyfmu_wrapper.cli.progress import StageProgress
    from pyfmu_wrapper.diagnose import progress

    buf = io.StringIO()
    bar = StageProgress("diagnose", stream=buf, tty=False, interval=0.05, quiet_start=0.0)
    with bar:
        old = progress.set_reporter(bar)
        try:
            progress.stage("time records: fitting the candidates")
            for e in ("viscous", "friction", "cubic"):
                progress.candidate(e)
            import time

            time.sleep(0.4)
        finally:
            progress.set_reporter(old)
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith("diagnose: time records: fitting the candidates") and "elapsed" in lines[0]
    assert any("3 candidate fits done (last: cubic)" in ln for ln in lines), lines
    assert lines[-1].startswith("diagnose: done") and "elapsed" in lines[-1]
    progress.candidate("nothing installed: no effect")  # a library call without a reporter
    quiet = io.StringIO()  # a refusal within the first second: not a line of progress, only its error
    with StageProgress("diagnose", stream=quiet, tty=False, interval=0.05):
        pass
    assert quiet.getvalue() == ""


def test_the_worked_example_is_the_tests_dataset(tmp_path):
    """make-benchmark --example swept-sine writes, byte for byte, the dataset docs/diagnose.md's worked
    example names (tests/test_diagnose_transient.py's make with those arguments)."""
    from pyfmu_wrapper.cli.diagnose import main_make_benchmark
    from tests.test_diagnose_transient import DECAY, SWEEP_DOWN, SWEEP_UP, make

    assert main_make_benchmark(["--example", "swept-sine", str(tmp_path / "ex")]) == 0
    make(tmp_path / "ref", {"dc": 10.0}, [SWEEP_UP, SWEEP_DOWN, DECAY], accel_only=True)
    for name in ("r0.csv", "r1.csv", "r2.csv"):
        assert (tmp_path / "ex" / name).read_bytes() == (tmp_path / "ref" / name).read_bytes(), name
    ours = yaml.safe_load((tmp_path / "ex" / "dataset.yaml").read_text())
    ref = yaml.safe_load((tmp_path / "ref" / "dataset.yaml").read_text())
    assert ours["records"] == ref["records"] and ours["nominal"] == ref["nominal"]
    assert ours["acquisition"] == ref["acquisition"]


def test_time_left_from_each_sweeps_own_cost_per_point(monkeypatch):
    """A cheap curve (no TMD: 50 points in 1 s) then an expensive one (1 s a point): the time left is
    the expensive curve's 89 points at its own 1 s each, not the run's average speed (61 points in
    11 s: 16 s, the issue's "about 49 s left" at 3 min 36 s)."""
    from pyfmu_wrapper.cli import progress as pg

    now = [0.0]
    monkeypatch.setattr(pg.time, "monotonic", lambda: now[0])
    bar = pg.Progress(150, "x", enabled=False)
    bar.task_points("no TMD", 1, 50)
    now[0] = 1.0
    bar.task_points("no TMD", 49, 50)
    bar.task_points("TMD", 1, 100)
    now[0] = 11.0
    bar.task_points("TMD", 10, 100)
    assert bar.done == 61
    assert bar.eta() == pytest.approx(89.0)
    assert 89 * 11.0 / 61 < 17  # what the run's average speed said
    # two sweeps at once: the work left is shared by the two processes
    bar = pg.Progress(200, "y", enabled=False)
    now[0] = 0.0
    bar.task_points("a", 1, 100)
    bar.task_points("b", 1, 100)
    now[0] = 10.0
    bar.task_points("a", 10, 100)  # 1 s a point
    bar.task_points("b", 5, 100)  # 2 s a point
    assert bar.eta() == pytest.approx((89 * 1.0 + 94 * 2.0) / 2)


def test_where_png_shows_a_negative_z_at_its_value(tmp_path, monkeypatch):
    """The winning candidate's held-out z is often below 0 (explained below the noise): its bar ends at
    its own value on a symmetric log axis, not clipped to 0.1 on a log one."""
    from types import SimpleNamespace

    from matplotlib.figure import Figure

    from pyfmu_wrapper.diagnose import plotting

    saved = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: saved.append(self))
    res = {
        "candidates": [
            {"ok": True, "gap_closed": 1.0, "z": -3.1, "effects": ["viscous"]},
            {"ok": True, "gap_closed": 0.62, "z": 41013.7, "effects": ["friction"]},
        ]
    }
    plotting.plot_transient(SimpleNamespace(views=[], nominal_resid=[]), res, tmp_path / "where.png")
    ax = saved[0].axes[-1]
    assert ax.get_xscale() == "symlog"
    ends = sorted(p.get_x() + p.get_width() for p in ax.patches)
    assert ends == pytest.approx([-3.1, 41013.7])
