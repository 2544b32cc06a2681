"""The frame benchmark (issue 41): its truth against the exact linear response of the frame
(:mod:`pyfmu_wrapper.physics.frame`, written from the matrices, not integrated), the format of what
``make-benchmark --suite frame`` writes (frame_contract.md), its command line's refusals, and the
scorer ``benchmarks/bench_diagnose_frame.py`` on a stand-in diagnose."""

from __future__ import annotations

import importlib.util
import json
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.cli.diagnose import main_make_benchmark
from pyfmu_wrapper.diagnose.acquisition import parse_acquisition
from pyfmu_wrapper.diagnose.framebench import suite
from pyfmu_wrapper.diagnose.framebench.truth import FineForce, FrameTruth, acquire
from pyfmu_wrapper.physics.frame import LinearTMD, ShearFrame, frequency_response

ROOT = Path(__file__).resolve().parents[1]
MASSES, STIFF, DAMP = [120.0, 100.0, 90.0], [2.0e5, 1.8e5, 1.5e5], [150.0, 120.0, 100.0]
TMD = {"storey": 3, "mass": 10.0, "stiffness": 3000.0, "damping": 30.0, "inertance": 1.5}


def _steady(truth: FrameTruth, X: np.ndarray, w: float, F0: float, periods: float = 6.0):
    """The truth started on the exact steady state X (complex amplitudes of every node) of F0 cos(w t),
    the force given by its samples at 8 kHz (the suite's force: a spline through fine samples)."""
    t = np.arange(0.0, periods * 2 * math.pi / w, 1.0 / 8000.0)
    F = FineForce(t[1], F0 * np.cos(w * t))
    z0 = np.concatenate([X.real, (1j * w * X).real])
    sim = truth.simulate(F, t, z0)
    ph = np.exp(1j * w * t)[None, :]
    return sim, (X[:, None] * ph).real, (-(w**2) * X[:, None] * ph).real


@pytest.mark.parametrize(
    ("n", "to", "force_storey", "f_hz"), [(3, 3, 3, 2.9), (3, 0, 2, 3.4), (3, 1, 1, 6.0), (5, 2, 4, 4.1)]
)
def test_truth_is_the_exact_linear_response(n, to, force_storey, f_hz):
    """TMD-inerter, TMDI to the ground, TMDI to a lower storey (3 and 5 storeys): the integrated truth
    stays on the exact steady state (displacements and accelerations of every storey and the TMD) to 1e-6."""
    w, F0 = 2 * math.pi * f_hz, 150.0
    ms, ks, cs = (v + [v[-1] * 0.9] * (n - 3) for v in (MASSES, STIFF, DAMP))
    tmd = dict(TMD, storey=n, inerter_to=to)
    X = frequency_response(
        ShearFrame(tuple(ms), tuple(ks), tuple(cs), force_amplitude=F0, force_storey=force_storey),
        LinearTMD(n, TMD["mass"], TMD["stiffness"], TMD["damping"], TMD["inertance"], to),
        [w],
    )[0]
    sim, x, a = _steady(FrameTruth(ms, ks, cs, force_storey, tmd), X, w, F0)
    assert np.max(np.abs(sim["q"] - x)) < 1e-6 * np.max(np.abs(x))
    assert np.max(np.abs(sim["qdd"] - a)) < 1e-6 * np.max(np.abs(a))


def test_flexible_foundation_is_a_storey_below():
    """The out-of-vocabulary foundation (a mass on a spring and damper under storey 1) is the exact
    frame with one more storey at the bottom."""
    w, F0, found = 2 * math.pi * 2.5, 100.0, {"mass": 150.0, "stiffness": 1.5e6, "damping": 900.0}
    truth = FrameTruth(MASSES, STIFF, DAMP, 3, dict(TMD, inerter_to=0), foundation=found)
    X = frequency_response(
        ShearFrame(
            (found["mass"], *MASSES),
            (found["stiffness"], *STIFF),
            (found["damping"], *DAMP),
            force_amplitude=F0,
            force_storey=4,
        ),
        LinearTMD(4, TMD["mass"], TMD["stiffness"], TMD["damping"], TMD["inertance"], 0),
        [w],
    )[0]
    X = np.concatenate([X[1:], X[:1]])  # the truth's node order: storeys, TMD, foundation
    sim, x, _ = _steady(truth, X, w, F0)
    assert np.max(np.abs(sim["q"] - x)) < 1e-6 * np.max(np.abs(x))


def test_acquisition_filter_is_the_declared_one():
    """The generator's anti-alias filter on a slow sine is the declared filter's frequency response
    (gain and phase of scipy's analog prototype at that frequency), once its start has decayed; lsim
    takes the input linear between the samples: (w dt)^2 / 8 = 1.5e-5 here."""
    from scipy import signal

    from pyfmu_wrapper.diagnose.acquisition import analog_lowpass

    filt = {"type": "bessel", "order": 6, "cutoff_hz": 40.0}
    t = np.arange(0.0, 4.0, 1.0 / 4000.0)
    f = 7.0
    m = acquire({"a": np.sin(2 * math.pi * f * t)}, t, 4, filt)
    b, a_ = analog_lowpass("bessel", 6, 40.0)
    H = signal.freqs(b, a_, [2 * math.pi * f])[1][0]
    ts = m["t"]
    expect = np.abs(H) * np.sin(2 * math.pi * f * ts + np.angle(H))
    late = ts > 1.0
    assert np.max(np.abs(m["a"][late] - expect[late])) < 3e-5


SHORT = (6.0, 8.0)  #: record lengths [s] of the tests' suites (the suite's 20-60 s would take 10-20 s here)


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """A 1-dataset suite written by the command line (seed 17), its records 6-8 s long."""
    out = tmp_path_factory.mktemp("fb") / "bench"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(suite, "RECORD_SECONDS", (6, 8))
        assert main_make_benchmark(["--suite", "frame", "--out", str(out), "-n", "1", "--seed", "17"]) == 0
    return out


ELEMENT = re.compile(r"^(storey [1-9]\d*|tmd|tmd link|force|channel (x[1-9]\d*dd|ydd))$")


def _check_dataset(path: Path, row: dict, seconds: tuple[float, float] = (20.0, 60.0)) -> dict:
    """Assert the contract's dataset format; returns dataset.yaml."""
    doc = yaml.safe_load((path / "dataset.yaml").read_text())
    assert set(doc) <= {"level", "description", "nominal", "acquisition", "records"}
    assert doc["level"] == "system"
    fr, tmd = doc["nominal"]["frame"], doc["nominal"]["tmd"]
    n = fr["storeys"]
    assert n in (3, 5) and n == row["storeys"]
    for key in ("mass", "stiffness", "damping"):
        assert len(fr[key]) == n and all(v > 0 for v in fr[key])
    assert all(50.0 <= m <= 500.0 for m in fr["mass"])
    assert 1 <= fr["force_storey"] <= n
    assert tmd["storey"] == n and 0 <= tmd["inerter_to"] <= n and tmd["inerter"] == "ideal"
    assert 0.0199 <= tmd["mass"] / sum(fr["mass"]) <= 0.0501
    assert 0.0 <= tmd["inertance"] <= 0.2 * tmd["mass"] + 1e-9
    f1 = row["frame_modes_hz"][0]
    assert 0.99 <= f1 <= 5.01
    if "acquisition" in doc:
        chains = parse_acquisition(doc["acquisition"], path / "dataset.yaml")  # the schema load_dataset reads
        assert chains and all(c.cutoff_hz < 0.5 * row["fs"] for c in chains.values())
    assert 2 <= len(doc["records"]) <= 3
    for rec in doc["records"]:
        assert rec["kind"] == "transient"
        with open(path / rec["file"]) as fh:
            header = fh.readline().strip().split(",")
        assert header[0] == "t" and header[1:] == row["channels"] and row["channels"][0] == "force"
        assert all(re.fullmatch(r"x[1-9]\d*dd|ydd", c) for c in header[2:])
        assert f"x{n}dd" in header
        data = np.loadtxt(path / rec["file"], delimiter=",", skiprows=1)
        assert np.all(np.isfinite(data)) and data.shape[1] == len(header)
        dt = np.diff(data[:, 0])
        assert np.allclose(dt, 1.0 / row["fs"], rtol=1e-6)
        assert seconds[0] - 1.0 / row["fs"] - 1e-9 <= data[-1, 0] < seconds[1]
    return doc


def test_generated_suite_format(bench):
    """manifest.json and the dataset folder follow frame_contract.md."""
    man = json.loads((bench / "manifest.json").read_text())
    assert man["suite"] == "frame" and man["seed"] == 17 and man["complete"] is True
    (row,) = man["datasets"]
    assert row["name"] == "fr000" and row["class"] == "single" and row["oov_kind"] is None
    (t,) = row["truth"]
    assert t["effect"] in suite.IN_VOCAB and t["param"] == suite.IN_VOCAB[t["effect"]]
    assert ELEMENT.match(t["element"]) and isinstance(t["value"], float) and t["value"] != 0.0
    assert row["visible_chi2"] > 100.0
    _check_dataset(bench / "fr000", row, SHORT)


def test_generated_suite_loads(bench):
    """load_dataset reads the frame dataset: its frame nominal, every record with the manifest's channels."""
    from pyfmu_wrapper.diagnose.data import load_dataset

    ds = load_dataset(bench / "fr000")
    row = json.loads((bench / "manifest.json").read_text())["datasets"][0]
    assert len(ds.records) == len(row["records"])
    for r in ds.records:
        assert set(r.columns) == {"t", *row["channels"]}


@pytest.mark.parametrize(
    ("effects", "oov"), [([e], None) for e in suite.IN_VOCAB] + [([], k) for k in suite.OOV] + [([], None)]
)
def test_every_class_is_written(tmp_path, monkeypatch, effects, oov):
    """Every in-vocabulary effect and out-of-vocabulary kind is drawn, applied (visible in the
    noise-free records: chi-square > 100, 0 for a clean dataset) and written in the format; short
    records keep the test fast."""
    monkeypatch.setattr(suite, "RECORD_SECONDS", (4, 5))
    row = suite.write_dataset(tmp_path / "ds", np.random.default_rng(3), effects, oov)
    assert [t["effect"] for t in row["truth"]] == effects and row["oov_kind"] == oov
    for t in row["truth"]:
        assert ELEMENT.match(t["element"])
        if t["effect"] == "channel_gain":
            assert t["element"].split()[1] in row["channels"]
    assert (row["visible_chi2"] > 100.0) if effects or oov else row["visible_chi2"] == 0.0
    doc = _check_dataset(tmp_path / "ds", row, (4.0, 5.0))
    assert len(doc["records"]) == len(row["records"])


@pytest.mark.parametrize(
    "argv",
    [
        ["-n", "0"],
        ["--seconds", "10"],
        ["--part", "1/2"],
        ["--noise", "1"],
        ["--held-out-oov"],
        ["--clean-fraction", "0.7", "--pair-fraction", "0.5"],
        ["--oov-fraction", "-0.1"],
    ],
)
def test_bad_arguments_exit_2(tmp_path, argv, capsys):
    assert main_make_benchmark(["--suite", "frame", "--out", str(tmp_path / "b"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("make-benchmark: error:") and err.count("\n") == 1
    assert not (tmp_path / "b").exists()


def test_unknown_suite_exits_2(tmp_path):
    with pytest.raises(SystemExit) as e:
        main_make_benchmark(["--suite", "frames", "--out", str(tmp_path / "b")])
    assert e.value.code == 2


def _scorer():
    spec = importlib.util.spec_from_file_location("_bench_frame", ROOT / "benchmarks" / "bench_diagnose_frame.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["_bench_frame"] = mod
    spec.loader.exec_module(mod)
    return mod


FAKE = """
import json, sys
from pathlib import Path
def main_diagnose():
    ds, out = Path(sys.argv[1]), Path(sys.argv[3])
    plan = json.loads((ds.parent / "fake_verdicts.json").read_text())[ds.name]
    if plan == "refuse":
        print(f"diagnose: error: {ds}/dataset.yaml: refused", file=sys.stderr)
        return 2
    if plan == "crash":
        raise RuntimeError("boom")
    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnosis.json").write_text(json.dumps({"verdict": plan}))
    return 0
"""


def test_scorer_on_a_stand_in_diagnose(tmp_path, monkeypatch):
    """The scorer's four measures, its errors (a refusal, a crash) and its resource record, with a
    stand-in diagnose (a source tree whose main_diagnose writes the verdicts of fake_verdicts.json)."""
    code = tmp_path / "code"
    (code / "pyfmu_wrapper" / "cli").mkdir(parents=True)
    (code / "pyfmu_wrapper" / "__init__.py").write_text("")
    (code / "pyfmu_wrapper" / "cli" / "__init__.py").write_text("")
    (code / "pyfmu_wrapper" / "cli" / "diagnose.py").write_text(FAKE)
    bench = tmp_path / "bench"
    T = lambda e, el, v=1.0: {"effect": e, "element": el, "param": "p", "value": v}  # noqa: E731
    rows = [
        ("s0", "single", [T("storey_stiffness", "storey 2", -1e4)]),
        ("s1", "single", [T("storey_stiffness", "storey 2", -1e4)]),
        ("s2", "single", [T("tmd_mass", "tmd")]),
        ("p0", "pair", [T("viscous", "tmd link"), T("storey_mass", "storey 1")]),
        ("c0", "clean", []),
        ("c1", "clean", []),
        ("o0", "oov", []),
        ("o1", "oov", []),
    ]
    verdicts = {
        "s0": {
            "effects": ["storey_stiffness"],
            "elements": ["storey 2"],
            "unexplained": False,
            "parameters": {"storey_stiffness@storey 2.p": {"value": -1.1e4, "std": 1.0}},
        },
        "s1": {"effects": ["storey_stiffness"], "elements": ["storey 3"], "unexplained": False},
        "s2": "crash",
        "p0": {"effects": ["storey_mass", "viscous"], "elements": ["storey 1", "tmd link"], "unexplained": False},
        "c0": {"effects": [], "elements": [], "unexplained": False},
        "c1": "refuse",
        "o0": {"effects": ["tmd_mass"], "elements": ["tmd"], "unexplained": True},
        "o1": {"effects": ["tmd_mass"], "elements": ["tmd"], "unexplained": False},
    }
    for name, _, _ in rows:
        (bench / name).mkdir(parents=True)
        (bench / name / "dataset.yaml").write_text("level: system\n")
    (bench / "fake_verdicts.json").write_text(json.dumps(verdicts))
    man = [
        {"name": n, "class": c, "storeys": 3, "truth": t, "oov_kind": "k" if c == "oov" else None, "visible_chi2": 1e3}
        for n, c, t in rows
    ]
    (bench / "manifest.json").write_text(json.dumps({"suite": "frame", "seed": 0, "datasets": man}))
    mod = _scorer()
    out = tmp_path / "res"
    assert mod.main([str(bench), "--out", str(out), "--code", str(code)]) == 0
    res = json.loads((out / "results.json").read_text())
    s = res["summary"]
    assert s["singles_right"] == pytest.approx(1 / 3, abs=1e-4)
    assert s["pairs_right"] == 1.0
    assert s["clean_false"] == 0.5  # the refusal counts against the measure
    assert s["oov_confidently_wrong"] == 0.5
    assert s["errors"] == {"clean": 1, "single": 1, "pair": 0, "oov": 0}
    assert s["param_rel_error_median"] == pytest.approx(0.1)
    by = {r["name"]: r for r in res["rows"]}
    assert by["c1"]["exit"] == 2 and by["s2"]["exit"] == 1 and by["o0"]["outcome"] == "honest"
    assert all(r["cpu_s"] >= 0 and r["peak_rss_mb"] > 0 for r in res["rows"])
    assert "| singles_right | 33 % | >= 0.9 | NO |" in (out / "results.md").read_text()
    # --resume --only: the named dataset again, every other row kept
    (out / "runs" / "s1" / "diagnosis.json").unlink()
    verdicts["s1"] = verdicts["s0"] | {"elements": ["storey 2"]}
    (bench / "fake_verdicts.json").write_text(json.dumps(verdicts))
    assert mod.main([str(bench), "--out", str(out), "--code", str(code), "--resume", "--only", "s1"]) == 0
    res = json.loads((out / "results.json").read_text())
    assert [r["name"] for r in res["rows"]] == [n for n, _, _ in rows]
    assert res["summary"]["singles_right"] == pytest.approx(2 / 3, abs=1e-4)
    # a folder the scorer did not write is refused
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x").write_text("")
    assert mod.main([str(bench), "--out", str(tmp_path / "other"), "--code", str(code)]) == 2


@pytest.mark.parametrize("j", [1, 2])
def test_storey_force_path_is_a_stiffness_change(j):
    """The out-of-vocabulary storey forces (cubic, friction, drift) act through one path; a drift frozen at
    its start (share 0, start -0.2) is storey j's stiffness at 0.8 k_j: the exact frame's response."""
    w, F0 = 2 * math.pi * 3.0, 120.0
    tmd = dict(TMD, inerter_to=3)
    ks = list(STIFF)
    ks[j - 1] *= 0.8
    X = frequency_response(
        ShearFrame(tuple(MASSES), tuple(ks), tuple(DAMP), force_amplitude=F0, force_storey=3),
        LinearTMD(3, TMD["mass"], TMD["stiffness"], TMD["damping"], TMD["inertance"], 3),
        [w],
    )[0]
    truth = FrameTruth(MASSES, STIFF, DAMP, 3, tmd, drift={"storey": j, "share": 0.0, "start": -0.2, "T": 1.0})
    sim, x, _ = _steady(truth, X, w, F0)
    assert np.max(np.abs(sim["q"] - x)) < 1e-6 * np.max(np.abs(x))
