"""The FMI 3.0 variants of the FMUs: built from the same declaration as the FMI 2.0 ones (validated and
compared variable by variable in tests/test_fmu_every_spec.py), equal to them bit for bit (one core, two
API layers), exact where a solution is known, refusing what FMI 3.0 says they must refuse, and run by the master to the FMI 2.0 numbers.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from _fmu_support import built_fmus, damped_forced_response
from fmpy.fmi3 import FMU3Slave

from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.models.catalog import pick

NAMES = ("BaseOscillator", "TMDInerter", "Trivial")
FMI3_ERROR = 3


@pytest.fixture(scope="module")
def fmus3():
    return ensure_fmus(pick(NAMES), fmi_version=3)


@pytest.fixture(scope="module")
def fmus2():
    return built_fmus()


def open3(fmu, tmp_path, name="inst", start=None, init=True):
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / f"{name}_{fmu.stem}"
    fmpy.extract(str(fmu), str(d))
    s = FMU3Slave(
        guid=md.guid, unzipDirectory=str(d), modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name
    )
    s.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    if init:
        s.enterInitializationMode(startTime=0.0)
        for k, v in (start or {}).items():
            (s.setInt32 if isinstance(v, int) else s.setFloat64)([vr[k]], [v])
        s.exitInitializationMode()
    return s, vr


def raw(s, name, restype, *argtypes):
    f = getattr(s.dll, name)
    f.restype, f.argtypes = restype, [ctypes.c_void_p, *argtypes]
    return lambda *a: f(s.component, *a)


def test_binaries_export_their_own_api_only(fmus2, fmus3, tmp_path):
    if shutil.which("nm") is None:
        pytest.skip("nm (binutils) not installed")  # pragma: no cover
    for version, fmu, prefix in ((2, fmus2["TMDInerter"], "fmi2"), (3, fmus3["TMDInerter"], "fmi3")):
        with zipfile.ZipFile(fmu) as z:
            so = [n for n in z.namelist() if n.startswith("binaries/") and n.endswith(".so")]
            assert so == [("binaries/linux64/" if version == 2 else "binaries/x86_64-linux/") + "TMDInerter.so"]
            z.extract(so[0], tmp_path / str(version))
        out = subprocess.run(
            ["nm", "-D", "--defined-only", str(tmp_path / str(version) / so[0])],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        syms = {line.split()[-1] for line in out.splitlines() if line.strip()}
        assert syms and all(s.startswith(prefix) for s in syms), sorted(s for s in syms if not s.startswith(prefix))
    # every function of the FMI 3.0 headers is there
    hdr = (Path(fmpy.__file__).parent / "c-code" / "fmi3FunctionTypes.h").read_text()
    import re

    want = {m[:-4] for m in re.findall(r"fmi3\w+TYPE", hdr)}
    assert want <= syms


def test_base_fmi3_matches_exact_forced_response_and_fmi2(fmus2, fmus3):
    p = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=15.0, x0=0.01, xd0=-0.05)
    r3 = fmpy.simulate_fmu(
        str(fmus3["BaseOscillator"]), stop_time=1.0, output_interval=1e-3, start_values=p, output=["x", "xd"]
    )
    r2 = fmpy.simulate_fmu(
        str(fmus2["BaseOscillator"]), stop_time=1.0, output_interval=1e-3, start_values=p, output=["x", "xd"]
    )
    x, xd = damped_forced_response(r3["time"], **p)
    assert np.max(np.abs(r3["x"] - x)) < 1e-9
    assert np.array_equal(r3["x"], r2["x"]) and np.array_equal(r3["xd"], r2["xd"])


def test_tmd_fmi3_equals_fmi2_bit_for_bit_with_play(fmus2, fmus3):
    p = dict(m=9.0, I=1.0, k=4.0e3, c=10.0, y0=0.01, inerter=2, eps=1e-4, ki=2e7, x=0.002)
    r = {
        v: fmpy.simulate_fmu(
            str(f["TMDInerter"]),
            stop_time=0.5,
            output_interval=1e-3,
            start_values=p,
            output=["y", "yd", "force", "contact"],
        )
        for v, f in ((2, fmus2), (3, fmus3))
    }
    for k in ("y", "yd", "force", "contact"):
        assert np.array_equal(r[2][k], r[3][k]), k
    assert np.any(r[3]["contact"] != 0)  # the gear chain did touch


def test_input_derivative_variables_extrapolate_over_the_step(fmus3, tmp_path):
    # M xdd = -f_link with f_link(t) = b t + g t^2/2 (value 0 and derivatives b, g at t = 0):
    # x(h) = -(b h^3/6 + g h^4/24)/M (exact: polynomial in t). FMI 3.0: der(f_link), der(f_link,2).
    M, b, g, h = 2.0, 3.0, 40.0, 0.1
    s, vr = open3(fmus3["BaseOscillator"], tmp_path, start=dict(M=M, K=0.0, C=0.0, F=0.0))
    try:
        s.setFloat64([vr["der(f_link)"], vr["der(f_link,2)"]], [b, g])
        s.setFloat64([vr["f_link"]], [0.0])  # FMI 3.0: setting the input leaves its derivatives as they are
        assert s.getFloat64([vr["der(f_link)"], vr["der(f_link,2)"]]) == [b, g]
        s.doStep(0.0, h)
        x, xd, t = s.getFloat64([vr["x"], vr["xd"], vr["time"]])
        assert x == pytest.approx(-(b * h**3 / 6 + g * h**4 / 24) / M, rel=1e-9)
        assert xd == pytest.approx(-(b * h**2 / 2 + g * h**3 / 6) / M, rel=1e-9)
        assert t == h
        # they applied to that step only (reset after it, as FMI 2.0 input derivatives are)
        assert s.getFloat64([vr["der(f_link)"], vr["der(f_link,2)"]]) == [0.0, 0.0]
    finally:
        s.terminate()
        s.freeInstance()


def test_directional_derivative_fmi3(fmus3, tmp_path):
    m, I, k, c = 9.0, 1.0, 4.0e3, 10.0
    s, vr = open3(fmus3["TMDInerter"], tmp_path, start=dict(m=m, I=I, k=k, c=c, y0=0.003))
    try:
        s.setFloat64([vr["x"], vr["xd"], vr["xdd"]], [0.001, 0.02, -0.3])
        # force = m/(m+I) (k (x-y) + c (xd-yd) + I xdd): exact partial derivatives
        assert s.getDirectionalDerivative([vr["force"]], [vr["xdd"]], [1.0])[0] == pytest.approx(
            m * I / (m + I), rel=1e-14
        )
        both = s.getDirectionalDerivative([vr["force"], vr["y"]], [vr["x"], vr["xdd"]], [2.0, 1.0])
        assert both[0] == pytest.approx(2 * m * k / (m + I) + m * I / (m + I), rel=1e-14)
        assert both[1] == 0.0
        md = ET.fromstring(zipfile.ZipFile(fmus3["TMDInerter"]).read("modelDescription.xml"))
        assert md.find("CoSimulation").get("providesDirectionalDerivatives") == "true"
    finally:
        s.terminate()
        s.freeInstance()


def test_fmu_state_and_serialization_fmi3(fmus3, tmp_path):
    p = dict(m=9.0, I=1.0, k=4.0e3, c=10.0, y0=0.01, inerter=2, eps=1e-4, ki=2e7)
    s, vr = open3(fmus3["TMDInerter"], tmp_path, start=p)
    try:
        s.setFloat64([vr["x"]], [0.002])
        for i in range(20):
            s.doStep(i * 1e-3, 1e-3)
        st = s.getFMUState()
        blob = s.serializeFMUState(st)
        ref = []
        for i in range(20, 40):
            s.doStep(i * 1e-3, 1e-3)
            ref.append(s.getFloat64([vr["y"], vr["yd"], vr["force"]]))
        for restore in ("state", "bytes"):
            if restore == "state":
                s.setFMUState(st)
            else:
                st2 = s.deserializeFMUState(blob)
                s.setFMUState(st2)
                s.freeFMUState(st2)
            again = []
            for i in range(20, 40):
                s.doStep(i * 1e-3, 1e-3)
                again.append(s.getFloat64([vr["y"], vr["yd"], vr["force"]]))
            assert again == ref, restore
        s.freeFMUState(st)
    finally:
        s.terminate()
        s.freeInstance()


def test_invalid_fmi3_calls_are_refused_and_logged(fmus3, tmp_path):
    """Calls FMI 3.0 does not allow here answer fmi3Error with a message, never fmi3OK."""
    logged = []
    md = fmpy.read_model_description(str(fmus3["TMDInerter"]))
    d = tmp_path / "bad"
    fmpy.extract(str(fmus3["TMDInerter"]), str(d))
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="TMDInerter", instanceName="bad")
    s.instantiate(logMessage=lambda env, status, cat, msg: logged.append((status, msg.decode())))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    u32 = ctypes.c_uint32
    do_step = raw(
        s,
        "fmi3DoStep",
        ctypes.c_int,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_bool,
        *[ctypes.POINTER(ctypes.c_bool)] * 3,
        ctypes.POINTER(ctypes.c_double),
    )
    flags = [ctypes.c_bool() for _ in range(3)]
    last = ctypes.c_double()

    def step(t, h):
        return do_step(t, h, False, *[ctypes.byref(f) for f in flags], ctypes.byref(last))

    set64 = raw(
        s,
        "fmi3SetFloat64",
        ctypes.c_int,
        ctypes.POINTER(u32),
        ctypes.c_size_t,
        ctypes.POINTER(ctypes.c_double),
        ctypes.c_size_t,
    )
    get32 = raw(
        s,
        "fmi3GetFloat32",
        ctypes.c_int,
        ctypes.POINTER(u32),
        ctypes.c_size_t,
        ctypes.POINTER(ctypes.c_float),
        ctypes.c_size_t,
    )
    one = (u32 * 1)(vr["x"])
    val = (ctypes.c_double * 2)(1.0, 2.0)

    try:
        before = len(logged)
        assert step(0.0, 1e-3) == FMI3_ERROR  # before initialisation
        assert set64(one, 1, val, 2) == FMI3_ERROR  # nValues != nValueReferences
        assert raw(s, "fmi3EnterEventMode", ctypes.c_int)() == FMI3_ERROR
        assert raw(s, "fmi3EnterStepMode", ctypes.c_int)() == FMI3_ERROR
        assert raw(s, "fmi3EnterConfigurationMode", ctypes.c_int)() == FMI3_ERROR
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        assert get32(one, 1, (ctypes.c_float * 1)(), 1) == FMI3_ERROR  # no Float32 variables
        t = (u32 * 1)(vr["time"])
        assert set64(t, 1, val, 1) == FMI3_ERROR  # time cannot be set
        out = (u32 * 1)(vr["force"])
        assert set64(out, 1, val, 1) == FMI3_ERROR  # an output cannot be set
        nan = (ctypes.c_double * 1)(float("nan"))
        der = (u32 * 1)(vr["der(x)"])
        assert set64(der, 1, nan, 1) == FMI3_ERROR  # a derivative must be finite
        assert step(0.0, -1e-3) == FMI3_ERROR
        assert step(0.5, 1e-3) == FMI3_ERROR  # not the FMU's time
        assert raw(s, "fmi3GetAdjointDerivative", ctypes.c_int, *[ctypes.c_void_p] * 8)(*[None] * 8) == FMI3_ERROR
        assert len(logged) - before >= 12 and all(st == FMI3_ERROR for st, _ in logged[before:])
        assert any("fmi3DoStep" in m for _, m in logged) and not any("fmi2" in m for _, m in logged)
        assert step(0.0, 1e-3) == 0  # after all that, a valid step is fine
        assert last.value == 1e-3 and not any(f.value for f in flags)
    finally:
        s.terminate()
        s.freeInstance()


@pytest.mark.parametrize(
    "tmd_kw", [dict(damping=10.0), dict(inerter="play", play_gap=1e-4, mesh_stiffness=2e7)], ids=["ideal-c10", "play"]
)
def test_cosimulation_through_fmi3_equals_fmi2_bit_for_bit(tmd_kw, monkeypatch):
    """run-scenario's co-simulation engine on the FMI 3.0 FMUs gives the FMI 2.0 numbers to the last bit
    (Case 1; the impulse coupling with its input derivatives and interface Jacobian), in the compiled
    stepping loop (its fmi3 adapters) and on the Python path."""
    from pyfmu_wrapper.cosim.settings import CosimSettings
    from pyfmu_wrapper.models.base_tmd import UNIT

    sweep = UNIT.cosim().sweep
    from pyfmu_wrapper.physics.params import BaseParams, paper_case

    base, tmd = BaseParams(), paper_case(1, **tmd_kw)
    r = {v: sweep(base, tmd, [17.0], settings=CosimSettings(fmi_version=v)) for v in (2, 3)}
    monkeypatch.setenv("PYFMU_COMPILED_LOOP", "0")
    r["3py"] = sweep(base, tmd, [17.0], settings=CosimSettings(fmi_version=3))
    for col in ("amplitude", "periods", "steps", "change"):
        assert np.array_equal(r[2][col].to_numpy(), r[3][col].to_numpy()), col
        assert np.array_equal(r[3][col].to_numpy(), r["3py"][col].to_numpy()), col
    assert r[3]["master_loop_time"].iloc[0] > 0 and r["3py"]["master_loop_time"].iloc[0] == 0  # which path ran
    # and the numbers are the physics: within 0.5 % of the monolithic solver (docs/cosimulation.md)
    from pyfmu_wrapper.models.solve import steady_state

    mono = steady_state(base, tmd, 17.0).amplitude
    assert r[3]["amplitude"].iloc[0] == pytest.approx(mono, rel=5e-3)


def test_fmi3_runs_from_a_copy_in_a_numpy_numba_fmpy_venv(fmus3, tmp_path):
    """The portability check of tests/test_fmu_portable.py on the FMI 3.0 variants: copied elsewhere,
    run by fmpy in a venv with only numpy, numba and fmpy, the checkout out of reach, exact numbers."""
    from test_fmu_portable import _check_run, cached_venv

    root = tmp_path / "portable3"
    root.mkdir()
    fmus = {n: Path(shutil.copy(fmus3[n], root / Path(fmus3[n]).name)) for n in ("BaseOscillator", "TMDInerter")}
    py = cached_venv(root)
    _check_run(root, fmus, py.parent.parent, py)


SCENARIO3 = """\
schema_version: 2
name: fmi3_check
description: Case 1 with play, a short FRC, co-simulated through FMI {v} FMUs.
base: {{mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}}
tmd: {{case: 1, inerter: play, stiffness: 4000.0, mesh_stiffness: 2.0e7, mesh_damping: 0.01, play_gap: 1.0e-4}}
frequencies: {{start: 18.0, stop: 20.0, count: 2}}
cosim: {{fmi_version: {v}}}
studies:
  - kind: frc
    name: frc
    curves:
      - {{label: "play eps = 1e-4"}}
"""


def test_run_scenario_cosim_fmi3_equals_fmi2(tmp_path):
    """The user's path: run-scenario with `cosim: {fmi_version: 3}` writes the FMI 2.0 numbers; a
    version the builder does not write is refused (exit 2, naming the key)."""
    import csv

    from pyfmu_wrapper.cli.run_scenario import main

    rows = {}
    for v in (2, 3):
        (tmp_path / f"s{v}.yaml").write_text(SCENARIO3.format(v=v))
        assert (
            main(
                [
                    str(tmp_path / f"s{v}.yaml"),
                    "--engine",
                    "cosim",
                    "--out",
                    str(tmp_path / f"o{v}"),
                    "--no-resume",
                    "--workers",
                    "1",
                ]
            )
            == 0
        )
        with open(tmp_path / f"o{v}" / "frc.csv") as f:
            rows[v] = [{k: x for k, x in r.items() if "time" not in k} for r in csv.DictReader(f)]
    assert rows[2] == rows[3] and len(rows[3]) == 2
    (tmp_path / "s4.yaml").write_text(SCENARIO3.format(v=4))
    assert main([str(tmp_path / "s4.yaml"), "--engine", "cosim", "--out", str(tmp_path / "o4")]) == 2
    assert not (tmp_path / "o4").exists()
