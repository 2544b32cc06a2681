"""Native FMUs (pyfmu_wrapper/fmubuild/native_build.py): the model's compiled functions linked into the
stub, no Python on the target.

- The Case 1 pair (base + TMD, ideal inerter and with play), co-simulated by a C host
  (tests/c_host/fmu_pair.c) run with ``env -i`` from a folder outside the checkout, prints the same
  digits (%.17g, every output, every step) as the same run of the Python-hosted FMUs, and maps no
  Python file, no libpython and nothing of the checkout.
- The binary needs only the C library (libc, libm, libdl).
- What the Python slave refuses, the native FMU refuses (a cross-field check of TMDParams); its
  directional derivatives and FMU states equal the Python-hosted FMU's.
"""

from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from _fmu_support import built_fmus, guid
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from test_fmu_ranges import Logged

from pyfmu_wrapper.fmubuild.build import REPO_ROOT, fmi_headers_dir
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick

PAIR = Path(__file__).parent / "c_host" / "fmu_pair.c"
CASE1 = dict(m=9.0, I=1.0, k=4.0e3, c=10.0)
PLAY = dict(CASE1, inerter=2, eps=1e-4, ki=2e7)


@pytest.fixture(scope="module")
def native(tmp_path_factory):
    return {p.stem: p for p in build_native_fmus(pick(PROJECT_FMUS), out_dir=tmp_path_factory.mktemp("native"))}


@pytest.fixture(scope="module")
def hosted():
    return built_fmus()


@pytest.fixture(scope="module")
def outside():
    """A folder outside the checkout, the pair host compiled into it."""
    root = Path(tempfile.mkdtemp(prefix="pyfmu_native_"))
    assert not str(root).startswith(str(REPO_ROOT))
    exe = root / "fmu_pair"
    subprocess.run(["gcc", "-O2", f"-I{fmi_headers_dir()}", str(PAIR), "-o", str(exe), "-ldl"], check=True)
    return root, exe


def _vrs(fmu: Path) -> dict[str, int]:
    return {v.name: v.valueReference for v in fmpy.read_model_description(str(fmu)).modelVariables}


def _pair(fmus: dict[str, Path], tmd: dict, root: Path, exe: Path, tag: str, clean: bool) -> tuple[list[str], set]:
    dirs = {}
    for n, p in fmus.items():
        d = root / tag / n
        with zipfile.ZipFile(p) as z:
            z.extractall(d)
        dirs[n] = d
    vb, vt = _vrs(fmus["BaseOscillator"]), _vrs(fmus["TMDInerter"])
    args = [f"{'i2' if isinstance(v, int) else 'r2'}:{vt[k]}={v!r}" for k, v in tmd.items()]
    args += [f"c12:{vb[a]}={vt[a]}" for a in ("x", "xd", "xdd")] + [f"c21:{vt['force']}={vb['f_link']}"]
    args += [f"o1:{vb[n]}" for n in ("x", "xd", "xdd", "f_link")]
    b, t = dirs["BaseOscillator"], dirs["TMDInerter"]
    env = ["env", "-i", "PATH=/usr/bin:/bin", f"HOME={root}"] if clean else []
    cmd = [*env, str(exe), "0.5", "0.001", str(b), guid(b), str(t), guid(t), *args]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=root, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = [line for line in r.stdout.splitlines() if line.startswith("row ")]
    maps = {line[4:] for line in r.stdout.splitlines() if line.startswith("map ")}
    return rows, maps


@pytest.mark.parametrize("tmd", [CASE1, PLAY], ids=["ideal", "play"])
def test_pair_is_bit_identical_to_the_python_hosted_fmus_with_no_python(native, hosted, outside, tmd):
    root, exe = outside
    rows_n, maps_n = _pair(native, tmd, root, exe, f"n{len(tmd)}", clean=True)
    rows_p, _ = _pair({n: hosted[n] for n in native}, tmd, root, exe, f"p{len(tmd)}", clean=False)
    assert len(rows_n) == 501 and rows_n == rows_p  # every printed digit of every output at every step
    x = np.array([float(r.split()[2]) for r in rows_n])
    assert np.ptp(x) > 1e-4  # the base moves
    assert [m for m in maps_n if m.endswith("/TMDInerter.so")]  # the map lists what was loaded
    assert not [m for m in maps_n if "python" in m.lower() or "numba" in m or "llvmlite" in m], maps_n
    assert not [m for m in maps_n if m.startswith(str(REPO_ROOT))]


def test_native_binary_needs_only_the_c_library(native, tmp_path):
    with zipfile.ZipFile(native["TMDInerter"]) as z:
        z.extractall(tmp_path)
        names = z.namelist()
    assert not [n for n in names if n.endswith(".py")]
    so = tmp_path / "binaries" / "linux64" / "TMDInerter.so"
    d = subprocess.run(["readelf", "-d", str(so)], capture_output=True, text=True, check=True).stdout
    needed = {line.split("[")[1].rstrip("]") for line in d.splitlines() if "(NEEDED)" in line}
    assert needed <= {"libc.so.6", "libm.so.6", "libdl.so.2", "ld-linux-x86-64.so.2"}, needed
    assert "RUNPATH" not in d and "RPATH" not in d
    assert native["TMDInerter"].stat().st_size < 2_000_000


def test_cross_field_check_refused_as_in_python(native, hosted, tmp_path):
    """inerter = none with I = 1: TMDParams refuses it; so does the native configure."""
    msgs = {}
    for tag, fmus in (("native", native), ("hosted", hosted)):
        f = Logged(fmus["TMDInerter"], tmp_path, tag)
        try:
            f.s.setupExperiment(startTime=0.0)
            f.s.enterInitializationMode()
            f.s.setInteger([f.vr["inerter"]], [0])
            f.s.setReal([f.vr["I"]], [1.0])
            with pytest.raises(FMICallException):
                f.s.exitInitializationMode()
            msgs[tag] = f.text()
        finally:
            f.s.freeInstance()
    assert "inertance must be 0 when inerter is 'none'" in msgs["native"]
    assert "inertance must be 0 when inerter is 'none'" in msgs["hosted"]


def _open(fmu: Path, tmp_path: Path, tag: str, start: dict) -> tuple[FMU2Slave, dict]:
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / tag
    fmpy.extract(str(fmu), str(d))
    s = FMU2Slave(
        guid=md.guid, unzipDirectory=str(d), modelIdentifier=md.coSimulation.modelIdentifier, instanceName=tag
    )
    s.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for k, v in start.items():
        (s.setInteger if isinstance(v, int) else s.setReal)([vr[k]], [v])
    s.exitInitializationMode()
    return s, vr


def test_derivatives_and_states_equal_the_python_hosted_fmu(native, hosted, tmp_path):
    out = {}
    for tag, fmus in (("native", native), ("hosted", hosted)):
        s, vr = _open(fmus["TMDInerter"], tmp_path, tag, dict(PLAY, y0=0.003))
        try:
            res = []
            for k in range(50):
                s.setReal([vr["x"], vr["xd"], vr["xdd"]], [1e-3 * np.sin(0.1 * k), 2e-3, -0.1])
                s.doStep(k * 1e-3, 1e-3)
                if k == 20:
                    state = s.getFMUstate()
                    blob = bytes(s.serializeFMUstate(state))
                res += s.getReal([vr["force"], vr["y"], vr["yd"]])
            dd = s.getDirectionalDerivative([vr["force"], vr["y"]], [vr["x"], vr["xdd"]], [2.0, 1.0])
            s.setFMUstate(s.deSerializeFMUstate(blob))
            s.setReal([vr["x"], vr["xd"], vr["xdd"]], [0.0, 0.0, 0.0])
            s.doStep(21e-3, 1e-3)
            again = s.getReal([vr["force"], vr["y"]])
            out[tag] = (res, dd, len(blob), again)
            s.freeFMUstate(state)
        finally:
            s.terminate()
            s.freeInstance()
    assert out["native"] == out["hosted"]
    assert out["native"][1][0] != 0.0


def test_fmi3_native_equals_the_python_hosted_fmi3(tmp_path):
    from fmpy.fmi3 import FMU3Slave
    from fmpy.validation import validate_fmu

    from pyfmu_wrapper.fmubuild.build import ensure_fmus
    from pyfmu_wrapper.models.catalog import pick

    nat = {p.stem: p for p in build_native_fmus(pick("TMDInerter"), tmp_path / "n3", fmi_version=3)}
    hosted3 = ensure_fmus(pick("TMDInerter"), fmi_version=3)
    out = {}
    for tag, fmu in (("native", nat["TMDInerter"]), ("hosted", hosted3["TMDInerter"])):
        assert validate_fmu(str(fmu)) == []
        md = fmpy.read_model_description(str(fmu))
        d = tmp_path / f"x3{tag}"
        fmpy.extract(str(fmu), str(d))
        s = FMU3Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="TMDInerter", instanceName=tag)
        s.instantiate()
        vr = {v.name: v.valueReference for v in md.modelVariables}
        start = s.getFloat64([vr["m"], vr["k"]])  # readable in Instantiated
        s.enterInitializationMode(startTime=0.0)
        s.setFloat64([vr[k] for k in ("m", "I", "c", "eps", "ki")], [9.0, 1.0, 10.0, 1e-4, 2e7])
        s.setInt32([vr["inerter"]], [2])
        s.exitInitializationMode()
        res = []
        for k in range(100):
            s.setFloat64([vr["x"], vr["xd"], vr["xdd"]], [2e-3 * np.sin(0.05 * k), 0.1 * np.cos(0.05 * k), -0.2])
            s.doStep(k * 1e-3, 1e-3)
            res += s.getFloat64([vr["force"], vr["y"], vr["yd"]])
        out[tag] = (start, res)
        s.terminate()
        s.freeInstance()
    assert out["native"] == out["hosted"]


def test_native_configure_checks_are_tmdparams_checks():
    """The compiled configure (models/base_tmd/fmus/native_model.py, calling physics.params.tmd_check) refuses exactly
    what TMDParams refuses, with the same check, on a grid of mass, inertance and inerter model
    including the edges."""
    import ctypes

    from pyfmu_wrapper.fmi.contract import NATIVE_OK
    from pyfmu_wrapper.models.base_tmd.fmus.native_model import tmd_functions
    from pyfmu_wrapper.models.base_tmd.fmus.variables import TMD_INERTER
    from pyfmu_wrapper.physics.params import TMD_CHECKS, ParameterError, TMDParams

    nvr = max(v.vr for v in TMD_INERTER.variables) + 1
    reals, ints = np.zeros(nvr), np.zeros(nvr, dtype=np.int32)
    for v in TMD_INERTER.variables:
        if v.start is not None:
            (ints if v.type != "Real" else reals)[v.vr] = v.start
    p, z, u = np.zeros(64), np.zeros(4), np.zeros(64)
    conf = tmd_functions()["configure"]
    f64 = ctypes.POINTER(ctypes.c_double)
    seen = set()
    for model in (0, 1, 2):
        for m in (0.0, 1e-300, 1.0, 9.0):
            for inertance in (0.0, 5e-324, 1.0):
                reals[TMD_INERTER.vr("m")], reals[TMD_INERTER.vr("I")] = m, inertance
                ints[TMD_INERTER.vr("inerter")] = model
                rc = conf.ctypes(
                    reals.ctypes.data_as(f64), ints.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
                    p.ctypes.data_as(f64), z.ctypes.data_as(f64), u.ctypes.data_as(f64),
                )  # fmt: skip
                try:
                    TMDParams(mass=m, inertance=inertance, inerter=model)
                    refused = None
                except ParameterError as e:
                    refused = str(e)
                assert (rc != NATIVE_OK) == (refused is not None), (model, m, inertance, rc, refused)
                if refused:
                    assert refused.startswith(TMD_CHECKS[rc - 1]), (refused, rc)
                    seen.add(rc)
    assert seen == {1, 2, 3, 4}  # every check is reached on the grid


def test_parameter_sensitivities_in_initialisation_equal_the_python_hosted(native, hosted, tmp_path):
    """In initialisation mode a Real parameter among the knowns enters by a central difference through
    configure (one-sided at the edge of its domain: eps = 0); the native FMU computes the same bits."""
    out = {}
    for tag, fmus in (("native", native), ("hosted", hosted)):
        vals = []
        for name, start, unknowns, knowns, seeds in (
            ("TMDInerter", dict(CASE1, y0=0.003), ["force", "y", "yd"], ["k", "m", "x", "c"], [1.0, 0.5, 2.0, 1.0]),
            ("TMDInerter", dict(PLAY, eps=0.0, y0=0.003), ["force"], ["eps", "k"], [1.0, 1.0]),
            ("BaseOscillator", {"x0": 1e-3, "xd0": 0.01}, ["x", "xd", "xdd"], ["M", "K", "f_link"], [1.0, 1e-3, 1.0]),
        ):
            f = Logged(fmus[name], tmp_path, f"{tag}{name}{len(vals)}")
            try:
                f.s.setupExperiment(startTime=0.0)
                f.s.enterInitializationMode()
                for k, v in start.items():
                    (f.s.setInteger if isinstance(v, int) else f.s.setReal)([f.vr[k]], [v])
                vals.append(f.s.getDirectionalDerivative([f.vr[u] for u in unknowns], [f.vr[k] for k in knowns], seeds))
            finally:
                f.s.freeInstance()
        out[tag] = vals
    assert out["native"] == out["hosted"]
    assert all(any(v != 0.0 for v in row) for row in out["native"])
