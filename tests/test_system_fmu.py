"""The system FMUs, co-simulation and Model Exchange: TMDSystem (the paper's base with its TMD-inerter as one
native FMU) and FrameSystem (the shear frame with its TMD or TMDI).

- Its model descriptions (FMI 2.0 and 3.0) declare both interfaces, six states and three event indicators, and
  pass FMPy's validation.
- Model Exchange under FMPy's CVode and co-simulation under FMPy (h = 1 ms) give max |x| over the last two
  periods after 30 s within 1e-4 of the exact linear response (Case 1, c = 10 N s/m, 17 and 23 rad/s), and the
  paper's full Case 1 (c = 10, df = 10, eps = 1e-4) within 1 % of the monolithic engine over the same time
  (a short run by default; 30 s at 15 and 25 rad/s in the slow run and in benchmarks/bench_system_fmu.py).
- The Model Exchange functions are the unit's: derivatives = its right-hand side, event indicators = its
  switching functions, nominals = its tolerance scales, directional derivatives = its Jacobian (held against
  finite differences of the FMU's own derivatives).
- No Python file of the project, no numba and no llvmlite is opened in a Model Exchange run (strace).
- The co-simulation step is the Python-hosted FMU's, bit for bit.
- FrameSystem: one storey gives the exact linear response as TMDSystem does; a 3-storey TMDI (linear, and the
  full TMD with play and friction) gives the monolithic engine's response over the same time, in both
  interfaces; the states of the storeys above the top stay at rest in Model Exchange.
"""

from __future__ import annotations

import ctypes
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.validation import validate_fmu

from pyfmu_wrapper.fmubuild.build import REPO_ROOT, ensure_fmus
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.base_tmd.tolerances import coupled_atol
from pyfmu_wrapper.models.catalog import pick
from pyfmu_wrapper.models.frame_model import FrameParams
from pyfmu_wrapper.models.solve import exact_amplitude, simulate
from pyfmu_wrapper.physics.models import coupled_jac, coupled_rhs, coupled_switching
from pyfmu_wrapper.physics.params import BaseParams, InerterModel, pack, paper_case

LINEAR = {"c": 10.0}  # Case 1 (the FMU's defaults: m = 9, I = 1, ideal inerter) with c = 10 N s/m
FULL = {"c": 10.0, "df": 10.0, "inerter": 2, "eps": 1e-4}  # the paper's full Case 1
FULL_TMD = paper_case(1, damping=10.0, friction_force=10.0, inerter=InerterModel.PLAY, play_gap=1e-4)
STATES = ("x", "xd", "y", "yd", "d", "dd")


@pytest.fixture(scope="session")
def systems(tmp_path_factory) -> dict[int, dict[str, Path]]:
    """TMDSystem and FrameSystem built natively (linux64), FMI 2.0 and 3.0, once per session."""
    root = tmp_path_factory.mktemp("system")
    names = ("TMDSystem", "FrameSystem")
    return {
        v: {f.stem: f for f in build_native_fmus(pick(names), out_dir=root / f"fmi{v}", fmi_version=v, win64=False)}
        for v in (2, 3)
    }


@pytest.fixture(scope="session")
def system(systems) -> dict[int, Path]:
    """TMDSystem, FMI 2.0 and 3.0."""
    return {v: systems[v]["TMDSystem"] for v in systems}


@pytest.fixture(scope="session")
def frame_system(systems) -> dict[int, Path]:
    """FrameSystem, FMI 2.0 and 3.0."""
    return {v: systems[v]["FrameSystem"] for v in systems}


def peak(t: np.ndarray, x: np.ndarray, t0: float, t1: float) -> float:
    """max |x| over [t0, t1] from samples, the largest refined by the parabola through it and its neighbours
    when that parabola's vertex lies within half a sample of it (a kink, a gear impact, is left as sampled)."""
    a = np.abs(x)
    m = np.flatnonzero((t >= t0) & (t <= t1))
    i = m[np.argmax(a[m])]
    if i == 0 or i == a.size - 1:  # at the end of the samples: as sampled
        return float(a[i])
    y0, y1, y2 = a[i - 1], a[i], a[i + 1]
    den = 2 * y1 - y0 - y2
    if den > 0 and abs(y0 - y2) <= den:
        return float(y1 + 0.125 * (y0 - y2) ** 2 / den)
    return float(y1)


def fmu_peak(fmu: Path, kind: str, w: float, start: dict, t_from: float = 30.0, out: str = "x") -> float:
    """max |out| over the two periods after t_from: Model Exchange under FMPy's CVode, or co-simulation (h = 1 ms)."""
    T = 2 * math.pi / w
    kw = dict(solver="CVode", relative_tolerance=1e-10) if kind == "ModelExchange" else dict(step_size=1e-3)
    r = simulate_fmu(
        str(fmu), fmi_type=kind, start_values={"w": w, **start}, stop_time=t_from + 2.2 * T, output=[out],
        output_interval=T / 200, **kw,
    )  # fmt: skip
    return peak(r["time"], r[out], t_from, t_from + 2 * T)


def mono_peak(w: float, t_from: float = 30.0, structure: object = None, tmd: object = FULL_TMD) -> float:
    """The same measure from the monolithic engine (the unit's integrator, from rest), finely sampled."""
    T = 2 * math.pi / w
    ts = np.linspace(t_from, t_from + 2 * T, 4001)
    _, z = simulate(BaseParams() if structure is None else structure, tmd, w, t_from + 2 * T, sample_times=ts)
    return peak(ts, z[:, 0], t_from, t_from + 2 * T)


@pytest.mark.parametrize("version", [2, 3])
def test_model_description_declares_both_interfaces(system, version):
    fmu = system[version]
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.modelExchange is not None and md.coSimulation is not None
    assert [d.variable.derivative.name for d in md.derivatives] == list(STATES)
    assert [d.variable.name for d in md.derivatives] == [f"der({n})" for n in STATES]
    if version == 2:
        assert md.numberOfEventIndicators == 3
    else:
        assert [e.variable.name for e in md.eventIndicators] == ["g_friction", "g_compression", "g_extension"]
    names = {v.name for v in md.modelVariables}
    assert {"M", "K", "C", "F", "w", "m", "k", "c", "df", "s", "I", "ki", "ci", "eps", "inerter", "k3"} <= names
    assert {"x", "xd", "xdd", "f_exc", "xdd_free", "force", "y", "yd", "inerter_force", "contact"} <= names
    assert not [v for v in md.modelVariables if v.causality == "input"]


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("w", [17.0, 23.0])
@pytest.mark.parametrize("kind", ["ModelExchange", "CoSimulation"])
def test_linear_case1_matches_the_exact_response(system, version, w, kind):
    exact = float(exact_amplitude(BaseParams(), paper_case(1, damping=10.0), [w])[0])
    got = fmu_peak(system[version], kind, w, LINEAR)
    assert abs(got / exact - 1.0) < 1e-4, (got, exact)


@pytest.mark.parametrize("kind", ["ModelExchange", "CoSimulation"])
def test_full_case1_matches_the_monolithic_engine_short(system, kind):
    """The full model (play, friction, damper) over 4 s at 25 rad/s: its events (gear impacts, friction
    reversals) handled by FMPy's CVode on the event indicators, or by the FMU's own integrator."""
    w = 25.0
    got, ref = fmu_peak(system[2], kind, w, FULL, t_from=4.0), mono_peak(w, t_from=4.0)
    assert abs(got / ref - 1.0) < 0.01, (got, ref)


@pytest.mark.slow  # 30 s of the rattling model: ~20-40 s per FMPy run (also run by benchmarks/bench_system_fmu.py)
@pytest.mark.parametrize("w", [15.0, 25.0])
@pytest.mark.parametrize("kind", ["ModelExchange", "CoSimulation"])
def test_full_case1_matches_the_monolithic_engine(system, w, kind):
    got, ref = fmu_peak(system[2], kind, w, FULL), mono_peak(w)
    assert abs(got / ref - 1.0) < 0.01, (got, ref)


def _me_instance(fmu: Path, tmp: Path, start: dict) -> tuple[FMU2Model, dict[str, int]]:
    md = read_model_description(str(fmu))
    d = tmp / "unzipped"
    shutil.unpack_archive(str(fmu), str(d), "zip")
    vr = {v.name: v.valueReference for v in md.modelVariables}
    m = FMU2Model(guid=md.guid, unzipDirectory=str(d), modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName="me")  # fmt: skip
    m.instantiate()
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    for name, value in start.items():
        if isinstance(value, int):
            m.setInteger([vr[name]], [value])
        else:
            m.setReal([vr[name]], [value])
    m.exitInitializationMode()
    assert m.newDiscreteStates()[0] == 0  # no discrete state: nothing to update
    m.enterContinuousTimeMode()
    return m, vr


def _ptr(a: np.ndarray) -> ctypes._Pointer:
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def test_model_exchange_functions_are_the_units(system, tmp_path):
    """Derivatives, event indicators, nominals and directional derivatives at a state in the gear's contact
    with the friction sliding: the unit's functions of the same state (the same compiled code), the Jacobian
    also against central differences of the FMU's own derivatives."""
    w, t = 21.0, 0.37
    m, vr = _me_instance(system[2], tmp_path, {"w": w, **FULL})
    p = pack(BaseParams(), FULL_TMD, w)
    z = np.array([3e-3, -0.05, 1e-3, 0.08, 1.3e-4, 0.02])
    m.setTime(t)
    m.setContinuousStates(_ptr(z.copy()), 6)
    dx, g, nom, back = np.empty(6), np.empty(3), np.empty(6), np.empty(6)
    m.getDerivatives(_ptr(dx), 6)
    m.getEventIndicators(_ptr(g), 3)
    m.getNominalsOfContinuousStates(_ptr(nom), 6)
    m.getContinuousStates(_ptr(back), 6)
    ref_dx, ref_g, ref_nom = np.empty(6), np.empty(3), np.empty(6)
    coupled_rhs(t, z, p, np.zeros(1), ref_dx)
    coupled_switching(z, p, ref_g)
    coupled_atol(p, 1.0, ref_nom)
    np.testing.assert_array_equal(back, z)
    np.testing.assert_allclose(dx, ref_dx, rtol=1e-14, atol=0)
    np.testing.assert_allclose(g, [z[1] - z[3], z[4] - 1e-4, z[4] + 1e-4], rtol=1e-15)
    np.testing.assert_allclose(g, ref_g, rtol=1e-15)
    np.testing.assert_allclose(nom, ref_nom, rtol=1e-15)
    assert m.getReal([vr["xdd"], vr["der(xd)"], vr["d"], vr["g_compression"]]) == pytest.approx(
        [dx[1], dx[1], z[4], g[1]], rel=1e-14
    )
    J, ft = np.empty((6, 6)), np.empty(6)
    coupled_jac(t, z, p, np.zeros(1), J, ft, np.empty(6, complex), np.empty(6, complex))
    states = [vr[n] for n in STATES]
    ders = [vr[f"der({n})"] for n in STATES]
    for j in range(6):
        seed = np.zeros(6)
        seed[j] = 1.0
        col = np.array(m.getDirectionalDerivative(ders + [vr["x"]], states, list(seed)))
        np.testing.assert_allclose(col[:6], J[:, j], rtol=1e-13, atol=1e-13 * np.abs(J).max())
        assert col[6] == seed[0]  # the output x is the state x
        h = 1e-6 * nom[j]
        fd = []
        for s in (1, -1):
            zz = z.copy()
            zz[j] += s * h
            m.setContinuousStates(_ptr(zz), 6)
            d = np.empty(6)
            m.getDerivatives(_ptr(d), 6)
            fd.append(d)
        m.setContinuousStates(_ptr(z.copy()), 6)
        np.testing.assert_allclose(col[:6], (fd[0] - fd[1]) / (2 * h), rtol=1e-5, atol=1e-7 * np.abs(J).max())
    m.terminate()
    m.freeInstance()


def test_co_simulation_instance_refuses_model_exchange_calls(system, tmp_path):
    md = read_model_description(str(system[2]))
    d = tmp_path / "cs"
    shutil.unpack_archive(str(system[2]), str(d), "zip")
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="TMDSystem", instanceName="cs")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    get = s.dll.fmi2GetDerivatives
    get.argtypes, get.restype = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t], ctypes.c_int
    assert get(s.component, _ptr(np.empty(6)), 6) == 3  # fmi2Error: the instance is a co-simulation one
    s.doStep(0.0, 1e-3)
    s.terminate()
    s.freeInstance()


def test_native_step_is_the_python_hosted_step(system):
    """The same co-simulation (the full Case 1, 0.2 s, h = 1 ms) of the native and the Python-hosted TMDSystem:
    bit-identical outputs (both call the unit's compiled integrator through the same function)."""
    hosted = ensure_fmus(pick("TMDSystem"))["TMDSystem"]
    runs = [
        simulate_fmu(
            str(f),
            fmi_type="CoSimulation",
            start_values={"w": 19.0, **FULL},
            stop_time=0.2,
            step_size=1e-3,
            output=["x", "y", "force", "d"],
        )  # fmt: skip
        for f in (system[2], hosted)
    ]
    for name in ("x", "y", "force", "d"):
        np.testing.assert_array_equal(runs[0][name], runs[1][name])
    assert read_model_description(str(hosted)).modelExchange is None  # the Python-hosted FMU: co-simulation only


NO_PYTHON_RUN = textwrap.dedent(
    """
    import sys
    from fmpy import simulate_fmu
    r = simulate_fmu(sys.argv[1], fmi_type="ModelExchange", solver="CVode", stop_time=1.0,
                     start_values={"w": 25.0, "c": 10.0, "df": 10.0, "inerter": 2, "eps": 1e-4}, output=["x"])
    assert len(r) > 10
    bad = [m for m in sys.modules if m.split(".")[0] in ("numba", "llvmlite", "pyfmu_wrapper")]
    assert not bad, bad
    print("ok")
    """
)


@pytest.mark.skipif(shutil.which("strace") is None, reason="needs strace")
def test_model_exchange_run_opens_no_python_of_the_project(system, tmp_path):
    """FMPy (a Python host) runs TMDSystem in Model Exchange from a clean environment: no file of the project,
    of numba or of llvmlite is opened (strace), none of them imported; the FMU's binary is."""
    fmu = tmp_path / "TMDSystem.fmu"
    shutil.copy(system[2], fmu)
    trace = tmp_path / "trace.txt"
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    r = subprocess.run(
        ["strace", "-f", "-qq", "-e", "trace=openat", "-o", str(trace), sys.executable, "-c", NO_PYTHON_RUN, str(fmu)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]
    opened = re.findall(r'openat\([^"]*"([^"]*)"', trace.read_text())
    assert any(p.endswith("binaries/linux64/TMDSystem.so") for p in opened)
    project = str(REPO_ROOT)
    # the host's own interpreter files (its venv: sys.prefix, inside the checkout in CI) are the host's, not the
    # project's; numba, llvmlite and the package are caught wherever they live
    venv = sys.prefix
    bad = [
        p
        for p in opened
        if re.search(r"/(numba|llvmlite|pyfmu_wrapper)(/|$)", p) or (project in p and not p.startswith(venv))
    ]
    assert not bad, bad[:10]
    assert os.path.commonpath([project, str(tmp_path)]) != project


# --- FrameSystem -----------------------------------------------------------------------------------------

TMDI3 = FrameParams.uniform(3, 100.0, 1.2e5, 100.0, tmd_storey=3, inerter_to=2)
TMDI3_START = {"storeys": 3, "tmd_storey": 3, "inerter_to": 2, "k1": 1.2e5, "k2": 1.2e5, "k3": 1.2e5}


@pytest.mark.parametrize("version", [2, 3])
def test_frame_system_model_description(frame_system, version):
    fmu = frame_system[version]
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.modelExchange is not None and md.coSimulation is not None
    states = [d.variable.derivative.name for d in md.derivatives]
    assert len(states) == 44 and states[:8] == ["x_20", "xd_20", "y", "yd", "d", "dd", "x_19", "xd_19"]
    names = {v.name for v in md.modelVariables}
    assert {"storeys", "m1", "k3", "k_cubic", "inerter_to", "x_top", "force", "contact"} <= names


@pytest.mark.parametrize("kind", ["ModelExchange", "CoSimulation"])
def test_frame_system_one_storey_is_the_papers_model(frame_system, kind):
    """One storey with the TMD on it (the defaults): the exact linear response of Case 1 with c = 10."""
    w = 17.0
    exact = float(exact_amplitude(BaseParams(), paper_case(1, damping=10.0), [w])[0])
    got = fmu_peak(frame_system[2], kind, w, LINEAR, out="x_top")
    assert abs(got / exact - 1.0) < 1e-4, (got, exact)


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("kind", ["ModelExchange", "CoSimulation"])
def test_frame_system_tmdi_matches_the_monolithic_engine(frame_system, version, kind):
    """A 3-storey frame with a TMDI (TMD on the top, inerter to storey 2), linear (c = 10): the monolithic
    engine's response from rest over the same time (within 1e-4), and the full TMD (play, friction; within 1 %)."""
    w, t_from = 20.0, 6.0
    lin = mono_peak(w, t_from, TMDI3, paper_case(1, damping=10.0))
    got = fmu_peak(frame_system[version], kind, w, {**TMDI3_START, **LINEAR}, t_from, out="x_top")
    assert abs(got / lin - 1.0) < 1e-4, (got, lin)
    if version == 2:
        full = mono_peak(w, 3.0, TMDI3, FULL_TMD)
        got = fmu_peak(frame_system[2], kind, w, {**TMDI3_START, **FULL}, 3.0, out="x_top")
        assert abs(got / full - 1.0) < 0.01, (got, full)


def test_frame_system_storeys_above_the_top_stay_at_rest(frame_system, tmp_path):
    """Model Exchange of a 3-storey frame: the states of storeys 4..20 keep their start (0), with derivative 0
    and nominal 1; the others are the frame model's."""
    m, vr = _me_instance(frame_system[2], tmp_path, {**TMDI3_START, "w": 20.0, "x0_3": 1e-3, "xd0_5": 0.0})
    x, dx, nom = np.empty(44), np.empty(44), np.empty(44)
    m.getContinuousStates(_ptr(x), 44)
    m.getDerivatives(_ptr(dx), 44)
    m.getNominalsOfContinuousStates(_ptr(nom), 44)
    names = [f"x_{i}" for i in range(20, 0, -1)]
    order = ["x_20", "xd_20", "y", "yd", "d", "dd"] + [n for i in range(19, 0, -1) for n in (f"x_{i}", f"xd_{i}")]
    above = [k for k, n in enumerate(order) if n.split("_")[-1].isdigit() and int(n.split("_")[-1]) > 3]
    assert len(above) == 34 and not np.any(x[above]) and not np.any(dx[above]) and np.all(nom[above] == 1.0)
    assert x[order.index("x_3")] == 1e-3 and dx[order.index("xd_3")] != 0.0
    assert m.getReal([vr["x_top"]]) == [1e-3] and names[17] == "x_3"
    m.terminate()
    m.freeInstance()


def test_frame_system_native_step_is_the_python_hosted_step(frame_system):
    hosted = ensure_fmus(pick("FrameSystem"))["FrameSystem"]
    start = {**TMDI3_START, **FULL, "w": 21.0}
    runs = [
        simulate_fmu(
            str(f),
            fmi_type="CoSimulation",
            start_values=start,
            stop_time=0.2,
            step_size=1e-3,
            output=["x_top", "x_2", "force", "d"],
        )  # fmt: skip
        for f in (frame_system[2], hosted)
    ]
    for name in ("x_top", "x_2", "force", "d"):
        np.testing.assert_array_equal(runs[0][name], runs[1][name])


def test_model_exchange_fmu_state_round_trip(system, tmp_path):
    """In continuous-time mode: get the FMU state (and serialise it), move time and states, set it back: the
    states, time-dependent derivatives and outputs are those saved."""
    m, vr = _me_instance(system[2], tmp_path, {"w": 21.0, **FULL})
    z = np.array([2e-3, 0.03, -1e-3, 0.01, 5e-5, 0.0])
    m.setTime(0.25)
    m.setContinuousStates(_ptr(z.copy()), 6)
    d0 = np.empty(6)
    m.getDerivatives(_ptr(d0), 6)
    f0 = m.getReal([vr["force"], vr["f_exc"]])
    state = m.getFMUstate()
    blob = m.serializeFMUstate(state)
    m.setTime(0.5)
    m.setContinuousStates(_ptr(np.zeros(6)), 6)
    for s in (state, m.deSerializeFMUstate(blob)):
        m.setFMUstate(s)
        back, d1 = np.empty(6), np.empty(6)
        m.getContinuousStates(_ptr(back), 6)
        m.getDerivatives(_ptr(d1), 6)
        np.testing.assert_array_equal(back, z)
        np.testing.assert_array_equal(d1, d0)
        assert m.getReal([vr["force"], vr["f_exc"]]) == f0
        m.freeFMUstate(s)
    m.terminate()
    m.freeInstance()
