"""Native-speed steps: the stub calls the compiled step (pyfmu_wrapper/fmi/native.py) directly.

* The native and the Python path give bit-identical results (same compiled integrator), for
  both FMUs, in the C host (PYFMU_NATIVE=0 forces the Python path).
* An ordinary step does not enter the Python slave at all; a long step (> 1 s) and a step with
  debug_raise set do.
"""

from __future__ import annotations

import os
import subprocess
import sys

import fmpy
import numpy as np
import pytest
from _fmu_support import built_fmus, compile_c_host, extract, guid
from fmpy.fmi2 import FMU2Slave

BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=18.0, x0=0.01, xd0=0.0)
TMD = dict(m=9.0, k=4.0e3, c=10.0, df=5.0, I=1.0, y0=0.01)


#: the play model (gear chain with a gap, Case 1 of the paper): the rattle, with the per-state tolerances
PLAY = dict(TMD, c=0.0, df=0.0, ki=2.0e7, ci=0.01, eps=1e-4)


def _args(d, name, start, outputs, ints=None):
    md = fmpy.read_model_description(str(d))
    vr = {v.name: v for v in md.modelVariables}
    args = [str(d), guid(d), name]
    args += [f"r:{vr[k].valueReference}={v!r}" for k, v in start.items()]
    args += [f"i:{vr[k].valueReference}={v:d}" for k, v in (ints or {}).items()]
    return args + [f"o:{vr[o].valueReference}" for o in outputs]


@pytest.mark.parametrize("tmd,ints", [(TMD, None), (PLAY, {"inerter": 2})], ids=["ideal", "play"])
def test_native_and_python_paths_bit_identical(tmp_path, tmd, ints):
    fmus = built_fmus()
    dirs = {n: extract(p, tmp_path) for n, p in fmus.items()}
    exe = compile_c_host(tmp_path)
    cmd = [
        str(exe),
        "run",
        "0.3",
        "0.001",
        *_args(dirs["BaseOscillator"], "base", BASE, ["x", "xd", "xdd", "f_exc"]),
        "--",
        *_args(dirs["TMDInerter"], "tmd", tmd, ["force", "y", "yd", "inerter_force"], ints),
    ]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "PYFMU_NATIVE"))}
    runs = {}
    for native in ("1", "0"):
        r = subprocess.run(cmd, capture_output=True, text=True, env=dict(env, PYFMU_NATIVE=native), timeout=300)
        assert r.returncode == 0, r.stderr
        runs[native] = np.loadtxt(r.stdout.splitlines())
    assert runs["1"].shape == (301, 9)
    assert np.array_equal(runs["1"], runs["0"])
    assert np.max(np.abs(runs["1"][:, 6])) > 1e-3  # the TMD moved


def _slave(fmu, tmp_path, name, start):
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / name
    fmpy.extract(str(fmu), str(d))
    s = FMU2Slave(
        guid=md.guid, unzipDirectory=str(d), modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    for k, v in start.items():
        s.setReal([vr[k]], [v])
    s.exitInitializationMode()
    return s, vr


def test_ordinary_steps_do_not_enter_the_python_slave(tmp_path, monkeypatch):
    if os.environ.get("PYFMU_NATIVE") == "0":
        pytest.skip("PYFMU_NATIVE=0 set in the environment")
    fmu = built_fmus()["TMDInerter"]
    s0, _ = _slave(fmu, tmp_path, "warm", TMD)  # imports the bundled package
    s0.terminate()
    s0.freeInstance()
    mods = [m for n, m in sys.modules.items() if n.startswith("_pyfmu_") and n.endswith(".models.base_tmd.fmus.slaves")]
    assert mods
    calls = []
    for m in mods:
        original = m.Slave.do_step
        monkeypatch.setattr(m.Slave, "do_step", lambda self, *a, _o=original: calls.append(a) or _o(self, *a))
    s, vr = _slave(fmu, tmp_path, "nat", TMD)
    try:
        t = 0.0
        for _ in range(50):
            s.setReal([vr["x"]], [1e-3 * np.sin(20 * t)])
            s.doStep(t, 1e-3)
            t += 1e-3
        assert calls == []  # 50 steps, none in Python
        y_native = s.getReal([vr["y"]])[0]
        s.doStep(t, 2.0)  # a long step goes through Python (in pieces)
        assert len(calls) == 1 and calls[0][1] == 2.0
        assert y_native != 0.0
    finally:
        s.terminate()
        s.freeInstance()


def test_gear_chain_rate_gets_atol_times_the_mesh_frequency():
    """The FMU's atol holds every state, except the play chain's rate dd: atol x sqrt(ki/I), the
    mesh frequency (the monolithic solver's scaling). Held to atol like the deflection d, the
    rattle cost the TMD FMU 2.7x the integrator steps per period."""
    from pyfmu_wrapper.models.base_tmd.fmus.integrators import fill_atol
    from pyfmu_wrapper.physics import kernels as kn
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams, pack

    a = 1e-10
    base = BaseParams(mass=100.0, stiffness=4.0e4)
    play = TMDParams(mass=9.0, stiffness=4.0e3, inertance=4.0, mesh_stiffness=1.6e7, inerter="play", play_gap=1e-4)
    ideal = TMDParams(mass=9.0, stiffness=4.0e3, inertance=1.0)
    expected = {
        (kn.SYS_TMD, play): [a, a, a, a * 2000.0],  # sqrt(1.6e7 / 4) = 2000 rad/s
        (kn.SYS_TMD, ideal): [a, a, a, a],
        (kn.SYS_BASE, ideal): [a, a],
        # a soft mesh (below 1 rad/s) never makes dd's tolerance tighter than d's
        (kn.SYS_TMD, TMDParams(mass=9.0, stiffness=4.0e3, inertance=4.0, mesh_stiffness=1.0, inerter="play")): [
            a,
            a,
            a,
            a,
        ],
    }
    for (system, t), want in expected.items():
        atol = np.zeros(len(want))
        fill_atol(system, a, pack(base, t, 0.0), atol)
        np.testing.assert_array_equal(atol, want)
