"""diagnose / make-benchmark / score: input checks of issue 28 (items 7-9) and the transient link
record of issue 31 -- each a case that failed (traceback, or silently accepted) before."""

from __future__ import annotations

import json
import math
import os
import stat

import numpy as np
import pandas as pd
import pytest
import yaml

from pyfmu_wrapper.cli.diagnose import main_diagnose, main_make_benchmark, main_score
from pyfmu_wrapper.diagnose.data import DataError, load_dataset
from pyfmu_wrapper.diagnose.link.benchmark import make_dataset
from pyfmu_wrapper.diagnose.records import write_record

NOM = {"stiffness": 4000.0, "damping": 40.0, "inertance": 1.0}


def _random_link(tmp_path, n_rec=3, fs=500.0, seconds=20.0, seed=0):
    """Band-limited random displacement (0.5-5 Hz) on a link with 6 N of dry friction the nominal
    lacks; force with 0.5 N of noise: records without a drive frequency."""
    from scipy.signal import butter, sosfiltfilt

    tmp_path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / fs)
    sos = butter(4, [0.5, 5.0], btype="band", fs=fs, output="sos")
    files = []
    for i in range(n_rec):
        d = sosfiltfilt(sos, rng.normal(size=t.size))
        d *= 0.01 / d.std()
        v, a = np.gradient(d, t), np.gradient(np.gradient(d, t), t)
        F = 4000 * d + 40 * v + a + 6.0 * (2 / np.pi) * np.arctan(1e4 * v) + rng.normal(0, 0.5, t.size)
        write_record(tmp_path / f"r{i}.csv", {"t": t, "displacement": d, "force": F})
        files.append(f"r{i}.csv")
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": "link", "nominal": NOM, "records": files}))
    return tmp_path


def test_link_transient_records_without_frequency_get_a_report(tmp_path, capsys):
    """The report writer formatted r['omega'] = None (TypeError, exit 1, nothing written)."""
    ds = _random_link(tmp_path / "ds")
    out = tmp_path / "out"
    assert main_diagnose([str(ds), "--out", str(out)]) == 0
    rep = (out / "report.md").read_text()
    assert "none (transient)" in rep
    res = json.loads((out / "diagnosis.json").read_text())
    assert all(r["omega"] is None for r in res["where"]["per_record"])
    assert res["attribution"]["effects"] == ["friction"]  # the 6 N the nominal lacks
    assert abs(res["attribution"]["params"]["friction.friction_force"] - 6.0) < 0.6


def _link_ds(tmp_path, **kw):
    make_dataset(tmp_path, {"friction": 6.0}, seed=3)
    y = yaml.safe_load((tmp_path / "dataset.yaml").read_text())
    return y


def test_time_in_milliseconds_without_velocity_is_a_located_error(tmp_path, capsys):
    """T in ms and no velocity column gave a LinAlgError traceback."""
    y = _link_ds(tmp_path)
    for r in y["records"]:
        f = tmp_path / r["file"]
        df = pd.read_csv(f, comment="#")
        df["t"] *= 1000.0
        df.drop(columns=["velocity", "acceleration"]).to_csv(f, index=False)
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "w15_A10mm.csv" in err and "Nyquist" in err and "seconds" in err
    assert "Traceback" not in err


def test_declared_omega_ten_times_the_data_is_refused(tmp_path, capsys):
    """A declared omega 10x the record's frequency was accepted silently."""
    y = _link_ds(tmp_path)
    y["records"][4]["omega"] *= 10.0  # w20_A20mm: 200 rad/s declared, 20 rad/s in the data
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(y))
    with pytest.raises(DataError, match=r"w20_A20mm\.csv.*declared drive frequency w = 200 rad/s.*20 rad/s"):
        load_dataset(tmp_path)
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2


def test_declared_omega_within_tolerance_is_accepted(tmp_path):
    y = _link_ds(tmp_path)
    y["records"][0]["omega"] *= 1.01  # 1 % off: a rounded declaration is fine
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(y))
    assert len(load_dataset(tmp_path).records) == 9


def test_omega_and_conflicting_frequency_hz(tmp_path):
    y = _link_ds(tmp_path)
    y["records"][0]["frequency_hz"] = 3.0  # omega 15 rad/s = 2.387 Hz
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(y))
    with pytest.raises(DataError, match=r"omega = 15.0 rad/s and frequency_hz = 3.0 Hz.*disagree"):
        load_dataset(tmp_path)
    y["records"][0]["frequency_hz"] = 15.0 / (2 * math.pi)  # the same frequency twice is fine
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(y))
    assert load_dataset(tmp_path).records[0].omega == pytest.approx(15.0)


def test_same_record_listed_twice(tmp_path):
    y = _link_ds(tmp_path)
    y["records"].append({"file": "./" + y["records"][2]["file"], "role": "test"})
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(y))
    with pytest.raises(DataError, match=r"records\[9\] \(\./w15_A30mm\.csv\) is the same file as records\[2\]"):
        load_dataset(tmp_path)


def test_duplicated_force_column(tmp_path):
    t = np.arange(200) * 0.005
    d = 0.01 * np.sin(20 * t)
    rows = "\n".join(f"{a},{b},{4000 * b},{4000 * b + 1}" for a, b in zip(t, d))
    (tmp_path / "r.csv").write_text("t,displacement,force,force\n" + rows + "\n")
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": "link", "nominal": NOM, "records": ["r.csv"]}))
    with pytest.raises(DataError, match=r"r\.csv, column 'force': column\(s\) \['force'\] appear more than once"):
        load_dataset(tmp_path)


def test_make_benchmark_system_honours_fractions_and_refuses_noise(tmp_path, capsys, monkeypatch):
    """--clean-fraction/--pair-fraction/--noise/--held-out-oov reach the system suite (they were ignored)."""
    from pyfmu_wrapper.diagnose import suites
    from pyfmu_wrapper.diagnose.system import suite

    seen = {}

    def fake(out, n, seed, n_clean=None, n_pair=None, n_oov=None, progress=None, held_out_oov=False):
        seen.update(n=n, counts=suites.counts("system", n, n_clean, n_pair, n_oov), held_out=held_out_oov)
        (out / "manifest.json").write_text(json.dumps({"datasets": []}))
        return []

    monkeypatch.setattr(suite, "make_system_benchmark", fake)
    assert main_make_benchmark(["--out", str(tmp_path / "b"), "-n", "4", "--clean-fraction", "1"]) == 0
    assert seen["counts"] == (4, 0, 0, 0)  # (clean, single, pair, oov)
    assert main_make_benchmark(["--out", str(tmp_path / "c"), "-n", "10", "--pair-fraction", "0.5"]) == 0
    assert seen["counts"][2] == 5 and sum(seen["counts"]) == 10
    assert main_make_benchmark(["--out", str(tmp_path / "d")]) == 0
    assert seen["counts"] == (10, 22, 8, 12) and seen["held_out"] is False  # the default suite unchanged
    assert main_make_benchmark(["--out", str(tmp_path / "h"), "--held-out-oov"]) == 0
    assert seen["held_out"] is True
    capsys.readouterr()
    assert main_make_benchmark(["--out", str(tmp_path / "e"), "--noise", "0.3"]) == 2
    assert "--noise 0.3" in capsys.readouterr().err and not (tmp_path / "e").exists()
    assert main_make_benchmark(["--out", str(tmp_path / "f"), "--suite", "link", "--oov-fraction", "0.1"]) == 2
    assert main_make_benchmark(["--out", str(tmp_path / "g"), "--clean-fraction", "0.6", "--oov-fraction", "0.6"]) == 2


@pytest.mark.parametrize(
    ("suite_name", "module", "func"),
    [
        ("transient", "pyfmu_wrapper.diagnose.system.transient_suite", "make_transient_benchmark"),
        ("frame", "pyfmu_wrapper.diagnose.framebench.suite", "make_frame_benchmark"),
    ],
)
def test_make_benchmark_default_composition_is_the_suites_own(tmp_path, monkeypatch, suite_name, module, func):
    """make-benchmark --suite S without shares writes the class counts the suite's generator takes by
    default (the command line once drew the transient suite with the system suite's shares)."""
    import importlib

    from pyfmu_wrapper.diagnose import suites

    mod = importlib.import_module(module)
    seen = {}

    def fake(out, n, seed, n_clean=None, n_pair=None, n_oov=None, progress=None, **kw):
        seen["counts"] = suites.counts(suite_name, n, n_clean, n_pair, n_oov)
        (out / "manifest.json").write_text(json.dumps({"datasets": []}))
        return []

    monkeypatch.setattr(mod, func, fake)
    assert main_make_benchmark(["--out", str(tmp_path / "b"), "--suite", suite_name]) == 0
    want = suites.SUITES[suite_name]
    n = want.n
    nc, npair, no = round(want.clean * n), round(want.pair * n), round(want.oov * n)
    assert seen["counts"] == (nc, n - nc - npair - no, npair, no)


def test_score_out_in_a_missing_folder_is_refused_before_scoring(tmp_path, capsys, monkeypatch):
    """Score --out nodir/sub/score.json is refused before any scoring (it failed only after it)."""
    from pyfmu_wrapper.diagnose.link import benchmark

    (tmp_path / "b" / "ds000").mkdir(parents=True)
    (tmp_path / "b" / "manifest.json").write_text(
        json.dumps({"datasets": [{"dataset": "ds000", "hidden": [], "truth": {}}]})
    )

    def boom(*a, **k):
        raise AssertionError("scored before checking --out")

    monkeypatch.setattr(benchmark, "score", boom)
    assert main_score([str(tmp_path / "b"), "--out", str(tmp_path / "nodir" / "sub" / "score.json")]) == 2
    assert "does not exist" in capsys.readouterr().err
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):  # (root writes anywhere)
            assert main_score([str(tmp_path / "b"), "--out", str(ro / "score.json")]) == 2
            assert "not writable" in capsys.readouterr().err
    finally:
        ro.chmod(0o700)


def test_result_folders_follow_the_umask(tmp_path):
    """Diagnose and make-benchmark folders were created mode 700 (mkdtemp)."""
    ds = tmp_path / "ds"
    ds.mkdir()
    t = np.arange(600) * (2 * math.pi / 20.0) / 200
    d = 0.01 * np.sin(20.0 * t)
    write_record(ds / "r0.csv", {"t": t, "displacement": d, "force": 4e3 * d})
    write_record(ds / "r1.csv", {"t": t, "displacement": 2 * d, "force": 8e3 * d})
    (ds / "dataset.yaml").write_text(
        yaml.safe_dump({"level": "link", "nominal": {"stiffness": 4e3}, "records": ["r0.csv", "r1.csv"]})
    )
    old = os.umask(0o022)
    try:
        assert main_diagnose([str(ds), "--out", str(tmp_path / "out")]) == 0
        assert stat.S_IMODE((tmp_path / "out").stat().st_mode) == 0o755
        os.umask(0o027)
        assert main_make_benchmark(["--out", str(tmp_path / "bench"), "--suite", "link", "-n", "1"]) == 0
        assert stat.S_IMODE((tmp_path / "bench").stat().st_mode) == 0o750
    finally:
        os.umask(old)


def test_where_png_colour_bars_carry_units(tmp_path, monkeypatch):
    """The where.png colour bar said 'amplitude' with no unit."""
    import matplotlib.figure

    from pyfmu_wrapper.diagnose.run import run_diagnosis

    labels = []
    orig = matplotlib.figure.Figure.colorbar

    def spy(self, *a, **k):
        labels.append(k.get("label", ""))
        return orig(self, *a, **k)

    monkeypatch.setattr(matplotlib.figure.Figure, "colorbar", spy)
    make_dataset(tmp_path / "ds", {}, seed=12)
    run_diagnosis(tmp_path / "ds", out=tmp_path / "out")
    assert labels and all("[" in lab and "]" in lab for lab in labels), labels
    assert "displacement amplitude [m]" in labels
