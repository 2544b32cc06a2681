"""Standard-conforming edges of the FMUs, one targeted case per test.

Every refused call must return fmi2Error (3) *and* log a message naming the function; every
accepted call must give the right numbers (held against exact solutions where it integrates).
"""

from __future__ import annotations

import ctypes
import math
import struct

import fmpy
import pytest
from _fmu_support import damped_forced_response, every_fmu
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2FMUstate

from pyfmu_wrapper.models.catalog import BUILD_FMUS

ERROR = 3


@pytest.fixture(scope="module")
def fmus():
    return every_fmu()


class Logged:
    """An FMU2Slave with a logger that keeps the messages."""

    def __init__(self, fmu, tmp_path, name, start=None, init=True):
        self.md = fmpy.read_model_description(str(fmu))
        d = tmp_path / f"{name}_{fmu.stem}"
        fmpy.extract(str(fmu), str(d))
        self.messages: list[tuple[int, str]] = []

        def log(env, inst, status, cat, msg):
            self.messages.append((status, msg.decode(errors="replace")))

        self._cb_logger = fmi2CallbackLoggerTYPE(log)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._cb_logger
        self.callbacks.allocateMemory = fmpy.fmi2.fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        self.callbacks.freeMemory = fmpy.fmi2.fmi2CallbackFreeMemoryTYPE(fmpy.free)
        self.s = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(d),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.s.instantiate(callbacks=self.callbacks)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        if init:
            self.s.setupExperiment(startTime=0.0)
            self.s.enterInitializationMode()
            self.start(start or {})
            self.s.exitInitializationMode()

    def start(self, values):
        for k, v in values.items():
            (self.s.setInteger if isinstance(v, int) else self.s.setReal)([self.vr[k]], [v])

    def status(self, fname, *args):
        """Call the raw fmi2 function; return its status (no exception)."""
        return self.s._functions[fname](self.s.component, *args)  # the raw ctypes function

    def refused(self, fname, *args):
        n = len(self.messages)
        st = self.status(fname, *args)
        new = [m for s, m in self.messages[n:] if s >= ERROR]
        return st == ERROR and any(fname in m for m in new)

    def close(self):
        self.s.terminate()
        self.s.freeInstance()


def _vrs(*v):
    return (ctypes.c_uint * len(v))(*v)


def _reals(*v):
    return (ctypes.c_double * len(v))(*v)


BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=15.0, x0=0.01, xd0=-0.05)


def test_long_run_with_t_equal_k_h_does_not_drift_out(fmus, tmp_path):
    # find a step count where a running sum of h differs from k*h by more than the old exact check
    h, s, k_bad = 1e-4, 0.0, None
    for k in range(1, 300_000):
        s += h
        if abs(k * h - s) > 1e-12 * (1.0 + abs(s)):
            k_bad = k
            break
    assert k_bad is not None
    f = Logged(fmus["BaseOscillator"], tmp_path, "long", BASE)
    try:
        n = k_bad + 50
        for k in range(n):
            assert f.status("fmi2DoStep", k * h, h, 1) == 0, f.messages[-3:]
        t_end = ctypes.c_double()
        assert f.status("fmi2GetRealStatus", 2, ctypes.byref(t_end)) == 0  # fmi2LastSuccessfulTime
        assert t_end.value == (n - 1) * h + h  # the FMU took the host's time
        x, _ = damped_forced_response([t_end.value], **BASE)
        assert abs(f.s.getReal([f.vr["x"]])[0] - x[0]) < 1e-6 * 0.01
    finally:
        f.close()


def test_communication_point_slack_is_relative_to_the_step(fmus, tmp_path):
    f = Logged(fmus["BaseOscillator"], tmp_path, "slack", BASE)
    try:
        h = 1e-3
        assert f.status("fmi2DoStep", 0.0, h, 1) == 0
        assert f.status("fmi2DoStep", h + 0.5e-6 * h, h, 1) == 0  # within 1e-6 h: the host's time is taken
        assert f.refused("fmi2DoStep", 2 * h + 0.5e-6 * h + 1e-5 * h, h, 1)  # 1e-5 h off: refused
    finally:
        f.close()


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf])
def test_doStep_non_finite_communication_point_refused(fmus, tmp_path, t):
    f = Logged(fmus["TMDInerter"], tmp_path, "tnan")
    try:
        assert f.refused("fmi2DoStep", t, 1e-3, 1)
        assert f.status("fmi2DoStep", 0.0, 1e-3, 1) == 0  # time did not advance
    finally:
        f.close()


@pytest.mark.parametrize("name", BUILD_FMUS)  # every model's FMU
@pytest.mark.parametrize("h", [math.nan, math.inf, -math.inf, 0.0, -1e-3, 1e30, 1000.0, 5e-324])
def test_doStep_bad_step_sizes_refused(fmus, tmp_path, name, h):
    f = Logged(fmus[name], tmp_path, "hbad")
    try:
        t0 = 1.0 if h == 5e-324 else 0.0  # 5e-324 is below the resolution of t = 1
        if t0:
            assert f.status("fmi2DoStep", 0.0, 1.0, 1) == 0
        assert f.refused("fmi2DoStep", t0, h, 1)
        assert f.status("fmi2DoStep", t0, 1e-3, 1) == 0  # still usable
    finally:
        f.close()


def test_longest_step_integrates_correctly_base(fmus, tmp_path):
    """h = 100 s (the longest accepted) in one doStep: the exact forced response."""
    f = Logged(fmus["BaseOscillator"], tmp_path, "big", BASE)
    try:
        assert f.status("fmi2DoStep", 0.0, 100.0, 1) == 0
        x, xd = damped_forced_response([100.0], **BASE)
        got = f.s.getReal([f.vr["x"], f.vr["xd"]])
        assert abs(got[0] - x[0]) < 1e-6 * 0.01 and abs(got[1] - xd[0]) < 1e-6 * 0.15
    finally:
        f.close()


def test_longest_step_integrates_correctly_tmd(fmus, tmp_path):
    """TMDInerter (ideal inerter, base at rest), h = 100 s: exact free decay of (m + I) ydd + c yd + k y = 0."""
    m, I, k, c, y0 = 9.0, 1.0, 4.0e3, 0.5, 0.01
    f = Logged(fmus["TMDInerter"], tmp_path, "bigt", dict(m=m, I=I, k=k, c=c, y0=y0))
    try:
        assert f.status("fmi2DoStep", 0.0, 100.0, 1) == 0
        y, _ = damped_forced_response([100.0], m + I, k, c, 0.0, 1.0, y0, 0.0)
        assert abs(f.s.getReal([f.vr["y"]])[0] - y[0]) < 1e-6 * y0
    finally:
        f.close()


@pytest.mark.parametrize("t0", [math.nan, math.inf])
def test_setupExperiment_non_finite_start_refused(fmus, tmp_path, t0):
    f = Logged(fmus["BaseOscillator"], tmp_path, "setup", init=False)
    try:
        assert f.refused("fmi2SetupExperiment", 0, 0.0, t0, 0, 0.0)
        assert f.refused("fmi2SetupExperiment", 1, math.nan, 0.0, 0, 0.0)  # NaN tolerance
        assert f.refused("fmi2SetupExperiment", 0, 0.0, 0.0, 1, math.inf)  # infinite stop time
        assert f.status("fmi2SetupExperiment", 0, 0.0, 0.0, 0, 0.0) == 0
    finally:
        f.s.freeInstance()


def test_setReal_non_finite_refused(fmus, tmp_path):
    f = Logged(fmus["TMDInerter"], tmp_path, "setnan")
    try:
        assert f.refused("fmi2SetReal", _vrs(f.vr["x"]), 1, _reals(math.nan))
        assert f.refused("fmi2SetRealInputDerivatives", _vrs(f.vr["x"]), 1, (ctypes.c_int * 1)(1), _reals(math.inf))
    finally:
        f.close()


def _serialized(f):
    st = f.s.getFMUstate()
    blob = f.s.serializeFMUstate(st)
    f.s.freeFMUstate(st)
    return bytes(blob)


def _deserialize(f, blob):
    state = fmi2FMUstate()
    buf = ctypes.create_string_buffer(blob, len(blob))
    return f.refused("fmi2DeSerializeFMUstate", buf, len(blob), ctypes.byref(state)), state


def test_deserialize_wrapping_length_field_refused(fmus, tmp_path):
    """The length field set so that a size check in 64 bits wraps (used to segfault)."""
    f = Logged(fmus["TMDInerter"], tmp_path, "wrap")
    try:
        good = _serialized(f)
        nvr = struct.unpack_from("<I", good, 4)[0]
        for pylen in (2**64 - 28 * nvr, 2**64 - 1, 2**63):
            bad = bytearray(good)
            struct.pack_into("<Q", bad, 32, pylen)
            assert _deserialize(f, bytes(bad))[0]
            assert _deserialize(f, bytes(bad[:48]))[0]  # header only
        assert _deserialize(f, good[:31])[0]
        assert _deserialize(f, good + b"\0")[0]
        ok, state = _deserialize(f, good)
        assert not ok and f.s.setFMUstate(state) is None  # the intact bytes still restore
    finally:
        f.close()


def test_deserialize_garbage_fmi_state_field_refused(fmus, tmp_path):
    f = Logged(fmus["BaseOscillator"], tmp_path, "garb", BASE)
    try:
        good = _serialized(f)
        for field in (0, 3, 1 << 7, -1):
            bad = bytearray(good)
            struct.pack_into("<i", bad, 8, field)
            assert _deserialize(f, bytes(bad))[0]
        bad = bytearray(good)
        struct.pack_into("<d", bad, 16, math.nan)  # time
        assert _deserialize(f, bytes(bad))[0]
    finally:
        f.close()


def test_states_of_another_fmu_refused(fmus, tmp_path):
    a = Logged(fmus["BaseOscillator"], tmp_path, "a", BASE)
    b = Logged(fmus["TMDInerter"], tmp_path, "b")
    try:
        sb = b.s.getFMUstate()
        assert a.refused("fmi2GetFMUstate", ctypes.byref(sb))  # into a state of the other FMU
        assert a.refused("fmi2SetFMUstate", sb)
        assert a.refused("fmi2FreeFMUstate", ctypes.byref(sb))
        assert _deserialize(a, _serialized(b))[0]
        garbage = fmi2FMUstate(ctypes.addressof(ctypes.create_string_buffer(256)))
        assert a.refused("fmi2SetFMUstate", garbage)  # not a state at all: refused, not dereferenced
        b.s.freeFMUstate(sb)
        assert b.refused("fmi2SetFMUstate", sb)  # freed
    finally:
        a.close()
        b.close()


def test_directional_derivative_with_respect_to_non_inputs_is_zero(fmus, tmp_path):
    """OMSimulator's default call: knowns BaseOscillator VR 0 (M) and TMDInerter VR 9 (inerter)."""
    base = Logged(fmus["BaseOscillator"], tmp_path, "ddb", BASE)
    tmd = Logged(fmus["TMDInerter"], tmp_path, "ddt", dict(m=9.0, I=1.0))
    try:
        outs = [base.vr[n] for n in ("x", "xd", "xdd", "f_exc")]
        assert base.s.getDirectionalDerivative(outs, [0], [1.0]) == [0.0] * 4
        touts = [tmd.vr[n] for n in ("force", "y", "yd", "inerter_force")]
        assert tmd.s.getDirectionalDerivative(touts, [9], [1.0]) == [0.0] * 4
        # inputs still give the feed-through: d xdd / d f_link = -1/M, d force / d xdd = m I / (m + I)
        assert base.s.getDirectionalDerivative([base.vr["xdd"]], [base.vr["f_link"], 0], [1.0, 1.0]) == pytest.approx(
            [-1.0 / 100.0], rel=1e-12
        )
        assert tmd.s.getDirectionalDerivative([tmd.vr["force"]], [tmd.vr["xdd"], 9], [1.0, 1.0]) == pytest.approx(
            [9.0 / 10.0], rel=1e-12
        )
        assert base.refused("fmi2GetDirectionalDerivative", _vrs(outs[0]), 1, _vrs(12345), 1, _reals(1.0), _reals(0.0))
    finally:
        base.close()
        tmd.close()


def test_directional_derivative_wrt_parameter_in_initialization_mode(fmus, tmp_path):
    """In initialisation mode d xdd / d M = -xdd / M (xdd = (F - C xd0 - K x0) / M at t = 0)."""
    f = Logged(fmus["BaseOscillator"], tmp_path, "ddp", init=False)
    try:
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        f.start(BASE)
        xdd = f.s.getReal([f.vr["xdd"]])[0]
        assert xdd == pytest.approx((200.0 - 100.0 * -0.05 - 4.0e4 * 0.01) / 100.0, rel=1e-12)
        d = f.s.getDirectionalDerivative([f.vr["xdd"]], [f.vr["M"]], [1.0])[0]
        assert d == pytest.approx(-xdd / 100.0, rel=1e-6)
        f.s.exitInitializationMode()
        assert f.s.getDirectionalDerivative([f.vr["xdd"]], [f.vr["M"]], [1.0]) == [0.0]
    finally:
        f.close()


def test_directional_derivative_wrt_parameter_at_the_edge_of_its_domain(fmus, tmp_path):
    """A play gap eps = 0 cannot be perturbed below 0: a one-sided difference. With the ideal
    inerter the outputs do not depend on eps: zero."""
    f = Logged(fmus["TMDInerter"], tmp_path, "ddedge", init=False)
    try:
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        f.start(dict(y0=0.01))
        outs = [f.vr[n] for n in ("force", "y", "yd", "inerter_force")]
        assert f.s.getDirectionalDerivative(outs, [f.vr["eps"]], [1.0]) == [0.0] * 4
        # d y / d y0 = 1 (a parameter that the output equals at initialisation)
        assert f.s.getDirectionalDerivative([f.vr["y"]], [f.vr["y0"]], [1.0])[0] == pytest.approx(1.0, rel=1e-9)
        f.s.exitInitializationMode()
    finally:
        f.close()
