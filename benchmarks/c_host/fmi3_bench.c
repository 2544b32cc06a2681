/*
 * The per-doStep cost of an FMI 3.0 co-simulation FMU in a pure C host: the FMI 3.0 twin of
 * tests/c_host/fmu_host.c's "bench" mode (same steps, same counts, same output lines), so
 * benchmarks/bench_fmi3_step.py compares fmi2DoStep and fmi3DoStep of the same model in one run.
 * Build: gcc -O2 -I<fmpy/c-code> fmi3_bench.c -o fmi3_bench -ldl
 *
 *   fmi3_bench N DIR TOKEN UVR YVR [r:VR=VAL]...   us per fmi3DoStep, and per (SetFloat64, DoStep, GetFloat64)
 */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi3Functions.h"

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static void logger(fmi3InstanceEnvironment env, fmi3Status st, fmi3String cat, fmi3String msg) {
    (void)env;
    if (st > fmi3Warning) fprintf(stderr, "[%d|%s] %s\n", st, cat, msg);
}

#define LOAD(T, name)                                                             \
    T *name = (T *)dlsym(h, #name);                                               \
    if (!name) {                                                                  \
        fprintf(stderr, "missing %s\n", #name);                                   \
        return 2;                                                                 \
    }

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: fmi3_bench N DIR TOKEN UVR YVR [r:VR=VAL]...\n");
        return 2;
    }
    long n = atol(argv[1]);
    const char *dir = argv[2], *token = argv[3];
    fmi3ValueReference u = (fmi3ValueReference)atoi(argv[4]), y = (fmi3ValueReference)atoi(argv[5]);
    /* the model identifier is the folder's name (as fmu_host.c assumes) */
    const char *base = strrchr(dir, '/') ? strrchr(dir, '/') + 1 : dir;
    char lib[4096], res[4096];
    snprintf(lib, sizeof lib, "%s/binaries/x86_64-linux/%s.so", dir, base);
    snprintf(res, sizeof res, "%s/resources/", dir);
    void *h = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        fprintf(stderr, "%s\n", dlerror());
        return 2;
    }
    LOAD(fmi3InstantiateCoSimulationTYPE, fmi3InstantiateCoSimulation)
    LOAD(fmi3EnterInitializationModeTYPE, fmi3EnterInitializationMode)
    LOAD(fmi3ExitInitializationModeTYPE, fmi3ExitInitializationMode)
    LOAD(fmi3SetFloat64TYPE, fmi3SetFloat64)
    LOAD(fmi3GetFloat64TYPE, fmi3GetFloat64)
    LOAD(fmi3DoStepTYPE, fmi3DoStep)
    LOAD(fmi3TerminateTYPE, fmi3Terminate)
    LOAD(fmi3FreeInstanceTYPE, fmi3FreeInstance)
    fmi3Instance c = fmi3InstantiateCoSimulation("bench", token, res, fmi3False, fmi3False, fmi3False, fmi3False, NULL,
                                                 0, NULL, logger, NULL);
    if (!c) return 3;
    fmi3EnterInitializationMode(c, fmi3False, 0, 0, fmi3False, 0);
    for (int i = 6; i < argc; i++) { /* parameters r:VR=VAL */
        fmi3ValueReference pvr;
        double pv;
        if (sscanf(argv[i], "r:%u=%lf", &pvr, &pv) == 2) fmi3SetFloat64(c, &pvr, 1, &pv, 1);
    }
    fmi3ExitInitializationMode(c);
    double step = 1e-3, t = 0, yv = 0, sum = 0, last = 0;
    fmi3Boolean ev, term, early;
    for (long k = 0; k < 1000; k++, t += step) fmi3DoStep(c, t, step, fmi3True, &ev, &term, &early, &last); /* warm up */
    double t0 = now();
    for (long k = 0; k < n; k++) {
        fmi3DoStep(c, t, step, fmi3True, &ev, &term, &early, &last);
        t += step;
    }
    double t1 = now();
    for (long k = 0; k < n; k++) {
        double uv = (double)k;
        fmi3SetFloat64(c, &u, 1, &uv, 1);
        fmi3DoStep(c, t, step, fmi3True, &ev, &term, &early, &last);
        fmi3GetFloat64(c, &y, 1, &yv, 1);
        sum += yv;
        t += step;
    }
    double t2 = now();
    printf("us_per_doStep %.4f\nus_per_set_doStep_get %.4f\ncheck %.17g\n", 1e6 * (t1 - t0) / n, 1e6 * (t2 - t1) / n,
           sum);
    fmi3Terminate(c);
    fmi3FreeInstance(c);
    return 0;
}
