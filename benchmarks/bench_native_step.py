"""Per-step cost of the model step as native object code (issue 30) against the Python-hosted FMUs,
in one run, at h = 1 ms: base, TMD with an ideal inerter, TMD with play (eps = 1e-4, ki = 2e7).

    python benchmarks/bench_native_step.py [--steps 200000] [--rounds 3]

"object" = the step emitted by llvmlite from the numba source (pyfmu_wrapper/fmubuild/native_obj.py),
linked with fmu/src/native/native_rt.c and a C timing loop: per step, write the inputs and their
derivatives into the value buffers (what fmi2SetReal and fmi2SetRealInputDerivatives do), take the
step, read one output; no FMI stub around it (a native FMU adds the stub's argument checks, some
tens of ns). "FMU" = the Python-hosted FMU (FMI 2.0) in a C host doing the same per step through the FMI calls
(SetReal and SetRealInputDerivatives of the inputs, DoStep, GetReal of one output; the stub calls
the numba cfunc of the same step, Python is not entered).
Both sides run alternately within each round; medians over the rounds. Also: size of each object
file (linux64 / win64). Results: benchmarks/results/bench_native_step.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from _fmu_support import extract, guid  # noqa: E402
from test_native_objects import CASES, _blob_and_reference  # noqa: E402

from pyfmu_wrapper.fmubuild.build import ensure_fmus, fmi_headers_dir  # noqa: E402
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus  # noqa: E402
from pyfmu_wrapper.fmubuild.native_obj import RUNTIME_C, STEP_SYMBOL, write_objects  # noqa: E402
from pyfmu_wrapper.models.catalog import NATIVE_FMUS, PROJECT_FMUS, SPECS, pick  # noqa: E402

TIMER = r"""
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
extern int32_t STEP_SYMBOL(double *, int32_t *, double *, double *, double *, int64_t *, double *, double *,
                           double *, double *, double, double);
static void *take(FILE *f, size_t n) {
    void *p = calloc(n ? n : 1, 1);
    if (fread(p, 1, n, f) != n) exit(2);
    return p;
}
int main(int argc, char **argv) {
    FILE *f = fopen(argv[1], "rb");
    long n = atol(argv[2]);
    int yvr = atoi(argv[3]);
    int64_t *hd = take(f, 64);
    int64_t nvr = hd[0], np = hd[1], nz = hd[2], nu = hd[3], na = hd[4], nb = hd[5], ni = hd[7];
    double *reals = take(f, 8 * nvr);
    int32_t *ints = take(f, 4 * nvr);
    double *derivs = take(f, 16 * nvr), *z = take(f, 8 * nz), *p = take(f, 8 * np);
    int64_t *stats = take(f, 32);
    double *th = take(f, 16), *u = take(f, 8 * nu), *atol = take(f, 8 * na), *backup = take(f, 8 * nb);
    double *th0 = take(f, 16);
    int64_t *vr = take(f, 8 * ni);
    double amp[3] = {atof(argv[4]), atof(argv[5]), atof(argv[6])}, w = 25.0, h = th0[1], sum = 0.0;
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long k = 0; k < n; k++) {
        double t = k * h;
        for (int64_t j = 0; j < ni; j++) { /* set: the input and its derivatives */
            double ph = w * t + j * 1.5707963267948966;
            reals[vr[j]] = amp[j] * sin(ph);
            derivs[2 * vr[j]] = amp[j] * w * cos(ph);
            derivs[2 * vr[j] + 1] = -amp[j] * w * w * sin(ph);
        }
        if (STEP_SYMBOL(reals, ints, derivs, z, p, stats, th, u, atol, backup, t, h) != 0x4F4B) return 3;
        sum += reals[yvr]; /* get */
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    double us = ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / 1e3 / n;
    printf("%.6f %.17g\n", us, sum);
    return 0;
}
""".replace("STEP_SYMBOL", STEP_SYMBOL)

FMU_TIMER = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"
static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...) {
    (void)e; (void)n; (void)c; if (s > fmi2Warning) fprintf(stderr, "%s\n", m);
}
#define SYM(T, n) T *n = (T *)dlsym(h, #n); if (!n) return 2;
int main(int argc, char **argv) {
    /* argv: binary, resource URI, guid, steps, output vr, "vr vr vr" inputs, amplitudes x3, then r:VR=V / i:VR=V */
    struct timespec i0, i1;
    clock_gettime(CLOCK_MONOTONIC, &i0);
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    SYM(fmi2InstantiateTYPE, fmi2Instantiate) SYM(fmi2SetupExperimentTYPE, fmi2SetupExperiment)
    SYM(fmi2EnterInitializationModeTYPE, fmi2EnterInitializationMode)
    SYM(fmi2ExitInitializationModeTYPE, fmi2ExitInitializationMode) SYM(fmi2SetRealTYPE, fmi2SetReal)
    SYM(fmi2SetIntegerTYPE, fmi2SetInteger) SYM(fmi2GetRealTYPE, fmi2GetReal) SYM(fmi2DoStepTYPE, fmi2DoStep)
    SYM(fmi2SetRealInputDerivativesTYPE, fmi2SetRealInputDerivatives) SYM(fmi2FreeInstanceTYPE, fmi2FreeInstance)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("t", fmi2CoSimulation, argv[3], argv[2], &cb, 0, 0);
    if (!c || fmi2SetupExperiment(c, 0, 0, 0, 0, 0) || fmi2EnterInitializationMode(c)) return 3;
    long n = atol(argv[4]);
    fmi2ValueReference y = (fmi2ValueReference)atoi(argv[5]), in[3];
    int ni = sscanf(argv[6], "%u %u %u", &in[0], &in[1], &in[2]);
    if (ni < 0) ni = 0; /* no inputs (e.g. VanDerPol): doStep + get */
    double amp[3] = {atof(argv[7]), atof(argv[8]), atof(argv[9])}, w = 25.0, hh = 1e-3, sum = 0, yv;
    for (int i = 10; i < argc; i++) {
        fmi2ValueReference vr; double v; int iv;
        if (sscanf(argv[i], "r:%u=%lf", &vr, &v) == 2) fmi2SetReal(c, &vr, 1, &v);
        else if (sscanf(argv[i], "i:%u=%d", &vr, &iv) == 2) fmi2SetInteger(c, &vr, 1, &iv);
    }
    if (fmi2ExitInitializationMode(c)) return 3;
    clock_gettime(CLOCK_MONOTONIC, &i1);
    fmi2Integer o1[3] = {1, 1, 1}, o2[3] = {2, 2, 2};
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long k = 0; k < n; k++) {
        double t = k * hh, v[3], d1[3], d2[3];
        for (int j = 0; j < ni; j++) {
            double ph = w * t + j * 1.5707963267948966;
            v[j] = amp[j] * sin(ph); d1[j] = amp[j] * w * cos(ph); d2[j] = -amp[j] * w * w * sin(ph);
        }
        if ((ni && (fmi2SetReal(c, in, ni, v) || fmi2SetRealInputDerivatives(c, in, ni, o1, d1) ||
                    fmi2SetRealInputDerivatives(c, in, ni, o2, d2))) ||
            fmi2DoStep(c, t, hh, 1) || fmi2GetReal(c, &y, 1, &yv))
            return 4;
        sum += yv;
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    printf("%.6f %.17g %.6f\n", ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / 1e3 / n, sum,
           ((i1.tv_sec - i0.tv_sec) * 1e9 + (i1.tv_nsec - i0.tv_nsec)) / 1e6);
    fmi2FreeInstance(c);
    return 0;
}
"""

#: output read per step (as in benchmarks/bench_fmu.py: the base's x, the TMD's force)
OUTPUT = {"BaseOscillator": "x", "TMDInerter": "force"}


def compile_fmu_timer(tmp: Path) -> Path:
    """The FMI 2.0 C host of FMU_TIMER, compiled into ``tmp``: dlopen, instantiate + initialise (timed),
    then per step set the inputs and their derivatives, doStep, get one output (timed)."""
    (tmp / "fmu_timer.c").write_text(FMU_TIMER)
    host = tmp / "fmu_timer"
    subprocess.run(
        ["gcc", "-O2", f"-I{fmi_headers_dir()}", str(tmp / "fmu_timer.c"), "-o", str(host), "-ldl", "-lm"],
        check=True,
    )
    return host


def case_args(case: str) -> list[str]:
    """FMU_TIMER's arguments after the step count for one of CASES: output vr, input vrs, amplitudes, settings."""
    model, params, inputs = CASES[case]
    spec = SPECS[model]
    in_vrs = " ".join(str(spec.vr(k)) for k, _ in inputs)
    sets = [f"r:{spec.vr(k)}={v}" for k, v in params.items() if not isinstance(v, int)]
    sets += [f"i:{spec.vr(k)}={v}" for k, v in params.items() if isinstance(v, int)]
    amps = [str(x) for _, x in inputs] + ["0"] * (3 - len(inputs))
    return [str(spec.vr(OUTPUT[model])), in_vrs, *amps, *sets]


def time_fmu(
    host: Path, binary: Path, resources_uri: str, token: str, steps: int, args: list[str]
) -> tuple[float, str, float]:
    """One FMU_TIMER run: (us per set+doStep+get, %.17g sum of the output read, instantiate+initialise ms)."""
    r = subprocess.run(
        [str(host), str(binary), resources_uri, token, str(steps), *args], capture_output=True, text=True, check=True
    )
    step_us, total, init = r.stdout.split()
    return float(step_us), total, float(init)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        objects = write_objects(tmp / "obj", pick(NATIVE_FMUS))
        sizes = {f"{m}.{p}": sum(o.stat().st_size for o in obj) for (m, p), obj in objects.items()}
        fmus = ensure_fmus(pick(("BaseOscillator", "TMDInerter")))
        native = {p.stem: p for p in build_native_fmus(pick(PROJECT_FMUS), out_dir=tmp / "native")}
        fmu_bytes = {
            f"{n}.{kind}": f.stat().st_size
            for kind, fs in (("native", native), ("hosted", fmus))
            for n, f in fs.items()
        }
        (tmp / "timer.c").write_text(TIMER)
        host = compile_fmu_timer(tmp)
        rows = {}
        for case, (model, _params, inputs) in CASES.items():
            spec = SPECS[model]
            blob, _ = _blob_and_reference(case)
            (tmp / f"{case}.bin").write_bytes(blob)
            exe = tmp / f"timer_{model}"
            if not exe.exists():
                srcs = [str(tmp / "timer.c"), str(RUNTIME_C), *[str(o) for o in objects[(model, "linux64")]]]
                subprocess.run(["gcc", "-O2", *srcs, "-o", str(exe), "-lm"], check=True)
            dirs = {"hosted": extract(fmus[model], tmp / case), "native": extract(native[model], tmp / f"n_{case}")}
            yvr = spec.vr(OUTPUT[model])
            amps = [str(x) for _, x in inputs] + ["0"] * (3 - len(inputs))
            fmu_args = case_args(case)
            us: dict[str, list[float]] = {"object": [], "hosted": [], "native": []}
            init_ms: dict[str, list[float]] = {"hosted": [], "native": []}
            sums: dict[str, set[str]] = {"hosted": set(), "native": set()}
            for _ in range(a.rounds):
                r = subprocess.run(
                    [str(exe), str(tmp / f"{case}.bin"), str(a.steps), str(yvr), *amps],
                    capture_output=True, text=True, check=True,
                )  # fmt: skip
                us["object"].append(float(r.stdout.split()[0]))
                for kind, d in dirs.items():
                    so = d / "binaries" / "linux64" / f"{model}.so"
                    step_us, total, init = time_fmu(host, so, (d / "resources").as_uri(), guid(d), a.steps, fmu_args)
                    us[kind].append(step_us)
                    init_ms[kind].append(init)
                    sums[kind].add(total)
            rows[case] = {
                **{f"{k}_us": statistics.median(v) for k, v in us.items()},
                **{f"{k}_init_ms": statistics.median(v) for k, v in init_ms.items()},
                "same_outputs": sums["hosted"] == sums["native"] and len(sums["native"]) == 1,
                "rounds_us": us,
                "rounds_init_ms": init_ms,
            }
            print(
                f"{case:10s} us per set+step+get: object {rows[case]['object_us']:.3f}, native FMU "
                f"{rows[case]['native_us']:.3f}, Python-hosted FMU {rows[case]['hosted_us']:.3f}; instantiate+init ms: "
                f"native {rows[case]['native_init_ms']:.3f}, Python-hosted {rows[case]['hosted_init_ms']:.1f}; "
                f"same outputs {rows[case]['same_outputs']}"
            )
    load = Path("/proc/loadavg").read_text().split()[:3]
    out = {
        "steps": a.steps, "rounds": a.rounds, "h": 1e-3, "load": load, "object_bytes": sizes,
        "fmu_bytes": fmu_bytes, "cases": rows,
    }  # fmt: skip
    print(json.dumps(out["object_bytes"]), json.dumps(fmu_bytes), "load", load)
    res = REPO / "benchmarks" / "results"
    res.mkdir(exist_ok=True)
    (res / "bench_native_step.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
