"""FMU state save/restore/serialise (bit-identical re-steps) and several instances in one process."""

from __future__ import annotations

import fmpy
import numpy as np
import pytest
from _fmu_support import built_fmus
from fmpy.fmi2 import FMU2Slave

TMD = dict(m=9.0, k=4.0e3, c=10.0, df=5.0, I=1.0, y0=0.002, yd0=-0.01)


@pytest.fixture(scope="module")
def fmus():
    return built_fmus()


def slave(fmu, tmp_path, name, start):
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
        (s.setInteger if isinstance(v, int) else s.setReal)([vr[k]], [v])
    s.exitInitializationMode()
    return s, vr


def drive(s, vr, t0, n, h=1e-3):
    """Step a TMD with a prescribed base motion x = 1e-3 sin(20 t) (value + derivatives)."""
    out = []
    t = t0
    for _ in range(n):
        w = 20.0
        x, xd, xdd = 1e-3 * np.sin(w * t), 1e-3 * w * np.cos(w * t), -1e-3 * w * w * np.sin(w * t)
        s.setReal([vr["x"], vr["xd"], vr["xdd"]], [x, xd, xdd])
        s.setRealInputDerivatives([vr["x"], vr["xd"], vr["xdd"]], [1, 1, 1], [xd, xdd, -w * w * xd])
        s.doStep(t, h)
        t += h
        out.append(s.getReal([vr["force"], vr["y"], vr["yd"], vr["inerter_force"]]))
    return np.array(out), t


def test_save_step_restore_restep_is_bit_identical(fmus, tmp_path):
    s, vr = slave(fmus["TMDInerter"], tmp_path, "st", TMD)
    try:
        _, t = drive(s, vr, 0.0, 50)
        state = s.getFMUstate()
        first, t1 = drive(s, vr, t, 100)
        s.setFMUstate(state)
        second, t2 = drive(s, vr, t, 100)
        assert t1 == t2
        assert np.array_equal(first, second)  # bit-identical, friction included
        # serialised state, restored into a *fresh* instance of the same FMU
        blob = s.serializeFMUstate(state)
        s.freeFMUstate(state)
        s2, vr2 = slave(fmus["TMDInerter"], tmp_path, "st2", TMD)
        st2 = s2.deSerializeFMUstate(blob)
        s2.setFMUstate(st2)
        third, _ = drive(s2, vr2, t, 100)
        assert np.array_equal(first, third)
        s2.freeFMUstate(st2)
        s2.terminate()
        s2.freeInstance()
    finally:
        s.terminate()
        s.freeInstance()


def test_two_instances_and_two_fmus_in_one_process(fmus, tmp_path):
    a, vra = slave(fmus["TMDInerter"], tmp_path, "a", TMD)
    b, vrb = slave(fmus["TMDInerter"], tmp_path, "b", dict(TMD, c=50.0, y0=-0.004))
    base, vrx = slave(fmus["BaseOscillator"], tmp_path, "base", dict(x0=0.01))
    try:
        # interleaved stepping of both instances and of the other FMU
        ra, rb, rx = [], [], []
        t = 0.0
        for _ in range(200):
            ra.append(drive(a, vra, t, 1)[0][0])
            rb.append(drive(b, vrb, t, 1)[0][0])
            base.doStep(t, 1e-3)
            rx.append(base.getReal([vrx["x"]])[0])
            t += 1e-3
        # each equals a run of the same configuration alone
        s_a, _ = slave(fmus["TMDInerter"], tmp_path, "a1", TMD)
        alone_a, _ = drive(s_a, vra, 0.0, 200)
        s_b, _ = slave(fmus["TMDInerter"], tmp_path, "b1", dict(TMD, c=50.0, y0=-0.004))
        alone_b, _ = drive(s_b, vrb, 0.0, 200)
        for s in (s_a, s_b):
            s.terminate()
            s.freeInstance()
        assert np.array_equal(np.array(ra), alone_a)
        assert np.array_equal(np.array(rb), alone_b)
        assert not np.allclose(alone_a[:, 1], alone_b[:, 1])  # really different configurations
        assert abs(rx[-1]) > 0
    finally:
        for s in (a, b, base):
            s.terminate()
            s.freeInstance()


def test_wrong_call_sequence_is_an_error(fmus, tmp_path):
    md = fmpy.read_model_description(str(fmus["BaseOscillator"]))
    d = tmp_path / "seq"
    fmpy.extract(str(fmus["BaseOscillator"]), str(d))
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="BaseOscillator", instanceName="seq")
    s.instantiate()
    with pytest.raises(fmpy.fmi1.FMICallException) as e:
        s.doStep(0.0, 1e-3)
    assert e.value.status == 3
    with pytest.raises(fmpy.fmi1.FMICallException):
        s.exitInitializationMode()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    with pytest.raises(fmpy.fmi1.FMICallException):
        s.setReal([0], [1.0])  # M is a fixed parameter
    with pytest.raises(fmpy.fmi1.FMICallException):
        s.setReal([20], [1.0])  # x is an output
    with pytest.raises(fmpy.fmi1.FMICallException):
        s.doStep(0.5, 1e-3)  # not the current communication point
    s.doStep(0.0, 1e-3)
    s.terminate()
    s.freeInstance()
