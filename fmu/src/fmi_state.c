/*
 * FMU state: the C value buffers + the slave's own state bytes.
 *
 * Every state handed out is registered; a pointer that is not a live state of this library is
 * refused without being dereferenced. Each state carries the fingerprint of its FMU's GUID, so a
 * state (or serialized bytes) of another FMU is refused, and the id of the instance it belongs to:
 * a state is used only by its own instance (another instance of the same FMU refuses it; moving a
 * state between instances goes through fmi2SerializeFMUstate / fmi2DeSerializeFMUstate), and
 * fmi2FreeInstance frees every state of the instance that the host left alive, after which those
 * pointers are refused like any freed state. Sizes of serialized bytes are checked
 * with overflow-safe arithmetic: the fixed part is computed from this FMU's own table, and the
 * variable part must equal what is left of the given size.
 */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyfmu.h"

typedef struct {
    uint32_t magic, nvr;
    int32_t state, dirty;
    double time;
    uint64_t fingerprint;
    uint64_t owner; /* Comp.id of the instance the state belongs to */
    double *reals, *derivs;
    int32_t *ints;
    char *pystate;
    size_t pylen;
} FmuState;
#define STATE_MAGIC 0x50594d56u
#define HEADER_BYTES 48 /* u32 magic, u32 nvr, i32 state, i32 dirty, f64 time, u64 fingerprint, u64 pylen, u64 reserved */

/* ---- registry of live states ------------------------------------------------------------------ */
static pthread_mutex_t g_states_lock = PTHREAD_MUTEX_INITIALIZER;
static FmuState **g_states = NULL;
static size_t g_nstates = 0, g_capstates = 0;

static int registry_add(FmuState *s) {
    pthread_mutex_lock(&g_states_lock);
    int ok = 1;
    if (g_nstates == g_capstates) {
        size_t cap = g_capstates ? 2 * g_capstates : 16;
        FmuState **n = realloc(g_states, cap * sizeof *n);
        if (n) {
            g_states = n;
            g_capstates = cap;
        } else ok = 0;
    }
    if (ok) g_states[g_nstates++] = s;
    pthread_mutex_unlock(&g_states_lock);
    return ok;
}

static int registry_has(const void *s) {
    pthread_mutex_lock(&g_states_lock);
    int found = 0;
    for (size_t i = 0; i < g_nstates && !found; i++) found = g_states[i] == s;
    pthread_mutex_unlock(&g_states_lock);
    return found;
}

static void registry_remove(const void *s) {
    pthread_mutex_lock(&g_states_lock);
    for (size_t i = 0; i < g_nstates; i++)
        if (g_states[i] == s) {
            g_states[i] = g_states[--g_nstates];
            break;
        }
    pthread_mutex_unlock(&g_states_lock);
}

/* The memory of one state (already out of the registry). */
static void release_state(FmuState *s) {
    free(s->reals);
    free(s->derivs);
    free(s->ints);
    free(s->pystate);
    s->magic = 0;
    free(s);
}

static void free_state(FmuState *s) {
    if (!s) return;
    registry_remove(s);
    release_state(s);
}

/* Free every state of one instance (fmi2FreeInstance); the number freed. */
size_t free_states_of(uint64_t instance_id) {
    size_t n = 0;
    pthread_mutex_lock(&g_states_lock);
    for (size_t i = 0; i < g_nstates;) {
        FmuState *s = g_states[i];
        if (s->owner == instance_id) {
            g_states[i] = g_states[--g_nstates];
            release_state(s);
            n++;
        } else i++;
    }
    if (g_nstates == 0) { /* the last state is gone: give the table back too */
        free(g_states);
        g_states = NULL;
        g_capstates = 0;
    }
    pthread_mutex_unlock(&g_states_lock);
    return n;
}

/* A live state of this instance, or NULL (logged). */
static FmuState *own_state(Comp *c, const char *f, const void *p) {
    if (!registry_has(p)) {
        logmsg(c, fmi2Error, "logStatusError",
               "%s: %p is not a live FMU state (unknown, freed, or freed with its instance by fmi2FreeInstance)", f, p);
        return NULL;
    }
    FmuState *s = (FmuState *)p;
    if (s->magic != STATE_MAGIC || s->fingerprint != c->fingerprint || s->nvr != (uint32_t)c->nvr) {
        logmsg(c, fmi2Error, "logStatusError", "%s: the FMU state belongs to another FMU", f);
        return NULL;
    }
    if (s->owner != c->id) {
        logmsg(c, fmi2Error, "logStatusError",
               "%s: the FMU state belongs to another instance of this FMU (a state is used by the instance that "
               "made it; to move one, serialize it and deserialize it in the other instance)", f);
        return NULL;
    }
    return s;
}

static FmuState *new_state(Comp *c) {
    FmuState *s = calloc(1, sizeof(FmuState));
    if (!s) return NULL;
    s->magic = STATE_MAGIC;
    s->nvr = (uint32_t)c->nvr;
    s->fingerprint = c->fingerprint;
    s->owner = c->id;
    s->reals = malloc(sizeof(double) * (size_t)c->nvr);
    s->derivs = malloc(2 * sizeof(double) * (size_t)c->nvr);
    s->ints = malloc(sizeof(int32_t) * (size_t)c->nvr);
    if (!s->reals || !s->derivs || !s->ints || !registry_add(s)) {
        free(s->reals);
        free(s->derivs);
        free(s->ints);
        free(s);
        return NULL;
    }
    return s;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2GetFMUstate", M_ANY_BUT_FATAL);
    NEED_PY("fmi2GetFMUstate");
    NULLARG("fmi2GetFMUstate", FMUstate);
    FmuState *s = NULL;
    if (*FMUstate && !(s = own_state(c, "fmi2GetFMUstate", *FMUstate))) return fmi2Error;
    int g = gil_take();
    PyObject *r = py.CallFunction(c->m_get, NULL);
    char *buf = NULL;
    Py_ssize_t len = 0;
    fmi2Status st = fmi2OK;
    if (!r) {
        report_py_exception(c, "fmi2GetFMUstate");
        st = fmi2Error;
    } else if (r == py.NoneStruct || py.BytesAsStringAndSize(r, &buf, &len) != 0 || len < 0) {
        if (r != py.NoneStruct) report_py_exception(c, "fmi2GetFMUstate");
        else {
            PyObject *e = py.GetAttrString(c->slave, "last_error");
            loglong(c, fmi2Error, "logStatusError", "fmi2GetFMUstate: error in the model\n", e ? py.UnicodeAsUTF8(e) : "");
            if (e) py.DecRef(e);
            py.ErrClear();
        }
        st = fmi2Error;
    }
    if (st == fmi2OK) {
        int fresh = s == NULL;
        char *copy = malloc(len ? (size_t)len : 1);
        if (fresh) s = new_state(c);
        if (!s || !copy) {
            free(copy);
            logmsg(c, fmi2Error, "logStatusError", "fmi2GetFMUstate: out of memory");
            st = fmi2Error;
        } else {
            memcpy(copy, buf, (size_t)len);
            free(s->pystate);
            s->pystate = copy;
            s->pylen = (size_t)len;
            memcpy(s->reals, c->reals, sizeof(double) * (size_t)c->nvr);
            memcpy(s->derivs, c->derivs, 2 * sizeof(double) * (size_t)c->nvr);
            memcpy(s->ints, c->ints, sizeof(int32_t) * (size_t)c->nvr);
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
    NEED_PY("fmi2SetFMUstate");
    NULLARG("fmi2SetFMUstate", FMUstate);
    FmuState *s = own_state(c, "fmi2SetFMUstate", FMUstate);
    if (!s) return fmi2Error;
    int g = gil_take();
    PyObject *b = py.BytesFromStringAndSize(s->pystate, (Py_ssize_t)s->pylen);
    fmi2Status st = py_status(c, "fmi2SetFMUstate", b ? py.CallFunction(c->m_set, "O", b) : NULL);
    if (b) py.DecRef(b);
    GIL_DROP(g);
    if (st > fmi2Warning) return st;
    memcpy(c->reals, s->reals, sizeof(double) * (size_t)c->nvr);
    memcpy(c->derivs, s->derivs, 2 * sizeof(double) * (size_t)c->nvr);
    memcpy(c->ints, s->ints, sizeof(int32_t) * (size_t)c->nvr);
    c->state = s->state;
    c->dirty = s->dirty;
    c->time = s->time;
    return st;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2FreeFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2FreeFMUstate", FMUstate);
    if (*FMUstate == NULL) return fmi2OK;
    if (!own_state(c, "fmi2FreeFMUstate", *FMUstate)) return fmi2Error;
    free_state((FmuState *)*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

/* Bytes of the fixed part (header + value buffers) for this FMU's table: small, cannot overflow. */
static size_t fixed_bytes(const Comp *c) { return HEADER_BYTES + (size_t)c->nvr * (3 * sizeof(double) + sizeof(int32_t)); }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SerializedFMUstateSize", M_ANY_BUT_FATAL);
    NULLARG("fmi2SerializedFMUstateSize", FMUstate);
    NULLARG("fmi2SerializedFMUstateSize", size);
    FmuState *s = own_state(c, "fmi2SerializedFMUstateSize", FMUstate);
    if (!s) return fmi2Error;
    *size = fixed_bytes(c) + s->pylen;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte out[], size_t size) {
    Comp *c = (Comp *)comp;
    CHECK("fmi2SerializeFMUstate", M_ANY_BUT_FATAL);
    NULLARG("fmi2SerializeFMUstate", FMUstate);
    NULLARG("fmi2SerializeFMUstate", out);
    FmuState *s = own_state(c, "fmi2SerializeFMUstate", FMUstate);
    if (!s) return fmi2Error;
    size_t need = fixed_bytes(c) + s->pylen;
    if (size < need) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2SerializeFMUstate: buffer of %zu bytes, %zu needed", size, need);
        return fmi2Error;
    }
    char *p = out;
    uint64_t pylen = s->pylen, reserved = 0;
    size_t nv = (size_t)s->nvr;
    memcpy(p, &s->magic, 4); p += 4;
    memcpy(p, &s->nvr, 4); p += 4;
    memcpy(p, &s->state, 4); p += 4;
    memcpy(p, &s->dirty, 4); p += 4;
    memcpy(p, &s->time, 8); p += 8;
    memcpy(p, &s->fingerprint, 8); p += 8;
    memcpy(p, &pylen, 8); p += 8;
    memcpy(p, &reserved, 8); p += 8;
    memcpy(p, s->reals, sizeof(double) * nv); p += sizeof(double) * nv;
    memcpy(p, s->derivs, 2 * sizeof(double) * nv); p += 2 * sizeof(double) * nv;
    memcpy(p, s->ints, sizeof(int32_t) * nv); p += sizeof(int32_t) * nv;
    memcpy(p, s->pystate, s->pylen);
    return fmi2OK;
}

/* A state of the instance's kind: co-simulation (step complete, step failed) or Model Exchange (event mode,
 * continuous-time mode), or one both share. */
static int valid_fmi_state(const Comp *c, int32_t st) {
    if (st == S_INSTANTIATED || st == S_INIT || st == S_TERMINATED || st == S_ERROR) return 1;
    return c->me ? (st == S_EVENT || st == S_CONT) : (st == S_STEP_COMPLETE || st == S_STEP_FAILED);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte in[], size_t size, fmi2FMUstate *FMUstate) {
    Comp *c = (Comp *)comp;
    const char *f = "fmi2DeSerializeFMUstate";
    CHECK(f, M_ANY_BUT_FATAL);
    NULLARG(f, in);
    NULLARG(f, FMUstate);
    if (*FMUstate && !own_state(c, f, *FMUstate)) return fmi2Error;
    size_t fixed = fixed_bytes(c);
    if (size < fixed) {
        logmsg(c, fmi2Error, "logStatusError", "%s: %zu bytes, a state of this FMU has at least %zu", f, size, fixed);
        return fmi2Error;
    }
    FmuState h = {0};
    uint64_t pylen = 0, reserved = 0;
    memcpy(&h.magic, in, 4);
    memcpy(&h.nvr, in + 4, 4);
    memcpy(&h.state, in + 8, 4);
    memcpy(&h.dirty, in + 12, 4);
    memcpy(&h.time, in + 16, 8);
    memcpy(&h.fingerprint, in + 24, 8);
    memcpy(&pylen, in + 32, 8);
    memcpy(&reserved, in + 40, 8);
    const char *why = NULL;
    if (h.magic != STATE_MAGIC) why = "not a serialized FMU state (bad magic number)";
    else if (h.fingerprint != c->fingerprint || h.nvr != (uint32_t)c->nvr) why = "a state of another FMU";
    else if (pylen != (uint64_t)(size - fixed)) why = "its length field does not match the number of bytes";
    else if (!valid_fmi_state(c, h.state)) why = "its FMI state field is not a valid state";
    else if (h.dirty != 0 && h.dirty != 1) why = "its flags are corrupt";
    else if (!isfinite(h.time)) why = "its time is not finite";
    else if (reserved != 0) why = "its reserved field is not zero";
    if (why) {
        logmsg(c, fmi2Error, "logStatusError", "%s: refused: %s", f, why);
        return fmi2Error;
    }
    FmuState *s = new_state(c);
    char *py_bytes = malloc(pylen ? (size_t)pylen : 1);
    if (!s || !py_bytes) {
        free(py_bytes);
        free_state(s);
        logmsg(c, fmi2Error, "logStatusError", "%s: out of memory", f);
        return fmi2Error;
    }
    s->state = h.state;
    s->dirty = h.dirty;
    s->time = h.time;
    s->pystate = py_bytes;
    s->pylen = (size_t)pylen;
    size_t nv = (size_t)s->nvr;
    const char *p = in + HEADER_BYTES;
    memcpy(s->reals, p, sizeof(double) * nv); p += sizeof(double) * nv;
    memcpy(s->derivs, p, 2 * sizeof(double) * nv); p += 2 * sizeof(double) * nv;
    memcpy(s->ints, p, sizeof(int32_t) * nv); p += sizeof(int32_t) * nv;
    memcpy(s->pystate, p, s->pylen);
    if (*FMUstate) free_state((FmuState *)*FMUstate);
    *FMUstate = s;
    return fmi2OK;
}
