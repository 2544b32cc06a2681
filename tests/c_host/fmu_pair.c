/*
 * Two FMUs coupled in a pure C host (no Python in this process), used by
 * tests/test_fmu_standalone.py. After the run it prints every file mapped into the process
 * (/proc/self/maps), so a test can check where libpython and the extension modules came from.
 * Build: gcc -O2 -I<fmpy/c-code> fmu_pair.c -o fmu_pair -ldl
 *
 *   fmu_pair STOP STEP DIR1 GUID1 DIR2 GUID2 ARG...
 *     ARG = r1:VR=VAL | i1:VR=VAL | r2:VR=VAL | i2:VR=VAL   start values of FMU 1 / FMU 2
 *         | c12:VR1=VR2    output VR1 of FMU 1 -> input VR2 of FMU 2
 *         | c21:VR2=VR1    output VR2 of FMU 2 -> input VR1 of FMU 1
 *         | o1:VR          output of FMU 1 printed per step
 *   Gauss-Seidel coupling: FMU 1 steps with FMU 2's last outputs, FMU 2 with FMU 1's new ones.
 *   Prints "row t o1..." per communication point, then "map PATH" per mapped file, then
 *   "locale NAME": this process's LC_CTYPE locale (it never sets one itself).
 *   The FMUs are instantiated with logging on; FMU_HOST_VERBOSE=1 prints the log to stderr.
 */
#include <dlfcn.h>
#include <locale.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat, fmi2String msg, ...) {
    char buf[16384];
    va_list ap;
    va_start(ap, msg);
    vsnprintf(buf, sizeof buf, msg, ap);
    va_end(ap);
    if (getenv("FMU_HOST_VERBOSE") || st > fmi2Warning) fprintf(stderr, "[%s|%d|%s] %s\n", name, st, cat, buf);
}
static fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

typedef struct {
    void *h;
    fmi2Component c;
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2DoStepTYPE *do_step;
} Fmu;

static void *sym(void *h, const char *n) {
    void *p = dlsym(h, n);
    if (!p) {
        fprintf(stderr, "missing %s\n", n);
        exit(2);
    }
    return p;
}

static void die(const char *what) {
    fprintf(stderr, "fmu_pair: %s failed\n", what);
    exit(3);
}

static Fmu load(const char *dir, const char *guid, const char *name) {
    Fmu f;
    char so[4096], uri[4200];
    const char *id = strrchr(dir, '/');
    id = id ? id + 1 : dir;
    snprintf(so, sizeof so, "%s/binaries/linux64/%s.so", dir, id);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    f.h = dlopen(so, RTLD_NOW | RTLD_LOCAL);
    if (!f.h) {
        fprintf(stderr, "dlopen %s: %s\n", so, dlerror());
        exit(2);
    }
    fmi2InstantiateTYPE *inst = (fmi2InstantiateTYPE *)sym(f.h, "fmi2Instantiate");
    f.set_real = (fmi2SetRealTYPE *)sym(f.h, "fmi2SetReal");
    f.get_real = (fmi2GetRealTYPE *)sym(f.h, "fmi2GetReal");
    f.set_integer = (fmi2SetIntegerTYPE *)sym(f.h, "fmi2SetInteger");
    f.do_step = (fmi2DoStepTYPE *)sym(f.h, "fmi2DoStep");
    f.c = inst(name, fmi2CoSimulation, guid, uri, &callbacks, fmi2False, fmi2True);
    if (!f.c) die("fmi2Instantiate");
    return f;
}

#define MAXC 16
int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: fmu_pair STOP STEP DIR1 GUID1 DIR2 GUID2 ARG...\n");
        return 2;
    }
    double stop = atof(argv[1]), h = atof(argv[2]);
    Fmu f[2] = {load(argv[3], argv[4], "one"), load(argv[5], argv[6], "two")};
    unsigned cfrom[2][MAXC], cto[2][MAXC], outs[MAXC];
    int nc[2] = {0, 0}, no = 0;
    for (int k = 0; k < 2; k++) {
        fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)sym(f[k].h, "fmi2SetupExperiment");
        if (setup(f[k].c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK) die("fmi2SetupExperiment");
        fmi2EnterInitializationModeTYPE *enter =
            (fmi2EnterInitializationModeTYPE *)sym(f[k].h, "fmi2EnterInitializationMode");
        if (enter(f[k].c) != fmi2OK) die("fmi2EnterInitializationMode");
    }
    for (int a = 7; a < argc; a++) {
        unsigned vr, vr2;
        double v;
        int k = -1;
        if (sscanf(argv[a], "r1:%u=%lf", &vr, &v) == 2) k = 0;
        else if (sscanf(argv[a], "r2:%u=%lf", &vr, &v) == 2) k = 1;
        if (k >= 0) {
            if (f[k].set_real(f[k].c, &vr, 1, &v) != fmi2OK) die("fmi2SetReal");
            continue;
        }
        int iv;
        if (sscanf(argv[a], "i1:%u=%d", &vr, &iv) == 2) k = 0;
        else if (sscanf(argv[a], "i2:%u=%d", &vr, &iv) == 2) k = 1;
        if (k >= 0) {
            if (f[k].set_integer(f[k].c, &vr, 1, &iv) != fmi2OK) die("fmi2SetInteger");
            continue;
        }
        if (sscanf(argv[a], "c12:%u=%u", &vr, &vr2) == 2 && nc[0] < MAXC) {
            cfrom[0][nc[0]] = vr, cto[0][nc[0]++] = vr2;
        } else if (sscanf(argv[a], "c21:%u=%u", &vr, &vr2) == 2 && nc[1] < MAXC) {
            cfrom[1][nc[1]] = vr, cto[1][nc[1]++] = vr2;
        } else if (sscanf(argv[a], "o1:%u", &vr) == 1 && no < MAXC) {
            outs[no++] = vr;
        } else {
            fprintf(stderr, "bad argument %s\n", argv[a]);
            return 2;
        }
    }
    for (int k = 0; k < 2; k++) {
        fmi2ExitInitializationModeTYPE *ex = (fmi2ExitInitializationModeTYPE *)sym(f[k].h, "fmi2ExitInitializationMode");
        if (ex(f[k].c) != fmi2OK) die("fmi2ExitInitializationMode");
    }
    /* transfer: from FMU k's outputs to the other's inputs */
#define TRANSFER(k)                                                                                   \
    for (int i = 0; i < nc[k]; i++) {                                                                 \
        double val;                                                                                   \
        if (f[k].get_real(f[k].c, &cfrom[k][i], 1, &val) != fmi2OK) die("fmi2GetReal");               \
        if (f[1 - k].set_real(f[1 - k].c, &cto[k][i], 1, &val) != fmi2OK) die("fmi2SetReal (input)"); \
    }
    TRANSFER(0);
    TRANSFER(1);
    long n = (long)(stop / h + 0.5);
    for (long s = 0; s <= n; s++) {
        double t = s * h, o[MAXC];
        if (no && f[0].get_real(f[0].c, outs, (size_t)no, o) != fmi2OK) die("fmi2GetReal (outputs)");
        printf("row %.17g", t);
        for (int i = 0; i < no; i++) printf(" %.17g", o[i]);
        printf("\n");
        if (s == n) break;
        if (f[0].do_step(f[0].c, t, h, fmi2True) != fmi2OK) die("fmi2DoStep (FMU 1)");
        TRANSFER(0);
        if (f[1].do_step(f[1].c, t, h, fmi2True) != fmi2OK) die("fmi2DoStep (FMU 2)");
        TRANSFER(1);
    }
    FILE *m = fopen("/proc/self/maps", "r");
    char line[8192];
    while (m && fgets(line, sizeof line, m)) {
        char *p = strchr(line, '/');
        if (p) printf("map %s", p);
    }
    if (m) fclose(m);
    printf("locale %s\n", setlocale(LC_CTYPE, NULL));
    for (int k = 0; k < 2; k++) {
        ((fmi2TerminateTYPE *)sym(f[k].h, "fmi2Terminate"))(f[k].c);
        ((fmi2FreeInstanceTYPE *)sym(f[k].h, "fmi2FreeInstance"))(f[k].c);
    }
    return 0;
}
