/*
 * Generic FMI 2.0 co-simulation stub that runs a Python slave (pyfmu_wrapper.fmi.slaves).
 *
 * - Python is not linked: every C-API function is looked up with dlsym. Inside a Python process
 *   (fmpy) the running interpreter is found through the global symbol scope and reused
 *   (Py_IsInitialized); in a pure C host the stub dlopens the libpython recorded at build time
 *   with RTLD_GLOBAL (so extension modules such as numpy resolve its symbols), initialises it and
 *   releases the GIL (PyEval_SaveThread).
 * - One Python thread state per calling thread: a thread without one gets it once and keeps it
 *   (PyGILState_Ensure + PyEval_SaveThread); every call then only takes and drops the GIL.
 * - Each instance loads resources/model.py under a unique module name.
 * - Value buffers (one per type, indexed by value reference) are bytearrays shared with the slave:
 *   fmi2Get/Set* never enter Python; outputs are recomputed lazily after inputs changed.
 * - The FMI 2.0 state machine, GUID and arguments are checked on every call; a Python exception
 *   becomes fmi2Error with its traceback sent to the logger.
 *
 * Build: see pyfmu_wrapper/fmi/build.py (gcc -shared -fPIC -I<fmpy c-code> -ldl -lpthread).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>
#include <sys/types.h>

#include "fmi2Functions.h"

/* ------------------------------------------------------------------------------------------ */
/* Python C-API, resolved at run time                                                            */
typedef void PyObject;
typedef ssize_t Py_ssize_t;
#define PY_FILE_INPUT 257

static struct {
    int (*IsInitialized)(void);
    void (*InitializeEx)(int);
    void (*SetPythonHome)(const wchar_t *);
    wchar_t *(*DecodeLocale)(const char *, size_t *);
    void *(*SaveThread)(void);
    int (*GILEnsure)(void);
    void (*GILRelease)(int);
    void *(*GILThisThreadState)(void);
    PyObject *(*RunString)(const char *, int, PyObject *, PyObject *);
    PyObject *(*DictNew)(void);
    int (*DictSetItemString)(PyObject *, const char *, PyObject *);
    PyObject *(*DictGetItemString)(PyObject *, const char *);
    PyObject *(*EvalGetBuiltins)(void);
    const char *(*UnicodeAsUTF8)(PyObject *);
    PyObject *(*GetAttrString)(PyObject *, const char *);
    PyObject *(*CallFunction)(PyObject *, const char *, ...);
    long (*LongAsLong)(PyObject *);
    PyObject *(*ByteArrayFromStringAndSize)(const char *, Py_ssize_t);
    char *(*ByteArrayAsString)(PyObject *);
    int (*BytesAsStringAndSize)(PyObject *, char **, Py_ssize_t *);
    PyObject *(*BytesFromStringAndSize)(const char *, Py_ssize_t);
    void (*DecRef)(PyObject *);
    PyObject *(*ErrOccurred)(void);
    void (*ErrFetch)(PyObject **, PyObject **, PyObject **);
    void (*ErrNormalize)(PyObject **, PyObject **, PyObject **);
    void (*ErrClear)(void);
    PyObject *(*NoneStruct);
} py;

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static int g_py_ready = 0;
static unsigned long g_counter = 0;
static __thread int tls_primed = 0;

#define RESOLVE(field, name, optional)                                        \
    do {                                                                      \
        *(void **)(&py.field) = dlsym(h, name);                               \
        if (!py.field && !(optional)) {                                       \
            snprintf(err, nerr, "symbol %s not found in libpython", name);    \
            return 0;                                                         \
        }                                                                     \
    } while (0)

static int resolve_python(void *h, char *err, size_t nerr) {
    RESOLVE(IsInitialized, "Py_IsInitialized", 0);
    RESOLVE(InitializeEx, "Py_InitializeEx", 0);
    RESOLVE(SetPythonHome, "Py_SetPythonHome", 1);
    RESOLVE(DecodeLocale, "Py_DecodeLocale", 0);
    RESOLVE(SaveThread, "PyEval_SaveThread", 0);
    RESOLVE(GILEnsure, "PyGILState_Ensure", 0);
    RESOLVE(GILRelease, "PyGILState_Release", 0);
    RESOLVE(GILThisThreadState, "PyGILState_GetThisThreadState", 0);
    RESOLVE(RunString, "PyRun_String", 0);
    RESOLVE(DictNew, "PyDict_New", 0);
    RESOLVE(DictSetItemString, "PyDict_SetItemString", 0);
    RESOLVE(DictGetItemString, "PyDict_GetItemString", 0);
    RESOLVE(EvalGetBuiltins, "PyEval_GetBuiltins", 0);
    RESOLVE(UnicodeAsUTF8, "PyUnicode_AsUTF8", 0);
    RESOLVE(GetAttrString, "PyObject_GetAttrString", 0);
    RESOLVE(CallFunction, "PyObject_CallFunction", 0);
    RESOLVE(LongAsLong, "PyLong_AsLong", 0);
    RESOLVE(ByteArrayFromStringAndSize, "PyByteArray_FromStringAndSize", 0);
    RESOLVE(ByteArrayAsString, "PyByteArray_AsString", 0);
    RESOLVE(BytesAsStringAndSize, "PyBytes_AsStringAndSize", 0);
    RESOLVE(BytesFromStringAndSize, "PyBytes_FromStringAndSize", 0);
    RESOLVE(DecRef, "Py_DecRef", 0);
    RESOLVE(ErrOccurred, "PyErr_Occurred", 0);
    RESOLVE(ErrFetch, "PyErr_Fetch", 0);
    RESOLVE(ErrNormalize, "PyErr_NormalizeException", 0);
    RESOLVE(ErrClear, "PyErr_Clear", 0);
    RESOLVE(NoneStruct, "_Py_NoneStruct", 0);
    return 1;
}

/* Take the GIL; a thread calling for the first time gets a thread state that it keeps. */
static int gil_take(void) {
    if (!tls_primed) {
        if (py.GILThisThreadState() == NULL) {
            py.GILEnsure();  /* creates this thread's state (kept: the count never drops to 0) */
            py.SaveThread(); /* ... and releases the GIL again */
        }
        tls_primed = 1;
    }
    return py.GILEnsure();
}
#define GIL_DROP(g) py.GILRelease(g)

/* ------------------------------------------------------------------------------------------ */
/* Instance                                                                                      */
enum {
    S_INSTANTIATED = 1 << 0,
    S_INIT = 1 << 1,
    S_STEP_COMPLETE = 1 << 2,
    S_STEP_FAILED = 1 << 3,
    S_TERMINATED = 1 << 4,
    S_ERROR = 1 << 5,
    S_FATAL = 1 << 6
};
static const char *state_name(int s) {
    switch (s) {
    case S_INSTANTIATED: return "Instantiated";
    case S_INIT: return "InitializationMode";
    case S_STEP_COMPLETE: return "StepComplete";
    case S_STEP_FAILED: return "StepFailed";
    case S_TERMINATED: return "Terminated";
    case S_ERROR: return "Error";
    default: return "Fatal";
    }
}
#define M_ANY_BUT_FATAL (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)
#define M_GET (S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)
#define M_SET (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE)

enum { C_PARAMETER = 1, C_INPUT, C_OUTPUT, C_LOCAL, C_CALCPAR, C_INDEPENDENT };
enum { V_CONSTANT = 1, V_FIXED, V_TUNABLE, V_DISCRETE, V_CONTINUOUS };

typedef struct {
    char *instance_name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    int state;
    int dirty;
    double time;
    /* variable table */
    int nvr;            /* max value reference + 1 */
    int nvars;
    char *vtype;        /* 'R', 'I', 'B' or 0 per value reference */
    char *vcaus;
    char *vvar;
    /* buffers shared with Python (bytearrays) */
    double *reals;
    int32_t *ints;
    double *derivs;     /* [vr][2]: input derivatives of order 1 and 2 */
    double *scratch;
    int nscratch;
    /* Python objects */
    PyObject *globals, *slave, *b_reals, *b_ints, *b_derivs, *b_scratch;
    PyObject *m_setup, *m_enter, *m_exit, *m_update, *m_step, *m_reset, *m_terminate, *m_get, *m_set, *m_dd;
    char modname[160];
} Comp;

/* The message is passed pre-formatted as the format string with '%' doubled: C hosts that
 * vsnprintf it and Python hosts (fmpy) that print it as is both show the text. */
static void emit(Comp *c, fmi2Status st, const char *cat, const char *a, const char *b) {
    size_t na = strlen(a), nb = b ? strlen(b) : 0;
    char *m = malloc(2 * (na + nb) + 1), *q = m;
    if (!m) return;
    for (const char *p = a; *p; p++) { if (*p == '%') *q++ = '%'; *q++ = *p; }
    for (const char *p = b; p && *p; p++) { if (*p == '%') *q++ = '%'; *q++ = *p; }
    *q = 0;
    c->logger(c->env, c->instance_name, st, cat, m);
    free(m);
}

static void logmsg(Comp *c, fmi2Status st, const char *cat, const char *fmt, ...) {
    if (!c || !c->logger) return;
    if (st == fmi2OK && !c->logging_on) return;
    char buf[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    emit(c, st, cat, buf, NULL);
}

static void loglong(Comp *c, fmi2Status st, const char *cat, const char *prefix, const char *text) {
    if (!c || !c->logger) return;
    emit(c, st, cat, prefix, text);
}

static int check_state(Comp *c, const char *f, int mask) {
    if (!c) return 0;
    if (!(c->state & mask)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: not allowed in state %s", f, state_name(c->state));
        return 0;
    }
    return 1;
}
#define CHECK(f, mask)                          \
    if (!c) return fmi2Error;                   \
    if (!check_state(c, f, mask)) return fmi2Error;
#define NULLARG(f, p)                                                                  \
    if ((p) == NULL) {                                                                 \
        logmsg(c, fmi2Error, "logStatusError", "%s: argument %s is NULL", f, #p);      \
        return fmi2Error;                                                              \
    }

/* Report the pending Python exception (if any) with its traceback. Call with the GIL. */
static void report_py_exception(Comp *c, const char *f) {
    PyObject *t = NULL, *v = NULL, *tb = NULL;
    if (!py.ErrOccurred()) return;
    py.ErrFetch(&t, &v, &tb);
    py.ErrNormalize(&t, &v, &tb);
    PyObject *fmt = c && c->globals ? py.DictGetItemString(c->globals, "_format") : NULL;
    PyObject *s = NULL;
    if (fmt) s = py.CallFunction(fmt, "OOO", t ? t : py.NoneStruct, v ? v : py.NoneStruct, tb ? tb : py.NoneStruct);
    char prefix[200];
    snprintf(prefix, sizeof prefix, "%s: Python exception\n", f);
    if (s) {
        loglong(c, fmi2Error, "logStatusError", prefix, py.UnicodeAsUTF8(s));
        py.DecRef(s);
    } else {
        py.ErrClear();
        loglong(c, fmi2Error, "logStatusError", prefix, "(traceback unavailable)");
    }
    if (t) py.DecRef(t);
    if (v) py.DecRef(v);
    if (tb) py.DecRef(tb);
}

/* Turn the result of a slave call (an int status) into fmi2Status; call with the GIL. */
static fmi2Status py_status(Comp *c, const char *f, PyObject *r) {
    if (!r) {
        report_py_exception(c, f);
        return fmi2Error;
    }
    long st = py.LongAsLong(r);
    py.DecRef(r);
    if (st == -1 && py.ErrOccurred()) {
        report_py_exception(c, f);
        return fmi2Error;
    }
    if (st >= fmi2Error || st == fmi2Warning) {
        PyObject *e = py.GetAttrString(c->slave, "last_error");
        char prefix[200];
        snprintf(prefix, sizeof prefix, "%s: Python exception in the model\n", f);
        if (e) {
            loglong(c, st == fmi2Warning ? fmi2Warning : fmi2Error, "logStatusError", prefix, py.UnicodeAsUTF8(e));
            py.DecRef(e);
        }
        py.ErrClear();
    }
    if (st < 0 || st > fmi2Fatal) return fmi2Error;
    return (fmi2Status)st;
}

/* ------------------------------------------------------------------------------------------ */
/* Resources: configuration and variable table                                                   */
typedef struct {
    char guid[128];
    char libpython[1024];
    char pythonhome[1024];
    char model[256];
    char paths[8192]; /* newline separated */
} Config;

static void chomp(char *s) {
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\n' || s[n - 1] == '\r')) s[--n] = 0;
}

static int read_config(const char *resdir, Config *cfg, char *err, size_t nerr) {
    char path[2048];
    snprintf(path, sizeof path, "%s/pyfmu.cfg", resdir);
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, nerr, "cannot open %.1900s", path);
        return 0;
    }
    memset(cfg, 0, sizeof *cfg);
    char line[4096];
    while (fgets(line, sizeof line, f)) {
        chomp(line);
        char *eq = strchr(line, '=');
        if (!eq || line[0] == '#') continue;
        *eq = 0;
        const char *k = line, *v = eq + 1;
        if (!strcmp(k, "guid")) snprintf(cfg->guid, sizeof cfg->guid, "%s", v);
        else if (!strcmp(k, "libpython")) snprintf(cfg->libpython, sizeof cfg->libpython, "%s", v);
        else if (!strcmp(k, "pythonhome")) snprintf(cfg->pythonhome, sizeof cfg->pythonhome, "%s", v);
        else if (!strcmp(k, "model")) snprintf(cfg->model, sizeof cfg->model, "%s", v);
        else if (!strcmp(k, "path")) {
            size_t n = strlen(cfg->paths);
            snprintf(cfg->paths + n, sizeof cfg->paths - n, "%s\n", v);
        }
    }
    fclose(f);
    return 1;
}

static int code_of(const char *s, const char *const *names, int n) {
    for (int i = 0; i < n; i++)
        if (!strcmp(s, names[i])) return i + 1;
    return 0;
}

static int read_variables(Comp *c, const char *resdir, char *err, size_t nerr) {
    static const char *caus[] = {"parameter", "input", "output", "local", "calculatedParameter", "independent"};
    static const char *var[] = {"constant", "fixed", "tunable", "discrete", "continuous"};
    char path[2048];
    snprintf(path, sizeof path, "%s/variables.tsv", resdir);
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, nerr, "cannot open %.1900s", path);
        return 0;
    }
    int maxvr = -1;
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        int vr;
        if (sscanf(line, "%d", &vr) == 1 && vr > maxvr) maxvr = vr;
    }
    if (maxvr < 0 || maxvr > 1000000) {
        fclose(f);
        snprintf(err, nerr, "bad variable table %.1900s", path);
        return 0;
    }
    c->nvr = maxvr + 1;
    c->vtype = calloc(c->nvr, 1);
    c->vcaus = calloc(c->nvr, 1);
    c->vvar = calloc(c->nvr, 1);
    rewind(f);
    while (fgets(line, sizeof line, f)) {
        int vr;
        char t[8], ca[32], va[32];
        if (sscanf(line, "%d %7s %31s %31s", &vr, t, ca, va) != 4) continue;
        c->vtype[vr] = t[0];
        c->vcaus[vr] = (char)code_of(ca, caus, 6);
        c->vvar[vr] = (char)code_of(va, var, 5);
        c->nvars++;
    }
    fclose(f);
    return 1;
}

static void uri_to_path(const char *uri, char *out, size_t n) {
    const char *p = uri;
    if (!strncmp(p, "file://localhost/", 17)) p += 16;
    else if (!strncmp(p, "file:///", 8)) p += 7;
    else if (!strncmp(p, "file:/", 6)) p += 5;
    size_t j = 0;
    for (; *p && j + 1 < n; p++) {
        if (*p == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            out[j++] = (char)strtol(hex, NULL, 16);
            p += 2;
        } else out[j++] = *p;
    }
    out[j] = 0;
    while (j > 1 && out[j - 1] == '/') out[--j] = 0;
}

static void resources_from_library(char *out, size_t n) {
    Dl_info info;
    out[0] = 0;
    if (!dladdr((void *)&resources_from_library, &info) || !info.dli_fname) return;
    snprintf(out, n, "%s", info.dli_fname);
    for (int i = 0; i < 3; i++) { /* <fmu>/binaries/linux64/x.so -> <fmu> */
        char *s = strrchr(out, '/');
        if (s) *s = 0;
    }
    strncat(out, "/resources", n - strlen(out) - 1);
}

/* ------------------------------------------------------------------------------------------ */
/* Python bootstrap, run once per instance in its own globals                                    */
static const char *BOOTSTRAP =
    "import sys, site, importlib.util, traceback\n"
    "def _format(t, v, tb):\n"
    "    return ''.join(traceback.format_exception(t, v, tb))\n"
    "def _load(paths, model_file, modname):\n"
    "    for p in paths.split('\\n'):\n"
    "        if p and p not in sys.path:\n"
    "            site.addsitedir(p)\n"
    "    spec = importlib.util.spec_from_file_location(modname, model_file)\n"
    "    mod = importlib.util.module_from_spec(spec)\n"
    "    sys.modules[modname] = mod\n"
    "    try:\n"
    "        spec.loader.exec_module(mod)\n"
    "    except BaseException:\n"
    "        sys.modules.pop(modname, None)\n"
    "        raise\n"
    "    return mod\n"
    "def _unload(modname):\n"
    "    sys.modules.pop(modname, None)\n";

static int ensure_python(const Config *cfg, char *err, size_t nerr) {
    pthread_mutex_lock(&g_lock);
    int ok = 1;
    if (!g_py_ready) {
        void *h = RTLD_DEFAULT;
        if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
            h = dlopen(cfg->libpython, RTLD_NOW | RTLD_GLOBAL);
            if (!h) {
                snprintf(err, nerr, "cannot load libpython %s: %s", cfg->libpython, dlerror());
                ok = 0;
            }
        }
        if (ok) ok = resolve_python(h, err, nerr);
        if (ok) g_py_ready = 1;
    }
    if (ok && !py.IsInitialized()) {
        if (cfg->pythonhome[0] && py.SetPythonHome) {
            wchar_t *home = py.DecodeLocale(cfg->pythonhome, NULL); /* must outlive the interpreter */
            if (home) py.SetPythonHome(home);
        }
        py.InitializeEx(0);
        if (!py.IsInitialized()) {
            snprintf(err, nerr, "Py_InitializeEx failed");
            ok = 0;
        } else {
            py.SaveThread(); /* this thread keeps its thread state; the GIL is released */
            tls_primed = 1;
        }
    }
    pthread_mutex_unlock(&g_lock);
    return ok;
}

static void free_comp(Comp *c) {
    if (!c) return;
    if (c->globals && g_py_ready) {
        int g = gil_take();
        PyObject *unload = py.DictGetItemString(c->globals, "_unload");
        if (unload) {
            PyObject *r = py.CallFunction(unload, "s", c->modname);
            if (r) py.DecRef(r);
            else py.ErrClear();
        }
        PyObject **objs[] = {&c->m_setup, &c->m_enter, &c->m_exit, &c->m_update, &c->m_step, &c->m_reset,
                             &c->m_terminate, &c->m_get, &c->m_set, &c->m_dd, &c->slave, &c->b_reals,
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
    free(c->instance_name);
    free(c);
}

/* ------------------------------------------------------------------------------------------ */
/* FMI 2.0 API                                                                                   */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String cats[]) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SetDebugLogging", M_ANY_BUT_FATAL);
    static const char *known[] = {"logStatusError", "logStatusWarning", "logAll"};
    if (n > 0) NULLARG("fmi2SetDebugLogging", cats);
    for (size_t i = 0; i < n; i++) {
        if (!cats[i] || !code_of(cats[i], known, 3)) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetDebugLogging: unknown log category %s", cats[i] ? cats[i] : "NULL");
            return fmi2Error;
        }
    }
    c->logging_on = loggingOn;
    return fmi2OK;
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
    if (!instanceName || !instanceName[0]) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: this FMU supports co-simulation only");
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
    c->instance_name = strdup(instanceName);
    c->logging_on = loggingOn;
    c->state = S_INSTANTIATED;
    c->dirty = 1;
    if (!read_variables(c, resdir, err, sizeof err)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2Instantiate: %s", err);
        free_comp(c);
        return NULL;
    }
    if (!ensure_python(&cfg, err, sizeof err)) {
        logmsg(c, fmi2Fatal, "logStatusError", "fmi2Instantiate: %s", err);
        free_comp(c);
        return NULL;
    }
    pthread_mutex_lock(&g_lock);
    unsigned long id = ++g_counter;
    pthread_mutex_unlock(&g_lock);
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
            PyObject *mod = py.CallFunction(py.DictGetItemString(c->globals, "_load"), "sss", cfg.paths, model_file, c->modname);
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
    logmsg(c, fmi2OK, "logAll", "fmi2Instantiate: module %s, resources %s", c->modname, resdir);
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
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2ExitInitializationMode", py.CallFunction(c->m_exit, NULL));
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->state = S_STEP_COMPLETE;
        c->dirty = 0;
    } else c->state = S_ERROR;
    return s;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2Terminate", S_STEP_COMPLETE | S_STEP_FAILED);
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2Terminate", py.CallFunction(c->m_terminate, NULL));
    GIL_DROP(g);
    c->state = S_TERMINATED;
    return s;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2Reset", M_ANY_BUT_FATAL);
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
static fmi2Status refresh(Comp *c, const char *f) {
    if (!c->dirty || !(c->state & (S_INIT | S_STEP_COMPLETE))) return fmi2OK;
    int g = gil_take();
    fmi2Status s = py_status(c, f, py.CallFunction(c->m_update, "i", c->state == S_INIT));
    GIL_DROP(g);
    if (s <= fmi2Warning) c->dirty = 0;
    return s;
}

static int check_vr(Comp *c, const char *f, fmi2ValueReference vr, char type) {
    if (vr >= (fmi2ValueReference)c->nvr || c->vtype[vr] != type) {
        logmsg(c, fmi2Error, "logStatusError", "%s: invalid value reference %u", f, vr);
        return 0;
    }
    return 1;
}

static int check_settable(Comp *c, const char *f, fmi2ValueReference vr) {
    int ca = c->vcaus[vr], va = c->vvar[vr];
    int ok = 0;
    if (ca == C_INPUT) ok = 1;
    else if (ca == C_PARAMETER && va == V_TUNABLE) ok = 1;
    else if (ca == C_PARAMETER && va == V_FIXED) ok = c->state & (S_INSTANTIATED | S_INIT);
    if (!ok) logmsg(c, fmi2Error, "logStatusError", "%s: variable %u cannot be set in state %s", f, vr, state_name(c->state));
    return ok;
}

#define GETTER(NAME, CTYPE, TCODE, BUF, CONV)                                                    \
    fmi2Status NAME(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, CTYPE value[]) { \
        Comp *c = (Comp *)comp;                                                                  \
        CHECK(#NAME, M_GET);                                                                     \
        if (nvr == 0) return fmi2OK;                                                             \
        NULLARG(#NAME, vr);                                                                      \
        NULLARG(#NAME, value);                                                                   \
        for (size_t i = 0; i < nvr; i++)                                                         \
            if (!check_vr(c, #NAME, vr[i], TCODE)) return fmi2Error;                             \
        fmi2Status s = refresh(c, #NAME);                                                        \
        if (s > fmi2Warning) return s;                                                           \
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
            if (!check_vr(c, #NAME, vr[i], TCODE) || !check_settable(c, #NAME, vr[i])) return fmi2Error; \
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

/* --- FMU state: the C buffers + the slave's own state bytes ------------------------------------ */
typedef struct {
    uint32_t magic, nvr;
    int32_t state, dirty;
    double time;
    double *reals, *derivs;
    int32_t *ints;
    char *pystate;
    size_t pylen;
} FmuState;
#define STATE_MAGIC 0x50594d55u

static void free_state(FmuState *s) {
    if (!s) return;
    free(s->reals);
    free(s->derivs);
    free(s->ints);
    free(s->pystate);
    free(s);
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2GetFMUstate", FMUstate);
    int g = gil_take();
    PyObject *r = py.CallFunction(c->m_get, NULL);
    char *buf = NULL;
    Py_ssize_t len = 0;
    fmi2Status st = fmi2OK;
    if (!r) {
        report_py_exception(c, "fmi2GetFMUstate");
        st = fmi2Error;
    } else if (r == py.NoneStruct || py.BytesAsStringAndSize(r, &buf, &len) != 0) {
        if (r != py.NoneStruct) report_py_exception(c, "fmi2GetFMUstate");
        else {
            PyObject *e = py.GetAttrString(c->slave, "last_error");
            loglong(c, fmi2Error, "logStatusError", "fmi2GetFMUstate: Python exception in the model\n",
                    e ? py.UnicodeAsUTF8(e) : "");
            if (e) py.DecRef(e);
            py.ErrClear();
        }
        st = fmi2Error;
    }
    FmuState *s = NULL;
    if (st == fmi2OK) {
        s = *FMUstate ? (FmuState *)*FMUstate : calloc(1, sizeof(FmuState));
        if (s->magic == STATE_MAGIC && s->nvr != (uint32_t)c->nvr) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2GetFMUstate: the given state belongs to another FMU");
            st = fmi2Error;
        } else {
            s->magic = STATE_MAGIC;
            s->nvr = (uint32_t)c->nvr;
            if (!s->reals) s->reals = malloc(sizeof(double) * c->nvr);
            if (!s->derivs) s->derivs = malloc(2 * sizeof(double) * c->nvr);
            if (!s->ints) s->ints = malloc(sizeof(int32_t) * c->nvr);
            memcpy(s->reals, c->reals, sizeof(double) * c->nvr);
            memcpy(s->derivs, c->derivs, 2 * sizeof(double) * c->nvr);
            memcpy(s->ints, c->ints, sizeof(int32_t) * c->nvr);
            free(s->pystate);
            s->pystate = malloc(len ? (size_t)len : 1);
            memcpy(s->pystate, buf, (size_t)len);
            s->pylen = (size_t)len;
            s->state = c->state;
            s->dirty = c->dirty;
            s->time = c->time;
            *FMUstate = s;
        }
    }
    if (r) py.DecRef(r);
    GIL_DROP(g);
    return st;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SetFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2SetFMUstate", FMUstate);
    FmuState *s = (FmuState *)FMUstate;
    if (s->magic != STATE_MAGIC || s->nvr != (uint32_t)c->nvr) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SetFMUstate: not a state of this FMU");
        return fmi2Error;
    }
    int g = gil_take();
    PyObject *b = py.BytesFromStringAndSize(s->pystate, (Py_ssize_t)s->pylen);
    fmi2Status st = py_status(c, "fmi2SetFMUstate", b ? py.CallFunction(c->m_set, "O", b) : NULL);
    if (b) py.DecRef(b);
    GIL_DROP(g);
    if (st > fmi2Warning) return st;
    memcpy(c->reals, s->reals, sizeof(double) * c->nvr);
    memcpy(c->derivs, s->derivs, 2 * sizeof(double) * c->nvr);
    memcpy(c->ints, s->ints, sizeof(int32_t) * c->nvr);
    c->state = s->state;
    c->dirty = s->dirty;
    c->time = s->time;
    return st;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2FreeFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2FreeFMUstate", FMUstate);
    free_state((FmuState *)*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

/* Serialized layout: u32 magic, u32 nvr, i32 state, i32 dirty, f64 time, u64 pylen, reals, derivs, ints, pystate */
static size_t serial_size(const FmuState *s) {
    return 4 + 4 + 4 + 4 + 8 + 8 + s->nvr * (sizeof(double) * 3 + sizeof(int32_t)) + s->pylen;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SerializedFMUstateSize", M_ANY_BUT_FATAL);
    NULLARG("fmi2SerializedFMUstateSize", FMUstate);
    NULLARG("fmi2SerializedFMUstateSize", size);
    *size = serial_size((FmuState *)FMUstate);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte out[], size_t size) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SerializeFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2SerializeFMUstate", FMUstate);
    NULLARG("fmi2SerializeFMUstate", out);
    FmuState *s = (FmuState *)FMUstate;
    if (size < serial_size(s)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SerializeFMUstate: buffer of %zu bytes, %zu needed", size, serial_size(s));
        return fmi2Error;
    }
    char *p = out;
    uint64_t pylen = s->pylen;
    memcpy(p, &s->magic, 4); p += 4;
    memcpy(p, &s->nvr, 4); p += 4;
    memcpy(p, &s->state, 4); p += 4;
    memcpy(p, &s->dirty, 4); p += 4;
    memcpy(p, &s->time, 8); p += 8;
    memcpy(p, &pylen, 8); p += 8;
    memcpy(p, s->reals, sizeof(double) * s->nvr); p += sizeof(double) * s->nvr;
    memcpy(p, s->derivs, 2 * sizeof(double) * s->nvr); p += 2 * sizeof(double) * s->nvr;
    memcpy(p, s->ints, sizeof(int32_t) * s->nvr); p += sizeof(int32_t) * s->nvr;
    memcpy(p, s->pystate, s->pylen);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte in[], size_t size, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2DeSerializeFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2DeSerializeFMUstate", in);
    NULLARG("fmi2DeSerializeFMUstate", FMUstate);
    FmuState h = {0};
    uint64_t pylen = 0;
    if (size < 32) goto bad;
    memcpy(&h.magic, in, 4);
    memcpy(&h.nvr, in + 4, 4);
    memcpy(&h.state, in + 8, 4);
    memcpy(&h.dirty, in + 12, 4);
    memcpy(&h.time, in + 16, 8);
    memcpy(&pylen, in + 24, 8);
    h.pylen = (size_t)pylen;
    if (h.magic != STATE_MAGIC || h.nvr != (uint32_t)c->nvr || size != serial_size(&h)) goto bad;
    FmuState *s = calloc(1, sizeof(FmuState));
    *s = h;
    const char *p = in + 32;
    s->reals = malloc(sizeof(double) * s->nvr);
    s->derivs = malloc(2 * sizeof(double) * s->nvr);
    s->ints = malloc(sizeof(int32_t) * s->nvr);
    s->pystate = malloc(s->pylen ? s->pylen : 1);
    memcpy(s->reals, p, sizeof(double) * s->nvr); p += sizeof(double) * s->nvr;
    memcpy(s->derivs, p, 2 * sizeof(double) * s->nvr); p += 2 * sizeof(double) * s->nvr;
    memcpy(s->ints, p, sizeof(int32_t) * s->nvr); p += sizeof(int32_t) * s->nvr;
    memcpy(s->pystate, p, s->pylen);
    if (*FMUstate) free_state((FmuState *)*FMUstate);
    *FMUstate = s;
    return fmi2OK;
bad:
    logmsg(c, fmi2Error, "logStatusError", "fmi2DeSerializeFMUstate: not a serialized state of this FMU");
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetDirectionalDerivative", M_GET);
    if (nUnknown == 0) return fmi2OK;
    NULLARG("fmi2GetDirectionalDerivative", vUnknown_ref);
    NULLARG("fmi2GetDirectionalDerivative", dvUnknown);
    if (nKnown > 0) {
        NULLARG("fmi2GetDirectionalDerivative", vKnown_ref);
        NULLARG("fmi2GetDirectionalDerivative", dvKnown);
    }
    if (2 * (nUnknown + nKnown) > (size_t)c->nscratch) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2GetDirectionalDerivative: too many variables (%zu, %zu)", nUnknown, nKnown);
        return fmi2Error;
    }
    for (size_t i = 0; i < nUnknown; i++) {
        if (!check_vr(c, "fmi2GetDirectionalDerivative", vUnknown_ref[i], 'R')) return fmi2Error;
        c->scratch[i] = (double)vUnknown_ref[i];
    }
    for (size_t i = 0; i < nKnown; i++) {
        if (!check_vr(c, "fmi2GetDirectionalDerivative", vKnown_ref[i], 'R')) return fmi2Error;
        c->scratch[nUnknown + i] = (double)vKnown_ref[i];
        c->scratch[nUnknown + nKnown + i] = dvKnown[i];
    }
    fmi2Status s = refresh(c, "fmi2GetDirectionalDerivative");
    if (s > fmi2Warning) return s;
    int g = gil_take();
    s = py_status(c, "fmi2GetDirectionalDerivative", py.CallFunction(c->m_dd, "nn", (Py_ssize_t)nUnknown, (Py_ssize_t)nKnown));
    GIL_DROP(g);
    if (s <= fmi2Warning)
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
    CHECK("fmi2DoStep", S_STEP_COMPLETE);
    if (!(communicationStepSize > 0.0)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2DoStep: communicationStepSize must be > 0 but was %.16g", communicationStepSize);
        return fmi2Error;
    }
    double tol = 1e-12 * (1.0 + (c->time < 0 ? -c->time : c->time));
    if (currentCommunicationPoint > c->time + tol || currentCommunicationPoint < c->time - tol) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2DoStep: expected currentCommunicationPoint = %.16g but was %.16g",
               c->time, currentCommunicationPoint);
        return fmi2Error;
    }
    int g = gil_take();
    fmi2Status s = py_status(c, "fmi2DoStep", py.CallFunction(c->m_step, "ddi", c->time, communicationStepSize,
                                                              noSetFMUStatePriorToCurrentPoint));
    GIL_DROP(g);
    if (s <= fmi2Warning) {
        c->time += communicationStepSize;
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

/* Model-exchange entry points: this FMU is co-simulation only. */
#define ME_ONLY(comp, name)                                                                      \
    do {                                                                                         \
        logmsg((Comp *)(comp), fmi2Error, "logStatusError", name ": model exchange is not supported"); \
        return fmi2Error;                                                                        \
    } while (0)
fmi2Status fmi2EnterEventMode(fmi2Component c) { ME_ONLY(c, "fmi2EnterEventMode"); }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *e) { (void)e; ME_ONLY(c, "fmi2NewDiscreteStates"); }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { ME_ONLY(c, "fmi2EnterContinuousTimeMode"); }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean a, fmi2Boolean *b, fmi2Boolean *d) {
    (void)a; (void)b; (void)d; ME_ONLY(c, "fmi2CompletedIntegratorStep");
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { (void)t; ME_ONLY(c, "fmi2SetTime"); }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) { (void)x; (void)n; ME_ONLY(c, "fmi2SetContinuousStates"); }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; ME_ONLY(c, "fmi2GetDerivatives"); }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; ME_ONLY(c, "fmi2GetEventIndicators"); }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; ME_ONLY(c, "fmi2GetContinuousStates"); }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { (void)x; (void)n; ME_ONLY(c, "fmi2GetNominalsOfContinuousStates"); }
