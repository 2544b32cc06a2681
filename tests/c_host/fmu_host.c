/*
 * A minimal FMI 2.0 co-simulation host in pure C, used by tests/test_fmu_c_host.py and the
 * benchmark. No Python in this process and no LD_PRELOAD: the FMU binary is dlopened with
 * RTLD_LOCAL and links only -ldl. Build: gcc -O2 -I<fmpy/c-code> fmu_host.c -o fmu_host -ldl
 *
 *   fmu_host run STOP STEP SPEC [-- SPEC ...]     lockstep run of several instances, prints
 *                                                 "t out..." rows (%.17g) for all instances
 *      SPEC = DIR GUID NAME [r:VR=VAL] [i:VR=VAL] [in:VR=VAL] [o:VR] ...
 *   fmu_host loop N DIR GUID                      instantiate/init/step/free N times, print RSS
 *   fmu_host bench N DIR GUID UVR YVR [r:VR=VAL]  us per (SetReal, DoStep, GetReal)
 *   fmu_host errors DIR GUID                      wrong call sequences and an injected exception
 *
 * How "run" ends (FMU_HOST_EXIT; the teardown check of tests/test_fmu_teardown.py): "free" (default:
 * fmi2Terminate + fmi2FreeInstance, then return from main), "nofree" (exit with the instances alive,
 * as a host that crashes or forgets would), "dlclose" (free, then dlclose every FMU binary), "exit"
 * (free, then exit() from inside a function, atexit handlers running with the libraries loaded).
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fmi2Functions.h"

typedef struct {
    void *h;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealTYPE *set_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2SetIntegerTYPE *set_integer;
    fmi2DoStepTYPE *do_step;
} Api;

static int g_log_count = 0;
static int g_traceback_seen = 0;
static int g_range_seen = 0;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat, fmi2String msg, ...) {
    char buf[16384];
    va_list ap;
    va_start(ap, msg);
    vsnprintf(buf, sizeof buf, msg, ap);
    va_end(ap);
    g_log_count++;
    if (strstr(buf, "Traceback (most recent call last)")) g_traceback_seen = 1;
    if (strstr(buf, "is out of range")) g_range_seen = 1;
    if (getenv("FMU_HOST_VERBOSE")) fprintf(stderr, "[%s|%d|%s] %s\n", name, st, cat, buf);
}
static fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

static void *sym(void *h, const char *n) {
    void *p = dlsym(h, n);
    if (!p) {
        fprintf(stderr, "missing %s\n", n);
        exit(2);
    }
    return p;
}

static Api load(const char *dir) {
    Api a;
    char path[4096];
    const char *id = strrchr(dir, '/');
    id = id ? id + 1 : dir;
    /* the FMU directory is named after the model identifier: DIR/binaries/linux64/ID.so */
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    a.h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!a.h) {
        fprintf(stderr, "dlopen %s: %s\n", path, dlerror());
        exit(2);
    }
    a.instantiate = sym(a.h, "fmi2Instantiate");
    a.free_instance = sym(a.h, "fmi2FreeInstance");
    a.setup = sym(a.h, "fmi2SetupExperiment");
    a.enter = sym(a.h, "fmi2EnterInitializationMode");
    a.exit_init = sym(a.h, "fmi2ExitInitializationMode");
    a.terminate = sym(a.h, "fmi2Terminate");
    a.reset = sym(a.h, "fmi2Reset");
    a.get_real = sym(a.h, "fmi2GetReal");
    a.set_real = sym(a.h, "fmi2SetReal");
    a.get_integer = sym(a.h, "fmi2GetInteger");
    a.set_integer = sym(a.h, "fmi2SetInteger");
    a.do_step = sym(a.h, "fmi2DoStep");
    return a;
}

static void uri(const char *dir, char *out, size_t n) { snprintf(out, n, "file://%s/resources", dir); }

#define MAXO 16
typedef struct {
    Api a;
    fmi2Component c;
    int nout;
    fmi2ValueReference out[MAXO];
    int nin;
    fmi2ValueReference in[MAXO];
    double inval[MAXO];
} Inst;

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static long rss_kb(void) {
    long pages = 0, res = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &res) != 2) res = 0;
        fclose(f);
    }
    return res * (sysconf(_SC_PAGESIZE) / 1024);
}

static int run(int argc, char **argv) {
    double stop = atof(argv[2]), step = atof(argv[3]);
    Inst inst[8];
    int ni = 0, i = 4;
    char res[4096];
    while (i < argc && ni < 8) {
        Inst *s = &inst[ni];
        memset(s, 0, sizeof *s);
        const char *dir = argv[i], *guid = argv[i + 1], *name = argv[i + 2];
        i += 3;
        s->a = load(dir);
        uri(dir, res, sizeof res);
        s->c = s->a.instantiate(name, fmi2CoSimulation, guid, res, &callbacks, fmi2False, fmi2False);
        if (!s->c) {
            fprintf(stderr, "instantiate %s failed\n", name);
            return 3;
        }
        if (s->a.setup(s->c, fmi2False, 0.0, 0.0, fmi2True, stop) != fmi2OK) return 4;
        for (; i < argc && strcmp(argv[i], "--"); i++) {
            fmi2ValueReference vr;
            double v;
            int iv;
            if (sscanf(argv[i], "r:%u=%lf", &vr, &v) == 2) s->a.set_real(s->c, &vr, 1, &v);
            else if (sscanf(argv[i], "i:%u=%d", &vr, &iv) == 2) s->a.set_integer(s->c, &vr, 1, &iv);
            else if (sscanf(argv[i], "in:%u=%lf", &vr, &v) == 2) {
                s->in[s->nin] = vr;
                s->inval[s->nin++] = v;
                s->a.set_real(s->c, &vr, 1, &v);
            } else if (sscanf(argv[i], "o:%u", &vr) == 1) s->out[s->nout++] = vr;
        }
        if (i < argc) i++; /* skip "--" */
        if (s->a.enter(s->c) != fmi2OK || s->a.exit_init(s->c) != fmi2OK) return 5;
        ni++;
    }
    long n = (long)(stop / step + 0.5);
    for (long k = 0; k <= n; k++) {
        double t = k * step;
        printf("%.17g", t);
        for (int j = 0; j < ni; j++) {
            double v[MAXO];
            if (inst[j].a.get_real(inst[j].c, inst[j].out, inst[j].nout, v) != fmi2OK) return 6;
            for (int o = 0; o < inst[j].nout; o++) printf(" %.17g", v[o]);
        }
        printf("\n");
        if (k == n) break;
        for (int j = 0; j < ni; j++)
            if (inst[j].a.do_step(inst[j].c, t, (k + 1) * step - t, fmi2True) != fmi2OK) return 7; /* as fmpy */
    }
    const char *how = getenv("FMU_HOST_EXIT");
    fflush(stdout);
    if (how && !strcmp(how, "nofree")) exit(0); /* instances alive at process exit */
    for (int j = 0; j < ni; j++) {
        inst[j].a.terminate(inst[j].c);
        inst[j].a.free_instance(inst[j].c);
    }
    if (how && !strcmp(how, "dlclose"))
        for (int j = 0; j < ni; j++) dlclose(inst[j].a.h);
    if (how && !strcmp(how, "exit")) exit(0);
    return 0;
}

static int loop(int argc, char **argv) {
    int n = atoi(argv[2]);
    const char *dir = argv[3], *guid = argv[4];
    Api a = load(dir);
    char res[4096];
    uri(dir, res, sizeof res);
    long rss5 = 0;
    for (int k = 0; k < n; k++) {
        fmi2Component c = a.instantiate("loop", fmi2CoSimulation, guid, res, &callbacks, fmi2False, fmi2False);
        if (!c) return 3;
        a.setup(c, fmi2False, 0, 0, fmi2False, 0);
        a.enter(c);
        a.exit_init(c);
        for (int s = 0; s < 10; s++)
            if (a.do_step(c, s * 1e-3, 1e-3, fmi2True) != fmi2OK) return 4;
        a.terminate(c);
        a.free_instance(c);
        if (k == 4) rss5 = rss_kb();
    }
    printf("rss_after_5_kb %ld\nrss_after_%d_kb %ld\n", rss5, n, rss_kb());
    return 0;
}

static int bench(int argc, char **argv) {
    long n = atol(argv[2]);
    const char *dir = argv[3], *guid = argv[4];
    fmi2ValueReference u = (fmi2ValueReference)atoi(argv[5]), y = (fmi2ValueReference)atoi(argv[6]);
    Api a = load(dir);
    char res[4096];
    uri(dir, res, sizeof res);
    fmi2Component c = a.instantiate("bench", fmi2CoSimulation, guid, res, &callbacks, fmi2False, fmi2False);
    if (!c) return 3;
    a.setup(c, fmi2False, 0, 0, fmi2False, 0);
    a.enter(c);
    for (int i = 7; i < argc; i++) { /* parameters r:VR=VAL */
        fmi2ValueReference pvr;
        double pv;
        if (sscanf(argv[i], "r:%u=%lf", &pvr, &pv) == 2) a.set_real(c, &pvr, 1, &pv);
    }
    a.exit_init(c);
    double h = 1e-3, t = 0, yv = 0, sum = 0;
    for (long k = 0; k < 1000; k++, t += h) a.do_step(c, t, h, fmi2True); /* warm up */
    double t0 = now();
    for (long k = 0; k < n; k++) {
        a.do_step(c, t, h, fmi2True);
        t += h;
    }
    double t1 = now();
    for (long k = 0; k < n; k++) {
        double uv = (double)k;
        a.set_real(c, &u, 1, &uv);
        a.do_step(c, t, h, fmi2True);
        a.get_real(c, &y, 1, &yv);
        sum += yv;
        t += h;
    }
    double t2 = now();
    printf("us_per_doStep %.4f\nus_per_set_doStep_get %.4f\ncheck %.17g\n", 1e6 * (t1 - t0) / n, 1e6 * (t2 - t1) / n, sum);
    a.terminate(c);
    a.free_instance(c);
    return 0;
}

#define EXPECT(name, cond) printf("CHECK %s %s\n", name, (cond) ? "ok" : "FAILED")

static int errors(int argc, char **argv) {
    const char *dir = argv[2], *guid = argv[3];
    Api a = load(dir);
    char res[4096];
    uri(dir, res, sizeof res);
    EXPECT("guid_mismatch_refused", a.instantiate("bad", fmi2CoSimulation, "{wrong}", res, &callbacks, 0, 0) == NULL);
    EXPECT("model_exchange_refused", a.instantiate("bad", fmi2ModelExchange, guid, res, &callbacks, 0, 0) == NULL);
    EXPECT("null_callbacks_refused", a.instantiate("bad", fmi2CoSimulation, guid, res, NULL, 0, 0) == NULL);
    fmi2Component c = a.instantiate("err", fmi2CoSimulation, guid, res, &callbacks, 0, 0);
    EXPECT("instantiate", c != NULL);
    if (!c) return 3;
    double v = 0;
    fmi2ValueReference vr0 = 0, vr_bad = 12345, vr_debug = 99;
    EXPECT("doStep_before_init", a.do_step(c, 0, 1e-3, 1) == fmi2Error);
    EXPECT("getReal_before_init", a.get_real(c, &vr0, 1, &v) == fmi2Error);
    EXPECT("exitInit_before_enter", a.exit_init(c) == fmi2Error);
    EXPECT("setReal_null_values", a.set_real(c, &vr0, 1, NULL) == fmi2Error);
    EXPECT("setReal_bad_vr", a.set_real(c, &vr_bad, 1, &v) == fmi2Error);
    /* ranges (TMDInerter: inerter vr 9 in 0 ... 2, atol vr 91 > 0) */
    fmi2ValueReference vr_inerter = 9, vr_atol = 91;
    int three = 3;
    double zero = 0.0;
    g_range_seen = 0;
    EXPECT("setInteger_out_of_range_refused", a.set_integer(c, &vr_inerter, 1, &three) == fmi2Error);
    EXPECT("range_message_logged", g_range_seen);
    g_range_seen = 0;
    EXPECT("setReal_atol_zero_refused", a.set_real(c, &vr_atol, 1, &zero) == fmi2Error);
    EXPECT("range_message_logged_atol", g_range_seen);
    EXPECT("setup", a.setup(c, 0, 0, 0, 0, 0) == fmi2OK);
    EXPECT("enter", a.enter(c) == fmi2OK);
    EXPECT("enter_twice", a.enter(c) == fmi2Error);
    EXPECT("exit", a.exit_init(c) == fmi2OK);
    double one = 1.0;
    EXPECT("set_fixed_parameter_after_init", a.set_real(c, &vr0, 1, &one) == fmi2Error);
    EXPECT("doStep_negative_h", a.do_step(c, 0, -1e-3, 1) == fmi2Error);
    EXPECT("doStep_wrong_time", a.do_step(c, 0.5, 1e-3, 1) == fmi2Error);
    EXPECT("doStep_ok", a.do_step(c, 0, 1e-3, 1) == fmi2OK);
    int on = 1;
    g_traceback_seen = 0;
    EXPECT("set_debug_raise", a.set_integer(c, &vr_debug, 1, &on) == fmi2OK);
    EXPECT("doStep_python_exception_is_error", a.do_step(c, 1e-3, 1e-3, 1) == fmi2Error);
    EXPECT("traceback_logged", g_traceback_seen);
    EXPECT("doStep_after_error_refused", a.do_step(c, 1e-3, 1e-3, 1) == fmi2Error);
    EXPECT("reset_after_error", a.reset(c) == fmi2OK);
    EXPECT("reinit", a.setup(c, 0, 0, 0, 0, 0) == fmi2OK && a.enter(c) == fmi2OK && a.exit_init(c) == fmi2OK);
    EXPECT("doStep_after_reset", a.do_step(c, 0, 1e-3, 1) == fmi2OK);
    /* an exception raised inside the compiled (native) step: fmi2Error with the traceback logged */
    int two = 2;
    g_traceback_seen = 0;
    EXPECT("set_debug_raise_native", a.set_integer(c, &vr_debug, 1, &two) == fmi2OK);
    EXPECT("doStep_native_exception_is_error", a.do_step(c, 1e-3, 1e-3, 1) == fmi2Error);
    EXPECT("native_traceback_logged", g_traceback_seen);
    EXPECT("reset_after_native_error", a.reset(c) == fmi2OK);
    EXPECT("reinit2", a.setup(c, 0, 0, 0, 0, 0) == fmi2OK && a.enter(c) == fmi2OK && a.exit_init(c) == fmi2OK);
    EXPECT("doStep_after_reset2", a.do_step(c, 0, 1e-3, 1) == fmi2OK);
    EXPECT("terminate", a.terminate(c) == fmi2OK);
    EXPECT("doStep_after_terminate", a.do_step(c, 1e-3, 1e-3, 1) == fmi2Error);
    a.free_instance(c);
    printf("survived\n");
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 2) return 1;
    if (!strcmp(argv[1], "run") && argc > 6) return run(argc, argv);
    if (!strcmp(argv[1], "loop") && argc > 4) return loop(argc, argv);
    if (!strcmp(argv[1], "bench") && argc > 6) return bench(argc, argv);
    if (!strcmp(argv[1], "errors") && argc > 3) return errors(argc, argv);
    fprintf(stderr, "usage: see the header of fmu_host.c\n");
    return 1;
}
