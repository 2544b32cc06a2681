/* The compiled stepping loop of the co-simulation master (pyfmu_wrapper/master/cloop.py).

   Fixed-step communication steps of any FMI 2.0 co-simulation FMUs, calling each FMU's
   fmi2SetReal / fmi2SetRealInputDerivatives / fmi2DoStep / fmi2GetReal through its C function
   pointers. The arithmetic is that of the Python reference path (pyfmu_wrapper/master/schemes.py)
   operation for operation, in the same order and without contraction into fused multiply-adds
   (compiled with -ffp-contract=off), so the two agree bit for bit.

   Schemes: 0 Jacobi (value connections), 1 two-phase stepping with rate connections,
   2 Gauss-Seidel. The derivative weights of the input polynomials are the master's own
   (History.weights, cached in Python): the loop looks them up by the exact time offsets of the
   history points and returns CL_NEED_WEIGHTS when it meets offsets it has not been given.

   The start-up steps (fewer known points than order + 1, Stepper.step in Python) are iterated
   here too when every FMU can get and set its state: taken, rolled back with fmi2SetFMUstate and
   taken again with the polynomial through the known points and the point just found.

   Return: CL_DONE (all steps taken), CL_NEED_WEIGHTS, CL_FMU_ERROR (status > fmi2Warning of
   one call: which instance, which call, the status; the step is not completed). */
#include <stdint.h>
#include <string.h>
#include <time.h>

#define CL_DONE 0
#define CL_NEED_WEIGHTS 1
#define CL_FMU_ERROR 2

typedef int (*set_real_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_real_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set_der_t)(void *, const unsigned int *, size_t, const int *, const double *);
typedef int (*do_step_t)(void *, double, double, int);
typedef int (*get_state_t)(void *, void **);
typedef int (*set_state_t)(void *, void *);
typedef int (*free_state_t)(void *, void **);

typedef struct {
    void *comp;
    set_real_t set_real;
    get_real_t get_real;
    set_der_t set_der; /* NULL if not exported */
    do_step_t do_step;
    int64_t n_in, n_out;
    const unsigned int *in_vr, *out_vr, *der_vr;
    const int *der_order;
    double *in_val, *out_val, *der_val;
    const int64_t *sig_in, *sig_out;
    int64_t n_orders, rate_orders;
    int64_t n_rate, any_int, phase; /* phase 1 / 2 with rate connections */
    const int64_t *rate_pos, *rate_src, *rate_int; /* rate_int < 0: no integral port */
    const double *rate_gain;
    double *rate_prev, *slope; /* slope: work array (n_rate) */
    int64_t rate_ready;
    double time_in; /* seconds inside this FMU's calls (when timing) */
    int64_t calls;
    get_state_t get_state; /* fmi2GetFMUstate, fmi2SetFMUstate, fmi2FreeFMUstate (start-up rollback) */
    set_state_t set_state;
    free_state_t free_state;
    void *fmu_state; /* the state saved at the start of a start-up step (NULL: none) */
} cl_inst;

typedef struct {
    int64_t n_inst, nsig, scheme, order, timing;
    const int64_t *gs_order; /* instance indices, Gauss-Seidel order */
    double t, h, h_prev, half_h, hh2, h3;
    double *y, *y0, *d1, *d2, *pred, *ynew;
    uint8_t *stepped;
    double *hist_y, *hist_t; /* (3, nsig), (3), oldest first */
    int64_t hist_n;
    int64_t n_w, max_w;
    double *w_key; /* (max_w, 3): k, x0, x1 */
    double *w_val; /* (max_w, 6): w1[0..2], w2[0..2] */
    int64_t steps, steps_done;
    int64_t need_k;
    double need_x0, need_x1;
    int64_t err_inst, err_func, err_status;
    double loop_time; /* seconds in this function */
    int64_t startup_iters; /* iterations of a start-up step (0: none, the FMUs cannot roll back) */
    int64_t probe;         /* a start-up step that will be rolled back: the rate memory is kept */
    double *ysave, *yit;   /* (nsig) the signals at the start of a start-up step, after an iteration */
} cl_ctx;

static inline double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#define CALL(c, ins, idx, func, expr)                                                                   \
    do {                                                                                                \
        int st_;                                                                                        \
        if ((c)->timing) {                                                                              \
            double t0_ = now();                                                                         \
            st_ = (expr);                                                                               \
            (ins)->time_in += now() - t0_;                                                              \
        } else {                                                                                        \
            st_ = (expr);                                                                               \
        }                                                                                               \
        (ins)->calls++;                                                                                 \
        if (st_ > 1) {                                                                                  \
            (c)->err_inst = (idx);                                                                      \
            (c)->err_func = (func);                                                                     \
            (c)->err_status = st_;                                                                      \
            return CL_FMU_ERROR;                                                                        \
        }                                                                                               \
    } while (0)

/* the value inputs at t and their derivatives from the arrays (val, e1, e2) */
static int set_inputs(cl_ctx *c, cl_inst *s, int64_t idx, const double *val, const double *e1, const double *e2,
                      int64_t n_orders)
{
    int64_t nd = s->n_in;
    if (!nd)
        return CL_DONE;
    for (int64_t j = 0; j < nd; j++) {
        int64_t src = s->sig_in[j];
        s->in_val[j] = val[src];
        s->der_val[j] = e1[src];
        s->der_val[nd + j] = e2[src];
    }
    CALL(c, s, idx, 0, s->set_real(s->comp, s->in_vr, (size_t)nd, s->in_val));
    if (n_orders && s->set_der)
        CALL(c, s, idx, 1, s->set_der(s->comp, s->der_vr, (size_t)(nd * n_orders), s->der_order, s->der_val));
    return CL_DONE;
}

static int step_and_read(cl_ctx *c, cl_inst *s, int64_t idx, double *dst)
{
    CALL(c, s, idx, 2, s->do_step(s->comp, c->t, c->h, 0));
    if (s->n_out) {
        CALL(c, s, idx, 3, s->get_real(s->comp, s->out_vr, (size_t)s->n_out, s->out_val));
        for (int64_t j = 0; j < s->n_out; j++)
            dst[s->sig_out[j]] = s->out_val[j];
    }
    return CL_DONE;
}

static int step_jacobi(cl_ctx *c, cl_inst *ins)
{
    int r;
    double *y = c->y;
    for (int64_t i = 0; i < c->n_inst; i++)
        if ((r = set_inputs(c, &ins[i], i, y, c->d1, c->d2, ins[i].n_orders)))
            return r;
    for (int64_t i = 0; i < c->n_inst; i++)
        CALL(c, &ins[i], i, 2, ins[i].do_step(ins[i].comp, c->t, c->h, 0));
    for (int64_t j = 0; j < c->nsig; j++)
        c->pred[j] = (y[j] + c->h * c->d1[j]) + c->hh2 * c->d2[j];
    for (int64_t i = 0; i < c->n_inst; i++) {
        cl_inst *s = &ins[i];
        if (s->n_out) {
            CALL(c, s, i, 3, s->get_real(s->comp, s->out_vr, (size_t)s->n_out, s->out_val));
            for (int64_t j = 0; j < s->n_out; j++)
                y[s->sig_out[j]] = s->out_val[j];
        }
    }
    return CL_DONE;
}

static int step_rate(cl_ctx *c, cl_inst *ins)
{
    int r;
    double *y = c->y, *y0 = c->y0, h = c->h;
    memcpy(y0, y, (size_t)c->nsig * sizeof(double));
    for (int64_t i = 0; i < c->n_inst; i++) {
        cl_inst *s = &ins[i];
        if (s->phase != 1)
            continue;
        if ((r = set_inputs(c, s, i, y0, c->d1, c->d2, s->n_orders)))
            return r;
        if ((r = step_and_read(c, s, i, y)))
            return r;
    }
    for (int64_t i = 0; i < c->n_inst; i++) {
        cl_inst *s = &ins[i];
        if (s->phase != 2)
            continue;
        int64_t nd = s->n_in;
        for (int64_t j = 0; j < nd; j++) {
            int64_t src = s->sig_in[j];
            s->in_val[j] = y0[src];
            s->der_val[j] = c->d1[src];
            s->der_val[nd + j] = c->d2[src];
        }
        double hmean = 0.5 * (h + c->h_prev);
        for (int64_t q = 0; q < s->n_rate; q++) {
            int64_t rs = s->rate_src[q];
            double s1 = y[rs];
            double mean = (s->rate_gain[q] * (s1 - y0[rs])) / h;
            double slope;
            if (s->any_int) {
                int64_t ii = s->rate_int[q];
                if (ii >= 0) {
                    double i0 = mean * h;
                    double i1 = s->rate_gain[q] * (h * s1 - (y[ii] - y0[ii]));
                    slope = (12.0 * (i1 - c->half_h * i0)) / c->h3;
                } else {
                    slope = (mean - s->rate_prev[q]) / hmean;
                }
            } else if (c->order >= 1 && s->rate_ready) {
                slope = (mean - s->rate_prev[q]) / hmean;
            } else {
                slope = 0.0 * mean;
            }
            s->slope[q] = slope;
            if (!c->probe)
                s->rate_prev[q] = mean; /* read above before being replaced, as in Python */
            int64_t pos = s->rate_pos[q];
            s->in_val[pos] = mean - c->half_h * slope;
            s->der_val[pos] = slope;
            s->der_val[nd + pos] = 0.0;
        }
        if (!c->probe)
            s->rate_ready = 1;
        if (nd) {
            CALL(c, s, i, 0, s->set_real(s->comp, s->in_vr, (size_t)nd, s->in_val));
            if (s->rate_orders && s->set_der)
                CALL(c, s, i, 1,
                     s->set_der(s->comp, s->der_vr, (size_t)(nd * s->rate_orders), s->der_order, s->der_val));
        }
        if ((r = step_and_read(c, s, i, y)))
            return r;
    }
    c->h_prev = h;
    for (int64_t j = 0; j < c->nsig; j++)
        c->pred[j] = (y0[j] + h * c->d1[j]) + c->hh2 * c->d2[j];
    return CL_DONE;
}

/* derivative weights at 0 of the polynomial through s[0..n-1] (lagrange_weights in Python) */
static void lagrange(const double *s, int64_t n, double *v1, double *v2)
{
    for (int64_t i = 0; i < n; i++) {
        v1[i] = 0.0;
        v2[i] = 0.0;
    }
    if (n == 2) {
        v1[0] = 1.0 / (s[0] - s[1]);
        v1[1] = 1.0 / (s[1] - s[0]);
    } else if (n == 3) {
        for (int64_t i = 0; i < 3; i++) {
            double o0 = s[i == 0 ? 1 : 0], o1 = s[i == 2 ? 1 : 2];
            double den = (s[i] - o0) * (s[i] - o1);
            v1[i] = (-o0 - o1) / den;
            v2[i] = 2.0 / den;
        }
    }
}

static int step_gauss_seidel(cl_ctx *c, cl_inst *ins)
{
    int r;
    double *y = c->y, *ynew = c->ynew, h = c->h, t = c->t;
    int64_t nsig = c->nsig;
    memcpy(ynew, y, (size_t)nsig * sizeof(double));
    memset(c->stepped, 0, (size_t)nsig);
    int64_t kk = c->hist_n < c->order ? c->hist_n : c->order;
    double s_i[3], v1[3], v2[3];
    int64_t ns = kk + 1;
    for (int64_t i = 0; i < kk; i++)
        s_i[i] = c->hist_t[3 - kk + i] - t;
    s_i[kk] = h;
    lagrange(s_i, ns, v1, v2);
    for (int64_t g = 0; g < c->n_inst; g++) {
        int64_t i = c->gs_order[g];
        cl_inst *s = &ins[i];
        int64_t nd = s->n_in;
        if (nd) {
            for (int64_t j = 0; j < nd; j++) {
                int64_t src = s->sig_in[j];
                double e1 = c->d1[src], e2 = c->d2[src];
                if (c->stepped[src] && ns > 1) {
                    double a1 = 0.0, a2 = 0.0;
                    for (int64_t p = 0; p < ns; p++) {
                        double pt = p < kk ? c->hist_y[(3 - kk + p) * nsig + src] : ynew[src];
                        if (p == 0) {
                            a1 = v1[0] * pt;
                            a2 = v2[0] * pt;
                        } else {
                            a1 = a1 + v1[p] * pt;
                            a2 = a2 + v2[p] * pt;
                        }
                    }
                    e1 = a1;
                    e2 = a2;
                }
                s->in_val[j] = y[src];
                s->der_val[j] = e1;
                s->der_val[nd + j] = e2;
            }
            CALL(c, s, i, 0, s->set_real(s->comp, s->in_vr, (size_t)nd, s->in_val));
            if (s->n_orders && s->set_der)
                CALL(c, s, i, 1,
                     s->set_der(s->comp, s->der_vr, (size_t)(nd * s->n_orders), s->der_order, s->der_val));
        }
        if ((r = step_and_read(c, s, i, ynew)))
            return r;
        for (int64_t j = 0; j < s->n_out; j++)
            c->stepped[s->sig_out[j]] = 1;
    }
    for (int64_t j = 0; j < nsig; j++)
        c->pred[j] = (y[j] + h * c->d1[j]) + c->hh2 * c->d2[j];
    memcpy(y, ynew, (size_t)nsig * sizeof(double));
    return CL_DONE;
}

/* d1, d2 at t from the last k history points; 0 if the weights are not known yet */
static int derivatives(cl_ctx *c)
{
    int64_t k = c->hist_n < c->order + 1 ? c->hist_n : c->order + 1;
    double x0 = c->hist_t[0] - c->t, x1 = c->hist_t[1] - c->t;
    const double *w = NULL;
    for (int64_t e = 0; e < c->n_w; e++) {
        const double *key = c->w_key + 3 * e;
        if (key[0] != (double)k)
            continue;
        if ((k == 3 && key[1] == x0 && key[2] == x1) || (k == 2 && key[2] == x1) || k <= 1) {
            w = c->w_val + 6 * e;
            break;
        }
    }
    if (!w) {
        c->need_k = k;
        c->need_x0 = x0;
        c->need_x1 = x1;
        return 0;
    }
    int64_t nsig = c->nsig;
    const double *hy = c->hist_y + (3 - k) * nsig;
    for (int64_t j = 0; j < nsig; j++) {
        double a1 = w[0] * hy[j], a2 = w[3] * hy[j];
        for (int64_t p = 1; p < k; p++) {
            a1 = a1 + w[p] * hy[p * nsig + j];
            a2 = a2 + w[3 + p] * hy[p * nsig + j];
        }
        c->d1[j] = a1;
        c->d2[j] = a2;
    }
    return 1;
}

static int advance_once(cl_ctx *c, cl_inst *ins)
{
    return c->scheme == 1 ? step_rate(c, ins) : step_jacobi(c, ins);
}

static void free_saved(cl_inst *ins, int64_t n_inst)
{
    for (int64_t i = 0; i < n_inst; i++)
        if (ins[i].fmu_state) {
            ins[i].free_state(ins[i].comp, &ins[i].fmu_state);
            ins[i].fmu_state = NULL;
        }
}

/* One start-up step (k <= order known points; d1, d2 from them), iterated startup_iters times
   with rollback as Stepper.step does: the polynomial of each new iteration passes through the
   known points and the point the previous iteration found (Lagrange weights, summed left to right). */
static int startup_body(cl_ctx *c, cl_inst *ins, int64_t k)
{
    int r;
    int64_t nsig = c->nsig;
    for (int64_t i = 0; i < c->n_inst; i++)
        CALL(c, &ins[i], i, 4, ins[i].get_state(ins[i].comp, &ins[i].fmu_state));
    memcpy(c->ysave, c->y, (size_t)nsig * sizeof(double));
    for (int64_t it = 0; it <= c->startup_iters; it++) {
        if (it) {
            memcpy(c->yit, c->y, (size_t)nsig * sizeof(double));
            for (int64_t i = 0; i < c->n_inst; i++)
                CALL(c, &ins[i], i, 5, ins[i].set_state(ins[i].comp, ins[i].fmu_state));
            memcpy(c->y, c->ysave, (size_t)nsig * sizeof(double));
            double s[3], v1[3], v2[3];
            int64_t np = k + 1;
            for (int64_t p = 0; p < k; p++)
                s[p] = c->hist_t[3 - k + p] - c->t;
            s[k] = c->h;
            lagrange(s, np, v1, v2);
            for (int64_t j = 0; j < nsig; j++) {
                double a1 = 0.0, a2 = 0.0;
                for (int64_t p = 0; p < np; p++) {
                    double pt = p < k ? c->hist_y[(3 - k + p) * nsig + j] : c->yit[j];
                    if (p == 0) {
                        a1 = v1[0] * pt;
                        a2 = v2[0] * pt;
                    } else {
                        a1 = a1 + v1[p] * pt;
                        a2 = a2 + v2[p] * pt;
                    }
                }
                c->d1[j] = a1;
                c->d2[j] = a2;
            }
        }
        c->probe = it < c->startup_iters;
        if ((r = advance_once(c, ins)))
            return r;
    }
    return CL_DONE;
}

static int startup_step(cl_ctx *c, cl_inst *ins, int64_t k)
{
    int r = startup_body(c, ins, k);
    c->probe = 0;
    free_saved(ins, c->n_inst);
    return r;
}

int cl_run(cl_ctx *c, cl_inst *ins, int64_t n_steps, double *rec_t, double *rec_y)
{
    double t_start = now();
    int r = CL_DONE;
    int64_t nsig = c->nsig;
    c->steps_done = 0;
    while (c->steps_done < n_steps) {
        if (!derivatives(c)) {
            r = CL_NEED_WEIGHTS;
            break;
        }
        int64_t k = c->hist_n < c->order + 1 ? c->hist_n : c->order + 1;
        if (c->scheme == 2)
            r = step_gauss_seidel(c, ins);
        else if (k <= c->order && c->startup_iters > 0)
            r = startup_step(c, ins, k);
        else if (c->scheme == 1)
            r = step_rate(c, ins);
        else
            r = step_jacobi(c, ins);
        if (r)
            break;
        c->t = c->t + c->h;
        c->steps++;
        memmove(c->hist_y, c->hist_y + nsig, 2 * (size_t)nsig * sizeof(double));
        memcpy(c->hist_y + 2 * nsig, c->y, (size_t)nsig * sizeof(double));
        c->hist_t[0] = c->hist_t[1];
        c->hist_t[1] = c->hist_t[2];
        c->hist_t[2] = c->t;
        c->hist_n = c->hist_n + 1 < 3 ? c->hist_n + 1 : 3;
        if (rec_t) {
            rec_t[c->steps_done] = c->t;
            memcpy(rec_y + c->steps_done * nsig, c->y, (size_t)nsig * sizeof(double));
        }
        c->steps_done++;
    }
    c->loop_time += now() - t_start;
    return r;
}

/* The plain C loop of the benchmark: the same calls on the same FMUs with no coupling
   arithmetic (inputs copied from the previous outputs, no derivatives): the baseline the
   master's overhead is measured against. */
int cl_plain(cl_inst *ins, int64_t n_inst, double t, double h, int64_t n_steps)
{
    for (int64_t k = 0; k < n_steps; k++) {
        for (int64_t i = 0; i < n_inst; i++) {
            cl_inst *s = &ins[i];
            if (s->n_in && s->set_real(s->comp, s->in_vr, (size_t)s->n_in, s->in_val) > 1)
                return 2;
        }
        for (int64_t i = 0; i < n_inst; i++)
            if (ins[i].do_step(ins[i].comp, t, h, 0) > 1)
                return 2;
        for (int64_t i = 0; i < n_inst; i++) {
            cl_inst *s = &ins[i];
            if (s->n_out && s->get_real(s->comp, s->out_vr, (size_t)s->n_out, s->out_val) > 1)
                return 2;
        }
        t = t + h;
    }
    return 0;
}

/* ---- FMI 3.0 instances ----------------------------------------------------------------------
   The loop calls every FMU through the fmi2 signatures above; for an FMI 3.0 instance the master
   passes these adapters and, as `comp`, a cl_fmi3 holding the instance and its fmi3 functions.
   FMI 3.0 has no fmi3SetInputDerivatives: the derivatives go to the FMU's der(u), der(u,2) input
   variables (der_vr: the variable of each position of the master's derivative arrays), and, as
   fmi2SetReal does in FMI 2.0, setting the inputs resets them to zero (the Python path,
   master/instance.py Instance3, does the same in one call: the FMU ends in the same state). */
typedef int (*f3_set64_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*f3_get64_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*f3_step_t)(void *, double, double, _Bool, _Bool *, _Bool *, _Bool *, double *);

typedef struct {
    void *inst;
    f3_set64_t set64;
    f3_get64_t get64;
    f3_step_t step;
    int64_t n_der; /* 2 n_in when the FMU declares der(u) and der(u,2) of its inputs, else 0 */
    const unsigned int *der_vr;
    const double *zeros; /* n_der zeros */
    get_state_t getst;   /* fmi3GetFMUState, fmi3SetFMUState, fmi3FreeFMUState (same shapes as FMI 2.0's) */
    set_state_t setst;
    free_state_t freest;
} cl_fmi3;

int cl_f3_set_real(void *p, const unsigned int *vr, size_t n, const double *v)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    int s = f->set64(f->inst, vr, n, v, n);
    if (s > 1 || !f->n_der)
        return s;
    int s2 = f->set64(f->inst, f->der_vr, (size_t)f->n_der, f->zeros, (size_t)f->n_der);
    return s2 > s ? s2 : s;
}

int cl_f3_set_der(void *p, const unsigned int *vr, size_t n, const int *order, const double *v)
{
    (void)vr;
    (void)order; /* position i of the master's arrays is der_vr[i] */
    cl_fmi3 *f = (cl_fmi3 *)p;
    return f->set64(f->inst, f->der_vr, n, v, n);
}

int cl_f3_get_real(void *p, const unsigned int *vr, size_t n, double *v)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    return f->get64(f->inst, vr, n, v, n);
}

int cl_f3_do_step(void *p, double t, double h, int no_set)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    _Bool event = 0, terminate = 0, early = 0;
    double last = 0.0;
    return f->step(f->inst, t, h, no_set != 0, &event, &terminate, &early, &last);
}

int cl_f3_get_state(void *p, void **state)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    return f->getst(f->inst, state);
}

int cl_f3_set_state(void *p, void *state)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    return f->setst(f->inst, state);
}

int cl_f3_free_state(void *p, void **state)
{
    cl_fmi3 *f = (cl_fmi3 *)p;
    return f->freest(f->inst, state);
}
