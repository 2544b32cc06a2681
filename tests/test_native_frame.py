"""The ShearFrame FMU's step (pyfmu_wrapper/models/frame_model/fmus/step.py): exact, and the same bits on every path.

- The exact step holds the frame on its exact steady orbit: a 3-storey frame started on the orbit of
  its structure's matrices (physics/frame.py: (K - w^2 M + i w C) X = F), with constant TMD forces
  f_link and f_inerter (whose static deflection, K x = the forces on storeys s and j, superposes),
  stays on it to 1e-10 of the amplitude over two periods of 40 steps.
- The Python-hosted FMU's compiled step (the stub calls the cfunc of pyfmu_wrapper/models/frame_model/fmus/native.py) and
  its Python path (PYFMU_NATIVE=0) give the same outputs bit for bit, input derivatives included; so
  does the native ShearFrame FMU (no Python: configure, outputs and step compiled into its binary,
  fmubuild/native_build.py), FMI 2.0 and 3.0 alike, and both validate.
- The native FMU refuses a frame FrameParams refuses, naming the check and the values it read; its
  directional derivatives and FMU states are the Python-hosted FMU's.
- (slow) Its win64 DLL under wine steps as its linux64 library, within 1e-12 of each output's range.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.fmubuild.native_build import ensure_native_fmus
from pyfmu_wrapper.models.catalog import pick
from pyfmu_wrapper.physics import frame as ref

#: a 3-storey frame (the frame3 scenarios' storeys), its TMD forces on storey 3 (links) and 2 (inerter)
STOREYS = dict(storeys=3, F=200.0, w=17.0, tmd_storey=3, inerter_to=2)
PER = dict(m=(100.0, 120.0, 90.0), k=(1.2e5, 1.0e5, 1.1e5), c=(100.0, 80.0, 60.0))

# Run in a fresh interpreter (PYFMU_NATIVE is read when the FMU is instantiated): the FMU at argv[1],
# the start values as JSON in argv[2], the steps' inputs and their derivatives in argv[3]; prints the
# outputs after every step as JSON.
_RUN = """
import json, sys
import fmpy
from fmpy.fmi2 import FMU2Slave
fmu, start, steps = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
md = fmpy.read_model_description(fmu)
vr = {v.name: v.valueReference for v in md.modelVariables}
d = fmpy.extract(fmu)
s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="f")
s.instantiate()
s.setupExperiment(startTime=0.0)
s.enterInitializationMode()
for k, v in start.items():
    (s.setInteger if isinstance(v, int) else s.setReal)([vr[k]], [v])
s.exitInitializationMode()
outs = ["x_top", "xd_top", "x", "xd", "xdd", "xdd_free"]
t, rows = 0.0, []
for h, f, fd, fdd, P, Pd in steps:
    s.setReal([vr["f_link"], vr["f_inerter"]], [f, P])
    s.setRealInputDerivatives([vr["f_link"], vr["f_inerter"]], [1, 1], [fd, Pd])
    s.setRealInputDerivatives([vr["f_link"]], [2], [fdd])
    s.doStep(t, h)
    t += h
    rows.append(s.getReal([vr[o] for o in outs]))
s.terminate()
s.freeInstance()
print(json.dumps(rows))
"""


def _start(x0: np.ndarray, xd0: np.ndarray) -> dict:
    out: dict = dict(STOREYS)
    for i in range(3):
        out |= {f"m{i + 1}": PER["m"][i], f"k{i + 1}": PER["k"][i], f"c{i + 1}": PER["c"][i]}
        out |= {f"x0_{i + 1}": float(x0[i]), f"xd0_{i + 1}": float(xd0[i])}
    return out


def _run(fmu: Path, start: dict, steps: list, native: str) -> np.ndarray:
    env = {k: v for k, v in os.environ.items() if k != "PYFMU_NATIVE"}
    r = subprocess.run(
        [sys.executable, "-c", _RUN, str(fmu), json.dumps(start), json.dumps(steps)],
        capture_output=True,
        text=True,
        env=dict(env, PYFMU_NATIVE=native),
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    return np.array(json.loads(r.stdout.splitlines()[-1]))


@pytest.fixture(scope="module")
def hosted() -> Path:
    return ensure_fmus(pick("ShearFrame"))["ShearFrame"]


def test_exact_step_stays_on_the_structures_exact_orbit(hosted):
    w = STOREYS["w"]
    structure = ref.ShearFrame(PER["m"], PER["k"], PER["c"], force_amplitude=200.0)
    X = ref.frequency_response(structure, None, [w])[0]
    _, _, _, K, _ = ref.matrices(structure)
    f, P = 35.0, 12.0  # the TMD's forces: f - P on storey 3, P on storey 2 (both against x)
    xs = np.linalg.solve(K, np.array([0.0, -P, -(f - P)]))
    T, n = 2 * np.pi / w, 40
    steps = [[T / n, f, 0.0, 0.0, P, 0.0]] * (2 * n)
    rows = _run(hosted, _start(X.real + xs, (1j * w * X).real), steps, "1")
    t = T / n * np.arange(1, 2 * n + 1)
    x = (X[:, None] * np.exp(1j * w * t)).real + xs[:, None]
    xd = (1j * w * X[:, None] * np.exp(1j * w * t)).real
    scale = np.max(np.abs(X))
    assert np.max(np.abs(rows[:, 0] - x[2])) < 1e-10 * scale  # the top storey
    assert np.max(np.abs(rows[:, 1] - xd[2])) < 1e-10 * scale * w
    assert np.array_equal(rows[:, 2], rows[:, 0])  # the TMD's storey is the top one
    assert scale > 1e-3


def test_compiled_and_python_steps_bit_identical(hosted):
    """Input polynomials of degree 2 (f_link) and 1 (f_inerter), a long step (1.3 s: in pieces) among them."""
    rng = np.random.default_rng(29)
    steps = [[1e-3, *(rng.normal(size=5) * [30.0, 300.0, 3e3, 10.0, 100.0])] for _ in range(60)]
    steps[30][0] = 1.3
    start = _start(np.array([1e-3, -2e-3, 3e-3]), np.array([0.0, 0.01, -0.02]))
    compiled, python = _run(hosted, start, steps, "1"), _run(hosted, start, steps, "0")
    assert compiled.shape == (60, 6)
    assert np.array_equal(compiled, python)
    assert np.all(np.isfinite(compiled)) and np.ptp(compiled[:, 0]) > 1e-4


@pytest.fixture(scope="module")
def native() -> dict[int, Path]:
    """The native ShearFrame FMUs (built if stale, where the frame's co-simulation finds them)."""
    return {v: ensure_native_fmus(pick("ShearFrame"), fmi_version=v)["ShearFrame"] for v in (2, 3)}


def test_native_fmu_is_the_python_hosted_fmu_bit_for_bit(hosted, native):
    rng = np.random.default_rng(30)
    steps = [[2e-3, *(rng.normal(size=5) * [30.0, 300.0, 3e3, 10.0, 100.0])] for _ in range(40)]
    steps[20][0] = 2.5  # a long step: three pieces
    start = _start(np.array([2e-3, 1e-3, -3e-3]), np.array([0.01, 0.0, 0.02]))
    assert np.array_equal(_run(native[2], start, steps, "1"), _run(hosted, start, steps, "1"))


def test_native_fmi3_fmu_validates_and_runs_as_fmi2(native):
    import fmpy
    from fmpy.validation import validate_fmu

    for v in (2, 3):
        assert validate_fmu(str(native[v])) == []
    start = _start(np.array([2e-3, 1e-3, -3e-3]), np.array([0.01, 0.0, 0.02]))
    runs = [
        fmpy.simulate_fmu(str(native[v]), start_values=start, stop_time=0.4, output_interval=2e-3, output=["x_top"])
        for v in (2, 3)
    ]
    assert np.array_equal(runs[0]["x_top"], runs[1]["x_top"]) and np.ptp(runs[0]["x_top"]) > 1e-3


def test_native_fmu_refuses_a_frame_with_a_storey_it_lacks(native, tmp_path):
    from fmpy.fmi1 import FMICallException
    from test_fmu_ranges import Logged

    f = Logged(native[2], tmp_path, "bad")
    try:
        with pytest.raises(FMICallException):
            f.start(dict(storeys=3, force_storey=5))
        text = f.text()
    finally:
        f.s.freeInstance()
    assert "force_storey must be an integer storey 0..storeys (0: the top), got storeys = 3, force_storey = 5" in text


def _slave(fmu: Path, tmp_path: Path, name: str, start: dict):
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    s = FMU2Slave(
        guid=md.guid,
        unzipDirectory=fmpy.extract(str(fmu), str(tmp_path / name)),
        modelIdentifier="ShearFrame",
        instanceName=name,
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for k, v in start.items():
        (s.setInteger if isinstance(v, int) else s.setReal)([md_vr(md)[k]], [v])
    s.exitInitializationMode()
    return s, md_vr(md)


def md_vr(md) -> dict:
    return {v.name: v.valueReference for v in md.modelVariables}


def test_native_derivatives_and_states_are_the_python_hosted_fmus(hosted, native, tmp_path):
    """d xdd / d f_inerter = -1 / m_j (the inerter's share acts on its terminal j = 2 alone) and
    d xdd / d f_link = 0, the same bits from both FMUs; a state taken, stepped from and set back
    steps again to the same outputs."""
    start = _start(np.array([1e-3, -2e-3, 3e-3]), np.array([0.0, 0.01, -0.02]))
    got = {}
    for tag, fmu in (("hosted", hosted), ("native", native[2])):
        s, vr = _slave(fmu, tmp_path, tag, start)
        try:
            s.doStep(0.0, 1e-3)
            outs = [vr["xdd"], vr["x_top"]]
            d_p = s.getDirectionalDerivative(outs, [vr["f_inerter"]], [1.0])
            d_f = s.getDirectionalDerivative(outs, [vr["f_link"]], [1.0])
            state = s.getFMUstate()
            s.setReal([vr["f_link"]], [50.0])
            s.doStep(1e-3, 1e-3)
            first = s.getReal([vr["x_top"], vr["xdd"]])
            s.setFMUstate(state)
            s.setReal([vr["f_link"]], [50.0])
            s.doStep(1e-3, 1e-3)
            again = s.getReal([vr["x_top"], vr["xdd"]])
            s.freeFMUstate(state)
            got[tag] = (d_p, d_f, first, again)
        finally:
            s.terminate()
            s.freeInstance()
    d_p, d_f, first, again = got["native"]
    assert d_p[0] == pytest.approx(-1.0 / PER["m"][1], rel=1e-14) and d_p[1] == 0.0 and d_f == [0.0, 0.0]
    assert first == again
    assert got["native"] == got["hosted"]


#: one ShearFrame FMU stepped alone (3 storeys, F cos(w t) on the top, no TMD forces), compiled for Linux
#: (gcc) and Windows (mingw-w64): argv = binary, resources URI, guid; prints t, x_top, xdd per step
FRAME_HOST = r"""
#include <stdio.h>
#include <stdlib.h>
#include "fmi2Functions.h"
#if defined(_WIN32)
#include <windows.h>
#define OPEN(p) (void *)LoadLibraryA(p)
#define SYM(h, n) (void *)GetProcAddress((HMODULE)(h), n)
#else
#include <dlfcn.h>
#define OPEN(p) dlopen(p, RTLD_NOW | RTLD_LOCAL)
#define SYM(h, n) dlsym(h, n)
#endif
static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...) {
    (void)e; (void)c;
    if (s > fmi2Warning) fprintf(stderr, "[%s] %s\n", n, m);
}
static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
int main(int argc, char **argv) {
    if (argc < 4) return 2;
    void *h = OPEN(argv[1]);
    if (!h) return 3;
    fmi2Component c = ((fmi2InstantiateTYPE *)SYM(h, "fmi2Instantiate"))("f", fmi2CoSimulation, argv[3], argv[2],
                                                                          &cb, fmi2False, fmi2False);
    fmi2DoStepTYPE *step = (fmi2DoStepTYPE *)SYM(h, "fmi2DoStep");
    fmi2GetRealTYPE *get = (fmi2GetRealTYPE *)SYM(h, "fmi2GetReal");
    fmi2ValueReference n_vr = 0, out[2] = {20, 24};
    fmi2Integer n = 3;
    if (!c || ((fmi2SetupExperimentTYPE *)SYM(h, "fmi2SetupExperiment"))(c, 0, 0, 0.0, 0, 0)) return 4;
    if (((fmi2EnterInitializationModeTYPE *)SYM(h, "fmi2EnterInitializationMode"))(c)) return 4;
    if (((fmi2SetIntegerTYPE *)SYM(h, "fmi2SetInteger"))(c, &n_vr, 1, &n)) return 4;
    if (((fmi2ExitInitializationModeTYPE *)SYM(h, "fmi2ExitInitializationMode"))(c)) return 4;
    double dt = 2e-3, y[2];
    for (int k = 1; k <= 300; k++) {
        if (step(c, (k - 1) * dt, dt, fmi2True) || get(c, out, 2, y)) return 5;
        printf("%.17g %.17g %.17g\n", k * dt, y[0], y[1]);
    }
    return 0;
}
"""


@pytest.mark.slow  # a fresh wine prefix: about 70 s on the shared machine
def test_win64_frame_under_wine_agrees_with_linux64(native, tmp_path):
    """The native ShearFrame's win64 DLL under wine steps as its linux64 library: within 1e-12 of each
    output's range (msvcrt's cos and sin may round the harmonic drive differently in the last bit)."""
    import shutil
    import zipfile

    import fmpy

    from pyfmu_wrapper.fmubuild.build import fmi_headers_dir
    from pyfmu_wrapper.fmubuild.native_obj import mingw_gcc

    if mingw_gcc() is None or shutil.which("wine") is None:
        pytest.skip("mingw-w64 or wine is missing (.ci/run installs gcc-mingw-w64-x86-64 and wine64)")
    d = tmp_path / "ShearFrame"
    with zipfile.ZipFile(native[2]) as z:
        z.extractall(d)
    (tmp_path / "host.c").write_text(FRAME_HOST)
    inc = f"-I{fmi_headers_dir()}"
    subprocess.run(["gcc", "-O2", inc, str(tmp_path / "host.c"), "-o", str(tmp_path / "host"), "-ldl"], check=True)
    subprocess.run([mingw_gcc(), "-O2", inc, str(tmp_path / "host.c"), "-o", str(tmp_path / "host.exe")], check=True)
    guid = fmpy.read_model_description(str(native[2])).guid
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all", "WINEPREFIX": str(tmp_path / "wp")}
    runs = []
    for win in (False, True):
        binary = d / "binaries" / ("win64/ShearFrame.dll" if win else "linux64/ShearFrame.so")
        uri = ("file:///Z:" + str(d / "resources")) if win else (d / "resources").as_uri()
        cmd = ["wine", str(tmp_path / "host.exe"), "Z:" + str(binary)] if win else [str(tmp_path / "host"), str(binary)]
        r = subprocess.run([*cmd, uri, guid], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=900)
        assert r.returncode == 0, r.stderr[-3000:]
        runs.append(np.array([[float(x) for x in line.split()] for line in r.stdout.splitlines() if line.strip()]))
    lin, win = runs
    assert lin.shape == (300, 3) and (lin[:, 0] == win[:, 0]).all() and np.ptp(lin[:, 1]) > 1e-3
    assert (np.abs(win[:, 1:] - lin[:, 1:]) / np.ptp(lin[:, 1:], axis=0)).max() <= 1e-12
