/*
 * Starting the bundled runtime of a standalone FMU, isolated, with the PyConfig API (PEP 587).
 *
 * Compiled with -DPYFMU_PYCONFIG and the build interpreter's include folder only into the stub of
 * a standalone FMU (pyfmu_wrapper/fmubuild/standalone.py): PyConfig and PyStatus are structs whose
 * layout belongs to one Python minor version, and the bundled runtime is the build interpreter's.
 * The runtime's version is checked against the headers before anything is touched. As everywhere
 * in the stub, Python is not linked: the functions are looked up with dlsym in the runtime's
 * libpython. The stub of an ordinary FMU has no bundled runtime and no Python headers; there this
 * function only says so.
 *
 * Configuration: PyPreConfig_InitIsolatedConfig with UTF-8 mode (the host's locale is neither read
 * nor changed; file names and stdio are UTF-8 whatever the locale), PyConfig_InitIsolatedConfig
 * (isolated: PYTHON* variables, the user site and the current folder are ignored; no signal
 * handlers), no byte code written, home = resources/python of the extracted FMU.
 */
#ifdef PYFMU_PYCONFIG
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#endif
#include <dlfcn.h>
#include <stdio.h>
#include <string.h>

#include "dl_compat.h"

__attribute__((visibility("hidden"))) int pyconfig_start_isolated(void *lib, const char *home, char *err, size_t nerr);

#ifdef PYFMU_PYCONFIG

#define SYM(var, name)                                                                  \
    do {                                                                                \
        *(void **)(&var) = dlsym(lib, name);                                            \
        if (!var) {                                                                     \
            snprintf(err, nerr, "symbol %s not found in the bundled libpython", name);  \
            return 0;                                                                   \
        }                                                                               \
    } while (0)

static int failed(PyStatus st, const char *what, char *err, size_t nerr) {
    snprintf(err, nerr, "starting the bundled Python runtime failed in %s: %s%s%s", what,
             st.func ? st.func : "", st.func ? ": " : "", st.err_msg ? st.err_msg : "(no message)");
    return 0;
}

int pyconfig_start_isolated(void *lib, const char *home, char *err, size_t nerr) {
    const char *(*get_version)(void);
    void (*pre_init_isolated)(PyPreConfig *);
    PyStatus (*pre_initialize)(const PyPreConfig *);
    void (*init_isolated)(PyConfig *);
    PyStatus (*set_bytes)(PyConfig *, wchar_t **, const char *);
    PyStatus (*initialize)(const PyConfig *);
    void (*clear)(PyConfig *);
    int (*is_exception)(PyStatus);
    SYM(get_version, "Py_GetVersion");
    char want[16];
    snprintf(want, sizeof want, "%d.%d.", PY_MAJOR_VERSION, PY_MINOR_VERSION);
    const char *have = get_version();
    if (strncmp(have, want, strlen(want)) != 0) {
        snprintf(err, nerr, "the bundled Python runtime is %.20s but this FMU's binary was built for Python %d.%d "
                 "(its PyConfig layout); rebuild the FMU with build-fmus --standalone", have, PY_MAJOR_VERSION,
                 PY_MINOR_VERSION);
        return 0;
    }
    SYM(pre_init_isolated, "PyPreConfig_InitIsolatedConfig");
    SYM(pre_initialize, "Py_PreInitialize");
    SYM(init_isolated, "PyConfig_InitIsolatedConfig");
    SYM(set_bytes, "PyConfig_SetBytesString");
    SYM(initialize, "Py_InitializeFromConfig");
    SYM(clear, "PyConfig_Clear");
    SYM(is_exception, "PyStatus_Exception");

    PyPreConfig pre;
    pre_init_isolated(&pre);
    pre.utf8_mode = 1;
    PyStatus st = pre_initialize(&pre);
    if (is_exception(st)) return failed(st, "Py_PreInitialize", err, nerr);

    PyConfig config;
    init_isolated(&config);
    config.write_bytecode = 0;
    config.install_signal_handlers = 0;
    st = set_bytes(&config, &config.home, home);
    if (is_exception(st)) {
        clear(&config);
        return failed(st, "PyConfig_SetBytesString(home)", err, nerr);
    }
    st = initialize(&config);
    clear(&config);
    if (is_exception(st)) return failed(st, "Py_InitializeFromConfig", err, nerr);
    return 1;
}

#else

int pyconfig_start_isolated(void *lib, const char *home, char *err, size_t nerr) {
    (void)lib;
    (void)home;
    snprintf(err, nerr, "this FMU's binary cannot start a bundled Python runtime: it was not built as a standalone "
             "FMU (build-fmus --standalone)");
    return 0;
}

#endif
