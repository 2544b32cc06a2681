"""The six FMI defects of issue 30, each refused or fixed in the C stub (FMI 2.0 and 3.0 where both apply):

1. a directional derivative that is not finite is fmi2Error / fmi3Error with a message, never OK;
2. fmi3InstantiateCoSimulation(eventModeUsed = true) fails: the FMU declares hasEventMode = false;
3. FMI 3.0 reads start values in Instantiated (fmi3GetFloat64 / fmi3GetInt32 / fmi3GetBoolean);
4. a blank instance name is refused;
5. the minimum declared in modelDescription.xml is exactly what is enforced ("> 0" is declared as the
   smallest normal double: the subnormals are refused);
6. fmi3SetFloat64 / fmi3GetFloat64 allocate nothing per call (a C host counting malloc/calloc/realloc).
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
from pathlib import Path

import fmpy
import pytest
from _fmu_support import built_fmus, extract, guid
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback
from test_fmu_ranges import Logged

from pyfmu_wrapper.fmubuild.build import ensure_fmus, fmi_headers_dir
from pyfmu_wrapper.models.catalog import pick

FMI3_ERROR = 3


@pytest.fixture(scope="module")
def fmus2():
    return built_fmus()


@pytest.fixture(scope="module")
def fmus3():
    return ensure_fmus(pick(("BaseOscillator", "TMDInerter")), fmi_version=3)


class Logged3:
    """An fmpy FMI 3.0 slave whose logger messages are collected; not instantiated (``open``)."""

    def __init__(self, fmu: Path, tmp_path: Path, name: str) -> None:
        self.messages: list[tuple[int, str]] = []
        self.md = fmpy.read_model_description(str(fmu))
        d = tmp_path / f"{name}_{fmu.stem}"
        if not d.is_dir():
            fmpy.extract(str(fmu), str(d))
        self.s = FMU3Slave(
            guid=self.md.guid, unzipDirectory=str(d), modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )  # fmt: skip
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self._log = fmi3LogMessageCallback(lambda env, st, cat, msg: self.messages.append((st, msg.decode())))

    def instantiate_raw(self, name: bytes, event_mode_used: bool) -> int | None:
        """fmi3InstantiateCoSimulation called directly: the instance pointer or None."""
        f = self.s.dll.fmi3InstantiateCoSimulation
        f.restype = ctypes.c_void_p
        f.argtypes = [
            ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_bool, ctypes.c_bool, ctypes.c_bool,
            ctypes.c_bool, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, fmi3LogMessageCallback, ctypes.c_void_p,
        ]  # fmt: skip
        res = str(Path(self.s.unzipDirectory) / "resources") + "/"
        return f(name, self.md.guid.encode(), res.encode(), False, False, event_mode_used, False, None, 0, None,
                 self._log, None)  # fmt: skip

    def instantiate(self) -> None:
        self.s.instantiate(logMessage=lambda env, st, cat, msg: self.messages.append((st, msg.decode())))

    def text(self) -> str:
        return "\n".join(m for _, m in self.messages)


# ---- 1. directional derivatives that are not finite ---------------------------------------------

# (FMU, start values, unknown, known): each drives the model past the range of doubles
OVERFLOWS = [
    ("BaseOscillator", {"x0": 1e306}, "xdd", "f_link"),
    ("TMDInerter", {"y0": 1e306}, "force", "x"),
]


@pytest.mark.parametrize("name,start,unknown,known", OVERFLOWS, ids=[o[0] for o in OVERFLOWS])
def test_non_finite_directional_derivative_is_an_error_fmi2(fmus2, tmp_path, name, start, unknown, known):
    f = Logged(fmus2[name], tmp_path, "dd")
    try:
        f.start(start)
        with pytest.raises(FMICallException) as e:
            f.s.getDirectionalDerivative([f.vr[unknown]], [f.vr[known]], [1.0])
        assert e.value.status == 3  # fmi2Error
        assert f"the derivative of {unknown} (value reference {f.vr[unknown]}) is" in f.text()
        assert "overflowed" in f.text()
    finally:
        f.s.freeInstance()


@pytest.mark.parametrize("name,start,unknown,known", OVERFLOWS, ids=[o[0] for o in OVERFLOWS])
def test_non_finite_directional_derivative_is_an_error_fmi3(fmus3, tmp_path, name, start, unknown, known):
    f = Logged3(fmus3[name], tmp_path, "dd")
    f.instantiate()
    try:
        f.s.enterInitializationMode(startTime=0.0)
        f.s.setFloat64([f.vr[k] for k in start], list(start.values()))
        f.s.exitInitializationMode()
        with pytest.raises(FMICallException) as e:
            f.s.getDirectionalDerivative([f.vr[unknown]], [f.vr[known]], [1.0])
        assert e.value.status == FMI3_ERROR
        assert f"fmi3GetDirectionalDerivative: the derivative of {unknown}" in f.text()
    finally:
        f.s.freeInstance()


def test_finite_directional_derivative_still_answers(fmus2, tmp_path):
    """The check refuses only what is not finite: d xdd / d f_link = -1 / M exactly (f_link pulls the base back)."""
    f = Logged(fmus2["BaseOscillator"], tmp_path, "ddok")
    try:
        f.start({"M": 4.0, "x0": 1e-3})
        assert f.s.getDirectionalDerivative([f.vr["xdd"]], [f.vr["f_link"]], [1.0])[0] == -0.25
    finally:
        f.s.freeInstance()


# ---- 2. eventModeUsed = true ------------------------------------------------------------------------


def test_event_mode_used_is_refused(fmus3, tmp_path):
    f = Logged3(fmus3["BaseOscillator"], tmp_path, "ev")
    assert f.instantiate_raw(b"ev", True) is None
    assert "eventModeUsed = true, but this FMU has no event mode (hasEventMode = false)" in f.text()
    inst = f.instantiate_raw(b"ev", False)  # the same call without event mode: an instance
    assert inst
    free = f.s.dll.fmi3FreeInstance
    free.argtypes, free.restype = [ctypes.c_void_p], None
    free(inst)


# ---- 3. start values readable in Instantiated (FMI 3.0) -----------------------------------------


def test_start_values_are_read_in_instantiated_fmi3(fmus3, tmp_path):
    f = Logged3(fmus3["TMDInerter"], tmp_path, "inst")
    f.instantiate()
    try:
        md = {v.name: v for v in f.md.modelVariables}
        reals = [n for n in ("m", "k", "c", "y0", "atol", "rtol") if md[n].start is not None]
        assert f.s.getFloat64([f.vr[n] for n in reals]) == [float(md[n].start) for n in reals]
        assert f.s.getInt32([f.vr["inerter"]]) == [int(md["inerter"].start)]
        f.s.setFloat64([f.vr["m"]], [7.5])  # what the host set is what it reads back
        assert f.s.getFloat64([f.vr["m"]]) == [7.5]
        assert not any(st >= FMI3_ERROR for st, _ in f.messages)
    finally:
        f.s.freeInstance()


def test_fmi2_still_refuses_get_in_instantiated(fmus2, tmp_path):
    """FMI 2.0's state machine does not allow fmi2GetReal before initialisation mode."""
    f = Logged(fmus2["BaseOscillator"], tmp_path, "inst2")
    try:
        with pytest.raises(FMICallException):
            f.s.getReal([f.vr["M"]])
        assert "fmi2GetReal: not allowed in state" in f.text()
    finally:
        f.s.freeInstance()


# ---- 4. blank instance names ------------------------------------------------------------------------


@pytest.mark.parametrize("name", [b"", b"   ", b"\t \n"])
def test_blank_instance_name_is_refused(fmus3, tmp_path, name):
    f = Logged3(fmus3["BaseOscillator"], tmp_path, "blank")
    assert f.instantiate_raw(name, False) is None
    assert "missing instance name" in f.text()


# ---- 5. declared min enforced exactly -----------------------------------------------------------------


@pytest.mark.parametrize(
    "name,var", [("TMDInerter", "atol"), ("TMDInerter", "rtol"), ("TMDInerter", "s"), ("BaseOscillator", "M")]
)
def test_subnormals_below_the_declared_min_are_refused(fmus2, tmp_path, name, var):
    f = Logged(fmus2[name], tmp_path, "sub")
    declared = float(next(v for v in f.md.modelVariables if v.name == var).min)
    assert declared == sys.float_info.min  # "> 0", declared as the smallest normal double
    try:
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        for bad in (5e-324, declared / 2, 0.0):
            with pytest.raises(FMICallException):
                f.s.setReal([f.vr[var]], [bad])
        assert f"{var} must be > 0" in f.text() and "(declared min 2.2250738585072014e-308)" in f.text()
        f.s.setReal([f.vr[var]], [declared])  # the declared minimum itself is accepted
        assert f.s.getReal([f.vr[var]]) == [declared]
    finally:
        f.s.freeInstance()


# ---- 6. fmi3SetFloat64 / fmi3GetFloat64 allocate nothing ---------------------------------------------

ALLOC_HOST = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"
/* malloc, calloc and realloc interposed (the FMU binds to these): counted when counting is on */
extern void *__libc_malloc(size_t), *__libc_calloc(size_t, size_t), *__libc_realloc(void *, size_t);
static volatile long n_alloc = 0;
static volatile int counting = 0;
void *malloc(size_t n) { if (counting) n_alloc++; return __libc_malloc(n); }
void *calloc(size_t a, size_t b) { if (counting) n_alloc++; return __libc_calloc(a, b); }
void *realloc(void *p, size_t n) { if (counting) n_alloc++; return __libc_realloc(p, n); }
static void logm(fmi3InstanceEnvironment e, fmi3Status s, fmi3String c, fmi3String m) { (void)e; (void)c;
    if (s > fmi3Warning) fprintf(stderr, "%s\n", m); }
#define SYM(T, n) T n = (T)dlsym(h, #n); if (!n) { fprintf(stderr, "no %s\n", #n); return 2; }
int main(int argc, char **argv) {
    /* argv: binary, token, resources, vr of the input, vr of two outputs */
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    SYM(fmi3InstantiateCoSimulationTYPE *, fmi3InstantiateCoSimulation)
    SYM(fmi3EnterInitializationModeTYPE *, fmi3EnterInitializationMode)
    SYM(fmi3ExitInitializationModeTYPE *, fmi3ExitInitializationMode)
    SYM(fmi3SetFloat64TYPE *, fmi3SetFloat64)
    SYM(fmi3GetFloat64TYPE *, fmi3GetFloat64)
    SYM(fmi3DoStepTYPE *, fmi3DoStep)
    SYM(fmi3FreeInstanceTYPE *, fmi3FreeInstance)
    fmi3Instance c = fmi3InstantiateCoSimulation("a", argv[2], argv[3], 0, 0, 0, 0, NULL, 0, NULL, logm, NULL);
    if (!c || fmi3EnterInitializationMode(c, 0, 0, 0, 0, 0) || fmi3ExitInitializationMode(c)) return 3;
    fmi3ValueReference in = (fmi3ValueReference)atoi(argv[4]);
    fmi3ValueReference out[2] = {(fmi3ValueReference)atoi(argv[5]), (fmi3ValueReference)atoi(argv[6])};
    double v = 0.0, y[2];
    fmi3Boolean a, b, d; double last;
    long set_allocs = 0, get_allocs = 0;
    for (int i = 0; i < 1000; i++) {
        v = 1e-3 * i;
        n_alloc = 0; counting = 1;
        fmi3Status s = fmi3SetFloat64(c, &in, 1, &v, 1);
        counting = 0; set_allocs += n_alloc;
        if (s) return 4;
        if (fmi3DoStep(c, 1e-3 * i, 1e-3, 1, &a, &b, &d, &last)) return 5;
        n_alloc = 0; counting = 1;
        s = fmi3GetFloat64(c, out, 2, y, 2);
        counting = 0; get_allocs += n_alloc;
        if (s) return 6;
    }
    printf("%ld %ld %.17g\n", set_allocs, get_allocs, y[0]);
    fmi3FreeInstance(c);
    return 0;
}
"""


def test_fmi3_set_and_get_float64_allocate_nothing(fmus3, tmp_path):
    src = tmp_path / "alloc_host.c"
    src.write_text(ALLOC_HOST)
    exe = tmp_path / "alloc_host"
    subprocess.run(["gcc", "-O1", f"-I{fmi_headers_dir()}", str(src), "-o", str(exe), "-ldl"], check=True)
    d = extract(fmus3["BaseOscillator"], tmp_path)
    md = fmpy.read_model_description(str(fmus3["BaseOscillator"]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    so = d / "binaries" / "x86_64-linux" / "BaseOscillator.so"
    r = subprocess.run(
        [str(exe), str(so), md.guid, str(d / "resources"), str(vr["f_link"]), str(vr["x"]), str(vr["xd"])],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    set_allocs, get_allocs, x = r.stdout.split()
    assert float(x) != 0.0  # the input drove the oscillator
    assert (int(set_allocs), int(get_allocs)) == (0, 0)
    assert guid(d) == md.guid
