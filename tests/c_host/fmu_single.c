/*
 * One FMI 2.0 co-simulation FMU driven by a small C host (no Python, no FMI library): used by
 * tests/test_native_platforms.py to run the same FMU's binary of another platform (aarch64-linux under
 * qemu-aarch64) with the same source as its x86_64 one.
 * Build: CC -O2 -I<fmpy/c-code> fmu_single.c -o fmu_single -ldl
 *
 *   fmu_single BINARY RESOURCE_DIR GUID STOP STEP ARG...
 *     BINARY       the shared library (e.g. <fmu>/binaries/aarch64-linux/BaseOscillator.so)
 *     RESOURCE_DIR the extracted FMU's resources folder (handed over as a file: URI)
 *     ARG = r:VR=VAL   a Real start value   | o:VR  an output printed at the end
 *   Steps from 0 to STOP with communication step STEP (an integer number of steps), then prints
 *   "out VR VALUE" (%.17g) per output. Exit status: 0, 2 (usage / load), 3 (an FMI call failed).
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat, fmi2String msg, ...) {
    char buf[4096];
    va_list ap;
    va_start(ap, msg);
    vsnprintf(buf, sizeof buf, msg, ap);
    va_end(ap);
    if (st > fmi2Warning) fprintf(stderr, "[%s|%d|%s] %s\n", name, st, cat, buf);
}

static void *sym(void *h, const char *n) {
    void *p = dlsym(h, n);
    if (!p) {
        fprintf(stderr, "fmu_single: missing %s\n", n);
        exit(2);
    }
    return p;
}

static void check(int ok, const char *what) {
    if (!ok) {
        fprintf(stderr, "fmu_single: %s failed\n", what);
        exit(3);
    }
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: fmu_single BINARY RESOURCE_DIR GUID STOP STEP ARG...\n");
        return 2;
    }
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        fprintf(stderr, "fmu_single: %s\n", dlerror());
        return 2;
    }
    fmi2InstantiateTYPE *instantiate = sym(h, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = sym(h, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = sym(h, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init = sym(h, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = sym(h, "fmi2SetReal");
    fmi2GetRealTYPE *get_real = sym(h, "fmi2GetReal");
    fmi2DoStepTYPE *do_step = sym(h, "fmi2DoStep");
    fmi2TerminateTYPE *terminate = sym(h, "fmi2Terminate");
    fmi2FreeInstanceTYPE *free_instance = sym(h, "fmi2FreeInstance");
    static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    char uri[4200];
    snprintf(uri, sizeof uri, "file://%s", argv[2]);
    fmi2Component c = instantiate("single", fmi2CoSimulation, argv[3], uri, &cb, fmi2False, fmi2False);
    check(c != NULL, "fmi2Instantiate");
    double stop = atof(argv[4]), step = atof(argv[5]);
    unsigned outs[64];
    int nout = 0;
    for (int i = 6; i < argc; i++) {
        unsigned vr;
        double v;
        if (sscanf(argv[i], "r:%u=%lf", &vr, &v) == 2) {
            check(set_real(c, &vr, 1, &v) == fmi2OK, argv[i]);
        } else if (sscanf(argv[i], "o:%u", &vr) == 1 && nout < 64) {
            outs[nout++] = vr;
        } else {
            fprintf(stderr, "fmu_single: argument %s: not r:VR=VALUE or o:VR\n", argv[i]);
            return 2;
        }
    }
    check(setup(c, fmi2False, 0.0, 0.0, fmi2True, stop) == fmi2OK, "fmi2SetupExperiment");
    check(enter(c) == fmi2OK, "fmi2EnterInitializationMode");
    check(exit_init(c) == fmi2OK, "fmi2ExitInitializationMode");
    long n = (long)(stop / step + 0.5);
    for (long k = 0; k < n; k++) check(do_step(c, k * step, step, fmi2True) == fmi2OK, "fmi2DoStep");
    for (int j = 0; j < nout; j++) {
        double v;
        check(get_real(c, &outs[j], 1, &v) == fmi2OK, "fmi2GetReal");
        printf("out %u %.17g\n", outs[j], v);
    }
    check(terminate(c) == fmi2OK, "fmi2Terminate");
    free_instance(c);
    dlclose(h);
    return 0;
}
