/* Reading resources/: pyfmu.cfg (GUID, model file, the build's interpreter and requirements, a
 * standalone FMU's bundled runtime),
 * variables.tsv (the variable table) and the resource location URI. */
#define _GNU_SOURCE
#if defined(_WIN32)
#include <windows.h>
#else
#include <dlfcn.h>
#endif
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyfmu.h"

static void chomp(char *s) {
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\n' || s[n - 1] == '\r')) s[--n] = 0;
}

int read_config(const char *resdir, Config *cfg, char *err, size_t nerr) {
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
        else if (!strcmp(k, "model")) snprintf(cfg->model, sizeof cfg->model, "%s", v);
        else if (!strcmp(k, "python")) snprintf(cfg->python, sizeof cfg->python, "%s", v);
        else if (!strcmp(k, "python_version")) snprintf(cfg->python_version, sizeof cfg->python_version, "%s", v);
        else if (!strcmp(k, "requires")) snprintf(cfg->requires, sizeof cfg->requires, "%s", v);
        else if (!strcmp(k, "min_python")) snprintf(cfg->min_python, sizeof cfg->min_python, "%s", v);
        else if (!strcmp(k, "runtime")) snprintf(cfg->runtime, sizeof cfg->runtime, "%s", v);
        else if (!strcmp(k, "runtime_libpython")) snprintf(cfg->runtime_libpython, sizeof cfg->runtime_libpython, "%s", v);
        else if (!strcmp(k, "runtime_version")) snprintf(cfg->runtime_version, sizeof cfg->runtime_version, "%s", v);
    }
    fclose(f);
    if (!cfg->guid[0]) {
        snprintf(err, nerr, "%.1900s has no guid", path);
        return 0;
    }
    return 1;
}

int code_of(const char *s, const char *const *names, int n) {
    for (int i = 0; i < n; i++)
        if (!strcmp(s, names[i])) return i + 1;
    return 0;
}

/* FNV-1a: identifies the FMU (by its GUID) inside FMU states and serialized bytes. */
uint64_t fingerprint_of(const char *s) {
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++) h = (h ^ (unsigned char)*s) * 1099511628211ull;
    return h;
}

int read_variables(Comp *c, const char *resdir, char *err, size_t nerr) {
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
    c->vname = calloc(c->nvr, sizeof(char *));
    c->vmin = malloc(c->nvr * sizeof(double));
    c->vmax = malloc(c->nvr * sizeof(double));
    c->vlo = malloc(c->nvr * sizeof(double));
    c->vexcl = calloc(c->nvr, 1);
    if (!c->vtype || !c->vcaus || !c->vvar || !c->vname || !c->vmin || !c->vlo || !c->vmax || !c->vexcl) {
        fclose(f);
        snprintf(err, nerr, "out of memory");
        return 0;
    }
    for (int i = 0; i < c->nvr; i++) {
        c->vmin[i] = -INFINITY;
        c->vlo[i] = -INFINITY;
        c->vmax[i] = INFINITY;
    }
    rewind(f);
    while (fgets(line, sizeof line, f)) {
        int vr, excl = 0;
        char t[8], ca[32], va[32], name[256] = "", lo[64] = "-inf", hi[64] = "inf", dlo[64] = "";
        int n = sscanf(line, "%d %7s %31s %31s %255s %63s %63s %d %63s", &vr, t, ca, va, name, lo, hi, &excl, dlo);
        if (n < 4 || vr < 0 || vr >= c->nvr) continue;
        c->vtype[vr] = t[0];
        c->vcaus[vr] = (char)code_of(ca, caus, 6);
        c->vvar[vr] = (char)code_of(va, var, 5);
        if (n >= 5) c->vname[vr] = strdup(name);
        if (n >= 7) {
            c->vmin[vr] = strtod(lo, NULL);
            c->vlo[vr] = c->vmin[vr];
            c->vmax[vr] = strtod(hi, NULL);
        }
        if (n >= 9) c->vlo[vr] = strtod(dlo, NULL); /* the declared (inclusive) minimum: enforced */
        if (n >= 8) c->vexcl[vr] = excl != 0;
        c->nvars++;
    }
    fclose(f);
    return 1;
}

const char *var_name(const Comp *c, unsigned vr) {
    return c->vname && vr < (unsigned)c->nvr && c->vname[vr] ? c->vname[vr] : "?";
}

/* The shortest %g form, from 6 digits on, that reads back as v (1e-10, -40000, 0.1; not 1.0000000000000000364e-10). */
void fmt_double(double v, char *out, size_t n) {
    for (int p = 6; p <= 17; p++) {
        snprintf(out, n, "%.*g", p, v);
        if (strtod(out, NULL) == v) return;
    }
}

void uri_to_path(const char *uri, char *out, size_t n) {
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
#if defined(_WIN32)
    /* file:///C:/dir -> /C:/dir -> C:/dir */
    if (out[0] == '/' && out[1] && out[2] == ':') memmove(out, out + 1, strlen(out));
#endif
}

void resources_from_library(char *out, size_t n) {
    out[0] = 0;
#if defined(_WIN32)
    HMODULE mod = NULL;
    if (!GetModuleHandleExA(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                            (LPCSTR)(void *)&resources_from_library, &mod) ||
        !GetModuleFileNameA(mod, out, (DWORD)n))
        return;
    for (char *q = out; *q; q++)
        if (*q == '\\') *q = '/';
#else
    Dl_info info;
    if (!dladdr((void *)&resources_from_library, &info) || !info.dli_fname) return;
    snprintf(out, n, "%s", info.dli_fname);
#endif
    for (int i = 0; i < 3; i++) { /* <fmu>/binaries/linux64/x.so -> <fmu> */
        char *s = strrchr(out, '/');
        if (s) *s = 0;
    }
    strncat(out, "/resources", n - strlen(out) - 1);
}
