/*
 * Shared declarations of the co-simulation stub that runs a Python slave (FMI 2.0 and 3.0).
 *
 * The stub is split along its jobs:
 *   py_embed.c   finding, loading and entering a Python interpreter (C-API resolved with dlsym)
 *   py_config.c  starting the bundled runtime of a standalone FMU isolated (PyConfig API)
 *   resources.c  reading resources/: pyfmu.cfg, variables.tsv, the resource URI
 *   fmi_api.c    the core, as the FMI 2.0 API: state machine, argument checks, values, doStep, derivatives
 *   fmi3_api.c   the FMI 3.0 API: a thin layer mapping each fmi3 function onto the core
 *   fmi_state.c  FMU state get/set/free/serialize (overflow-safe, ownership-checked)
 *   log.c        messages to the host's logger
 * Only the fmi2* (FMI 2.0 FMU) or the fmi3* (FMI 3.0 FMU) functions are exported (compiled with
 * -fvisibility=hidden and a linker version script, pyfmu_wrapper/fmubuild/build.py).
 */
#ifndef PYFMU_H
#define PYFMU_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "fmi2Functions.h"

#define HIDDEN __attribute__((visibility("hidden")))

#include "dl_compat.h"

/* ---- Python C-API, resolved at run time ------------------------------------------------- */
typedef void PyObject;
typedef ssize_t Py_ssize_t;
#define PY_FILE_INPUT 257

typedef struct {
    int (*IsInitialized)(void);
    int (*IsFinalizing)(void); /* Py_IsFinalizing (3.13+) or _Py_IsFinalizing; may be NULL */
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
} PyApi;

extern HIDDEN PyApi py;
extern HIDDEN int g_py_ready;

/* ---- resources ----------------------------------------------------------------------------- */
typedef struct {
    char guid[128];
    char model[256];
    char python[1024];         /* the build's interpreter (sys.executable) */
    char python_version[32];   /* major.minor.micro of the build's interpreter */
    char requires[512];        /* "numpy>=X,<Y numba>=..." checked in the interpreter */
    char min_python[16];       /* oldest major.minor the bundled code supports */
    char runtime[256];         /* standalone FMU: its Python runtime folder, relative to resources/ */
    char runtime_libpython[512]; /* ... and that runtime's shared libpython, relative to resources/ */
    char runtime_version[32];  /* major.minor.micro of the bundled runtime */
} Config;

/* ---- instance ------------------------------------------------------------------------------ */
enum {
    S_INSTANTIATED = 1 << 0,
    S_INIT = 1 << 1,
    S_STEP_COMPLETE = 1 << 2,
    S_STEP_FAILED = 1 << 3,
    S_TERMINATED = 1 << 4,
    S_ERROR = 1 << 5,
    S_FATAL = 1 << 6,
    S_EVENT = 1 << 7, /* Model Exchange: event mode */
    S_CONT = 1 << 8   /* Model Exchange: continuous-time mode */
};
#define M_ME (S_EVENT | S_CONT)
#define M_ANY_BUT_FATAL (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR | M_ME)
#define M_GET (S_INIT | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR | M_ME)
#define M_SET (S_INSTANTIATED | S_INIT | S_STEP_COMPLETE | M_ME)

enum { C_PARAMETER = 1, C_INPUT, C_OUTPUT, C_LOCAL, C_CALCPAR, C_INDEPENDENT };
enum { V_CONSTANT = 1, V_FIXED, V_TUNABLE, V_DISCRETE, V_CONTINUOUS };

typedef int32_t (*NativeStep)(double *reals, int32_t *ints, double *derivs, void *z, void *p, void *stats, void *th,
                              void *u, void *atol, void *backup, double t, double h);
/* PYFMU_NATIVE_OK (what a successful native step returns; never 0: a numba cfunc that raised
 * returns 0, which the stub reads as "the compiled step raised") and PYFMU_NATIVE_MAX_STEP (longest
 * step taken by the native function; longer ones go through Python, in pieces): see below. */
#include "pyfmu_contract.h"

typedef struct {
    uint32_t magic;     /* COMP_MAGIC while alive */
    char *instance_name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    int state;
    int dirty;
    double time;
    uint64_t fingerprint; /* of the GUID: FMU states of another FMU are refused */
    uint64_t id;          /* unique per instance in the process: its FMU states carry it */
    /* variable table */
    int nvr;            /* max value reference + 1 */
    int nvars;
    char *vtype;        /* 'R', 'I', 'B' or 0 per value reference */
    char *vcaus;
    char *vvar;
    char **vname;       /* variable names (messages) */
    double *vmin, *vmax; /* range per value reference (-inf / inf: none), as the registry states it */
    char *vexcl;        /* 1: the minimum itself is out of range ("> vmin") */
    double *vlo;        /* the minimum declared in modelDescription.xml (inclusive): what is enforced */
    /* buffers shared with Python (bytearrays) */
    double *reals;
    int32_t *ints;
    double *derivs;     /* [vr][2]: input derivatives of order 1 and 2 */
    double *scratch;
    int nscratch;
    /* Python objects */
    PyObject *globals, *slave, *b_reals, *b_ints, *b_derivs, *b_scratch;
    PyObject *m_setup, *m_enter, *m_exit, *m_update, *m_step, *m_reset, *m_terminate, *m_get, *m_set, *m_dd,
        *m_restore;
    char modname[160];
    /* native step (pyfmu_wrapper/fmi/native.py): a compiled function and the slave's arrays */
    NativeStep native;
    void *nat[7]; /* z, p, stats, th, u, atol, backup */
    int fmi3;     /* instantiated through the FMI 3.0 API (its state machine: values readable in Instantiated) */
    int me;       /* instantiated for Model Exchange (the host integrates: no doStep) */
} Comp;
#define COMP_MAGIC 0x434f4d50u

/* ---- Model Exchange: what the core's ME functions (fmi_api.c) ask of the model ------------------ */
/* A native FMU whose model declares states serves these (native/native_me.c, from its compiled
 * functions); the Python-hosted stub has no Model Exchange: me_model() is NULL (py_embed.c). */
typedef struct {
    int nx, nz; /* continuous states, event indicators */
    void (*set_time)(Comp *c, double t);
    void (*get_states)(Comp *c, double *x);
    void (*set_states)(Comp *c, const double *x);
    int (*derivatives)(Comp *c, double *dx); /* 1: done */
    int (*indicators)(Comp *c, double *g);
    int (*nominals)(Comp *c, double *nominal);
    fmi2Status (*directional)(Comp *c, const char *f, const fmi2ValueReference *vu, size_t nu,
                              const fmi2ValueReference *vk, size_t nk, const double *dvk, double *dvu);
} MeModel;
HIDDEN const MeModel *me_model(void);

/* ---- log.c --------------------------------------------------------------------------------- */
HIDDEN void logmsg(Comp *c, fmi2Status st, const char *cat, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
HIDDEN void loglong(Comp *c, fmi2Status st, const char *cat, const char *prefix, const char *text);
HIDDEN const char *state_name(int s);
HIDDEN int check_state(Comp *c, const char *f, int mask);

#define CHECK(f, mask)                          \
    if (!c) return fmi2Error;                   \
    if (!check_state(c, f, mask)) return fmi2Error;
#define NULLARG(f, p)                                                                  \
    if ((p) == NULL) {                                                                 \
        logmsg(c, fmi2Error, "logStatusError", "%s: argument %s is NULL", f, #p);      \
        return fmi2Error;                                                              \
    }

/* ---- resources.c --------------------------------------------------------------------------- */
HIDDEN int read_config(const char *resdir, Config *cfg, char *err, size_t nerr);
HIDDEN int read_variables(Comp *c, const char *resdir, char *err, size_t nerr);
HIDDEN void uri_to_path(const char *uri, char *out, size_t n);
HIDDEN void resources_from_library(char *out, size_t n);
HIDDEN int code_of(const char *s, const char *const *names, int n);
HIDDEN uint64_t fingerprint_of(const char *s);
HIDDEN void fmt_double(double v, char *out, size_t n);
HIDDEN const char *var_name(const Comp *c, unsigned vr);
/* Where the FMU's own documentation is, for messages (inside the FMU archive). */
#define PYFMU_DOC "documentation/index.html in the FMU"

/* ---- py_embed.c ---------------------------------------------------------------------------- */
extern HIDDEN const char *BOOTSTRAP;
HIDDEN int ensure_python(const Config *cfg, const char *resdir, char *err, size_t nerr);
HIDDEN int gil_take(void);
/* Python can be entered: loaded and initialised, and not being finalised (Py_IsInitialized is 0
 * from the start of Py_FinalizeEx). A host may call the FMU during or after its own exit (Ecos
 * frees a simulation from a __del__ run by Py_FinalizeEx; C++ destructors run after it); taking
 * the GIL then uses a finalised interpreter (thread states freed, modules torn down) or, on
 * another thread, ends that thread inside the host (PyThread_exit_thread). */
HIDDEN int py_usable(void);
#define NEED_PY(f)                                                                                         \
    if (!py_usable()) {                                                                                    \
        logmsg(c, fmi2Error, "logStatusError",                                                             \
               "%s: the Python that runs the model has been shut down (the host called the FMU during or " \
               "after its exit); nothing done", f);                                                       \
        return fmi2Error;                                                                                  \
    }
#define GIL_DROP(g) py.GILRelease(g)
HIDDEN void report_py_exception(Comp *c, const char *f);
HIDDEN fmi2Status py_status(Comp *c, const char *f, PyObject *r);
HIDDEN int python_is_host(void);
HIDDEN const char *python_site_paths(void);
HIDDEN const char *python_origin(void);

/* ---- py_config.c (does not include this header: it includes Python.h) ----------------------- */
HIDDEN int pyconfig_start_isolated(void *lib, const char *home, char *err, size_t nerr);

/* ---- fmi_api.c / fmi_state.c --------------------------------------------------------------- */
HIDDEN fmi2Status refresh(Comp *c, const char *f);
HIDDEN int check_vr(Comp *c, const char *f, fmi2ValueReference vr, char type);
HIDDEN int check_settable(Comp *c, const char *f, fmi2ValueReference vr);
HIDDEN int check_value(Comp *c, const char *f, fmi2ValueReference vr, double v, char type);
HIDDEN int check_finite(Comp *c, const char *f, fmi2ValueReference vr); /* the Real's value is finite */
HIDDEN int get_mask(const Comp *c); /* the states in which values can be read */
HIDDEN size_t free_states_of(uint64_t instance_id); /* fmi2FreeInstance: every state of the instance */

#endif
