/*
 * The FMI 2.0 co-simulation API: the state machine, GUID and argument checks on every call,
 * values (fmi2Get/Set* never enter Python: the buffers are shared with the slave), doStep,
 * directional derivatives. A Python exception becomes fmi2Error with its traceback logged.
 *
 * Edges (all refused with fmi2Error and a message): non-finite times, tolerances and values;
 * step sizes that are not finite, not positive, longer than PYFMU_MAX_STEP, or below the
 * resolution of the time; a communication point off the FMU's time by more than a small fraction
 * of the step (the FMU then takes the host's time, so t = k h hosts never drift apart).
 */
#define _GNU_SOURCE
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyfmu.h"
/* PYFMU_MAX_STEP, PYFMU_TIME_SLACK (and pyfmu.h's PYFMU_NATIVE_*) come from pyfmu_contract.h, which
 * the build generates from pyfmu_wrapper/fmi/contract.py: the one declaration of the doStep contract. */

static void range_text(const Comp *c, fmi2ValueReference vr, char *out, size_t n);
static int in_range(const Comp *c, fmi2ValueReference vr, double v);

static pthread_mutex_t g_count_lock = PTHREAD_MUTEX_INITIALIZER;
static unsigned long g_counter = 0;

static void free_comp(Comp *c) {
    if (!c) return;
    if (c->id) free_states_of(c->id); /* FMU states the host left alive die with their instance */
    if (c->globals && py_usable()) { /* at process exit, after Py_Finalize began: the objects die with it */
        int g = gil_take();
        PyObject *unload = py.DictGetItemString(c->globals, "_unload");
        if (unload) {
            PyObject *r = py.CallFunction(unload, "s", c->modname);
            if (r) py.DecRef(r);
            else py.ErrClear();
        }
        PyObject **objs[] = {&c->m_setup, &c->m_enter, &c->m_exit, &c->m_update, &c->m_step, &c->m_reset,
                             &c->m_terminate, &c->m_get, &c->m_set, &c->m_dd, &c->m_restore, &c->slave, &c->b_reals,
                             &c->b_ints, &c->b_derivs, &c->b_scratch, &c->globals};
        for (size_t i = 0; i < sizeof objs / sizeof objs[0]; i++)
            if (*objs[i]) {
                py.DecRef(*objs[i]);
                *objs[i] = NULL;
            }
        GIL_DROP(g);
    }
    free(c->vtype);
    free(c->vcaus);
    free(c->vvar);
    if (c->vname)
        for (int i = 0; i < c->nvr; i++) free(c->vname[i]);
    free(c->vname);
    free(c->vmin);
    free(c->vlo);
    free(c->vmax);
    free(c->vexcl);
    free(c->instance_name);
    c->magic = 0;
    free(c);
}

/* ------------------------------------------------------------------------------------------ */
/* FMI 2.0 API                                                                                   */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String cats[]) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SetDebugLogging", M_ANY_BUT_FATAL);
    static const char *known[] = PYFMU_LOG_CATEGORIES; /* fmi/contract.py */
    if (n > 0) NULLARG("fmi2SetDebugLogging", cats);
    for (size_t i = 0; i < n; i++) {
        if (!cats[i] || !code_of(cats[i], known, PYFMU_N_LOG_CATEGORIES)) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetDebugLogging: unknown log category %s", cats[i] ? cats[i] : "NULL");
            return fmi2Error;
        }
    }
    c->logging_on = loggingOn;
    return fmi2OK;
}

/* Ask the slave for its native step (empty bytes: none). PYFMU_NATIVE=0 in the environment keeps
 * every step in Python (benchmarks compare both). Call with the GIL; 0 on a Python error. */
static int query_native(Comp *c) {
    c->native = NULL;
    const char *env = getenv("PYFMU_NATIVE");
    if (env && !strcmp(env, "0")) return 1;
    PyObject *m = py.GetAttrString(c->slave, "native");
    if (!m) {
        py.ErrClear(); /* a slave without a native step */
        return 1;
    }
    PyObject *r = py.CallFunction(m, NULL);
    py.DecRef(m);
    if (!r) return 0;
    char *buf = NULL;
    Py_ssize_t len = 0;
    if (py.BytesAsStringAndSize(r, &buf, &len) == 0 && len == 8 * (Py_ssize_t)sizeof(uint64_t)) {
        uint64_t a[8];
        memcpy(a, buf, sizeof a);
        c->m_restore = py.GetAttrString(c->slave, "native_restore");
        if (c->m_restore) {
            *(void **)&c->native = (void *)(uintptr_t)a[0];
            for (int i = 0; i < 7; i++) c->nat[i] = (void *)(uintptr_t)a[i + 1];
        }
    }
    py.ErrClear();
    py.DecRef(r);
    return 1;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    Comp tmp = {0};
    tmp.instance_name = (char *)(instanceName ? instanceName : "?");
    tmp.logger = functions ? functions->logger : NULL;
    tmp.env = functions ? functions->componentEnvironment : NULL;
    Comp *c = &tmp;
    if (!functions) return NULL;
    if (!instanceName || !instanceName[strspn(instanceName, " \t\r\n\v\f")]) { /* NULL, empty or blank */
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: missing instance name (NULL, empty or blank)");
        return NULL;
    }
    if (fmuType == fmi2ModelExchange && !me_model()) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && fmuType != fmi2ModelExchange) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: fmuType %d is neither co-simulation nor model "
               "exchange", (int)fmuType);
        return NULL;
    }
    if (!fmuGUID) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: GUID is NULL");
        return NULL;
    }
    char resdir[2048], err[2048] = "";
    if (fmuResourceLocation && !strncmp(fmuResourceLocation, "file:", 5)) uri_to_path(fmuResourceLocation, resdir, sizeof resdir);
    else resources_from_library(resdir, sizeof resdir);
    Config cfg;
    memset(&cfg, 0, sizeof cfg);
    if (!read_config(resdir, &cfg, err, sizeof err)) {
        resources_from_library(resdir, sizeof resdir); /* a bad URI: try next to the binary */
        if (!read_config(resdir, &cfg, err, sizeof err)) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: %s", err);
            return NULL;
        }
    }
    if (strcmp(cfg.guid, fmuGUID)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: GUID mismatch: expected %s but was %s", cfg.guid, fmuGUID);
        return NULL;
    }
    c = calloc(1, sizeof(Comp));
    *c = tmp;
    c->magic = COMP_MAGIC;
    c->me = fmuType == fmi2ModelExchange;
    c->fingerprint = fingerprint_of(cfg.guid);
    c->instance_name = strdup(instanceName);
    c->logging_on = loggingOn;
    c->state = S_INSTANTIATED;
    c->dirty = 1;
    if (!read_variables(c, resdir, err, sizeof err)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: %s", err);
        free_comp(c);
        return NULL;
    }
    if (!ensure_python(&cfg, resdir, err, sizeof err)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: %s", err);
        free_comp(c);
        return NULL;
    }
    pthread_mutex_lock(&g_count_lock);
    unsigned long id = ++g_counter;
    pthread_mutex_unlock(&g_count_lock);
    c->id = id;
    snprintf(c->modname, sizeof c->modname, "_pyfmu_%.60s_%lu_%lx", fmuGUID[0] == '{' ? "model" : "m", id,
             (unsigned long)(uintptr_t)c);
    for (char *p = c->modname; *p; p++)
        if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9'))) *p = '_';

    int g = gil_take();
    int ok = 0;
    c->globals = py.DictNew();
    if (c->globals && py.DictSetItemString(c->globals, "__builtins__", py.EvalGetBuiltins()) == 0) {
        PyObject *r = py.RunString(BOOTSTRAP, PY_FILE_INPUT, c->globals, c->globals);
        if (r) {
            py.DecRef(r);
            char model_file[2400];
            snprintf(model_file, sizeof model_file, "%s/%s", resdir, cfg.model[0] ? cfg.model : "model.py");
            PyObject *mod = py.CallFunction(py.DictGetItemString(c->globals, "_load"), "sssss", python_site_paths(),
                                            model_file, c->modname, cfg.requires, cfg.min_python);
            if (mod) {
                c->nscratch = 4 * (c->nvr + 2);
                c->b_reals = py.ByteArrayFromStringAndSize(NULL, (Py_ssize_t)(sizeof(double) * c->nvr));
                c->b_ints = py.ByteArrayFromStringAndSize(NULL, (Py_ssize_t)(sizeof(int32_t) * c->nvr));
                c->b_derivs = py.ByteArrayFromStringAndSize(NULL, (Py_ssize_t)(2 * sizeof(double) * c->nvr));
                c->b_scratch = py.ByteArrayFromStringAndSize(NULL, (Py_ssize_t)(sizeof(double) * c->nscratch));
                if (c->b_reals && c->b_ints && c->b_derivs && c->b_scratch) {
                    c->reals = (double *)py.ByteArrayAsString(c->b_reals);
                    c->ints = (int32_t *)py.ByteArrayAsString(c->b_ints);
                    c->derivs = (double *)py.ByteArrayAsString(c->b_derivs);
                    c->scratch = (double *)py.ByteArrayAsString(c->b_scratch);
                    memset(c->reals, 0, sizeof(double) * c->nvr);
                    memset(c->ints, 0, sizeof(int32_t) * c->nvr);
                    memset(c->derivs, 0, 2 * sizeof(double) * c->nvr);
                    memset(c->scratch, 0, sizeof(double) * c->nscratch);
                    PyObject *create = py.GetAttrString(mod, "create");
                    if (create) {
                        c->slave = py.CallFunction(create, "OOOOss", c->b_reals, c->b_ints, c->b_derivs, c->b_scratch,
                                                   c->instance_name, resdir);
                        py.DecRef(create);
                    }
                }
                py.DecRef(mod);
                if (c->slave) {
                    struct { PyObject **dst; const char *name; } m[] = {
                        {&c->m_setup, "setup_experiment"}, {&c->m_enter, "enter_initialization"},
                        {&c->m_exit, "exit_initialization"}, {&c->m_update, "update_outputs"},
                        {&c->m_step, "do_step"}, {&c->m_reset, "reset"}, {&c->m_terminate, "terminate"},
                        {&c->m_get, "get_state"}, {&c->m_set, "set_state"}, {&c->m_dd, "directional_derivative"}};
                    ok = 1;
                    for (size_t i = 0; i < sizeof m / sizeof m[0]; i++) {
                        *m[i].dst = py.GetAttrString(c->slave, m[i].name);
                        if (!*m[i].dst) ok = 0;
                    }
                    if (ok) ok = query_native(c);
                }
            }
        }
    }
    if (!ok) report_py_exception(c, "fmi2Instantiate");
    GIL_DROP(g);
    if (!ok) {
        logmsg(c, fmi2Fatal, "logStatusError", "fmi2Instantiate: could not create the Python slave");
        free_comp(c);
        return NULL;
    }
    logmsg(c, fmi2OK, "logAll", "fmi2Instantiate: module %s, resources %s, %s", c->modname, resdir, python_origin());
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    if (!c) return;
    free_comp(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SetupExperiment", S_INSTANTIATED);
    NEED_PY("fmi2SetupExperiment");
    if (!isfinite(startTime)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetupExperiment: startTime must be finite but was %g", startTime);
        return fmi2Error;
    }
    if (toleranceDefined && !(isfinite(tolerance) && tolerance > 0.0)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetupExperiment: tolerance must be finite and > 0 but was %g", tolerance);
        return fmi2Error;
    }
    if (toleranceDefined) { /* the tolerance becomes rtol: within its range */
        for (int vr = 0; vr < c->nvr; vr++)
            if (c->vname[vr] && !strcmp(c->vname[vr], "rtol") && c->vtype[vr] == 'R' && !in_range(c, vr, tolerance)) {
                char val[40], range[120];
                fmt_double(tolerance, val, sizeof val);
                range_text(c, vr, range, sizeof range);
                logmsg(c, fmi2Error, "logStatusError",
                       "fmi2SetupExperiment: tolerance = %s is out of range: it sets rtol, which must be %s (see %s)", val,
                       range, PYFMU_DOC);
                return fmi2Error;
            }
    }
    if (stopTimeDefined && !isfinite(stopTime)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetupExperiment: stopTime must be finite but was %g", stopTime);
        return fmi2Error;
    }
    if (stopTimeDefined && stopTime < startTime) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetupExperiment: stopTime %.16g < startTime %.16g", stopTime, startTime);
        return fmi2Error;
    }
    c->time = startTime;
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2SetupExperiment",
                             py.CallFunction(c->m_setup, "idfid", toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime));
    GIL_DROP(g);
    return s;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2EnterInitializationMode", S_INSTANTIATED);
    NEED_PY("fmi2EnterInitializationMode");
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2EnterInitializationMode", py.CallFunction(c->m_enter, NULL));
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->state = S_INIT;
        c->dirty = 1;
    }
    return s;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2ExitInitializationMode", S_INIT);
    NEED_PY("fmi2ExitInitializationMode");
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2ExitInitializationMode", py.CallFunction(c->m_exit, NULL));
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->state = c->me ? S_EVENT : S_STEP_COMPLETE; /* Model Exchange: event mode (FMI 2.0 and 3.0) */
        c->dirty = 0;
    } else c->state = S_ERROR;
    return s;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2Terminate", S_STEP_COMPLETE | S_STEP_FAILED | M_ME);
    NEED_PY("fmi2Terminate");
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2Terminate", py.CallFunction(c->m_terminate, NULL));
    GIL_DROP(g);
    c->state = S_TERMINATED;
    return s;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2Reset", M_ANY_BUT_FATAL);
    NEED_PY("fmi2Reset");
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2Reset", py.CallFunction(c->m_reset, NULL));
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->state = S_INSTANTIATED;
        c->dirty = 1;
        c->time = 0.0;
    }
    return s;
}

/* Recompute outputs if inputs/parameters changed; call before reading outputs. */
fmi2Status refresh(Comp *c, const char *f) {
    if (!c->dirty || !(c->state & (S_INIT | S_STEP_COMPLETE | M_ME))) return fmi2OK;
    NEED_PY(f);
    int g = gil_take();
    fmi2Status s = py_status(c, f, py.CallFunction(c->m_update, "i", c->state == S_INIT));
    GIL_DROP(g);
    if (s <= fmi2Warning) c->dirty = 0;
    return s;
}

int check_vr(Comp *c, const char *f, fmi2ValueReference vr, char type) {
    if (vr >= (fmi2ValueReference)c->nvr || c->vtype[vr] != type) {
        logmsg(c, fmi2Error, "logStatusError", "%s: invalid value reference %u", f, vr);
        return 0;
    }
    return 1;
}

int check_settable(Comp *c, const char *f, fmi2ValueReference vr) {
    int ca = c->vcaus[vr], va = c->vvar[vr];
    int ok = 0;
    if (ca == C_INPUT) ok = 1;
    else if (ca == C_PARAMETER && va == V_TUNABLE) ok = 1;
    else if (ca == C_PARAMETER && va == V_FIXED) ok = c->state & (S_INSTANTIATED | S_INIT);
    if (!ok) logmsg(c, fmi2Error, "logStatusError", "%s: variable %u cannot be set in state %s", f, vr, state_name(c->state));
    return ok;
}

/* The range of a variable as people read it: "> 0", ">= 0 and <= 2", "any". */
static void range_text(const Comp *c, fmi2ValueReference vr, char *out, size_t n) {
    char lo[40], hi[40];
    fmt_double(c->vmin[vr], lo, sizeof lo);
    fmt_double(c->vmax[vr], hi, sizeof hi);
    int has_lo = isfinite(c->vmin[vr]), has_hi = isfinite(c->vmax[vr]);
    if (has_lo && has_hi) snprintf(out, n, "%s %s and <= %s", c->vexcl[vr] ? ">" : ">=", lo, hi);
    else if (has_lo) snprintf(out, n, "%s %s", c->vexcl[vr] ? ">" : ">=", lo);
    else if (has_hi) snprintf(out, n, "<= %s", hi);
    else snprintf(out, n, "any finite value");
    if (c->vlo[vr] != c->vmin[vr]) { /* "> 0": declared (and enforced) as the smallest normal double */
        char dlo[40];
        size_t k = strlen(out);
        fmt_double(c->vlo[vr], dlo, sizeof dlo);
        snprintf(out + k, n - k, " (declared min %s)", dlo);
    }
}

/* Whether v lies in the range of vr declared in modelDescription.xml (exactly that: an exclusive
 * minimum m is declared, and enforced, as the next double above m, the smallest normal for m = 0). */
static int in_range(const Comp *c, fmi2ValueReference vr, double v) {
    if (c->vexcl[vr] ? !(v > c->vmin[vr]) : !(v >= c->vmin[vr])) return 0;
    return v >= c->vlo[vr] && v <= c->vmax[vr];
}

/* Real values must be finite and Real/Integer values within the variable's range (declared as
 * min/max in modelDescription.xml); Booleans 0 or 1. */
int check_value(Comp *c, const char *f, fmi2ValueReference vr, double v, char type) {
    if (type == 'R' && !isfinite(v)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: value of variable %u (%s) must be finite but was %g", f, vr,
               var_name(c, vr), v);
        return 0;
    }
    if (type == 'B' && v != 0.0 && v != 1.0) {
        logmsg(c, fmi2Error, "logStatusError", "%s: value of Boolean variable %u (%s) must be 0 or 1 but was %g", f, vr,
               var_name(c, vr), v);
        return 0;
    }
    if (type != 'B' && !in_range(c, vr, v)) {
        char val[40], range[120];
        fmt_double(v, val, sizeof val);
        range_text(c, vr, range, sizeof range);
        logmsg(c, fmi2Error, "logStatusError",
               "%s: %s = %s is out of range: %s must be %s (value reference %u; the ranges of all variables: %s)", f,
               var_name(c, vr), val, var_name(c, vr), range, vr, PYFMU_DOC);
        return 0;
    }
    return 1;
}

/* Never answer OK with a value that is not finite: a model driven past the range of doubles (huge
 * parameters or inputs that are each within their declared range) overflows; that is an error naming
 * the variable, not a number for the host to propagate. */
int check_finite(Comp *c, const char *f, fmi2ValueReference vr) {
    if (isfinite(c->reals[vr])) return 1;
    logmsg(c, fmi2Error, "logStatusError",
           "%s: %s (value reference %u) is %g: the model overflowed (parameters, start values or inputs "
           "too large for each other?); nothing returned", f, var_name(c, vr), vr, c->reals[vr]);
    return 0;
}

static int all_finite(Comp *c, const char *f, const fmi2ValueReference vr[], size_t nvr) {
    for (size_t i = 0; i < nvr; i++)
        if (!check_finite(c, f, vr[i])) return 0;
    return 1;
}

/* Where values can be read: FMI 2.0 from initialisation mode on; FMI 3.0 also in Instantiated
 * (the start values, or what the host set), as FMI 3.0's state machine allows. */
int get_mask(const Comp *c) { return M_GET | ((c && c->magic == COMP_MAGIC && c->fmi3) ? S_INSTANTIATED : 0); }

#define GETTER(NAME, CTYPE, TCODE, BUF, CONV)                                                    \
    fmi2Status NAME(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, CTYPE value[]) { \
        Comp *c = (Comp *)comp;                                                                  \
        CHECK(#NAME, get_mask(c));                                                               \
        if (nvr == 0) return fmi2OK;                                                             \
        NULLARG(#NAME, vr);                                                                      \
        NULLARG(#NAME, value);                                                                   \
        for (size_t i = 0; i < nvr; i++)                                                         \
            if (!check_vr(c, #NAME, vr[i], TCODE)) return fmi2Error;                             \
        fmi2Status s = refresh(c, #NAME);                                                        \
        if (s > fmi2Warning) return s;                                                           \
        if (TCODE == 'R' && !all_finite(c, #NAME, vr, nvr)) return fmi2Error;                   \
        for (size_t i = 0; i < nvr; i++) value[i] = CONV(c->BUF[vr[i]]);                         \
        return s;                                                                                \
    }
#define ID(x) (x)
#define TOBOOL(x) ((x) ? fmi2True : fmi2False)
GETTER(fmi2GetReal, fmi2Real, 'R', reals, ID)
GETTER(fmi2GetInteger, fmi2Integer, 'I', ints, ID)
GETTER(fmi2GetBoolean, fmi2Boolean, 'B', ints, TOBOOL)

#define SETTER(NAME, CTYPE, TCODE, BUF, EXTRA)                                                           \
    fmi2Status NAME(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const CTYPE value[]) { \
        Comp *c = (Comp *)comp;                                                                          \
        CHECK(#NAME, M_SET);                                                                             \
        if (nvr == 0) return fmi2OK;                                                                     \
        NULLARG(#NAME, vr);                                                                              \
        NULLARG(#NAME, value);                                                                           \
        for (size_t i = 0; i < nvr; i++)                                                                 \
            if (!check_vr(c, #NAME, vr[i], TCODE) || !check_settable(c, #NAME, vr[i]) ||                 \
                !check_value(c, #NAME, vr[i], (double)value[i], TCODE)) return fmi2Error;                \
        for (size_t i = 0; i < nvr; i++) {                                                               \
            c->BUF[vr[i]] = value[i];                                                                    \
            EXTRA                                                                                        \
        }                                                                                                \
        c->dirty = 1;                                                                                    \
        return fmi2OK;                                                                                   \
    }
SETTER(fmi2SetReal, fmi2Real, 'R', reals, if (c->vcaus[vr[i]] == C_INPUT) { c->derivs[2 * vr[i]] = 0; c->derivs[2 * vr[i] + 1] = 0; })
SETTER(fmi2SetInteger, fmi2Integer, 'I', ints, )
SETTER(fmi2SetBoolean, fmi2Boolean, 'B', ints, )

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Comp *c = (Comp *)comp;
    (void)value;
    CHECK("fmi2GetString", M_GET);
    if (nvr == 0) return fmi2OK;
    NULLARG("fmi2GetString", vr);
    logmsg(c, fmi2Error, "logStatusError", "fmi2GetString: invalid value reference %u (no String variables)", vr[0]);
    return fmi2Error;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Comp *c = (Comp *)comp;
    (void)value;
    CHECK("fmi2SetString", M_SET);
    if (nvr == 0) return fmi2OK;
    NULLARG("fmi2SetString", vr);
    logmsg(c, fmi2Error, "logStatusError", "fmi2SetString: invalid value reference %u (no String variables)", vr[0]);
    return fmi2Error;
}

/* Derivatives of any Real unknowns with respect to any knowns (FMI 2.0, 2.1.9). Knowns that are
 * not inputs (parameters, outputs, Integer/Boolean variables: some masters, OMSimulator by default,
 * pass them) contribute what the model says: zero after initialisation (they cannot change) and,
 * in initialisation mode, the derivative with respect to a Real parameter. */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    Comp *c = (Comp *)comp;
    const char *f = "fmi2GetDirectionalDerivative";
    CHECK(f, M_GET);
    NEED_PY(f);
    if (nUnknown == 0) return fmi2OK;
    NULLARG(f, vUnknown_ref);
    NULLARG(f, dvUnknown);
    if (nKnown > 0) {
        NULLARG(f, vKnown_ref);
        NULLARG(f, dvKnown);
    }
    if (c->me) { /* Model Exchange: the states are knowns (the model's Jacobian) */
        for (size_t i = 0; i < nKnown; i++)
            if (!isfinite(dvKnown[i])) {
                logmsg(c, fmi2Error, "logStatusError", "%s: seed of known %u must be finite but was %g", f,
                       vKnown_ref[i], dvKnown[i]);
                return fmi2Error;
            }
        fmi2Status s = refresh(c, f);
        if (s > fmi2Warning) return s;
        return me_model()->directional(c, f, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
    }
    size_t cap = (size_t)c->nscratch / 2; /* layout [vUnknown, vKnown, dvKnown, dvUnknown] */
    if (nUnknown > cap || nKnown > cap || nUnknown + nKnown > cap) {
        logmsg(c, fmi2Error, "logStatusError", "%s: too many variables (%zu unknowns, %zu knowns; at most %zu in all)", f,
               nUnknown, nKnown, cap);
        return fmi2Error;
    }
    for (size_t i = 0; i < nUnknown; i++) {
        fmi2ValueReference vr = vUnknown_ref[i];
        if (vr >= (fmi2ValueReference)c->nvr || c->vtype[vr] != 'R') {
            logmsg(c, fmi2Error, "logStatusError", "%s: unknown %u is not a Real variable", f, vr);
            return fmi2Error;
        }
        c->scratch[i] = (double)vr;
    }
    for (size_t i = 0; i < nKnown; i++) {
        fmi2ValueReference vr = vKnown_ref[i];
        if (vr >= (fmi2ValueReference)c->nvr || !c->vtype[vr]) {
            logmsg(c, fmi2Error, "logStatusError", "%s: invalid value reference %u of a known", f, vr);
            return fmi2Error;
        }
        if (!isfinite(dvKnown[i])) {
            logmsg(c, fmi2Error, "logStatusError", "%s: seed of known %u must be finite but was %g", f, vr, dvKnown[i]);
            return fmi2Error;
        }
        c->scratch[nUnknown + i] = (double)vr;
        c->scratch[nUnknown + nKnown + i] = dvKnown[i];
    }
    fmi2Status s = refresh(c, f);
    if (s > fmi2Warning) return s;
    int g = gil_take();
    s = py_status(c, f, py.CallFunction(c->m_dd, "nni", (Py_ssize_t)nUnknown, (Py_ssize_t)nKnown, c->state == S_INIT));
    GIL_DROP(g);
    if (s > fmi2Warning) return s;
    for (size_t i = 0; i < nUnknown; i++) { /* never OK with a derivative that is not finite */
        double d = c->scratch[2 * nKnown + nUnknown + i];
        if (!isfinite(d)) {
            logmsg(c, fmi2Error, "logStatusError",
                   "%s: the derivative of %s (value reference %u) is %g: the model overflowed (parameters, start "
                   "values or inputs too large for each other?); nothing returned", f, var_name(c, vUnknown_ref[i]),
                   vUnknown_ref[i], d);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nUnknown; i++) dvUnknown[i] = c->scratch[2 * nKnown + nUnknown + i];
    return s;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SetRealInputDerivatives", M_SET);
    if (nvr == 0) return fmi2OK;
    NULLARG("fmi2SetRealInputDerivatives", vr);
    NULLARG("fmi2SetRealInputDerivatives", order);
    NULLARG("fmi2SetRealInputDerivatives", value);
    for (size_t i = 0; i < nvr; i++) {
        if (!check_vr(c, "fmi2SetRealInputDerivatives", vr[i], 'R')) return fmi2Error;
        if (c->vcaus[vr[i]] != C_INPUT) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetRealInputDerivatives: variable %u is not an input", vr[i]);
            return fmi2Error;
        }
        if (order[i] < 1 || order[i] > 2) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetRealInputDerivatives: order %d not supported (1 or 2)", order[i]);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nvr; i++)
        if (!isfinite(value[i])) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetRealInputDerivatives: value for %u must be finite but was %g",
                   vr[i], value[i]);
            return fmi2Error;
        }
    for (size_t i = 0; i < nvr; i++) c->derivs[2 * vr[i] + order[i] - 1] = value[i];
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Comp *c = (Comp *)comp;
    (void)vr; (void)order; (void)value;
    CHECK("fmi2GetRealOutputDerivatives", M_GET);
    if (nvr == 0) return fmi2OK;
    logmsg(c, fmi2Error, "logStatusError", "fmi2GetRealOutputDerivatives: maxOutputDerivativeOrder is 0");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Comp *c = (Comp *)comp;
    const char *f = "fmi2DoStep";
    double t = currentCommunicationPoint, h = communicationStepSize;
    CHECK(f, S_STEP_COMPLETE);
    NEED_PY(f);
    if (!isfinite(t)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: currentCommunicationPoint must be finite but was %g", f, t);
        return fmi2Error;
    }
    if (!isfinite(h) || !(h > 0.0)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: communicationStepSize must be finite and > 0 but was %g", f, h);
        return fmi2Error;
    }
    if (h > PYFMU_MAX_STEP) {
        logmsg(c, fmi2Error, "logStatusError",
               "%s: communicationStepSize %g s is longer than the %g s this FMU accepts in one step "
               "(the cost of a step grows with its length); split it into shorter steps", f, h, PYFMU_MAX_STEP);
        return fmi2Error;
    }
    if (!(t + h > t) || !isfinite(t + h)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: communicationStepSize %g is below the resolution of the time %.17g", f,
               h, t);
        return fmi2Error;
    }
    /* relative to the step: hosts computing t = k h differ from the FMU's sum of steps by rounding */
    double slack = PYFMU_TIME_SLACK * h, ulp = 8.0 * nextafter(fabs(c->time), INFINITY) - 8.0 * fabs(c->time);
    if (slack < ulp) slack = ulp;
    if (fabs(t - c->time) > slack) {
        logmsg(c, fmi2Error, "logStatusError",
               "%s: expected currentCommunicationPoint = %.17g (within %g) but was %.17g", f, c->time, slack, t);
        return fmi2Error;
    }
    int g = gil_take();
    fmi2Status s = fmi2OK;
    int rc = 1;
    if (c->native && h <= PYFMU_NATIVE_MAX_STEP) /* compiled step: no interpreter, no Python slave */
        rc = c->native(c->reals, c->ints, c->derivs, c->nat[0], c->nat[1], c->nat[2], c->nat[3], c->nat[4], c->nat[5],
                       c->nat[6], t, h);
    int raised = rc == 0;
    if (raised) {
        /* The compiled step raised: numba printed the exception to stderr and returned 0. Never
         * fmi2OK on that: put the state back to the start of the step and retake it in Python,
         * which raises the same exception, with its traceback, through the FMI logger. */
        s = py_status(c, f, py.CallFunction(c->m_restore, NULL));
        if (s <= fmi2Warning) rc = 1;
    }
    if (rc == PYFMU_NATIVE_OK) s = fmi2OK;
    else if (rc == 1) { /* no native step, a long step, the native step asks for Python (debug_raise,
                         * an integrator failure, to name it) or raised */
        s = py_status(c, f, py.CallFunction(c->m_step, "ddi", t, h, noSetFMUStatePriorToCurrentPoint));
        if (raised && s <= fmi2Warning) {
            logmsg(c, fmi2Warning, "logStatusWarning", "%s: the compiled step from t = %.17g s raised an exception "
                   "(printed on stderr) that the same step in Python did not: its result is the Python one", f, t);
            s = fmi2Warning;
        }
    } else if (rc != 0) {
        logmsg(c, fmi2Error, "logStatusError", "%s: the compiled step from t = %.17g s of %g s failed (code %d)", f, t, h,
               rc);
        s = fmi2Error;
    }
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->time = t + h; /* the host's time is the truth: no drift accumulates */
        c->dirty = 0;
    } else c->state = (s == fmi2Fatal) ? S_FATAL : S_ERROR;
    return s;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    if (!c) return fmi2Error;
    logmsg(c, fmi2Error, "logStatusError", "fmi2CancelStep: doStep is synchronous, nothing to cancel");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    NULLARG("fmi2GetStatus", value);
    (void)s;
    logmsg(c, fmi2Error, "logStatusError", "fmi2GetStatus: no asynchronous step in progress");
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetRealStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    NULLARG("fmi2GetRealStatus", value);
    if (s == fmi2LastSuccessfulTime) {
        *value = c->time;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value) {
    Comp *c = (Comp *)comp;
    (void)s;
    CHECK("fmi2GetIntegerStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    NULLARG("fmi2GetIntegerStatus", value);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetBooleanStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    NULLARG("fmi2GetBooleanStatus", value);
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value) {
    Comp *c = (Comp *)comp;
    (void)s;
    CHECK("fmi2GetStringStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    NULLARG("fmi2GetStringStatus", value);
    return fmi2Discard;
}

/* ------------------------------------------------------------------------------------------ */
/* Model Exchange (FMI 2.0, 3.2): the host integrates the model's states; the numbers come from the model
 * (me_model(): a native FMU whose model declares states). An event changes no state and has no discrete
 * state: the event indicators (the model's switching functions) make the host land on the surface and
 * restart its integrator there, as the model's own integrator does. */
static int me_instance(Comp *c, const char *f) {
    if (c->me && me_model()) return 1;
    logmsg(c, fmi2Error, "logStatusError", "%s: %s", f,
           me_model() ? "this instance was instantiated for co-simulation (fmuType fmi2CoSimulation)"
                      : "model exchange is not supported (co-simulation only)");
    return 0;
}
#define ME_CHECK(f, mask)                 \
    CHECK(f, mask);                       \
    if (!me_instance(c, f)) return fmi2Error;
#define ME_SIZE(f, n, want, what)                                                                          \
    if ((n) != (size_t)(want)) {                                                                           \
        logmsg(c, fmi2Error, "logStatusError", "%s: n%s = %zu but this FMU has %d", f, what, (size_t)(n), \
               (int)(want));                                                                               \
        return fmi2Error;                                                                                  \
    }

/* in initialisation mode the parameters may have changed: configure before the model is asked */
static fmi2Status me_ready(Comp *c, const char *f) { return c->state == S_INIT ? refresh(c, f) : fmi2OK; }

static fmi2Status me_finite(Comp *c, const char *f, const double *v, size_t n, const char *what) {
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i])) {
            logmsg(c, fmi2Error, "logStatusError", "%s: %s %zu is %g: the model overflowed (parameters or states too "
                   "large for each other?); nothing returned", f, what, i, v[i]);
            return fmi2Error;
        }
    return fmi2OK;
}

fmi2Status fmi2EnterEventMode(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    ME_CHECK("fmi2EnterEventMode", S_CONT | S_EVENT);
    c->state = S_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *e) {
    Comp *c = (Comp *)comp;
    ME_CHECK("fmi2NewDiscreteStates", S_EVENT);
    NULLARG("fmi2NewDiscreteStates", e);
    e->newDiscreteStatesNeeded = fmi2False; /* no discrete state: an event changes nothing */
    e->terminateSimulation = fmi2False;
    e->nominalsOfContinuousStatesChanged = fmi2False;
    e->valuesOfContinuousStatesChanged = fmi2False;
    e->nextEventTimeDefined = fmi2False;
    e->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    ME_CHECK("fmi2EnterContinuousTimeMode", S_EVENT);
    c->state = S_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    Comp *c = (Comp *)comp;
    (void)noSetFMUStatePriorToCurrentPoint;
    ME_CHECK("fmi2CompletedIntegratorStep", S_CONT);
    NULLARG("fmi2CompletedIntegratorStep", enterEventMode);
    NULLARG("fmi2CompletedIntegratorStep", terminateSimulation);
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real t) {
    Comp *c = (Comp *)comp;
    ME_CHECK("fmi2SetTime", M_ME);
    if (!isfinite(t)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetTime: time must be finite but was %g", t);
        return fmi2Error;
    }
    c->time = t;
    me_model()->set_time(c, t);
    c->dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t n) {
    Comp *c = (Comp *)comp;
    const char *f = "fmi2SetContinuousStates";
    ME_CHECK(f, S_CONT);
    ME_SIZE(f, n, me_model()->nx, "x");
    if (n == 0) return fmi2OK;
    NULLARG(f, x);
    for (size_t i = 0; i < n; i++)
        if (!isfinite(x[i])) {
            logmsg(c, fmi2Error, "logStatusError", "%s: state %zu must be finite but was %g", f, i, x[i]);
            return fmi2Error;
        }
    me_model()->set_states(c, x);
    c->dirty = 1;
    return fmi2OK;
}

/* Derivatives, event indicators, states: from initialisation mode on (FMI 2.0 allows them there). */
#define ME_GETTER(NAME, WANT, WHAT, CALL)                                                                  \
    fmi2Status NAME(fmi2Component comp, fmi2Real v[], size_t n) {                                        \
        Comp *c = (Comp *)comp;                                                                          \
        ME_CHECK(#NAME, M_GET);                                                                          \
        ME_SIZE(#NAME, n, me_model()->WANT, WHAT);                                                       \
        if (n == 0) return fmi2OK;                                                                       \
        NULLARG(#NAME, v);                                                                               \
        fmi2Status s = me_ready(c, #NAME);                                                               \
        if (s > fmi2Warning) return s;                                                                   \
        CALL;                                                                                            \
        return me_finite(c, #NAME, v, n, WHAT) > s ? fmi2Error : s;                                     \
    }
#define ME_COMPUTE(FN)                                                                                   \
    if (!me_model()->FN(c, v)) {                                                                         \
        logmsg(c, fmi2Error, "logStatusError", "%s: the compiled model function raised", __func__);      \
        return fmi2Error;                                                                                \
    }
ME_GETTER(fmi2GetDerivatives, nx, "derivative", ME_COMPUTE(derivatives))
ME_GETTER(fmi2GetEventIndicators, nz, "eventIndicator", ME_COMPUTE(indicators))
ME_GETTER(fmi2GetContinuousStates, nx, "x", me_model()->get_states(c, v))

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real v[], size_t n) {
    Comp *c = (Comp *)comp;
    const char *f = "fmi2GetNominalsOfContinuousStates";
    ME_CHECK(f, M_ANY_BUT_FATAL);
    ME_SIZE(f, n, me_model()->nx, "x");
    if (n == 0) return fmi2OK;
    NULLARG(f, v);
    if (c->state == S_INSTANTIATED) { /* the parameters are not fixed yet: FMI's default */
        for (size_t i = 0; i < n; i++) v[i] = 1.0;
        return fmi2OK;
    }
    fmi2Status s = me_ready(c, f);
    if (s > fmi2Warning) return s;
    if (!me_model()->nominals(c, v)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: the compiled model function raised", f);
        return fmi2Error;
    }
    return me_finite(c, f, v, n, "nominal") > s ? fmi2Error : s;
}
