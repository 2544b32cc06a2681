"""FMUs of one build loaded, freed, deleted and loaded again in one process, in any order.

The FMUs of one build share their bundled package (``_pyfmu_<hash>``) in a process. fmpy deletes
an FMU's extraction folder when it is done with it; the package stayed bound to that folder, so a
later FMU of the same build could not import a submodule the first never imported
("No module named '_pyfmu_<hash>.fmi.native'": Trivial does not import the native step,
BaseOscillator does). Each case runs in a fresh interpreter (the package must not be imported
already) a sequence of operations on FMU instances, each from its own extraction folder; every
BaseOscillator run is held against the exact forced response.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from _fmu_support import built_fmus, damped_forced_response

BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=18.0, x0=0.01, xd0=0.0)

SCRIPT = textwrap.dedent("""
    import json, shutil, sys, tempfile
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    fmus, ops, root = json.loads(sys.argv[1]), json.loads(sys.argv[2]), sys.argv[3]
    BASE = {base!r}
    live, dirs, out = {{}}, {{}}, {{}}
    for op, key, *arg in ops:
        if op == "load":  # extract into a folder of its own and instantiate
            name = arg[0]
            md = fmpy.read_model_description(fmus[name])
            d = tempfile.mkdtemp(dir=root)
            fmpy.extract(fmus[name], d)
            s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=name, instanceName=key)
            s.instantiate()
            vr = {{v.name: v.valueReference for v in md.modelVariables}}
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            if name == "BaseOscillator":
                s.setReal([vr[k] for k in BASE], list(BASE.values()))
            s.exitInitializationMode()
            live[key], dirs[key] = (s, vr, name, [0.0]), d
        elif op == "step":  # n steps of 1 ms
            s, vr, name, t = live[key]
            ys = []
            for _ in range(int(arg[0])):
                if name == "Trivial":
                    s.setReal([vr["u"]], [t[0]])
                elif name == "TMDInerter":
                    s.setReal([vr["x"]], [1e-3])
                s.doStep(t[0], 1e-3)
                t[0] += 1e-3
                ys.append(s.getReal([vr["x" if name == "BaseOscillator" else ("y" if name == "TMDInerter" else "y")]])[0])
            out.setdefault(key, []).append((t[0], ys))
        elif op == "free":
            s = live.pop(key)[0]
            s.terminate()
            s.freeInstance()
        elif op == "rm":  # what fmpy does with the extraction folder of an FMU it is done with
            shutil.rmtree(dirs.pop(key))
        elif op == "simulate":  # fmpy's own cycle: extract to a temporary folder, run, delete it
            res = fmpy.simulate_fmu(fmus[arg[0]], stop_time=0.05, output_interval=1e-3,
                                    start_values=BASE if arg[0] == "BaseOscillator" else {{}},
                                    output=["x"] if arg[0] == "BaseOscillator" else None)
            if arg[0] == "BaseOscillator":
                out[key] = [(0.05, [float(v) for v in res["x"]])]
    print("RESULT " + json.dumps(out))
""").format(base=BASE)


def _run(ops, tmp_path):
    fmus = {k: str(v) for k, v in built_fmus().items()}
    env = {k: v for k, v in os.environ.items() if k != "PYFMU_NATIVE"}
    r = subprocess.run(
        [sys.executable, "-c", SCRIPT, json.dumps(fmus), json.dumps(ops), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert r.returncode == 0, r.stderr[-4000:]
    line = [x for x in r.stdout.splitlines() if x.startswith("RESULT ")]
    assert line, r.stdout[-2000:] + r.stderr[-2000:]
    return json.loads(line[0][7:])


def _assert_exact(runs):
    """Each run of BaseOscillator (steps of 1 ms from t = 0) against the exact forced response."""
    t_end = 0.0
    xs = []
    for t1, ys in runs:
        xs += ys
        t_end = t1
    t = np.arange(1, len(xs) + 1) * 1e-3
    assert abs(t[-1] - t_end) < 1e-12
    x, _ = damped_forced_response(t, **BASE)
    assert np.max(np.abs(np.array(xs) - x)) < 1e-7 * BASE["x0"]


def test_trivial_freed_and_deleted_then_base_oscillator(tmp_path):
    """The failing case of bench_cosim.py: Trivial (no native step) loaded, freed, its folder
    deleted; BaseOscillator of the same build then imports fmi.native from its own folder."""
    out = _run(
        [
            ["load", "t1", "Trivial"],
            ["step", "t1", 5],
            ["free", "t1"],
            ["rm", "t1"],
            ["load", "b", "BaseOscillator"],
            ["step", "b", 200],
            ["free", "b"],
        ],
        tmp_path,
    )
    _assert_exact(out["b"])
    assert out["t1"][0][1][-1] == pytest.approx(2.0 * 4e-3)  # y = gain u (gain 2), u = 4 ms at the 5th step


def test_both_orders_and_two_live_instances_of_one_build(tmp_path):
    """BaseOscillator first, deleted, then Trivial and TMDInerter; two instances of one FMU from
    two folders, the first freed and deleted while the second steps on; and a new instance after
    every folder loaded so far is gone."""
    out = _run(
        [
            ["load", "b1", "BaseOscillator"],
            ["step", "b1", 100],
            ["load", "b2", "BaseOscillator"],
            ["free", "b1"],
            ["rm", "b1"],
            ["step", "b2", 100],
            ["load", "tr", "Trivial"],
            ["step", "tr", 3],
            ["load", "tmd", "TMDInerter"],
            ["step", "tmd", 50],
            ["free", "b2"],
            ["rm", "b2"],
            ["free", "tr"],
            ["rm", "tr"],
            ["free", "tmd"],
            ["rm", "tmd"],
            ["load", "b3", "BaseOscillator"],
            ["step", "b3", 100],
            ["free", "b3"],
        ],
        tmp_path,
    )
    _assert_exact(out["b1"])
    _assert_exact(out["b2"])
    _assert_exact(out["b3"])
    assert max(abs(v) for v in out["tmd"][0][1]) > 0  # the TMD moved under the held base displacement


def test_fmpy_simulate_fmu_one_after_the_other(tmp_path):
    """fmpy.simulate_fmu extracts each FMU into a temporary folder and deletes it afterwards."""
    out = _run(
        [
            ["simulate", "t", "Trivial"],
            ["simulate", "b", "BaseOscillator"],
            ["simulate", "t2", "Trivial"],
            ["simulate", "b2", "BaseOscillator"],
        ],
        tmp_path,
    )
    for key in ("b", "b2"):
        xs = out[key][0][1]
        t = np.arange(len(xs)) * 1e-3
        x, _ = damped_forced_response(t, **BASE)
        assert np.max(np.abs(np.array(xs) - x)) < 1e-7 * BASE["x0"]


@pytest.mark.slow
def test_two_builds_in_one_process_never_mix(tmp_path):
    """Two builds of BaseOscillator (the second from a copy of the sources with one comment added
    to a bundled module: another bundle hash, another package name) loaded, freed, deleted and
    loaded again in one process: each gets its own package (both in sys.modules at the end), and
    every run matches the exact response. (Slow the first time: build B's numba cache is cold.)"""
    import shutil

    from pyfmu_wrapper.fmubuild.build import PACKAGE_DIR, REPO_ROOT, fmu_source_hash

    src = tmp_path / "src"
    shutil.copytree(PACKAGE_DIR, src / PACKAGE_DIR.name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO_ROOT / "fmu" / "src", src / "fmu" / "src")
    slaves = src / PACKAGE_DIR.name / "fmi" / "slaves.py"
    slaves.write_text(slaves.read_text() + "\n# build B: the same code, another bundle hash\n")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pyfmu_wrapper.cli.build_fmus",
            "--python",
            "--out",
            str(tmp_path / "b"),
            "BaseOscillator",
        ],
        cwd=src,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    fmu_b = tmp_path / "b" / "BaseOscillator.fmu"
    fmu_a = built_fmus()["BaseOscillator"]
    assert fmu_source_hash(fmu_b) != fmu_source_hash(fmu_a)
    script = SCRIPT.replace(
        'print("RESULT "',
        'out["packages"] = sorted(n for n in sys.modules if n.startswith("_pyfmu_") '
        'and n.count(".") == 0 and "_model_" not in n)\nprint("RESULT "',
    )
    fmus = {"A": str(fmu_a), "B": str(fmu_b)}
    ops = [
        ["load", "a1", "A"],
        ["step", "a1", 100],
        ["free", "a1"],
        ["rm", "a1"],
        ["load", "b1", "B"],
        ["step", "b1", 100],
        ["load", "a2", "A"],
        ["step", "a2", 100],
        ["free", "b1"],
        ["rm", "b1"],
        ["load", "b2", "B"],
        ["step", "b2", 100],
        ["free", "a2"],
        ["free", "b2"],
    ]
    ops = [
        [op, key, *("BaseOscillator:" + a for a in arg)] if op == "load" else [op, key, *arg] for op, key, *arg in ops
    ]
    script = script.replace(
        "md = fmpy.read_model_description(fmus[name])",
        "name, path = 'BaseOscillator', fmus[name.split(':')[1]]\n        md = fmpy.read_model_description(path)",
    )
    script = script.replace("fmpy.extract(fmus[name], d)", "fmpy.extract(path, d)")
    env = {k: v for k, v in os.environ.items() if k != "PYFMU_NATIVE"}
    r = subprocess.run(
        [sys.executable, "-c", script, json.dumps(fmus), json.dumps(ops), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=1200,
        env=env,
    )
    assert r.returncode == 0, r.stderr[-4000:]
    out = json.loads([x for x in r.stdout.splitlines() if x.startswith("RESULT ")][0][7:])
    for key in ("a1", "b1", "a2", "b2"):
        _assert_exact(out[key])
    assert len(out["packages"]) == 2  # one package per build, never shared
