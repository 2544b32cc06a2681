/*
 * Embedding Python: find an interpreter, load it, enter it.
 *
 * - Python is not linked: every C-API function is looked up with dlsym.
 * - Inside a Python process (fmpy, ecospy...) the running interpreter is found through the
 *   global symbol scope (Py_IsInitialized) and reused; the model code then checks that this
 *   interpreter fits (version, numpy, numba) and says what to install when it does not.
 * - In a pure C host a Python is found in this order: the environment variable PYFMU_PYTHON
 *   (a python executable or a virtual environment folder), then the runtime bundled in a
 *   standalone FMU (resources/python/), then the interpreter recorded at build time. Each
 *   external candidate is probed in a subprocess (its version, shared libpython, site folders,
 *   numpy and numba versions); the bundled runtime is not probed (it has no executable; its files
 *   are checked, and the packages after start-up as for any Python). The first that fits is
 *   dlopened with RTLD_GLOBAL (so extension modules resolve its symbols), initialised, and the
 *   GIL released. The bundled runtime is started isolated with the PyConfig API (py_config.c):
 *   its home is resources/python, the environment (PYTHONPATH, PYTHONHOME...) and the user site
 *   are ignored, no byte code written, UTF-8 mode, the host's locale untouched.
 * - One Python thread state per calling thread: a thread without one gets it once and keeps it
 *   (PyGILState_Ensure + PyEval_SaveThread); every call then only takes and drops the GIL.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>
#include <wchar.h>

#include "pyfmu.h"

PyApi py;
int g_py_ready = 0;
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static __thread int tls_primed = 0;
static int g_host_python = 0;
static void *g_lib = NULL; /* the libpython this stub dlopened (NULL: the host's) */

/* Checks run inside the interpreter (probe subprocess and bootstrap alike). */
#define FIT_CODE                                                                                     \
    "def _vt(s):\n"                                                                                  \
    "    out = []\n"                                                                                 \
    "    for part in s.split('.'):\n"                                                                \
    "        digits = ''.join(ch for ch in part if ch.isdigit()) if part[:1].isdigit() else ''\n"   \
    "        if not digits: break\n"                                                             \
    "        out.append(int(digits))\n"                                                              \
    "    return tuple(out)\n"                                                                        \
    "_SYSLIBS = (('libffi.so.8', 'libffi8'), ('libstdc++.so.6', 'libstdc++6'), ('libgcc_s.so.1', 'libgcc-s1'),\n" \
    "            ('libz.so.1', 'zlib1g'))\n"                                                        \
    "def _syslibs():\n"                                                                             \
    "    try:\n"                                                                                     \
    "        import ctypes\n"                                                                        \
    "    except ImportError as e:\n"                                                                 \
    "        return ['the system library libffi.so.8 is missing (Debian/Ubuntu package libffi8; %s)' % e]\n" \
    "    out = []\n"                                                                                 \
    "    for lib, pkg in _SYSLIBS[1:]:\n"                                                            \
    "        try:\n"                                                                                 \
    "            ctypes.CDLL(lib)\n"                                                                 \
    "        except OSError:\n"                                                                      \
    "            out.append('the system library %s is missing (Debian/Ubuntu package %s)' % (lib, pkg))\n" \
    "    return out\n"                                                                               \
    "def _exe():\n"                                                                                  \
    "    import os, sys\n"                                                                           \
    "    own = os.path.join(sys.prefix, 'bin', 'python%d.%d' % sys.version_info[:2])\n"               \
    "    exe = sys.executable or ''\n"                                                               \
    "    inside = exe and os.path.realpath(exe).startswith(os.path.realpath(sys.prefix) + os.sep)\n"  \
    "    return exe if inside else own\n"                                                             \
    "def _fit(requires, min_python):\n"                                                              \
    "    import sys, re, importlib, importlib.metadata as md\n"                                      \
    "    why = []\n"                                                                                 \
    "    if min_python and sys.version_info[:2] < _vt(min_python):\n"                                \
    "        why.append('Python %d.%d is older than %s' % (sys.version_info[0], sys.version_info[1], min_python))\n" \
    "        return why\n"                                                                           \
    "    why += _syslibs()\n"                                                                        \
    "    for req in requires.split():\n"                                                             \
    "        name = re.match(r'[A-Za-z0-9_.-]+', req).group(0)\n"                                    \
    "        try:\n"                                                                                 \
    "            have = md.version(name)\n"                                                          \
    "        except md.PackageNotFoundError:\n"                                                      \
    "            why.append('%s is not installed' % name)\n"                                         \
    "            continue\n"                                                                         \
    "        for op, v in re.findall(r'(>=|<=|==|<|>)([0-9][0-9A-Za-z.]*)', req[len(name):]):\n"  \
    "            a, b = _vt(have), _vt(v)\n"                                                         \
    "            ok = {'>=': a >= b, '<=': a <= b, '==': a == b, '<': a < b, '>': a > b}[op]\n"      \
    "            if not ok:\n"                                                                       \
    "                why.append('%s %s does not satisfy %s' % (name, have, req))\n"                  \
    "        try:\n"                                                                                 \
    "            importlib.import_module(name)\n"                                                    \
    "        except Exception as e:\n"                                                               \
    "            why.append('import %s failed: %s: %s' % (name, type(e).__name__, e))\n"             \
    "    return why\n"

static const char *PROBE =
    "import sys, os, site, sysconfig\n" FIT_CODE
    "d = sysconfig.get_config_var('LIBDIR') or ''\n"
    "lib = ''\n"
    "for n in (sysconfig.get_config_var('INSTSONAME'), sysconfig.get_config_var('LDLIBRARY')):\n"
    "    if n and '.so' in n and os.path.isfile(os.path.join(d, n)):\n"
    "        lib = os.path.join(d, n)\n"
    "        break\n"
    "print('version', '%d.%d.%d' % sys.version_info[:3])\n"
    "print('libpython', lib)\n"
    "print('home', sys.base_prefix)\n"
    "for p in site.getsitepackages():\n"
    "    print('path', p)\n"
    "for w in _fit(os.environ.get('PYFMU_REQUIRES', ''), os.environ.get('PYFMU_MIN_PYTHON', '')):\n"
    "    print('unfit', w)\n";

const char *BOOTSTRAP =
    "import sys, site, importlib.util, traceback\n" FIT_CODE
    "def _format(t, v, tb):\n"
    "    return ''.join(traceback.format_exception(t, v, tb))\n"
    "class FmuEnvironmentError(RuntimeError):\n"
    "    pass\n"
    "def _load(paths, model_file, modname, requires, min_python):\n"
    "    for p in paths.split('\\n'):\n"
    "        if p and p not in sys.path:\n"
    "            site.addsitedir(p)\n"
    "    cache = sys.__dict__.setdefault('_pyfmu_fit', {})\n"
    "    key = (requires, min_python)\n"
    "    if key not in cache:\n"
    "        cache[key] = _fit(requires, min_python)\n"
    "    why = cache[key]\n"
    "    if why:\n"
    "        raise FmuEnvironmentError('the Python running this FMU (%s, %s) cannot run its model: %s. '\n"
    "            'Install what it needs into that Python: %s -m pip install %s '\n"
    "            '(see documentation/index.html in the FMU)'\n"
    "            % (_exe(), sys.version.split()[0], '; '.join(why), _exe(),\n"
    "               ' '.join('\"%s\"' % r for r in requires.split())))\n"
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
    RESOLVE(IsFinalizing, "Py_IsFinalizing", 1);
    if (!py.IsFinalizing) RESOLVE(IsFinalizing, "_Py_IsFinalizing", 1);
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

/* ---- finding a Python for a C host ----------------------------------------------------------- */
typedef struct {
    char exe[1024], version[32], libpython[1024], home[1024], paths[8192], unfit[2048];
    int bundled; /* the standalone FMU's own runtime */
} Probe;

static char g_paths[8192]; /* site folders of the chosen interpreter, added by the bootstrap */
static char g_origin[1400]; /* which Python runs the models, for the log */
static wchar_t *g_home = NULL;

/* open() instead of stat(): stat is versioned GLIBC_2.33 and would raise the glibc needed. */
static int is_dir(const char *p) {
    int fd = open(p, O_RDONLY | O_DIRECTORY);
    if (fd < 0) return 0;
    close(fd);
    return 1;
}
static int is_file(const char *p) { return access(p, F_OK) == 0 && !is_dir(p); }

/* A python executable, or a virtual environment / installation folder holding bin/python3. */
static void candidate_exe(const char *given, char *out, size_t n) {
    if (is_dir(given)) {
        static const char *names[] = {"bin/python3", "bin/python"};
        for (int i = 0; i < 2; i++) {
            snprintf(out, n, "%s/%s", given, names[i]);
            if (is_file(out)) return;
        }
    }
    snprintf(out, n, "%s", given);
}

static void shell_quote(const char *s, char *out, size_t n) {
    size_t j = 0;
    if (j + 1 < n) out[j++] = '\'';
    for (; *s && j + 5 < n; s++) {
        if (*s == '\'') { memcpy(out + j, "'\\''", 4); j += 4; }
        else out[j++] = *s;
    }
    if (j + 1 < n) out[j++] = '\'';
    out[j] = 0;
}

/* Run the candidate with the probe script; 1 if it fits (else why in pr->unfit). */
static int probe(const char *given, const Config *cfg, Probe *pr) {
    memset(pr, 0, sizeof *pr);
    candidate_exe(given, pr->exe, sizeof pr->exe);
    if (!is_file(pr->exe) || access(pr->exe, X_OK) != 0) {
        snprintf(pr->unfit, sizeof pr->unfit, "no executable %s", pr->exe);
        return 0;
    }
    char script[] = "/tmp/pyfmu_probe_XXXXXX";
    int fd = mkstemp(script);
    if (fd < 0) {
        snprintf(pr->unfit, sizeof pr->unfit, "cannot write a probe script in /tmp");
        return 0;
    }
    ssize_t len = (ssize_t)strlen(PROBE);
    int wrote = write(fd, PROBE, (size_t)len) == len;
    close(fd);
    char qexe[2100], qreq[1100], qmin[64], qscript[100], cmd[4096];
    shell_quote(pr->exe, qexe, sizeof qexe);
    shell_quote(cfg->requires, qreq, sizeof qreq);
    shell_quote(cfg->min_python, qmin, sizeof qmin);
    shell_quote(script, qscript, sizeof qscript);
    snprintf(cmd, sizeof cmd, "PYFMU_REQUIRES=%s PYFMU_MIN_PYTHON=%s PYTHONHOME= PYTHONPATH= %s -I %s 2>&1", qreq, qmin,
             qexe, qscript);
    FILE *p = wrote ? popen(cmd, "r") : NULL;
    if (!p) {
        unlink(script);
        snprintf(pr->unfit, sizeof pr->unfit, "cannot run %s", pr->exe);
        return 0;
    }
    char line[4096], other[512] = "";
    while (fgets(line, sizeof line, p)) {
        line[strcspn(line, "\n")] = 0;
        if (!strncmp(line, "version ", 8)) snprintf(pr->version, sizeof pr->version, "%s", line + 8);
        else if (!strncmp(line, "libpython ", 10)) snprintf(pr->libpython, sizeof pr->libpython, "%s", line + 10);
        else if (!strncmp(line, "home ", 5)) snprintf(pr->home, sizeof pr->home, "%s", line + 5);
        else if (!strncmp(line, "path ", 5)) {
            size_t k = strlen(pr->paths);
            snprintf(pr->paths + k, sizeof pr->paths - k, "%s\n", line + 5);
        } else if (!strncmp(line, "unfit ", 6)) {
            size_t k = strlen(pr->unfit);
            snprintf(pr->unfit + k, sizeof pr->unfit - k, "%s%s", k ? "; " : "", line + 6);
        } else if (!other[0]) snprintf(other, sizeof other, "%s", line);
    }
    int rc = pclose(p);
    unlink(script);
    if (!pr->version[0]) {
        snprintf(pr->unfit, sizeof pr->unfit, "%s did not run (exit status %d%s%s)", pr->exe, rc, other[0] ? ": " : "", other);
        return 0;
    }
    if (!pr->libpython[0]) {
        size_t k = strlen(pr->unfit);
        snprintf(pr->unfit + k, sizeof pr->unfit - k, "%sPython %s has no shared libpython (build it with --enable-shared)",
                 k ? "; " : "", pr->version);
    }
    return pr->unfit[0] == 0;
}

/* The runtime of a standalone FMU (resources/<runtime>): fits if its files are there. */
static int bundled(const Config *cfg, const char *resdir, Probe *pr) {
    memset(pr, 0, sizeof *pr);
    pr->bundled = 1;
    snprintf(pr->home, sizeof pr->home, "%s/%s", resdir, cfg->runtime);
    snprintf(pr->exe, sizeof pr->exe, "%s (bundled runtime)", pr->home);
    snprintf(pr->version, sizeof pr->version, "%s", cfg->runtime_version);
    snprintf(pr->libpython, sizeof pr->libpython, "%s/%s", resdir, cfg->runtime_libpython);
    if (!cfg->runtime_libpython[0] || !is_file(pr->libpython)) {
        snprintf(pr->unfit, sizeof pr->unfit, "no file %s", pr->libpython);
        return 0;
    }
    if (!is_dir(pr->home)) {
        snprintf(pr->unfit, sizeof pr->unfit, "no folder %s", pr->home);
        return 0;
    }
    return 1;
}

static int find_python(const Config *cfg, const char *resdir, Probe *chosen, char *err, size_t nerr) {
    const char *cands[3];
    const char *labels[3] = {"PYFMU_PYTHON", "the FMU's bundled runtime", "the build's interpreter"};
    cands[0] = getenv("PYFMU_PYTHON");
    cands[1] = cfg->runtime[0] ? cfg->runtime : NULL;
    cands[2] = cfg->python[0] ? cfg->python : NULL;
    char tried[3000] = "";
    for (int i = 0; i < 3; i++) {
        size_t k = strlen(tried);
        if (!cands[i] || !cands[i][0]) {
            if (i != 1) /* a non-standalone FMU has no runtime: not worth a word */
                snprintf(tried + k, sizeof tried - k, "%s%s: not set", k ? "; " : "", labels[i]);
            continue;
        }
        if (i == 1 ? bundled(cfg, resdir, chosen) : probe(cands[i], cfg, chosen)) return 1;
        snprintf(tried + k, sizeof tried - k, "%s%s = %s: %s", k ? "; " : "", labels[i], cands[i], chosen->unfit);
    }
    char quoted[1100] = ""; /* "numpy>=1.26" "numba>=0.59": unquoted, a shell reads >= as a redirection */
    char reqs[512];
    snprintf(reqs, sizeof reqs, "%s", cfg->requires);
    for (char *tok = strtok(reqs, " "); tok; tok = strtok(NULL, " ")) {
        size_t k = strlen(quoted);
        snprintf(quoted + k, sizeof quoted - k, "%s\"%s\"", k ? " " : "", tok);
    }
    snprintf(err, nerr,
             "no Python that can run this FMU was found. Tried, in order: %s. Install Python >= %s built with "
             "--enable-shared, run `python -m pip install %s` in it, and set PYFMU_PYTHON to that python "
             "executable or virtual environment folder (see %s)",
             tried, cfg->min_python[0] ? cfg->min_python : "3.11", quoted, PYFMU_DOC);
    return 0;
}

int ensure_python(const Config *cfg, const char *resdir, char *err, size_t nerr) {
    pthread_mutex_lock(&g_lock);
    int ok = 1;
    Probe pr;
    int probed = 0;
    if (!g_py_ready) {
        void *h = RTLD_DEFAULT;
        if (dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
            g_host_python = 1;
        } else {
            ok = find_python(cfg, resdir, &pr, err, nerr);
            if (ok) {
                probed = 1;
                h = g_lib = dlopen(pr.libpython, RTLD_NOW | RTLD_GLOBAL);
                if (!h) {
                    snprintf(err, nerr, "cannot load libpython %s of %s: %s", pr.libpython, pr.exe, dlerror());
                    ok = 0;
                }
            }
        }
        if (ok) ok = resolve_python(h, err, nerr);
        if (ok) g_py_ready = 1;
    }
    if (ok && py.IsFinalizing && py.IsFinalizing()) { /* the host's interpreter is shutting down */
        snprintf(err, nerr, "the Python of this process is being shut down; the model cannot be loaded");
        ok = 0;
    }
    if (ok && !py.IsInitialized()) {
        if (!probed) ok = find_python(cfg, resdir, &pr, err, nerr); /* libpython of a host that did not start it */
        if (ok) {
            snprintf(g_paths, sizeof g_paths, "%s", pr.paths);
            snprintf(g_origin, sizeof g_origin, "Python %s from %s, libpython %s", pr.version, pr.exe, pr.libpython);
            if (pr.bundled) {
                /* isolated, UTF-8 mode, home resources/python: PyConfig (py_config.c) */
                ok = pyconfig_start_isolated(g_lib ? g_lib : RTLD_DEFAULT, pr.home, err, nerr);
            } else {
                /* a Python of any version >= 3.11 found on the machine: no PyConfig (its layout
                 * is per version and this binary has no headers of it); Py_SetPythonHome and
                 * Py_InitializeEx, deprecated since 3.11, present up to 3.15 */
                if (py.SetPythonHome && pr.home[0] && !g_home) {
                    g_home = py.DecodeLocale(pr.home, NULL); /* must outlive the interpreter */
                    if (g_home) py.SetPythonHome(g_home);
                }
                py.InitializeEx(0);
            }
            if (ok && !py.IsInitialized()) {
                snprintf(err, nerr, "%s failed for %s", pr.bundled ? "Py_InitializeFromConfig" : "Py_InitializeEx",
                         pr.exe);
                ok = 0;
            }
            if (ok) {
                py.SaveThread(); /* this thread keeps its thread state; the GIL is released */
                tls_primed = 1;
            }
        }
    }
    pthread_mutex_unlock(&g_lock);
    return ok;
}

const char *python_site_paths(void) { return g_paths; }
const char *python_origin(void) { return g_host_python ? "the host's running Python" : g_origin; }
int python_is_host(void) { return g_host_python; }

int py_usable(void) {
    return g_py_ready && py.IsInitialized() && !(py.IsFinalizing && py.IsFinalizing());
}

/* Take the GIL; a thread calling for the first time gets a thread state that it keeps. */
int gil_take(void) {
    if (!tls_primed) {
        if (py.GILThisThreadState() == NULL) {
            py.GILEnsure();  /* creates this thread's state (kept: the count never drops to 0) */
            py.SaveThread(); /* ... and releases the GIL again */
        }
        tls_primed = 1;
    }
    return py.GILEnsure();
}

/* Report the pending Python exception (if any) with its traceback. Call with the GIL. */
void report_py_exception(Comp *c, const char *f) {
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
fmi2Status py_status(Comp *c, const char *f, PyObject *r) {
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
        snprintf(prefix, sizeof prefix, "%s: %s in the model\n", f, st == fmi2Warning ? "warning" : "error");
        if (e) {
            loglong(c, st == fmi2Warning ? fmi2Warning : fmi2Error, "logStatusError", prefix, py.UnicodeAsUTF8(e));
            py.DecRef(e);
        }
        py.ErrClear();
    }
    if (st < 0 || st > fmi2Fatal) return fmi2Error;
    return (fmi2Status)st;
}

/* The Python-hosted FMU is co-simulation only (Model Exchange: native FMUs, native/native_me.c). */
const MeModel *me_model(void) { return NULL; }
