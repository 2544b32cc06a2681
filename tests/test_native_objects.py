"""The compiled model step as object code (pyfmu_wrapper/fmubuild/native_obj.py, issue 30): emitted by llvmlite
from the numba source for x86_64 Linux and x86_64 Windows and linked with C that holds no model code
(fmu/src/native/native_rt.c and the C driver below), it computes the same bits as the JIT-compiled step
the Python-hosted FMUs call, on a driven run of the base, the TMD with an ideal inerter and the TMD with
play. Linux: gcc; Windows: mingw-w64 and wine (installed by .ci/run).

The driver reads the slave's arrays after initialisation (the Python slave's configure: parameters,
start states) and the inputs of every step from one file, takes the steps through the object's
``pyfmu_model_step`` and writes the return code and every value after each step; the reference is the
same run through the JIT-compiled cfunc, with the same arrays, in this process.
"""

from __future__ import annotations

import ctypes
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyfmu_wrapper.fmi.contract import NATIVE_OK
from pyfmu_wrapper.fmubuild.native_obj import RUNTIME_C, STEP_SYMBOL, mingw_gcc, write_objects
from pyfmu_wrapper.models.base_tmd.fmus.slaves import BaseOscillatorSlave, TMDInerterSlave
from pyfmu_wrapper.models.catalog import SPECS, pick

DRIVER = r"""
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
typedef int32_t (*Step)(double *, int32_t *, double *, double *, double *, int64_t *, double *, double *,
                        double *, double *, double, double);
extern int32_t STEP_SYMBOL(double *, int32_t *, double *, double *, double *, int64_t *, double *, double *,
                           double *, double *, double, double);
static void *take(FILE *f, size_t n) {
    void *p = calloc(n ? n : 1, 1);
    if (fread(p, 1, n, f) != n) { fprintf(stderr, "short input\n"); exit(2); }
    return p;
}
int main(int argc, char **argv) {
    FILE *f = fopen(argv[1], "rb"), *o = fopen(argv[2], "wb");
    if (!f || !o) return 2;
    int64_t *hd = take(f, 8 * 8); /* nvr, np, nz, nu, natol, nbackup, nsteps, nin */
    int64_t nvr = hd[0], np = hd[1], nz = hd[2], nu = hd[3], na = hd[4], nb = hd[5], ns = hd[6], ni = hd[7];
    double *reals = take(f, 8 * nvr);
    int32_t *ints = take(f, 4 * nvr);
    double *derivs = take(f, 16 * nvr), *z = take(f, 8 * nz), *p = take(f, 8 * np);
    int64_t *stats = take(f, 8 * 4);
    double *th = take(f, 16), *u = take(f, 8 * nu), *atol = take(f, 8 * na), *backup = take(f, 8 * nb);
    double *th0 = take(f, 16);
    int64_t *vr = take(f, 8 * ni);
    double *in = take(f, 8 * 3 * ni * ns);
    for (int64_t k = 0; k < ns; k++) {
        for (int64_t j = 0; j < ni; j++) {
            reals[vr[j]] = in[3 * (k * ni + j)];
            derivs[2 * vr[j]] = in[3 * (k * ni + j) + 1];
            derivs[2 * vr[j] + 1] = in[3 * (k * ni + j) + 2];
        }
        int32_t rc = STEP_SYMBOL(reals, ints, derivs, z, p, stats, th, u, atol, backup, th0[0] + k * th0[1], th0[1]);
        fwrite(&rc, 4, 1, o);
        fwrite(reals, 8, nvr, o);
        fwrite(ints, 4, nvr, o);
        fwrite(z, 8, nz, o);
    }
    fclose(o);
    return 0;
}
""".replace("STEP_SYMBOL", STEP_SYMBOL)

CASES = {  # name: (model, parameters, inputs (name, amplitude): sin(w t) with exact derivatives)
    "base": ("BaseOscillator", {}, (("f_link", 50.0),)),
    "tmd_ideal": (
        "TMDInerter",
        dict(m=9.0, I=1.0, k=4.0e3, c=10.0, y0=0.003),
        (("x", 2e-3), ("xd", 2e-3 * 25.0), ("xdd", -2e-3 * 625.0)),
    ),
    "tmd_play": (
        "TMDInerter",
        dict(m=9.0, I=1.0, k=4.0e3, c=10.0, y0=0.003, inerter=2, eps=1e-4, ki=2e7),
        (("x", 2e-3), ("xd", 2e-3 * 25.0), ("xdd", -2e-3 * 625.0)),
    ),
}
W, H, NSTEPS = 25.0, 1e-3, 600


def _slave(case: str):
    model, params, _ = CASES[case]
    spec = SPECS[model]
    nvr = max(v.vr for v in spec.variables) + 1
    cls = BaseOscillatorSlave if model == "BaseOscillator" else TMDInerterSlave
    bufs = [bytearray(8 * nvr), bytearray(4 * nvr), bytearray(16 * nvr), bytearray(8 * 4 * (nvr + 2))]
    s = cls(*bufs, instance_name="native", resources="")
    for k, v in params.items():
        var = spec.by_name(k)
        if isinstance(v, int):
            s.i[var.vr] = v
        else:
            s.r[var.vr] = v
    assert s.setup_experiment(0, 0.0, 0.0, 0, 0.0) == 0
    assert s.enter_initialization() == 0 and s.exit_initialization() == 0
    return s, bufs, spec, nvr


def _inputs(case: str, spec) -> tuple[list[int], np.ndarray]:
    """Per step, per input: value, d/dt, d2/dt2 of amplitude * sin(W t) (the phase shifts by the
    derivative order: x, xd, xdd of a harmonic base motion, each with its own exact derivatives)."""
    _, _, inputs = CASES[case]
    t = np.arange(NSTEPS) * H
    vals = np.empty((NSTEPS, len(inputs), 3))
    for j, (_, a) in enumerate(inputs):
        vals[:, j, 0] = a * np.sin(W * t + j * np.pi / 2)
        vals[:, j, 1] = a * W * np.cos(W * t + j * np.pi / 2)
        vals[:, j, 2] = -a * W * W * np.sin(W * t + j * np.pi / 2)
    return [spec.vr(n) for n, _ in inputs], vals


def _blob_and_reference(case: str) -> tuple[bytes, bytes]:
    s, bufs, spec, nvr = _slave(case)
    addr = np.frombuffer(s.native(), dtype=np.uint64)
    arrays = [s.z, s.p, s.stats, s._th, s._u, s._atol, s._native_backup]
    vrs, vals = _inputs(case, spec)
    head = struct.pack("<8q", nvr, s.p.size, s.z.size, s._u.size, s._atol.size, s._native_backup.size, NSTEPS, len(vrs))
    blob = head + b"".join(bytes(b) for b in bufs[:3]) + b"".join(a.tobytes() for a in arrays)
    blob += struct.pack("<2d", 0.0, H) + np.array(vrs, dtype=np.int64).tobytes() + vals.tobytes()
    proto = ctypes.CFUNCTYPE(ctypes.c_int32, *[ctypes.c_void_p] * 10, ctypes.c_double, ctypes.c_double)
    step = proto(int(addr[0]))
    ptrs = [ctypes.addressof(ctypes.c_char.from_buffer(b)) for b in bufs[:3]] + [int(a) for a in addr[1:]]
    out = bytearray()
    for k in range(NSTEPS):
        for j, vr in enumerate(vrs):
            s.r[vr] = vals[k, j, 0]
            s.du[vr] = vals[k, j, 1:]
        rc = step(*ptrs, 0.0 + k * H, H)
        out += struct.pack("<i", rc) + bytes(bufs[0]) + bytes(bufs[1]) + s.z.tobytes()
    return blob, bytes(out)


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    # only the models and platforms the cases run (each further model or platform is another compile)
    models = sorted({model for model, *_ in CASES.values()})
    return write_objects(tmp_path_factory.mktemp("native_obj"), pick(models), ("linux64", "win64"))


def _run(case: str, objects, tmp_path: Path, platform: str) -> tuple[bytes, bytes]:
    model = CASES[case][0]
    blob, ref = _blob_and_reference(case)
    (tmp_path / "in.bin").write_bytes(blob)
    (tmp_path / "driver.c").write_text(DRIVER)
    cc = "gcc" if platform == "linux64" else mingw_gcc()
    exe = tmp_path / ("driver" if platform == "linux64" else "driver.exe")
    srcs = [str(tmp_path / "driver.c"), str(RUNTIME_C), *[str(o) for o in objects[(model, platform)]]]
    subprocess.run([cc, "-O2", *srcs, "-o", str(exe), "-lm"], check=True, capture_output=True, text=True)
    run = [str(exe)] if platform == "linux64" else [shutil.which("wine") or "wine", str(exe)]
    env = {"PATH": "/usr/bin:/bin", "WINEDEBUG": "-all", "HOME": str(tmp_path), "WINEPREFIX": str(tmp_path / "wine")}
    r = subprocess.run(
        [*run, str(tmp_path / "in.bin"), str(tmp_path / "out.bin")], capture_output=True, env=env, timeout=600
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return (tmp_path / "out.bin").read_bytes(), ref


def _records(data: bytes, case: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step: return code, then the Real values and the state z (as one row), the Integer values."""
    nvr = max(v.vr for v in SPECS[CASES[case][0]].variables) + 1
    nz = 2 if CASES[case][0] == "BaseOscillator" else 4
    rec = np.dtype([("rc", "<i4"), ("r", "<f8", nvr), ("i", "<i4", nvr), ("z", "<f8", nz)])
    a = np.frombuffer(data, dtype=rec)
    return a["rc"], np.hstack([a["r"], a["z"]]), a["i"]


def _check(out: bytes, ref: bytes, case: str) -> None:
    assert len(out) == len(ref)
    rc, real, _ = _records(ref, case)
    assert set(rc) == {NATIVE_OK}  # every step taken by the compiled step, none handed back
    assert np.ptp(real, axis=0).max() > 0.0  # the run moves
    assert out == ref  # bit for bit: every value, every step


@pytest.mark.parametrize("case", sorted(CASES))
def test_linux_object_is_bit_identical_to_the_jit(objects, tmp_path, case):
    out, ref = _run(case, objects, tmp_path, "linux64")
    _check(out, ref, case)


#: the functions of the C library the compiled step calls, per case (nm -u of its object): where the
#: C run time of Windows computes them, its last bit may differ from glibc's, and so may the run
LIBM_CALLS = {"base": True, "tmd_ideal": False, "tmd_play": True}


@pytest.mark.parametrize("case", sorted(CASES))
def test_win64_object_under_wine_agrees_with_the_jit(objects, tmp_path, case):
    """Bit for bit where the step uses only IEEE arithmetic (the TMD with an ideal inerter). Where it
    calls maths functions of the C library (the base's exact step: sin, cos, exp2, log2; the play:
    atan, pow), mingw's C run time rounds some results differently in the last bit from glibc (the
    JIT's); the compiled code itself is the same. The base then differs by that last bit (1 of 600
    steps here: 3.6e-17 of the range of f_exc), within 1e-12 of each value's range. The play's
    stiff contact feeds such a bit into RODAS4's error estimate, which then picks other step sizes
    (from step 337 on here): the runs differ within the integrator's tolerance (rtol = 1e-8 of each
    value's range; 1.35e-9 here), which is the accuracy either run has."""
    if mingw_gcc() is None or shutil.which("wine") is None:
        pytest.skip("mingw-w64 or wine is missing (.ci/run installs gcc-mingw-w64-x86-64 and wine64)")
    out, ref = _run(case, objects, tmp_path, "win64")
    rc, real, ints = _records(out, case)
    rc0, real0, ints0 = _records(ref, case)
    assert (rc == rc0).all() and (ints == ints0).all()
    if not LIBM_CALLS[case]:
        assert out == ref
        return
    scale = np.maximum(np.abs(real0).max(axis=0), np.finfo(float).tiny)
    rel = (np.abs(real - real0) / scale).max()
    rtol = real0[0, SPECS["TMDInerter"].vr("rtol")] if case == "tmd_play" else 0.0
    assert rel <= (1e-12 if case == "base" else rtol)
    assert rel > 0.0  # the C run times do differ here (else this case belongs with the bit-identical ones)


#: the two-argument functions of LIBM (the others take one)
LIBM_BINARY = frozenset({"atan2", "pow", "hypot", "fmod", "copysign", "fmin", "fmax"})


@pytest.mark.parametrize("platform", ["linux64", "win64"])
def test_every_maths_function_the_objects_may_call_is_the_c_librarys(tmp_path, platform):
    """The maths functions an object may call (native_obj.LIBM) are all in the C library the native FMU
    links on both platforms (glibc's libm, mingw-w64's C run time): a program calling each through a
    pointer (no builtin folded) links and runs there, every value finite."""
    from pyfmu_wrapper.fmubuild.native_obj import LIBM

    if platform == "win64" and (mingw_gcc() is None or shutil.which("wine") is None):
        pytest.skip("mingw-w64 or wine is missing (.ci/run installs gcc-mingw-w64-x86-64 and wine64)")
    one, two = sorted(LIBM - LIBM_BINARY), sorted(LIBM & LIBM_BINARY)
    calls = [f'    printf("{n} %.17g\\n", (*(F1){n})({"y" if n == "acosh" else "x"}));' for n in one]  # acosh: >= 1
    calls += [f'    printf("{n} %.17g\\n", (*(F2){n})(x, y));' for n in two]
    src = "\n".join(
        [
            "#include <math.h>",
            "#include <stdio.h>",
            "typedef double (*F1)(double);",
            "typedef double (*F2)(double, double);",
            "int main(void) {",
            "    volatile double x = 0.3, y = 1.7;",
            *calls,
            "    return 0;",
            "}",
        ]
    )
    (tmp_path / "m.c").write_text(src)
    cc = "gcc" if platform == "linux64" else mingw_gcc()
    exe = tmp_path / ("m" if platform == "linux64" else "m.exe")
    subprocess.run([cc, "-O0", "-fno-builtin", str(tmp_path / "m.c"), "-o", str(exe), "-lm"], check=True)
    run = [str(exe)] if platform == "linux64" else [shutil.which("wine") or "wine", str(exe)]
    env = {"PATH": "/usr/bin:/bin", "WINEDEBUG": "-all", "HOME": str(tmp_path), "WINEPREFIX": str(tmp_path / "wine")}
    r = subprocess.run(run, capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    values = dict(line.split() for line in r.stdout.splitlines())
    assert set(values) == set(LIBM)
    assert all(np.isfinite(float(v)) for v in values.values()), values
