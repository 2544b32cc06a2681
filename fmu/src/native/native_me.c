/*
 * Model Exchange of a native FMU (included by native_embed.c, which it extends: the Slave and its objects):
 * the core's ME functions (fmi_api.c, fmi3_api.c) ask me_model() for the numbers, served here by the model's
 * compiled functions (fmubuild/native_obj.py's me_* entries, numba cfuncs of the model's folder):
 *
 *   pyfmu_model_me_derivatives   the states' derivatives: the model's right-hand side
 *   pyfmu_model_me_indicators    the event indicators: its switching functions
 *   pyfmu_model_me_nominals      the states' nominal values
 *   pyfmu_model_me_jacobian      [d derivatives / d states; d outputs / d states], row-major
 *
 * each f(reals, ints, z, p, u, t, out). The continuous states are the first NM_NX entries of the slave's z, in
 * the order of the FMU's state variables (NM_X_VR; their derivatives NM_DER_VR), generated into
 * pyfmu_native_model.h from the FMU's declaration. A model without states (NM_NX 0) has no Model Exchange.
 */
#if NM_NX > 0
extern int32_t pyfmu_model_me_derivatives(double *, int32_t *, double *, double *, double *, double, double *);
extern int32_t pyfmu_model_me_indicators(double *, int32_t *, double *, double *, double *, double, double *);
extern int32_t pyfmu_model_me_nominals(double *, int32_t *, double *, double *, double *, double, double *);
extern int32_t pyfmu_model_me_jacobian(double *, int32_t *, double *, double *, double *, double, double *);

static Slave *me_slave(Comp *c) { return ((Obj *)c->slave)->s; }
static void me_set_time(Comp *c, double t) { me_slave(c)->th[0] = t; }
static void me_get_states(Comp *c, double *x) { memcpy(x, me_slave(c)->z, NM_NX * sizeof(double)); }
static void me_set_states(Comp *c, const double *x) { memcpy(me_slave(c)->z, x, NM_NX * sizeof(double)); }
#define ME_CALL(FN, OUT) \
    (FN(me_slave(c)->reals, me_slave(c)->ints, me_slave(c)->z, me_slave(c)->p, me_slave(c)->u, me_slave(c)->th[0], \
        OUT) == PYFMU_NATIVE_OK)
static int me_derivatives(Comp *c, double *dx) { return ME_CALL(pyfmu_model_me_derivatives, dx); }
static int me_indicators(Comp *c, double *g) {
#if NM_NZ > 0
    return ME_CALL(pyfmu_model_me_indicators, g);
#else
    (void)c; (void)g;
    return 1;
#endif
}
static int me_nominals(Comp *c, double *nominal) { return ME_CALL(pyfmu_model_me_nominals, nominal); }

static int index_of(const unsigned *vrs, int n, fmi2ValueReference vr) {
    for (int i = 0; i < n; i++)
        if (vrs[i] == vr) return i;
    return -1;
}

/* Directional derivatives in Model Exchange: knowns are states (a seed on any other variable, a parameter
 * after initialisation, contributes nothing; an input is refused: not provided), unknowns derivatives,
 * outputs or states (1 with respect to itself); from the model's Jacobian. */
static fmi2Status me_directional(Comp *c, const char *f, const fmi2ValueReference *vu, size_t nu,
                                 const fmi2ValueReference *vk, size_t nk, const double *dvk, double *dvu) {
    double jac[(NM_NX + NM_NOUT) * NM_NX]; /* at most (44 + 10) x 44 doubles: on the stack, per call */
    double dz[NM_NX] = {0};
    for (size_t i = 0; i < nk; i++) {
        int k = index_of(NM_X_VR, NM_NX, vk[i]);
        if (k >= 0) dz[k] += dvk[i];
        else if (vk[i] < (fmi2ValueReference)c->nvr && c->vcaus[vk[i]] == C_INPUT) {
            logmsg(c, fmi2Error, "logStatusError", "%s: known %u is an input: derivatives with respect to inputs "
                   "are not provided in Model Exchange (only with respect to the states)", f, vk[i]);
            return fmi2Error;
        } else if (vk[i] >= (fmi2ValueReference)c->nvr || !c->vtype[vk[i]]) {
            logmsg(c, fmi2Error, "logStatusError", "%s: invalid value reference %u of a known", f, vk[i]);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nu; i++)
        if (vu[i] >= (fmi2ValueReference)c->nvr || c->vtype[vu[i]] != 'R') {
            logmsg(c, fmi2Error, "logStatusError", "%s: unknown %u is not a Real variable", f, vu[i]);
            return fmi2Error;
        }
    double *res = malloc((nu ? nu : 1) * sizeof(double));
    if (!res) {
        logmsg(c, fmi2Error, "logStatusError", "%s: out of memory", f);
        return fmi2Error;
    }
    if (!ME_CALL(pyfmu_model_me_jacobian, jac)) {
        free(res);
        logmsg(c, fmi2Error, "logStatusError", "%s: the compiled Jacobian raised", f);
        return fmi2Error;
    }
    for (size_t i = 0; i < nu; i++) {
        int row = index_of(NM_DER_VR, NM_NX, vu[i]), o = -1;
        if (row < 0) {
            for (int j = 0; j < NM_NOUT; j++)
                if (NM_OUT_VR[j] == vu[i] && NM_OUT_REAL[j]) o = j;
            if (o >= 0) row = NM_NX + o;
        }
        double sum = 0.0;
        if (row >= 0)
            for (int k = 0; k < NM_NX; k++) sum += jac[row * NM_NX + k] * dz[k];
        else /* a state, or another variable: 1 with respect to itself */
            for (size_t j = 0; j < nk; j++)
                if (vk[j] == vu[i]) sum += dvk[j];
        if (!isfinite(sum)) {
            free(res);
            logmsg(c, fmi2Error, "logStatusError", "%s: the derivative of %s (value reference %u) is %g: the model "
                   "overflowed; nothing returned", f, var_name(c, vu[i]), vu[i], sum);
            return fmi2Error;
        }
        res[i] = sum;
    }
    memcpy(dvu, res, nu * sizeof(double));
    free(res);
    return fmi2OK;
}

static const MeModel ME_MODEL = {NM_NX, NM_NZ, me_set_time, me_get_states, me_set_states, me_derivatives,
                                 me_indicators, me_nominals, me_directional};
const MeModel *me_model(void) { return &ME_MODEL; }
#else
const MeModel *me_model(void) { return NULL; }
#endif
