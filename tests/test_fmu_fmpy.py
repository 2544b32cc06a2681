"""The FMUs in fmpy: validation, exact solutions, directional derivatives, input derivatives."""

from __future__ import annotations

import fmpy
import numpy as np
import pytest
from _fmu_support import damped_forced_response, every_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from pyfmu_wrapper.models.catalog import BUILD_FMUS


@pytest.fixture(scope="module")
def fmus():
    return every_fmu()


def open_slave(fmu, tmp_path, name="inst", start=None):
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / f"{name}_{fmu.stem}"
    fmpy.extract(str(fmu), str(d))
    s = FMU2Slave(
        guid=md.guid, unzipDirectory=str(d), modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.enterInitializationMode()
    for k, v in (start or {}).items():
        if isinstance(v, int):
            s.setInteger([vr[k]], [v])
        else:
            s.setReal([vr[k]], [v])
    s.exitInitializationMode()
    return s, vr


@pytest.mark.parametrize("name", BUILD_FMUS)  # every model's FMU
def test_fmpy_validate(fmus, name):
    assert validate_fmu(str(fmus[name])) == []


def test_model_structure_declares_feedthrough(fmus):
    md = fmpy.read_model_description(str(fmus["TMDInerter"]))
    force = next(u for u in md.outputs if u.variable.name == "force")
    deps = {d.name: k for d, k in zip(force.dependencies, force.dependenciesKind)}
    assert deps == {"x": "fixed", "xd": "dependent", "xdd": "fixed"}
    y = next(u for u in md.outputs if u.variable.name == "y")
    assert y.dependencies == []
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert md.coSimulation.providesDirectionalDerivative and md.coSimulation.canInterpolateInputs
    assert {u.variable.name for u in md.initialUnknowns} == {"force", "y", "yd", "inerter_force", "contact"}


def test_base_alone_matches_exact_forced_response(fmus):
    par = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=15.0, x0=0.01, xd0=-0.05)
    r = fmpy.simulate_fmu(
        str(fmus["BaseOscillator"]),
        stop_time=2.0,
        output_interval=2e-3,
        start_values=par,
        output=["x", "xd", "xdd", "f_exc"],
    )
    x, xd = damped_forced_response(r["time"], **par)
    scale = np.max(np.abs(x))
    # the base steps exactly (the matrix exponential of the linear base with its drives): 1,000 steps
    # agree with the closed form to rounding (3.9e-14 measured)
    assert np.max(np.abs(r["x"] - x)) < 1e-12 * scale
    assert np.max(np.abs(r["xd"] - xd)) < 1e-12 * np.max(np.abs(xd))
    # outputs at each time: acceleration from the ODE, excitation force F cos(w t)
    assert np.allclose(r["f_exc"], 200.0 * np.cos(15.0 * r["time"]), rtol=0, atol=1e-9)
    xdd = (r["f_exc"] - par["C"] * r["xd"] - par["K"] * r["x"]) / par["M"]
    assert np.allclose(r["xdd"], xdd, rtol=0, atol=1e-9)


def test_base_step_is_exact_for_any_tolerance_and_step_length(fmus, tmp_path):
    # one doStep of 7.3 s (taken in 8 equal pieces of <= 1 s) lands on the closed form, and the FMU's
    # rtol/atol (declared "not used" for BaseOscillator) change nothing, not even the last bit
    par = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=15.0, x0=0.01, xd0=-0.05)
    ends = []
    for tol in (1e-8, 1e-3):
        s, vr = open_slave(fmus["BaseOscillator"], tmp_path, start=dict(par, rtol=tol, atol=tol))
        try:
            s.doStep(0.0, 7.3)
            ends.append(s.getReal([vr["x"], vr["xd"]]))
        finally:
            s.terminate()
            s.freeInstance()
    x, xd = damped_forced_response([7.3], **par)
    assert ends[0] == ends[1]
    assert abs(ends[0][0] - x[0]) < 1e-12 * 0.01 and abs(ends[0][1] - xd[0]) < 1e-12 * 0.2


@pytest.mark.parametrize("inerter,I", [(1, 1.0), (0, 0.0)])
def test_tmd_alone_free_decay_matches_exact(fmus, inerter, I):
    m, k, c, y0 = 9.0, 4.0e3, 10.0, 0.01
    par = dict(m=m, k=k, c=c, I=I, inerter=inerter, y0=y0)
    r = fmpy.simulate_fmu(
        str(fmus["TMDInerter"]),
        stop_time=1.0,
        output_interval=1e-3,
        start_values=par,
        output=["y", "yd", "force", "inerter_force"],
    )
    # base at rest: (m + I) ydd + c yd + k y = 0
    y, yd = damped_forced_response(r["time"], m + I, k, c, 0.0, 1.0, y0, 0.0)
    assert np.max(np.abs(r["y"] - y)) < 1e-8 * y0
    # force on the base (x = xd = xdd = 0): Fs + P = m ydd = -m (k y + c yd) / (m + I)
    f = -m * (k * y + c * yd) / (m + I)
    assert np.max(np.abs(r["force"] - f)) < 1e-6 * np.max(np.abs(f))
    assert np.max(np.abs(r["inerter_force"] - (-I * (-(k * y + c * yd) / (m + I))))) < 1e-6 * np.max(np.abs(f))


def test_directional_derivative_of_force(fmus, tmp_path):
    m, I, k, c = 9.0, 1.0, 4.0e3, 10.0
    s, vr = open_slave(fmus["TMDInerter"], tmp_path, start=dict(m=m, I=I, k=k, c=c, y0=0.003))
    try:
        s.setReal([vr["x"], vr["xd"], vr["xdd"]], [0.001, 0.02, -0.3])

        def dd(known):
            return s.getDirectionalDerivative([vr["force"]], [vr[known]], [1.0])[0]

        # force = m/(m+I) (k (x-y) + c (xd-yd) + I xdd): exact partial derivatives
        assert dd("xdd") == pytest.approx(m * I / (m + I), rel=1e-14)
        assert dd("x") == pytest.approx(m * k / (m + I), rel=1e-14)
        assert dd("xd") == pytest.approx(m * c / (m + I), rel=1e-14)
        both = s.getDirectionalDerivative([vr["force"], vr["y"]], [vr["x"], vr["xdd"]], [2.0, 1.0])
        assert both[0] == pytest.approx(2 * m * k / (m + I) + m * I / (m + I), rel=1e-14)
        assert both[1] == 0.0
    finally:
        s.terminate()
        s.freeInstance()


def test_input_derivatives_extrapolate_over_the_step(fmus, tmp_path):
    # M xdd = -f_link with f_link(t) = b t + g t^2/2 (value 0 and derivatives b, g at t = 0):
    # x(h) = -(b h^3/6 + g h^4/24)/M, xd(h) = -(b h^2/2 + g h^3/6)/M (exact: polynomial in t)
    M, b, g, h = 2.0, 3.0, 40.0, 0.1
    s, vr = open_slave(fmus["BaseOscillator"], tmp_path, start=dict(M=M, K=0.0, C=0.0, F=0.0))
    try:
        s.setReal([vr["f_link"]], [0.0])
        s.setRealInputDerivatives([vr["f_link"], vr["f_link"]], [1, 2], [b, g])
        s.doStep(0.0, h)
        x, xd = s.getReal([vr["x"], vr["xd"]])
        assert x == pytest.approx(-(b * h**3 / 6 + g * h**4 / 24) / M, rel=1e-13)
        assert xd == pytest.approx(-(b * h**2 / 2 + g * h**3 / 6) / M, rel=1e-13)
    finally:
        s.terminate()
        s.freeInstance()


def test_nonphysical_parameter_is_an_error_with_traceback(fmus, tmp_path):
    from fmpy.fmi2 import (
        calloc,
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
        free,
    )

    messages = []
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: messages.append((status, msg.decode())))
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    fmu = fmus["TMDInerter"]
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / "neg"
    fmpy.extract(str(fmu), str(d))
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="TMDInerter", instanceName="neg")
    s.instantiate(callbacks=cb)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    # each value within its range (out-of-range values are refused when set: test_fmu_ranges.py), the
    # combination non-physical: no inerter (inerter = 0) with an inertance I = 1 kg
    s.setInteger([vr["inerter"]], [0])
    s.setReal([vr["I"]], [1.0])
    with pytest.raises(fmpy.fmi1.FMICallException) as e:
        s.exitInitializationMode()
    assert e.value.status == 3  # fmi2Error
    text = "\n".join(m for _, m in messages)
    assert "Traceback (most recent call last)" in text and "ParameterError" in text and "inertance" in text
    s.freeInstance()
