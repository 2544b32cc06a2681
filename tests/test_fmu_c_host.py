"""Both FMUs in a pure C host (no Python in the host, RTLD_LOCAL, only -ldl): same numbers as fmpy."""

from __future__ import annotations

import os
import subprocess

import fmpy
import numpy as np
import pytest
from _fmu_support import built_fmus, compile_c_host, extract, guid

BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=18.0, x0=0.01, xd0=0.0)
TMD_A = dict(m=9.0, k=4.0e3, c=10.0, df=5.0, I=1.0, y0=0.01)
TMD_B = dict(m=5.0, k=4.0e3, c=30.0, I=5.0, y0=-0.005)


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    root = tmp_path_factory.mktemp("chost")
    fmus = built_fmus()
    dirs = {n: extract(p, root) for n, p in fmus.items()}
    exe = compile_c_host(root)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD", "VIRTUAL_ENV"))}
    return exe, dirs, fmus, env


def spec_args(d, name, start, outputs):
    md = fmpy.read_model_description(str(d))
    vr = {v.name: v for v in md.modelVariables}
    args = [str(d), guid(d), name]
    for k, v in start.items():
        args.append(f"i:{vr[k].valueReference}={v}" if vr[k].type == "Integer" else f"r:{vr[k].valueReference}={v!r}")
    args += [f"o:{vr[o].valueReference}" for o in outputs]
    return args


def test_c_host_runs_both_fmus_like_fmpy(host):
    exe, dirs, fmus, env = host
    outs_b, outs_t = ["x", "xd", "xdd", "f_exc"], ["force", "y", "yd", "inerter_force"]
    cmd = [
        str(exe),
        "run",
        "0.5",
        "0.001",
        *spec_args(dirs["BaseOscillator"], "base", BASE, outs_b),
        "--",
        *spec_args(dirs["TMDInerter"], "tmdA", TMD_A, outs_t),
        "--",
        *spec_args(dirs["TMDInerter"], "tmdB", TMD_B, outs_t),
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    c = np.loadtxt(r.stdout.splitlines())
    ref_b = fmpy.simulate_fmu(
        str(fmus["BaseOscillator"]), stop_time=0.5, output_interval=1e-3, start_values=BASE, output=outs_b
    )
    ref_a = fmpy.simulate_fmu(
        str(fmus["TMDInerter"]), stop_time=0.5, output_interval=1e-3, start_values=TMD_A, output=outs_t
    )
    ref_bb = fmpy.simulate_fmu(
        str(fmus["TMDInerter"]), stop_time=0.5, output_interval=1e-3, start_values=TMD_B, output=outs_t
    )
    assert c.shape == (len(ref_b), 13)
    np.testing.assert_allclose(c[:, 0], ref_b["time"], rtol=0, atol=1e-12)
    for k, o in enumerate(outs_b):
        np.testing.assert_allclose(c[:, 1 + k], ref_b[o], rtol=1e-13, atol=1e-15)
    for k, o in enumerate(outs_t):
        np.testing.assert_allclose(c[:, 5 + k], ref_a[o], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(c[:, 9 + k], ref_bb[o], rtol=1e-13, atol=1e-15)


def test_c_host_error_handling_and_survival(host):
    exe, dirs, _, env = host
    d = dirs["TMDInerter"]
    r = subprocess.run([str(exe), "errors", str(d), guid(d)], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    checks = [l.split() for l in r.stdout.splitlines() if l.startswith("CHECK")]
    assert len(checks) >= 20
    assert [c[1] for c in checks if c[2] != "ok"] == []
    assert r.stdout.rstrip().endswith("survived")


def test_c_host_load_unload_100_times(host):
    exe, dirs, _, env = host
    d = dirs["TMDInerter"]
    r = subprocess.run([str(exe), "loop", "100", str(d), guid(d)], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    vals = dict(l.split() for l in r.stdout.splitlines())
    growth_kb = int(vals["rss_after_100_kb"]) - int(vals["rss_after_5_kb"])
    assert growth_kb < 8 * 1024, f"RSS grew by {growth_kb} kB over 95 load/unload cycles"
