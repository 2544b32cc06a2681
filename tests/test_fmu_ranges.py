"""FMUs refuse what they cannot do:

* every parameter's range is declared in modelDescription.xml (min/max from the parameter
  registry; ``inerter`` a bounded Integer 0..2; ``atol``/``rtol`` > 0) and enforced when set: an
  out-of-range value is refused by fmi2SetReal/fmi2SetInteger with a message naming the variable,
  the value and the range; fmpy validate stays clean;
* no exception in the compiled (native) step answers fmi2OK: it becomes fmi2Error with the
  traceback sent to the FMI logger (``atol`` = 0 smuggled in through a serialized state: a
  ZeroDivisionError in the compiled integrator; ``debug_raise`` = 2: an exception raised inside
  the compiled step);
* fmi2FreeInstance frees the FMU states the host left alive (memory stays flat over cycles of
  5,000 orphan states), those states are refused afterwards, and a state is used only by its own
  instance;
* the FMU carries its documentation (``documentation/index.html``) and its messages point there.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import textwrap
import zipfile

import fmpy
import pytest
from _fmu_support import built_fmus
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)

from pyfmu_wrapper.models.catalog import SPECS, pick
from pyfmu_wrapper.physics import registry

TMD = dict(m=9.0, k=4.0e3, c=10.0, df=5.0, I=1.0, y0=0.01)


@pytest.fixture(scope="module")
def fmus():
    return built_fmus()


class Logged:
    """An fmpy slave whose logger messages are collected (status, text)."""

    def __init__(self, fmu, tmp_path, name, folder=None):
        self.messages = []
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(
            lambda env, n, status, cat, msg: self.messages.append((status, msg.decode()))
        )
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb = cb
        self.md = fmpy.read_model_description(str(fmu))
        d = tmp_path / (folder or name)  # one folder: one copy of the binary (one table of states)
        if not d.is_dir():
            fmpy.extract(str(fmu), str(d))
        self.s = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=str(d),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.s.instantiate(callbacks=cb)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}

    def text(self):
        return "\n".join(m for _, m in self.messages)

    def start(self, values):
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        for k, v in values.items():
            (self.s.setInteger if isinstance(v, int) else self.s.setReal)([self.vr[k]], [v])
        self.s.exitInitializationMode()


# ---- ranges declared ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["BaseOscillator", "TMDInerter"])
def test_declared_ranges_are_the_registry_bounds_and_validate_cleanly(fmus, name):
    md = fmpy.read_model_description(str(fmus[name]))
    var = {v.name: v for v in md.modelVariables}
    for p in registry.of("base" if name == "BaseOscillator" else "tmd"):
        v = var[p.fmu_name]
        if p.minimum is None:
            assert v.min is None, p.name
        elif p.strict:  # FMI's min is inclusive: "> 0" is declared as the smallest positive normal double
            assert float(v.min) == sys.float_info.min and p.minimum == 0.0, p.name
        else:
            assert float(v.min) == p.minimum, p.name
        assert (v.max is None) == (p.maximum is None), p.name
    assert var["atol"].min is not None and float(var["atol"].min) > 0.0
    assert float(var["rtol"].min) > 0.0 and float(var["rtol"].max) == 1.0
    if name == "TMDInerter":  # the inerter model: a bounded Integer 0 (none), 1 (ideal), 2 (play)
        assert var["inerter"].type == "Integer" and (int(var["inerter"].min), int(var["inerter"].max)) == (0, 2)
        assert float(var["base_compliance"].min) == 0.0
    else:
        assert float(var["M"].min) > 0.0 and float(var["w"].min) > 0.0
    assert fmpy.validation.validate_fmu(str(fmus[name])) == []


# ---- ranges enforced ------------------------------------------------------------------------------

REFUSED = [  # (FMU, variable, value, range in the message)
    ("TMDInerter", "inerter", 3, ">= 0 and <= 2"),
    ("TMDInerter", "inerter", 4, ">= 0 and <= 2"),
    ("TMDInerter", "inerter", -1, ">= 0 and <= 2"),
    ("TMDInerter", "atol", 0.0, "> 0"),
    ("TMDInerter", "atol", -1e-10, "> 0"),
    ("TMDInerter", "rtol", 0.0, "> 0 and <= 1"),
    ("TMDInerter", "rtol", 2.0, "> 0 and <= 1"),
    ("TMDInerter", "m", -1.0, ">= 0"),
    ("TMDInerter", "s", 0.0, "> 0"),
    ("TMDInerter", "ki", 0.0, "> 0"),
    ("TMDInerter", "eps", -1e-3, ">= 0"),
    ("TMDInerter", "base_compliance", -0.01, ">= 0"),
    ("TMDInerter", "debug_raise", 3, ">= 0 and <= 2"),
    ("BaseOscillator", "M", 0.0, "> 0"),
    ("BaseOscillator", "K", -4e4, ">= 0"),
    ("BaseOscillator", "w", 0.0, "> 0"),
    ("BaseOscillator", "atol", 0.0, "> 0"),
]


@pytest.mark.parametrize("name,var,value,rng", REFUSED, ids=[f"{a}.{b}={c}" for a, b, c, _ in REFUSED])
def test_out_of_range_value_is_refused_when_set(fmus, tmp_path, name, var, value, rng):
    f = Logged(fmus[name], tmp_path, "r")
    try:
        setter = f.s.setInteger if isinstance(value, int) else f.s.setReal
        getter = f.s.getInteger if isinstance(value, int) else f.s.getReal
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        before = getter([f.vr[var]])[0]
        with pytest.raises(FMICallException) as e:
            setter([f.vr[var]], [value])
        assert e.value.status == 3  # fmi2Error
        shown = f"{value:g}" if isinstance(value, float) else str(value)
        assert f"{var} = {shown} is out of range: {var} must be {rng}" in f.text()
        assert "documentation/index.html in the FMU" in f.text()
        assert getter([f.vr[var]])[0] == before  # nothing changed
    finally:
        f.s.freeInstance()


def test_values_at_the_edges_of_their_ranges_are_accepted(fmus, tmp_path):
    f = Logged(fmus["TMDInerter"], tmp_path, "edge")
    try:
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        for var, v in (
            ("atol", sys.float_info.min),  # "> 0" is declared as the smallest normal double
            ("rtol", 1.0),
            ("eps", 0.0),
            ("base_compliance", 0.0),
            ("rtol", 1e-8),
            ("atol", 1e-10),
        ):
            f.s.setReal([f.vr[var]], [v])
            assert f.s.getReal([f.vr[var]])[0] == v
        for v, inertance in ((0, 0.0), (2, 1.0), (1, 1.0)):  # no inerter: I = 0 (else configure refuses it)
            f.s.setReal([f.vr["I"]], [inertance])
            f.s.setInteger([f.vr["inerter"]], [v])
            assert f.s.getInteger([f.vr["inerter"]])[0] == v
        assert not any(st == 3 for st, _ in f.messages)
    finally:
        f.s.freeInstance()


def test_setup_experiment_tolerance_outside_the_range_of_rtol_is_refused(fmus, tmp_path):
    f = Logged(fmus["TMDInerter"], tmp_path, "tol")
    try:
        with pytest.raises(FMICallException):
            f.s.setupExperiment(tolerance=5.0, startTime=0.0)
        assert "tolerance = 5 is out of range: it sets rtol, which must be > 0 and <= 1" in f.text()
        f.s.setupExperiment(tolerance=1e-6, startTime=0.0)  # within: accepted, and it becomes rtol
        f.s.enterInitializationMode()
        assert f.s.getReal([f.vr["rtol"]])[0] == 1e-6
    finally:
        f.s.freeInstance()


# ---- a failure in the compiled step is never fmi2OK ------------------------------------------------


def _serialized_with(f, var, value):
    """The instance's state, serialized, with one Real value replaced (what a crafted or corrupt
    state could carry: the set-time range check never sees it)."""
    state = f.s.getFMUstate()
    data = bytearray(f.s.serializeFMUstate(state))
    f.s.freeFMUstate(state)
    off = 48 + 8 * f.vr[var]  # header, then the Real buffer indexed by value reference
    struct.pack_into("<d", data, off, value)
    return bytes(data)


@pytest.fixture
def unraisable(monkeypatch):
    """What numba reports when a compiled cfunc raised: it writes the exception as "unraisable"
    (sys.unraisablehook; stderr by default). Collected here: proof that the compiled step raised."""
    seen = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(f"{type(u.exc_value).__name__}: {u.exc_value}"))
    return seen


def test_native_step_with_atol_zero_is_an_error_not_ok(fmus, tmp_path, unraisable):
    if os.environ.get("PYFMU_NATIVE") == "0":
        pytest.skip("PYFMU_NATIVE=0 set in the environment")
    f = Logged(fmus["TMDInerter"], tmp_path, "atol0")
    try:
        f.start(TMD)
        f.s.doStep(0.0, 1e-3)  # a good step first (the native path is live)
        y1 = f.s.getReal([f.vr["y"]])[0]
        assert y1 != 0.0
        bad = f.s.deSerializeFMUstate(_serialized_with(f, "atol", 0.0))
        f.s.setFMUstate(bad)
        with pytest.raises(FMICallException) as e:
            f.s.doStep(1e-3, 1e-3)
        assert e.value.status == 3  # fmi2Error, not fmi2OK with y stuck
        assert any(u.startswith("ZeroDivisionError") for u in unraisable)  # the compiled step raised
        text = f.text()  # ... and the message reached the FMI logger, with a traceback
        assert "fmi2DoStep" in text and "Traceback (most recent call last)" in text and "ZeroDivisionError" in text
    finally:
        f.s.freeInstance()


def test_exception_raised_inside_the_compiled_step_is_an_error(fmus, tmp_path, unraisable):
    if os.environ.get("PYFMU_NATIVE") == "0":
        pytest.skip("PYFMU_NATIVE=0 set in the environment")
    for name, start in (("TMDInerter", TMD), ("BaseOscillator", dict(x0=0.01))):
        f = Logged(fmus[name], tmp_path, f"raise2{name}")
        try:
            f.start(start)
            f.s.doStep(0.0, 1e-3)
            f.s.setInteger([f.vr["debug_raise"]], [2])
            with pytest.raises(FMICallException) as e:
                f.s.doStep(1e-3, 1e-3)
            assert e.value.status == 3
            assert unraisable[-1] == "ZeroDivisionError: debug_raise = 2: exception injected in the compiled step"
            assert "InjectedError" in f.text() and "in the compiled step" in f.text()
        finally:
            f.s.freeInstance()


def test_retaken_step_after_a_compiled_failure_restarts_from_the_step_start(fmus, tmp_path, unraisable):
    """debug_raise = 2 raised mid-way; reset to 0 through a state restore, the same step then gives
    the numbers of an instance that never failed (the compiled step put z back before Python ran)."""
    ref = Logged(fmus["TMDInerter"], tmp_path, "ref")
    f = Logged(fmus["TMDInerter"], tmp_path, "fail")
    try:
        for x in (ref, f):
            x.start(TMD)
            x.s.doStep(0.0, 1e-3)
        s0 = f.s.getFMUstate()
        f.s.setInteger([f.vr["debug_raise"]], [2])
        with pytest.raises(FMICallException):
            f.s.doStep(1e-3, 1e-3)
        f.s.setFMUstate(s0)  # back to StepComplete at 1 ms, debug_raise 0
        f.s.doStep(1e-3, 1e-3)
        ref.s.doStep(1e-3, 1e-3)
        names = [f.vr[n] for n in ("y", "yd", "force", "inerter_force")]
        assert f.s.getReal(names) == ref.s.getReal(names)
        f.s.freeFMUstate(s0)
    finally:
        ref.s.freeInstance()
        f.s.freeInstance()


# ---- FMU states belong to their instance and die with it ------------------------------------------


def test_states_of_a_freed_instance_are_refused_and_states_belong_to_their_instance(fmus, tmp_path):
    a = Logged(fmus["TMDInerter"], tmp_path, "a", folder="one")
    b = Logged(fmus["TMDInerter"], tmp_path, "b", folder="one")
    try:
        a.start(TMD)
        b.start(TMD)
        sa = a.s.getFMUstate()
        with pytest.raises(FMICallException):  # a live state of another instance
            b.s.setFMUstate(sa)
        assert "belongs to another instance of this FMU" in b.text()
        data = a.s.serializeFMUstate(sa)  # moving a state between instances: serialize it
        moved = b.s.deSerializeFMUstate(data)
        b.s.setFMUstate(moved)
        b.s.freeFMUstate(moved)
        orphan = a.s.getFMUstate()  # never freed by the host
        a.s.freeInstance()
        a = None
        for op in (lambda: b.s.setFMUstate(orphan), lambda: b.s.setFMUstate(sa), lambda: b.s.serializeFMUstate(orphan)):
            with pytest.raises(FMICallException):
                op()
        assert "freed with its instance by fmi2FreeInstance" in b.text()
    finally:
        if a is not None:
            a.s.freeInstance()
        b.s.freeInstance()


MEMORY_SCRIPT = textwrap.dedent("""
    import sys, tempfile, fmpy
    from fmpy.fmi2 import FMU2Slave
    fmu, n, cycles = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    md = fmpy.read_model_description(fmu)
    d = tempfile.mkdtemp()
    fmpy.extract(fmu, d)
    page = 4096
    for k in range(cycles):
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="TMDInerter", instanceName=f"m{k}")
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        for _ in range(n):
            s.getFMUstate()  # never freed by this host
        s.terminate()
        s.freeInstance()
        print(int(open("/proc/self/statm").read().split()[1]) * page)
""")


def test_free_instance_frees_the_states_left_alive(fmus):
    """6 cycles of instantiate, 5,000 states never freed, free: resident memory flat after the
    first cycles (each state holds ~3 KB: +15 MiB per cycle when they were left behind)."""
    r = subprocess.run(
        [sys.executable, "-c", MEMORY_SCRIPT, str(fmus["TMDInerter"]), "5000", "6"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    rss = [int(x) for x in r.stdout.split()]
    growth = (rss[-1] - rss[1]) / 2**20
    assert growth < 3.0, f"resident memory grew by {growth:.1f} MiB over 4 cycles: {rss}"


# ---- the FMU's own documentation ------------------------------------------------------------------


@pytest.mark.parametrize("name", ["BaseOscillator", "TMDInerter"])
def test_documentation_in_the_archive_lists_every_variable_and_range(fmus, name):
    with zipfile.ZipFile(fmus[name]) as z:
        html = z.read("documentation/index.html").decode()
    for v in SPECS[name].variables:
        assert f"<td>{v.name}</td><td>{v.vr}</td>" in html
        if v.causality == "parameter":
            assert f"<td>{v.range_text().replace('>', '&gt;').replace('<', '&lt;')}</td>" in html
    assert "python -m pip install &quot;numpy&gt;=1.26&quot; &quot;numba&gt;=0.59&quot;" in html


def test_an_overflowed_output_is_an_error_never_ok(tmp_path):
    """Each value within its range, together past the range of doubles (x0 = 1e306 m with K = 4e4 N/m:
    K x0 = 4e310 N): the output is -inf, and the FMU refuses to return it (fmi2Error / fmi3Error
    naming the variable) instead of answering OK (found by the FMI 3.0 fuzz: 2 of 160,000 calls)."""
    import ctypes

    import fmpy
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    from pyfmu_wrapper.fmubuild.build import ensure_fmus

    for version in (2, 3):
        fmu = ensure_fmus(pick("BaseOscillator"), fmi_version=version)["BaseOscillator"]
        md = fmpy.read_model_description(str(fmu))
        d = tmp_path / f"v{version}"
        fmpy.extract(str(fmu), str(d))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        log = []
        if version == 2:
            s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="BaseOscillator", instanceName="o")
            s.instantiate()
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
            s.setReal([vr["x0"]], [1e306])
            s.exitInitializationMode()
            get = s.dll.fmi2GetReal
            get.argtypes = [
                ctypes.c_void_p,
                ctypes.POINTER(ctypes.c_uint),
                ctypes.c_size_t,
                ctypes.POINTER(ctypes.c_double),
            ]
            args = ()
        else:
            s = FMU3Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="BaseOscillator", instanceName="o")
            s.instantiate(logMessage=lambda env, st, cat, msg, log=log: log.append(msg.decode()))
            s.enterInitializationMode(startTime=0.0)
            s.setFloat64([vr["x0"]], [1e306])
            s.exitInitializationMode()
            get = s.dll.fmi3GetFloat64
            get.argtypes = [
                ctypes.c_void_p,
                ctypes.POINTER(ctypes.c_uint),
                ctypes.c_size_t,
                ctypes.POINTER(ctypes.c_double),
                ctypes.c_size_t,
            ]
            args = (1,)
        get.restype = ctypes.c_int
        out = (ctypes.c_double * 1)(123.0)
        assert get(s.component, (ctypes.c_uint * 1)(vr["xdd"]), 1, out, *args) == 3, version
        assert out[0] == 123.0  # nothing returned
        assert get(s.component, (ctypes.c_uint * 1)(vr["x"]), 1, out, *args) == 0  # x = 1e306 itself is finite
        assert out[0] == 1e306
        if version == 3:
            assert any("xdd" in m and "overflowed" in m for m in log)
        s.terminate()
        s.freeInstance()
