/*
 * Fuzz harness for the FMUs: random FMI 2.0 call sequences, one forked subprocess per sequence.
 *
 *   fmu_fuzz SEED NSEQ NCALLS DIR_A GUID_A DIR_B GUID_B
 *
 * The parent loads both FMUs (dlopen RTLD_LOCAL, no Python in the host: the stub finds one),
 * instantiates each once to warm the interpreter, then forks one child per sequence. A child
 * runs NCALLS random calls on two instances of each FMU: valid calls (steps, inputs, outputs,
 * state get/set/serialize, directional derivatives, the lifecycle) mixed with invalid ones
 * (wrong states, bad value references, NaN/Inf values, times and step sizes, zero/negative/huge
 * steps, states of the other FMU, states of the other instance of the same FMU (a state belongs
 * to the instance that made it), garbage and freed state pointers, states freed with their
 * instance by fmi2FreeInstance, corrupt serialized bytes).
 * The harness tracks each instance's FMI state, so it knows which calls must be refused.
 * Checked per call: an invalid call returns neither fmi2OK nor fmi2Warning and logs an error;
 * a successful getReal gives finite values; a restored state gives bit-identical outputs and
 * re-serializes to identical bytes. A child killed by a signal is a crash; one that overruns its
 * alarm (60 s) is a hang. The parent prints the totals as "key value" lines.
 */
#include <dlfcn.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "fmi2Functions.h"

#define MAX_VR 1024 /* value references read from variables.tsv (the ShearFrame FMU's reach 619) */

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
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *ser_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
    fmi2GetDirectionalDerivativeTYPE *dd;
    fmi2SetRealInputDerivativesTYPE *set_der;
    /* variable table */
    int nvr, nin, nout;
    char type[MAX_VR], caus[MAX_VR];
    unsigned in[16], out[16];
    char dir[2048], guid[256], res[2100];
} Fmu;

typedef struct {
    uint64_t calls, invalid, invalid_ok, unlogged, valid_refused, nonfinite_ok, roundtrips, roundtrip_bad,
        serial_roundtrips, serial_bad, instantiations;
} Counts;

static uint64_t g_errors_logged = 0;
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat, fmi2String msg, ...) {
    (void)env; (void)name; (void)cat;
    if (st >= fmi2Error) g_errors_logged++;
    if (getenv("FMU_FUZZ_VERBOSE")) fprintf(stderr, "[%d] %.300s\n", st, msg);
}
static fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

static uint64_t rng_state;
static uint64_t rnd(void) {
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}
static int pick(int n) { return (int)(rnd() % (uint64_t)n); }
static double uniform(double a, double b) { return a + (b - a) * (double)(rnd() >> 11) / 9007199254740992.0; }

static void *sym(void *h, const char *n) {
    void *p = dlsym(h, n);
    if (!p) {
        fprintf(stderr, "missing %s\n", n);
        exit(2);
    }
    return p;
}

static void load(Fmu *f, const char *dir, const char *guid) {
    char path[4096];
    const char *id = strrchr(dir, '/');
    id = id ? id + 1 : dir;
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    f->h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->h) {
        fprintf(stderr, "dlopen %s: %s\n", path, dlerror());
        exit(2);
    }
#define S(field, name) *(void **)(&f->field) = sym(f->h, name)
    S(instantiate, "fmi2Instantiate"); S(free_instance, "fmi2FreeInstance"); S(setup, "fmi2SetupExperiment");
    S(enter, "fmi2EnterInitializationMode"); S(exit_init, "fmi2ExitInitializationMode");
    S(terminate, "fmi2Terminate"); S(reset, "fmi2Reset"); S(get_real, "fmi2GetReal"); S(set_real, "fmi2SetReal");
    S(get_integer, "fmi2GetInteger"); S(do_step, "fmi2DoStep"); S(get_state, "fmi2GetFMUstate");
    S(set_state, "fmi2SetFMUstate"); S(free_state, "fmi2FreeFMUstate"); S(ser_size, "fmi2SerializedFMUstateSize");
    S(serialize, "fmi2SerializeFMUstate"); S(deserialize, "fmi2DeSerializeFMUstate");
    S(dd, "fmi2GetDirectionalDerivative"); S(set_der, "fmi2SetRealInputDerivatives");
#undef S
    snprintf(f->dir, sizeof f->dir, "%s", dir);
    snprintf(f->guid, sizeof f->guid, "%s", guid);
    snprintf(f->res, sizeof f->res, "file://%s/resources", dir);
    snprintf(path, sizeof path, "%s/resources/variables.tsv", dir);
    FILE *t = fopen(path, "r");
    if (!t) exit(2);
    char line[512], ty[16], ca[64], va[64];
    int vr;
    while (fgets(line, sizeof line, t))
        if (sscanf(line, "%d %15s %63s %63s", &vr, ty, ca, va) == 4 && vr >= 0 && vr < MAX_VR) {
            f->type[vr] = ty[0];
            f->caus[vr] = ca[0] == 'i' ? 'i' : ca[0] == 'o' ? 'o' : 'p';
            if (vr + 1 > f->nvr) f->nvr = vr + 1;
            if (ca[0] == 'i' && ty[0] == 'R' && f->nin < 16) f->in[f->nin++] = (unsigned)vr;
            if (ca[0] == 'o' && ty[0] == 'R' && f->nout < 16) f->out[f->nout++] = (unsigned)vr;
        }
    fclose(t);
}

/* ---- instances and states ------------------------------------------------------------------- */
enum { INSTANTIATED, INIT, STEPPING, TERMINATED, DEAD };
typedef struct {
    Fmu *f;
    fmi2Component c;
    int st;
    double t;
} Inst;

#define MAXS 24
typedef struct {
    Fmu *f;
    void *owner; /* the Inst whose fmi2GetFMUstate / DeSerialize made it: only it may use the state */
    fmi2FMUstate s;
    int st;
    double t;
    int have_out;
    double out[16];
} Saved;

static Inst inst[4];
static Saved saved[MAXS];
static int nsaved = 0;
static void *freed[64];
static int nfreed = 0;
static Counts K;

static int is_live_state(void *p) {
    for (int i = 0; i < nsaved; i++)
        if (saved[i].s == p) return 1;
    return 0;
}

/* The instance is about to be freed: its states die with it (fmi2FreeInstance frees them); their
 * addresses join the freed ones, which every instance must refuse. */
static void drop_states_of(Inst *in) {
    for (int i = 0; i < nsaved;)
        if (saved[i].owner == in) {
            if (nfreed < 64) freed[nfreed++] = saved[i].s;
            saved[i] = saved[--nsaved];
        } else i++;
}

static void instantiate(Inst *in) {
    char name[64];
    snprintf(name, sizeof name, "fz%lu", (unsigned long)(rnd() % 100000));
    in->c = in->f->instantiate(name, fmi2CoSimulation, in->f->guid, in->f->res, &callbacks, fmi2False, fmi2False);
    in->st = in->c ? INSTANTIATED : DEAD;
    in->t = 0.0;
    K.instantiations++;
}

/* Check one call: valid 1 (must succeed or is counted as refused), invalid 0 (must be refused
 * and logged), unknown -1 (either). Returns 1 if the call succeeded. */
static int g_op = -1;
static int judge(int valid, fmi2Status s, uint64_t logs_before) {
    K.calls++;
    if (valid == 1 && s != fmi2OK && s != fmi2Warning && getenv("FMU_FUZZ_VERBOSE"))
        fprintf(stderr, "valid call refused: operation %d, status %d\n", g_op, s);
    int ok = s == fmi2OK || s == fmi2Warning;
    if (valid == 0) {
        K.invalid++;
        if (ok) K.invalid_ok++;
        else if (g_errors_logged == logs_before) K.unlogged++;
    } else if (valid == 1 && !ok) K.valid_refused++;
    return ok;
}

static void recover(Inst *in) { /* after a refused valid call: back to a known state */
    if (in->f->reset(in->c) == fmi2OK) {
        in->st = INSTANTIATED;
        in->t = 0.0;
    } else {
        drop_states_of(in);
        in->f->free_instance(in->c);
        instantiate(in);
    }
}

static double bad_double(void) {
    static const double v[] = {NAN, INFINITY, -INFINITY};
    return v[pick(3)];
}

static void op(void) {
    Inst *in = &inst[pick(4)];
    Fmu *f = in->f;
    if (in->st == DEAD) {
        instantiate(in);
        return;
    }
    uint64_t L = g_errors_logged;
    fmi2Status s;
    int k = pick(24);
    g_op = k;
    switch (k) {
    case 0: case 1: case 2: case 3: { /* valid doStep (valid only when stepping) */
        double h = (double[]){1e-3, 5e-4, 2e-3}[pick(3)];
        s = f->do_step(in->c, in->t, h, fmi2True);
        int valid = in->st == STEPPING;
        if (judge(valid, s, L)) in->t += h;
        else if (valid) recover(in);
        break;
    }
    case 4: { /* doStep with a bad step size */
        static const double hs[] = {NAN, INFINITY, -INFINITY, 0.0, -1e-3, 1e30, 1000.0, 100.000001};
        s = f->do_step(in->c, in->t, hs[pick(8)], fmi2True);
        judge(0, s, L);
        break;
    }
    case 5: { /* doStep at a bad communication point */
        double t = pick(2) ? bad_double() : in->t + 0.5;
        s = f->do_step(in->c, t, 1e-3, fmi2True);
        judge(0, s, L);
        break;
    }
    case 6: case 7: { /* set an input (a system FMU has none) */
        if (!f->nin) break;
        unsigned vr = f->in[pick(f->nin)];
        double v = uniform(-1e-2, 1e-2) * (f->nin == 1 ? 1e4 : 1.0);
        s = f->set_real(in->c, &vr, 1, &v);
        judge(in->st == INSTANTIATED || in->st == INIT || in->st == STEPPING, s, L);
        break;
    }
    case 8: { /* set an input to NaN/Inf, an output, an unknown or non-Real value reference */
        unsigned vr;
        double v = 1.0;
        int w = pick(4);
        if (w == 0 && !f->nin) w = 1; /* no input to set to NaN/Inf */
        if (w == 0) { vr = f->in[pick(f->nin)]; v = bad_double(); }
        else if (w == 1) vr = f->out[pick(f->nout)];
        else if (w == 2) vr = (unsigned)(f->nvr + pick(1000000));
        else { vr = 0; while (vr < (unsigned)f->nvr && f->type[vr] == 'R') vr++; if (vr >= (unsigned)f->nvr) vr = 4000000000u; }
        s = f->set_real(in->c, &vr, 1, &v);
        judge(0, s, L);
        break;
    }
    case 9: case 10: { /* read the outputs */
        double v[16];
        s = f->get_real(in->c, f->out, (size_t)f->nout, v);
        if (judge(in->st != INSTANTIATED, s, L))
            for (int i = 0; i < f->nout; i++)
                if (!isfinite(v[i])) K.nonfinite_ok++;
        break;
    }
    case 11: { /* read bad value references */
        unsigned vr = pick(2) ? (unsigned)(f->nvr + pick(1 << 30)) : (unsigned)f->nvr;
        double v;
        int iv;
        s = pick(2) ? f->get_real(in->c, &vr, 1, &v) : f->get_integer(in->c, &vr, 1, &iv);
        judge(0, s, L);
        break;
    }
    case 12: { /* the lifecycle: setup (sometimes with a bad start time), enter, exit */
        int w = pick(4);
        if (w == 0) {
            s = f->setup(in->c, fmi2False, 0.0, bad_double(), fmi2False, 0.0);
            judge(0, s, L);
        } else if (w == 1) {
            s = f->setup(in->c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            judge(in->st == INSTANTIATED, s, L);
        } else if (w == 2) {
            s = f->enter(in->c);
            if (judge(in->st == INSTANTIATED, s, L)) in->st = INIT;
        } else {
            s = f->exit_init(in->c);
            if (judge(in->st == INIT, s, L)) in->st = STEPPING;
        }
        break;
    }
    case 13: { /* terminate or reset */
        if (pick(2)) {
            s = f->terminate(in->c);
            if (judge(in->st == STEPPING, s, L)) in->st = TERMINATED;
        } else {
            s = f->reset(in->c);
            if (judge(1, s, L)) { in->st = INSTANTIATED; in->t = 0.0; }
        }
        break;
    }
    case 14: case 15: { /* get a state (new, or reusing one of this FMU, or one of the other FMU) */
        int w = pick(3);
        Saved *sv = NULL;
        if (w > 0 && nsaved) sv = &saved[pick(nsaved)];
        if (sv && (sv->f != f || sv->owner != in)) { /* another FMU's or another instance's state */
            fmi2FMUstate st = sv->s;
            s = f->get_state(in->c, &st);
            judge(0, s, L);
            break;
        }
        if (!sv && nsaved == MAXS) break;
        fmi2FMUstate st = sv ? sv->s : NULL;
        s = f->get_state(in->c, &st);
        if (judge(1, s, L)) {
            if (!sv) sv = &saved[nsaved++];
            sv->f = f; sv->owner = in; sv->s = st; sv->st = in->st; sv->t = in->t;
            sv->have_out = in->st == STEPPING && f->get_real(in->c, f->out, (size_t)f->nout, sv->out) == fmi2OK;
        }
        break;
    }
    case 16: case 17: { /* set a state: of this FMU (checked bit-identical), of the other, garbage, freed */
        int w = pick(4);
        if (w <= 1 && nsaved) {
            Saved *sv = &saved[pick(nsaved)];
            s = f->set_state(in->c, sv->s);
            if (judge(sv->owner == in, s, L) && sv->owner == in) {
                in->st = sv->st; in->t = sv->t;
                if (sv->have_out) {
                    double v[16];
                    K.roundtrips++;
                    if (f->get_real(in->c, f->out, (size_t)f->nout, v) != fmi2OK ||
                        memcmp(v, sv->out, sizeof(double) * (size_t)f->nout)) K.roundtrip_bad++;
                }
            }
        } else if (w == 2) {
            static char garbage[512];
            for (size_t i = 0; i < sizeof garbage; i++) garbage[i] = (char)rnd();
            s = f->set_state(in->c, (fmi2FMUstate)(garbage + pick(64)));
            judge(0, s, L);
        } else if (nfreed) {
            void *p = freed[pick(nfreed)];
            if (is_live_state(p)) break; /* the address was handed out again: a live state now */
            s = f->set_state(in->c, p);
            judge(0, s, L);
        }
        break;
    }
    case 18: { /* free a state */
        if (!nsaved) break;
        int i = pick(nsaved);
        if (saved[i].owner != in) {
            fmi2FMUstate st = saved[i].s;
            s = f->free_state(in->c, &st);
            judge(0, s, L);
            break;
        }
        void *p = saved[i].s;
        s = f->free_state(in->c, &saved[i].s);
        if (judge(1, s, L)) {
            if (nfreed < 64) freed[nfreed++] = p;
            saved[i] = saved[--nsaved];
        }
        break;
    }
    case 19: case 20: { /* serialize a state of this FMU, deserialize it (intact or corrupt) */
        Saved *sv = NULL;
        for (int tries = 0; tries < 4 && nsaved && !sv; tries++) {
            Saved *c = &saved[pick(nsaved)];
            if (c->owner == in) sv = c;
        }
        if (!sv) break;
        size_t n = 0;
        s = f->ser_size(in->c, sv->s, &n);
        if (!judge(1, s, L) || n < 48 || n > 1 << 20) break;
        char *b = malloc(n), *b2 = malloc(n);
        L = g_errors_logged;
        s = f->serialize(in->c, sv->s, b, n);
        if (judge(1, s, L)) {
            int corrupt = pick(2);
            Fmu *target = f;
            Inst *tin = in;
            size_t m = n;
            if (corrupt) {
                int w = pick(8);
                uint64_t len;
                switch (w) {
                case 0: b[pick(4)] ^= (char)(1 + pick(255)); break;                  /* magic */
                case 1: b[4 + pick(4)] ^= (char)(1 + pick(255)); break;              /* nvr */
                case 2: { int32_t st = (int32_t)rnd(); if (st == 1 || st == 2 || st == 4 || st == 8 || st == 16 || st == 32) st = 3; memcpy(b + 8, &st, 4); break; }
                case 3: b[24 + pick(8)] ^= (char)(1 + pick(255)); break;             /* FMU fingerprint */
                case 4: len = (uint64_t)0 - 28u * (uint64_t)f->nvr; memcpy(b + 32, &len, 8); break;
                case 5: len = rnd(); memcpy(b + 32, &len, 8); break;
                case 6: m = (size_t)pick((int)n); break;                               /* truncated */
                default: { /* the other FMU's instance */
                    for (int i = 0; i < 4; i++) if (inst[i].f != f && inst[i].st != DEAD) { tin = &inst[i]; target = tin->f; }
                    if (target == f) corrupt = -1;
                }
                }
            }
            fmi2FMUstate st = NULL;
            L = g_errors_logged;
            s = target->deserialize(tin->c, b, m, &st);
            if (judge(corrupt ? (corrupt < 0 ? -1 : 0) : 1, s, L) && !corrupt) {
                size_t n2 = 0;
                K.serial_roundtrips++;
                if (f->ser_size(in->c, st, &n2) != fmi2OK || n2 != n || f->serialize(in->c, st, b2, n) != fmi2OK ||
                    memcmp(b, b2, n))
                    K.serial_bad++;
                if (nsaved < MAXS) {
                    Saved *d = &saved[nsaved++];
                    *d = *sv;
                    d->owner = in;
                    d->s = st;
                } else f->free_state(in->c, &st);
            } else if (s == fmi2OK && st) target->free_state(tin->c, &st);
        }
        free(b);
        free(b2);
        break;
    }
    case 21: { /* directional derivatives: any known (inputs, parameters), sometimes a bad one */
        unsigned u[2] = {f->out[pick(f->nout)], f->out[pick(f->nout)]};
        unsigned kn[2] = {(unsigned)pick(f->nvr), f->nin ? f->in[pick(f->nin)] : (unsigned)pick(f->nvr)};
        while (!f->type[kn[0]]) kn[0] = (unsigned)pick(f->nvr);
        while (!f->type[kn[1]]) kn[1] = (unsigned)pick(f->nvr);
        double seed[2] = {1.0, -0.5}, d[2];
        int bad = pick(4) == 0;
        if (bad) {
            if (pick(2)) kn[0] = (unsigned)(f->nvr + pick(1000));
            else seed[1] = bad_double();
        }
        s = f->dd(in->c, u, 2, kn, 2, seed, d);
        if (judge(bad ? 0 : in->st != INSTANTIATED, s, L) && !(isfinite(d[0]) && isfinite(d[1]))) K.nonfinite_ok++;
        break;
    }
    case 22: { /* input derivatives: valid order 1/2, or a bad order or value (a system FMU has no input) */
        if (!f->nin) break;
        unsigned vr = f->in[pick(f->nin)];
        int order = 1 + pick(2);
        double v = uniform(-1, 1);
        int bad = pick(2);
        if (bad) {
            if (pick(2)) order = pick(2) ? 0 : 3;
            else v = bad_double();
        }
        s = f->set_der(in->c, &vr, 1, &order, &v);
        judge(bad ? 0 : (in->st == INSTANTIATED || in->st == INIT || in->st == STEPPING), s, L);
        break;
    }
    default: { /* free and re-instantiate, or instantiate with a wrong GUID */
        if (pick(2)) {
            fmi2Component c = f->instantiate("bad", fmi2CoSimulation, "{not-this-fmu}", f->res, &callbacks, 0, 0);
            K.calls++;
            K.invalid++;
            if (c) { K.invalid_ok++; f->free_instance(c); }
            else if (g_errors_logged == L) K.unlogged++;
        } else {
            for (int i = 0; i < nsaved;) /* free some of this instance's FMU states; fmi2FreeInstance frees the rest */
                if (saved[i].owner == in && pick(2) == 0) {
                    void *p = saved[i].s;
                    s = f->free_state(in->c, &saved[i].s);
                    if (judge(1, s, L) && nfreed < 64) freed[nfreed++] = p;
                    saved[i] = saved[--nsaved];
                } else i++;
            drop_states_of(in);
            f->free_instance(in->c);
            instantiate(in);
        }
    }
    }
}

static void run_sequence(Fmu *a, Fmu *b, int ncalls) {
    memset(&K, 0, sizeof K);
    for (int i = 0; i < 4; i++) {
        inst[i].f = i < 2 ? a : b;
        instantiate(&inst[i]);
        /* most sequences start stepping; the rest start from Instantiated */
        if (inst[i].st != DEAD && pick(4)) {
            inst[i].f->setup(inst[i].c, fmi2False, 0, 0, fmi2False, 0);
            if (inst[i].f->enter(inst[i].c) == fmi2OK && inst[i].f->exit_init(inst[i].c) == fmi2OK) inst[i].st = STEPPING;
        }
    }
    for (int k = 0; k < ncalls; k++) op();
}

int main(int argc, char **argv) {
    if (argc < 8) {
        fprintf(stderr, "usage: fmu_fuzz SEED NSEQ NCALLS DIR_A GUID_A DIR_B GUID_B\n");
        return 1;
    }
    uint64_t seed = strtoull(argv[1], NULL, 10);
    int nseq = atoi(argv[2]), ncalls = atoi(argv[3]);
    static Fmu a, b;
    load(&a, argv[4], argv[5]);
    load(&b, argv[6], argv[7]);
    /* warm up: the interpreter and the model code are loaded once, before the forks */
    fmi2Component wa = a.instantiate("warm", fmi2CoSimulation, a.guid, a.res, &callbacks, 0, 0);
    fmi2Component wb = b.instantiate("warm", fmi2CoSimulation, b.guid, b.res, &callbacks, 0, 0);
    if (!wa || !wb) {
        fprintf(stderr, "warm-up instantiation failed\n");
        return 3;
    }
    /* ... and every compiled function the calls use (numba loads them on first call) */
    Fmu *fs[2] = {&a, &b};
    fmi2Component ws[2] = {wa, wb};
    for (int i = 0; i < 2; i++) {
        Fmu *f = fs[i];
        double v[16], seed = 1.0, d;
        unsigned kn = f->nin ? f->in[0] : f->out[0]; /* a system FMU has no input: any known will do */
        f->setup(ws[i], fmi2False, 0, 0, fmi2False, 0);
        f->enter(ws[i]);
        f->get_real(ws[i], f->out, (size_t)f->nout, v);
        f->exit_init(ws[i]);
        for (int k = 0; k < 3; k++) f->do_step(ws[i], k * 1e-3, 1e-3, fmi2True);
        f->get_real(ws[i], f->out, (size_t)f->nout, v);
        f->dd(ws[i], f->out, 1, &kn, 1, &seed, &d);
        f->free_instance(ws[i]);
    }
    fflush(stdout);
    fflush(stderr);
    Counts total = {0};
    uint64_t crashes = 0, hangs = 0, lost = 0;
    for (int q = 0; q < nseq; q++) {
        int pfd[2];
        if (pipe(pfd) != 0) return 4;
        pid_t pid = fork();
        if (pid == 0) {
            close(pfd[0]);
            alarm(60);
            rng_state = (seed + 1) * 0x9E3779B97F4A7C15ull + (uint64_t)q * 0xBF58476D1CE4E5B9ull;
            if (!rng_state) rng_state = 1;
            run_sequence(&a, &b, ncalls);
            if (write(pfd[1], &K, sizeof K) != sizeof K) _exit(5);
            _exit(0);
        }
        close(pfd[1]);
        Counts c;
        ssize_t got = read(pfd[0], &c, sizeof c);
        close(pfd[0]);
        int status = 0;
        waitpid(pid, &status, 0);
        if (WIFSIGNALED(status)) {
            if (WTERMSIG(status) == SIGALRM) hangs++;
            else crashes++;
            fprintf(stderr, "sequence %d (seed %llu): killed by signal %d\n", q, (unsigned long long)seed, WTERMSIG(status));
        } else if (got != sizeof c || WEXITSTATUS(status) != 0) lost++;
        if (got == sizeof c) {
            uint64_t *t = (uint64_t *)&total, *x = (uint64_t *)&c;
            for (size_t i = 0; i < sizeof c / sizeof(uint64_t); i++) t[i] += x[i];
        }
    }
    printf("sequences %d\ncrashes %llu\nhangs %llu\nlost %llu\n", nseq, (unsigned long long)crashes,
           (unsigned long long)hangs, (unsigned long long)lost);
    const char *names[] = {"calls", "invalid", "invalid_ok", "unlogged", "valid_refused", "nonfinite_ok", "roundtrips",
                           "roundtrip_bad", "serial_roundtrips", "serial_bad", "instantiations"};
    uint64_t *t = (uint64_t *)&total;
    for (size_t i = 0; i < sizeof total / sizeof(uint64_t); i++) printf("%s %llu\n", names[i], (unsigned long long)t[i]);
    return 0;
}
