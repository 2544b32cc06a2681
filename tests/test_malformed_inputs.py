"""One bad-input policy for all seven console scripts, table-driven.

Every case runs a malformed input through a CLI's ``main(argv)`` (the function the console script
calls, wrapped by :func:`pyfmu_wrapper.cli.errors.cli_main`) and asserts: exit status 2, one line
on stderr naming the what and the where (file, line/row, key, value), no traceback, and that no
file outside the output folder changed (the whole tree is hashed before and after). Each case fails
before anything heavy is computed. A second test runs one case per console script as a subprocess
(the installed entry point) to check the wiring.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.cli.build_fmus import main as build_main
from pyfmu_wrapper.cli.diagnose import main_diagnose, main_make_benchmark, main_score
from pyfmu_wrapper.cli.optimise import main as optimise_main
from pyfmu_wrapper.cli.reproduce import main as reproduce_main
from pyfmu_wrapper.cli.run_scenario import main as run_scenario_main
from pyfmu_wrapper.diagnose.records import write_record

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = (ROOT / "scenarios" / "viscous_case2.yaml").read_text(encoding="utf-8")
MAINS = {
    "run-scenario": run_scenario_main,
    "build-fmus": build_main,
    "diagnose": main_diagnose,
    "make-benchmark": main_make_benchmark,
    "score": main_score,
    "optimise": optimise_main,
    "reproduce": reproduce_main,
}
SYS_NOMINAL = {
    "base": {"mass": 100.0, "stiffness": 4e4, "damping": 100.0, "force_amplitude": 200.0},
    "tmd": {"mass": 9.0, "stiffness": 4e3, "damping": 15.0, "inertance": 1.0},
}


# --- inputs ---------------------------------------------------------------------------------------


def scenario(tmp, text=SCENARIO, name="s.yaml", raw: bytes | None = None):
    p = tmp / name
    p.write_bytes(raw if raw is not None else text.encode("utf-8"))
    return str(p)


def link_dataset(tmp, *, rows=None, nominal=None, yml=None, records=None, n=3, force_scale=1.0):
    """A valid link dataset (3 records of a linear spring-damper) in tmp/ds, then mutated."""
    d = tmp / "ds"
    d.mkdir(exist_ok=True)
    recs = []
    for k, w in enumerate((15.0, 20.0, 25.0)[:n]):
        t = np.arange(200) * (2 * math.pi / w) / 50
        x = 0.01 * np.sin(w * t)
        write_record(
            d / f"r{k}.csv",
            {"t": t, "displacement": x, "force": force_scale * (4e3 * x + 40 * w * 0.01 * np.cos(w * t))},
        )
        recs.append({"file": f"r{k}.csv", "omega": w})
    if rows is not None:  # replace r0.csv by this text
        (d / "r0.csv").write_bytes(rows if isinstance(rows, bytes) else rows.encode())
    doc = {
        "level": "link",
        "nominal": nominal if nominal is not None else {"stiffness": 4e3, "damping": 40.0},
        "records": records if records is not None else recs,
    }
    if yml is not None:
        (d / "dataset.yaml").write_bytes(yml if isinstance(yml, bytes) else yml.encode())
    else:
        (d / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(d)


def system_dataset(tmp, *, dead="", nominal=None):
    d = tmp / "ds"
    d.mkdir(exist_ok=True)
    recs = []
    for k, w in enumerate((17.0, 21.0)):
        t = np.arange(400) * (2 * math.pi / w) / 100
        cols = {"t": t, "force": 200 * np.cos(w * t), "x": 1e-3 * np.sin(w * t), "y": 3e-3 * np.sin(w * t + 0.3)}
        cols["xdd"], cols["ydd"] = -w * w * cols["x"], -w * w * cols["y"]
        if dead:
            cols[dead] = np.zeros_like(t)
        write_record(d / f"w{k}.csv", cols)
        recs.append({"file": f"w{k}.csv", "omega": w, "force_amplitude": 200.0})
    (d / "dataset.yaml").write_text(
        yaml.safe_dump({"level": "system", "nominal": nominal or SYS_NOMINAL, "records": recs}, sort_keys=False)
    )
    return str(d)


def good_rows(n=50, w=15.0):
    t = np.arange(n) * (2 * math.pi / w) / 25
    return ["t,displacement,force"] + [
        f"{a:.6g},{0.01 * math.sin(w * a):.6g},{40 * math.sin(w * a) + 1:.6g}" for a in t
    ]


def rows_with(i, line):
    r = good_rows()
    r[i] = line
    return "\n".join(r) + "\n"


def foreign_folder(tmp, name="thesis"):
    p = tmp / name
    p.mkdir()
    (p / "chapter1.tex").write_text("\\chapter{One}\n")
    return str(p)


def a_file(tmp, name="existing.txt"):
    p = tmp / name
    p.write_text("not ours\n")
    return str(p)


def benchmark(tmp, datasets):
    b = tmp / "bench"
    b.mkdir()
    (b / "manifest.json").write_text(json.dumps({"datasets": datasets}))
    return str(b)


OUT = "out"  # every case's output folder (tmp/out); files elsewhere must not change


def sc(mut):
    return lambda tmp: ["run-scenario", scenario(tmp, mut(SCENARIO)), "--out", str(tmp / OUT)]


def dg(make):
    return lambda tmp: ["diagnose", make(tmp), "--out", str(tmp / OUT)]


# (id, argv builder, regex the one-line message must match)
CASES = [
    # run-scenario
    ("scenario-unknown-key", sc(lambda s: s.replace("  damping: 0.0 ", "  dampng: 0.0 ")), r"s\.yaml:\d+: tmd.*dampng"),
    (
        "scenario-wrong-type",
        sc(lambda s: s.replace("stiffness: 40000.0", "stiffness: forty")),
        r"s\.yaml:\d+: base\.stiffness.*'forty'",
    ),
    (
        "scenario-negative-mass",
        sc(lambda s: s.replace("mass: 100.0", "mass: -100.0")),
        r"s\.yaml:\d+: base\.mass.*-100",
    ),
    (
        "scenario-non-utf8",
        lambda tmp: [
            "run-scenario",
            scenario(tmp, raw=SCENARIO.encode().replace(b"Viscous", b"Visc\xe9us")),
            "--out",
            str(tmp / OUT),
        ],
        r"s\.yaml: line 1, column \d+ \(byte offset \d+\): bytes e9",
    ),
    (
        "scenario-missing-file",
        lambda tmp: ["run-scenario", str(tmp / "nothere.yaml"), "--out", str(tmp / OUT)],
        r"nothere\.yaml: cannot read scenario file",
    ),
    (
        "scenario-bad-engine",
        lambda tmp: ["run-scenario", scenario(tmp), "--engine", "warp", "--out", str(tmp / OUT)],
        r"--engine: invalid choice: 'warp'",
    ),
    ("scenario-bad-yaml", sc(lambda s: s.replace("base:", "base: [", 1)), r"s\.yaml:\d+: not valid YAML"),
    (
        "scenario-duplicate-key",
        sc(lambda s: s.replace("name: viscous_case2", "name: viscous_case2\nname: again")),
        r"s\.yaml:\d+.*duplicate key 'name'",
    ),
    (
        "scenario-negative-workers",
        lambda tmp: ["run-scenario", scenario(tmp), "--workers", "-2", "--out", str(tmp / OUT)],
        r"--workers must be >= 0.*got -2",
    ),
    # diagnose: CSV records
    (
        "diagnose-missing-column",
        dg(lambda tmp: link_dataset(tmp, rows="t,displacement\n0,0\n0.1,1\n0.2,2\n")),
        r"r0\.csv, column 'force': missing column",
    ),
    (
        "diagnose-nan",
        dg(lambda tmp: link_dataset(tmp, rows=rows_with(3, "0.05,nan,1"))),
        r"r0\.csv, row 3, column 'displacement': value nan is not a finite number",
    ),
    (
        "diagnose-non-numeric",
        dg(lambda tmp: link_dataset(tmp, rows=rows_with(7, "0.3,0.001,abc"))),
        r"r0\.csv, row 7, column 'force': value 'abc'",
    ),
    (
        "diagnose-t-not-increasing",
        dg(lambda tmp: link_dataset(tmp, rows=rows_with(5, "0.01,0.001,1"))),
        r"r0\.csv, row 5, column 't': time must be strictly increasing: t = 0\.01 after",
    ),
    (
        "diagnose-zero-force-link",
        dg(lambda tmp: link_dataset(tmp, force_scale=0.0)),
        r"r0\.csv, column 'force': the channel is constant \(every value = 0\): a dead channel",
    ),
    (
        "diagnose-dead-force-system",
        dg(lambda tmp: system_dataset(tmp, dead="force")),
        r"w0\.csv, column 'force': the channel is constant .*dead channel",
    ),
    (
        "diagnose-dead-y-system",
        dg(lambda tmp: system_dataset(tmp, dead="y")),
        r"w0\.csv, column 'y': the channel is constant",
    ),
    (
        "diagnose-shorter-than-a-period",
        dg(
            lambda tmp: (
                lambda d: (
                    Path(d, "dataset.yaml").write_text(
                        Path(d, "dataset.yaml").read_text().replace("omega: 17.0", "omega: 0.5")
                    ),
                    d,
                )[1]
            )(system_dataset(tmp))
        ),
        r"w0\.csv: the record spans 1\.475 s, less than one period of w = 0\.5 rad/s \(12\.57 s\)",
    ),
    (
        "diagnose-too-few-rows",
        dg(lambda tmp: link_dataset(tmp, rows="t,displacement,force\n0,0,0\n0.1,1,2\n")),
        r"r0\.csv: needs at least 3 data rows, has 2",
    ),
    (
        "diagnose-non-utf8-csv",
        dg(lambda tmp: link_dataset(tmp, rows=b"t,displacement,force\n0,0,0\n0.1,1\xff,2\n")),
        r"r0\.csv: line 3, column 6 \(byte offset 32\): bytes ff are not UTF-8",
    ),
    (
        "diagnose-missing-csv",
        dg(lambda tmp: link_dataset(tmp, records=["r0.csv", "gone.csv"])),
        r"gone\.csv: file not found",
    ),
    (
        "diagnose-frc-direction",
        dg(
            lambda tmp: (
                lambda d: (
                    Path(d, "f.csv").write_text(
                        "omega,force_amplitude,x_max,direction\n15,200,0.01,up\n16,200,0.01,sideways\n17,200,0.01,up\n"
                    ),
                    Path(d, "dataset.yaml").write_text(
                        yaml.safe_dump({"level": "system", "nominal": SYS_NOMINAL, "records": ["f.csv"]})
                    ),
                    d,
                )[2]
            )(system_dataset(tmp))
        ),
        r"f\.csv, row 2, column 'direction': direction must be 'up' or 'down', got 'sideways'",
    ),
    # diagnose: dataset.yaml
    (
        "diagnose-unknown-record-key",
        dg(lambda tmp: link_dataset(tmp, records=[{"file": "r0.csv", "rol": "test"}, "r1.csv"])),
        r"dataset\.yaml:\d+: records\[0\] \(r0\.csv\): unknown key\(s\) \['rol'\]; allowed keys: \[.*'role'",
    ),
    (
        "diagnose-unknown-top-key",
        dg(lambda tmp: link_dataset(tmp, yml="level: link\nnominal: {stiffness: 1}\nrecords: [r0.csv]\nrecrods: []\n")),
        r"dataset\.yaml:4: dataset\.yaml: unknown key\(s\) \['recrods'\]; allowed keys",
    ),
    (
        "diagnose-unknown-nominal-key",
        dg(lambda tmp: link_dataset(tmp, nominal={"stifness": 4e3})),
        r"dataset\.yaml:\d+: unknown nominal link parameter\(s\) \['stifness'\]",
    ),
    (
        "diagnose-negative-friction",
        dg(lambda tmp: link_dataset(tmp, nominal={"friction_force": -11000})),
        r"dataset\.yaml:\d+: 'nominal\.friction_force' must be >= 0 N \(a physical value\), got -11000",
    ),
    (
        "diagnose-negative-stiffness",
        dg(lambda tmp: link_dataset(tmp, nominal={"stiffness": -4e3})),
        r"'nominal\.stiffness' must be >= 0 N/m.*got -4000",
    ),
    (
        "diagnose-negative-inertance",
        dg(lambda tmp: link_dataset(tmp, nominal={"inertance": -1})),
        r"'nominal\.inertance' must be >= 0 kg",
    ),
    (
        "diagnose-zero-slope",
        dg(lambda tmp: link_dataset(tmp, nominal={"friction_slope": 0})),
        r"'nominal\.friction_slope' must be > 0 s/m",
    ),
    (
        "diagnose-negative-system-damping",
        dg(
            lambda tmp: system_dataset(
                tmp, nominal={"base": SYS_NOMINAL["base"], "tmd": {**SYS_NOMINAL["tmd"], "damping": -5.0}}
            )
        ),
        r"dataset\.yaml:\d+: nominal model: tmd: damping \(c\) must be >= 0, got -5\.0",
    ),
    (
        "diagnose-negative-system-mass",
        dg(
            lambda tmp: system_dataset(
                tmp, nominal={"base": {**SYS_NOMINAL["base"], "mass": -100.0}, "tmd": SYS_NOMINAL["tmd"]}
            )
        ),
        r"nominal model: base: mass \(M\) must be > 0, got -100\.0",
    ),
    (
        "diagnose-system-unknown-tmd-key",
        dg(
            lambda tmp: system_dataset(
                tmp, nominal={"base": SYS_NOMINAL["base"], "tmd": {**SYS_NOMINAL["tmd"], "stifness": 1.0}}
            )
        ),
        r"nominal\.tmd: unknown key\(s\) \['stifness'\]; allowed keys: \['mass', 'stiffness'",
    ),
    (
        "diagnose-non-utf8-yaml",
        dg(lambda tmp: link_dataset(tmp, yml=b"level: link\ndescription: caf\xe9\nnominal: {}\nrecords: [r0.csv]\n")),
        r"dataset\.yaml: line 2, column 17 \(byte offset 28\): bytes e9 are not UTF-8 text",
    ),
    (
        "diagnose-bad-yaml",
        dg(lambda tmp: link_dataset(tmp, yml="level: link\nnominal: {stiffness: 1\nrecords: [r0.csv]\n")),
        r"dataset\.yaml:\d+: invalid YAML",
    ),
    (
        "diagnose-duplicate-key",
        dg(lambda tmp: link_dataset(tmp, yml="level: link\nlevel: system\nnominal: {}\nrecords: [r0.csv]\n")),
        r"dataset\.yaml:\d+: invalid YAML.*duplicate key 'level'",
    ),
    (
        "diagnose-bad-role",
        dg(lambda tmp: link_dataset(tmp, records=[{"file": "r0.csv", "role": "tset"}, "r1.csv"])),
        r"dataset\.yaml:\d+: records\[0\]\.role must be 'train' or 'test', got 'tset'",
    ),
    (
        "diagnose-negative-omega",
        dg(lambda tmp: link_dataset(tmp, records=[{"file": "r0.csv", "omega": -15}, "r1.csv"])),
        r"dataset\.yaml:\d+: 'records\[0\]\.omega' must be > 0 rad/s",
    ),
    (
        "diagnose-bad-level",
        dg(lambda tmp: link_dataset(tmp, yml="level: device\nnominal: {}\nrecords: [r0.csv]\n")),
        r"dataset\.yaml:1: 'level' must be 'link' or 'system', got 'device'",
    ),
    (
        "diagnose-empty-records",
        dg(lambda tmp: link_dataset(tmp, records=[])),
        r"dataset\.yaml:\d+: 'records' must be a non-empty list",
    ),
    (
        "diagnose-x-max-noise",
        dg(lambda tmp: link_dataset(tmp, yml="level: link\nnominal: {}\nrecords: [r0.csv]\nx_max_noise: lots\n")),
        r"dataset\.yaml:4: 'x_max_noise' must be a number, got 'lots'",
    ),
    (
        "diagnose-all-train",
        dg(lambda tmp: link_dataset(tmp, records=[{"file": f"r{k}.csv", "role": "train"} for k in range(3)])),
        r"dataset\.yaml:\d+: every record has role 'train'",
    ),
    (
        "diagnose-no-dataset-yaml",
        lambda tmp: ["diagnose", str(tmp), "--out", str(tmp / OUT)],
        r"dataset\.yaml: file not found",
    ),
    (
        "diagnose-missing-model",
        lambda tmp: ["diagnose", link_dataset(tmp), "--model", str(tmp / "m.yaml"), "--out", str(tmp / OUT)],
        r"m\.yaml: model file not found",
    ),
    (
        "diagnose-model-negative",
        lambda tmp: [
            "diagnose",
            link_dataset(tmp),
            "--model",
            scenario(tmp, "stiffness: -5\n", "m.yaml"),
            "--out",
            str(tmp / OUT),
        ],
        r"m\.yaml:1: 'nominal\.stiffness' must be >= 0",
    ),
    # diagnose: the output folder
    (
        "diagnose-out-is-file",
        lambda tmp: ["diagnose", link_dataset(tmp), "--out", a_file(tmp)],
        r"--out .*existing\.txt: .*existing\.txt exists and is not a folder; refusing to replace it",
    ),
    (
        "diagnose-out-foreign-folder",
        lambda tmp: ["diagnose", link_dataset(tmp), "--out", foreign_folder(tmp)],
        r"--out .*thesis: .*thesis is a non-empty folder that is not a result of diagnose \(it holds chapter1\.tex\)",
    ),
    (
        "diagnose-out-is-dataset",
        lambda tmp: ["diagnose", link_dataset(tmp), "--out", str(tmp / "ds")],
        r"--out .*ds: .*ds is a non-empty folder that is not a result of diagnose \(it holds dataset\.yaml",
    ),
    # make-benchmark
    (
        "make-benchmark-n-0",
        lambda tmp: ["make-benchmark", "-n", "0", "--out", str(tmp / OUT)],
        r"-n 0: the number of datasets must be >= 1",
    ),
    (
        "make-benchmark-n-negative",
        lambda tmp: ["make-benchmark", "--suite", "link", "-n", "-3", "--out", str(tmp / OUT)],
        r"-n -3",
    ),
    (
        "make-benchmark-fraction",
        lambda tmp: ["make-benchmark", "--suite", "link", "--clean-fraction", "2", "--out", str(tmp / OUT)],
        r"--clean-fraction 2\.0: must be in \[0, 1\]",
    ),
    (
        "make-benchmark-part-system",
        lambda tmp: ["make-benchmark", "--part", "1/2", "--out", str(tmp / OUT)],
        r"--part 1/2: only for --suite transient, written K/N with 1 <= K <= N",
    ),
    (
        "make-benchmark-part-out-of-range",
        lambda tmp: ["make-benchmark", "--suite", "transient", "--part", "3/2", "--out", str(tmp / OUT)],
        r"--part 3/2: only for --suite transient, written K/N with 1 <= K <= N",
    ),
    (
        "make-benchmark-held-out-link",
        lambda tmp: ["make-benchmark", "--suite", "link", "--held-out-oov", "--out", str(tmp / OUT)],
        r"--held-out-oov: only for --suite system \(the link suite has its own kinds\)",
    ),
    (
        "make-benchmark-out-file",
        lambda tmp: ["make-benchmark", "-n", "1", "--out", a_file(tmp)],
        r"existing\.txt exists and is not a folder",
    ),
    (
        "make-benchmark-out-foreign",
        lambda tmp: ["make-benchmark", "-n", "1", "--out", foreign_folder(tmp)],
        r"thesis is a non-empty folder that is not a result of make-benchmark",
    ),
    # score
    ("score-no-manifest", lambda tmp: ["score", foreign_folder(tmp)], r"thesis/manifest\.json: file not found"),
    (
        "score-empty-benchmark",
        lambda tmp: ["score", benchmark(tmp, [])],
        r"manifest\.json: the benchmark has no datasets",
    ),
    ("score-missing-folder", lambda tmp: ["score", str(tmp / "nobench")], r"nobench: not a folder"),
    (
        "score-bad-json",
        lambda tmp: (
            (lambda b: (Path(b, "manifest.json").write_text("{datasets: ["), b)[1])(foreign_folder(tmp, "bench"))
            and ["score", str(tmp / "bench")]
        ),
        r"manifest\.json: line 1, column 2: not valid JSON",
    ),
    (
        "score-missing-dataset",
        lambda tmp: ["score", benchmark(tmp, [{"dataset": "ds000", "hidden": [], "truth": {}}])],
        r"datasets\[0\]: folder .*ds000 not found",
    ),
    # optimise
    (
        "optimise-bounds-reversed",
        lambda tmp: ["optimise", "--case", "1", "-p", "damping", "--bounds", "5", "1"],
        r"bounds must be LO < HI, got \[5\.0, 1\.0\]",
    ),
    (
        "optimise-set-not-a-number",
        lambda tmp: ["optimise", "--case", "1", "-p", "damping", "--set", "tmd.damping=abc"],
        r"--set tmd\.damping=abc: 'abc' is not a number",
    ),
    (
        "optimise-unknown-parameter",
        lambda tmp: ["optimise", "--case", "1", "-p", "dampnig"],
        r"unknown tmd parameter 'dampnig'",
    ),
    (
        "optimise-missing-scenario",
        lambda tmp: ["optimise", str(tmp / "no.yaml"), "-p", "damping"],
        r"no\.yaml: cannot read scenario file",
    ),
    (
        "optimise-xtol",
        lambda tmp: ["optimise", "--case", "1", "-p", "damping", "--xtol", "-1"],
        r"--xtol must be a tolerance > 0, got -1\.0",
    ),
    (
        "optimise-json-foreign",
        lambda tmp: ["optimise", "--case", "1", "-p", "damping", "--json", a_file(tmp)],
        r"--json .*existing\.txt \(not written by optimise\)",
    ),
    (
        "optimise-negative-set",
        lambda tmp: ["optimise", "--case", "1", "-p", "damping", "--set", "tmd.mass=-5"],
        r"--set tmd\.mass=-5: mass \(m\) must be >= 0, got -5\.0",
    ),
    (
        "optimise-non-utf8-scenario",
        lambda tmp: ["optimise", scenario(tmp, raw=b"name: x\xff\n"), "-p", "damping"],
        r"s\.yaml: line 1, column 8 \(byte offset 7\): bytes ff",
    ),
    # reproduce
    ("reproduce-jobs", lambda tmp: ["reproduce", "--jobs", "-1", "--out", str(tmp / OUT)], r"--jobs -1: must be >= 0"),
    (
        "reproduce-unknown-name",
        lambda tmp: ["reproduce", "--only", "fig9", "--out", str(tmp / OUT)],
        r"unknown scenario names \['fig9'\]",
    ),
    (
        "reproduce-out-file",
        lambda tmp: ["reproduce", "--out", a_file(tmp), "--results", str(tmp / OUT)],
        r"--out .*existing\.txt: is a file",
    ),
    ("reproduce-dpi", lambda tmp: ["reproduce", "--dpi", "0", "--out", str(tmp / OUT)], r"--dpi 0: must be >= 10"),
    (
        "reproduce-dask-no-scheduler",
        lambda tmp: ["reproduce", "--executor", "dask", "--out", str(tmp / OUT)],
        r"--executor dask needs --scheduler",
    ),
    # build-fmus
    (
        "build-fmus-out-file",
        lambda tmp: ["build-fmus", "--out", a_file(tmp)],
        r"--out .*existing\.txt: is a file, not a folder",
    ),
    (
        "build-fmus-unknown-fmu",
        lambda tmp: ["build-fmus", "NoSuchFMU", "--out", str(tmp / OUT)],
        r"unknown FMU\(s\) \['NoSuchFMU'\]",
    ),
]


def tree_hash(root: Path, skip: Path) -> dict:
    """path -> sha256 of every file under root (and every folder), except under ``skip``."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        if d == skip or skip in d.parents:
            dirnames[:] = []
            continue
        out[str(d.relative_to(root)) + "/"] = "dir"
        for f in filenames:
            out[str((d / f).relative_to(root))] = hashlib.sha256((d / f).read_bytes()).hexdigest()
    return out


def call(prog, argv, capsys):
    try:
        rc = MAINS[prog](argv)
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def test_at_least_40_cases_over_all_seven_entry_points():
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert len(CASES) >= 40
    assert len({c[0] for c in CASES}) == len(CASES)
    assert {c[0].split("-")[0] for c in CASES} >= {
        "scenario",
        "diagnose",
        "optimise",
        "reproduce",
        "score",
        "build",
        "make",
    }
    assert set(MAINS) == set(scripts)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_malformed_input_exit_2_one_clear_line(case, tmp_path, capsys, monkeypatch):
    name, build, pattern = case
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PYFMU_TRACEBACK", raising=False)
    argv = build(tmp_path)
    prog, argv = argv[0], argv[1:]
    before = tree_hash(tmp_path, tmp_path / OUT)
    rc, out, err = call(prog, argv, capsys)
    assert rc == 2, f"{name}: exit {rc}\nstdout: {out}\nstderr: {err}"
    assert "Traceback" not in err and "Traceback" not in out
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(("usage:", " "))]
    assert len(lines) == 1, f"{name}: expected one message line, got {lines}"
    assert ": error: " in lines[0]
    assert re.search(pattern, lines[0]), f"{name}: {lines[0]!r} does not match {pattern!r}"
    assert "np.float" not in lines[0] and "np.int" not in lines[0]
    assert tree_hash(tmp_path, tmp_path / OUT) == before, f"{name}: a file outside the output folder changed"
    o = tmp_path / OUT
    assert not o.exists() or not any(p for p in o.iterdir()), f"{name}: the refused run wrote into {o}"
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name], f"{name}: a partial folder was left behind"


def _script(name):
    exe = Path(sys.executable).with_name(name)
    return str(exe) if exe.exists() else shutil.which(name)


@pytest.mark.parametrize(
    "prog,pick",
    [
        ("run-scenario", "scenario-non-utf8"),
        ("diagnose", "diagnose-dead-force-system"),
        ("make-benchmark", "make-benchmark-n-0"),
        ("score", "score-no-manifest"),
        ("optimise", "optimise-set-not-a-number"),
        ("reproduce", "reproduce-jobs"),
        ("build-fmus", "build-fmus-out-file"),
    ],
)
def test_console_scripts_apply_the_policy(prog, pick, tmp_path):
    exe = _script(prog)
    if exe is None:
        pytest.fail(f"console script {prog} is not installed (pip install -e .)")
    case = next(c for c in CASES if c[0] == pick)
    argv = case[1](tmp_path)
    assert argv[0] == prog
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("PYFMU_TRACEBACK", None)
    p = subprocess.run([exe, *argv[1:]], capture_output=True, text=True, cwd=tmp_path, timeout=120, env=env)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    assert re.search(case[2], p.stderr), p.stderr


def test_plain_numbers_in_messages():
    from pyfmu_wrapper.errors import plain, plain_text

    assert plain_text("got np.float64(nan) and np.float32(0.5), np.int64(3)") == "got nan and 0.5, 3"
    assert repr(plain(np.float64(0.5))) == "0.5" and repr(plain(np.float64("nan"))) == "nan"


def test_unexpected_errors_keep_their_traceback():
    from pyfmu_wrapper.cli.errors import cli_main

    @cli_main("x")
    def bug(argv=None):
        return 1 / 0

    with pytest.raises(ZeroDivisionError):
        bug([])


def test_a_closed_pipe_ends_a_command_quietly():
    """``diagnose ... | head -1``: the reader goes away while the command prints; it ends with status 141
    (as a tool killed by SIGPIPE) and no traceback (it printed one from its last line)."""
    import subprocess
    import sys

    code = (
        "import sys\nfrom pyfmu_wrapper.cli.errors import cli_main\n"
        "@cli_main('x')\ndef m():\n    for i in range(10**6):\n        print('line', i)\n    return 0\n"
        "sys.exit(m())\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stdout.readline() == b"line 0\n"
    p.stdout.close()
    _, err = p.communicate(timeout=60)
    assert p.returncode == 141 and b"Traceback" not in err and b"Error" not in err, err.decode()
