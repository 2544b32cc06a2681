/*
 * The FMI 3.0 co-simulation API: a thin layer over the stub's one core (fmi_api.c: state machine,
 * argument and range checks, the embedded slave, doStep; fmi_state.c: FMU states). Every fmi3
 * function maps its arguments onto the core's call and its answer back; nothing of the core is
 * repeated here. The binary of an FMI 3.0 FMU exports only the fmi3* symbols (a linker version
 * script written by pyfmu_wrapper/fmubuild/build.py), the FMI 2.0 one only the fmi2* symbols.
 *
 * What FMI 3.0 has that FMI 2.0 had differently, and how this layer maps it:
 *  - the resource *path* (FMI 2.0: a file URI) becomes a file URI for the core;
 *  - fmi3EnterInitializationMode carries the experiment (FMI 2.0: fmi2SetupExperiment);
 *  - input derivatives (FMI 2.0: fmi2SetRealInputDerivatives) are input variables of their own,
 *    declared in modelDescription.xml (fmubuild/model_description3.py): the derivative of order k
 *    (1, 2) of the Real input with value reference v has the value reference N + 1 + 2 v + k - 1,
 *    where N = (largest value reference of the FMI 2.0 table) + 1; they apply to the
 *    next doStep only (the core resets them after each step, as in FMI 2.0); setting the input
 *    itself does not clear them (FMI 3.0 semantics);
 *  - the independent variable `time` (required in FMI 3.0) has the value reference N;
 *  - Float64 = fmi2Real, Int32 = fmi2Integer, Boolean = bool; no other types are declared, so
 *    every other getter and setter answers fmi3Error for any value reference;
 *  - Model Exchange (fmi3InstantiateModelExchange, event mode, continuous-time mode) maps onto the core's
 *    ME functions, which refuse it unless the model provides it (a native FMU with states: me_model());
 *  - no event mode in co-simulation, no clocks, no scheduled execution: those functions answer
 *    fmi3Error with a message (never fmi3OK).
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyfmu.h"
#include "fmi3Functions.h"

#undef NULLARG /* the core's returns fmi2Error */
#define NULLARG(f, p)                                                                  \
    if ((p) == NULL) {                                                                 \
        logmsg(c, fmi2Error, "logStatusError", "%s: argument %s is NULL", f, #p);      \
        return fmi3Error;                                                              \
    }

/* The FMI 3.0 host's environment and logger, behind the FMI 2.0 callbacks the core calls. */
typedef struct {
    uint32_t magic;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Env3;
#define ENV3_MAGIC 0x454e5633u

/* FMI 2.0 function names in the core's messages, as this API calls them. */
static const char *const RENAMES[][2] = {
    {"fmi2SetupExperiment", "fmi3EnterInitializationMode"},
    {"fmi2SetRealInputDerivatives", "fmi3SetFloat64"},
    {"fmi2GetReal", "fmi3GetFloat64"},
    {"fmi2SetReal", "fmi3SetFloat64"},
    {"fmi2GetInteger", "fmi3GetInt32"},
    {"fmi2SetInteger", "fmi3SetInt32"},
    {"fmi2Instantiate", "fmi3InstantiateCoSimulation"},
    {"fmi2GetFMUstate", "fmi3GetFMUState"},
    {"fmi2SetFMUstate", "fmi3SetFMUState"},
    {"fmi2FreeFMUstate", "fmi3FreeFMUState"},
    {"fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize"},
    {"fmi2SerializeFMUstate", "fmi3SerializeFMUState"},
    {"fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"},
    {"fmi2GetDerivatives", "fmi3GetContinuousStateDerivatives"},
    {"fmi2NewDiscreteStates", "fmi3UpdateDiscreteStates"},
};

/* The core's messages come pre-formatted with '%' doubled (log.c): format them once more to undo
 * that, rename the FMI 2.0 functions and hand the text to the FMI 3.0 logger. */
static void logger3(fmi2ComponentEnvironment e, fmi2String name, fmi2Status st, fmi2String cat, fmi2String fmt, ...) {
    (void)name;
    Env3 *env = (Env3 *)e;
    if (!env || env->magic != ENV3_MAGIC || !env->log) return;
    char raw[8192], out[8400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    const char *p = raw;
    size_t o = 0;
    out[0] = 0;
    while (*p && o < sizeof out - 64) {
        int done = 0;
        if (p[0] == 'f' && !strncmp(p, "fmi2", 4)) {
            for (size_t i = 0; i < sizeof RENAMES / sizeof RENAMES[0]; i++) {
                size_t n = strlen(RENAMES[i][0]);
                char after = p[n];
                if (!strncmp(p, RENAMES[i][0], n) && !((after >= 'A' && after <= 'Z') || (after >= 'a' && after <= 'z'))) {
                    o += (size_t)snprintf(out + o, sizeof out - o, "%s", RENAMES[i][1]);
                    p += n;
                    done = 1;
                    break;
                }
            }
            if (!done) { /* fmi2X -> fmi3X */
                o += (size_t)snprintf(out + o, sizeof out - o, "fmi3");
                p += 4;
                done = 1;
            }
        }
        if (!done) out[o++] = *p++;
        out[o] = 0;
    }
    env->log(env->env, (fmi3Status)st, cat, out);
}

static Comp *inst(fmi3Instance instance) {
    Comp *c = (Comp *)instance;
    return (c && c->magic == COMP_MAGIC) ? c : NULL;
}

/* N: the first value reference after the FMI 2.0 table (the time variable). */
static int n2(const Comp *c) { return c->nvr; }
static int is_time_vr(const Comp *c, fmi3ValueReference vr) { return vr == (fmi3ValueReference)n2(c); }
/* The input whose derivative vr is (order in *order), or -1. */
static int derivative_of(const Comp *c, fmi3ValueReference vr, int *order) {
    if (vr <= (fmi3ValueReference)n2(c) || vr > (fmi3ValueReference)(3 * n2(c))) return -1;
    unsigned k = vr - (unsigned)n2(c) - 1u;
    int v = (int)(k / 2u);
    if (v >= c->nvr || c->vtype[v] != 'R' || c->vcaus[v] != C_INPUT) return -1;
    *order = (int)(k % 2u) + 1;
    return v;
}

#define INST(f)                                                  \
    Comp *c = inst(instance);                                    \
    if (!c) return fmi3Error;                                    \
    (void)(f)

static fmi3Status refuse(Comp *c, const char *f, const char *why) {
    logmsg(c, fmi2Error, "logStatusError", "%s: %s", f, why);
    return fmi3Error;
}

#define NVALUES(f)                                                                                           \
    if (nValues != nValueReferences) {                                                                       \
        logmsg(c, fmi2Error, "logStatusError", "%s: nValues = %zu but nValueReferences = %zu (every variable " \
               "of this FMU is a scalar)", f, nValues, nValueReferences);                                    \
        return fmi3Error;                                                                                    \
    }

/* ---- common functions ------------------------------------------------------------------------ */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    INST(0);
    return (fmi3Status)fmi2SetDebugLogging(c, loggingOn, nCategories, categories);
}

/* An instance for co-simulation or (fmi2ModelExchange) Model Exchange; refused: why (NULL: nothing refused). */
static fmi3Instance instantiate3(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                 fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                 fmi3LogMessageCallback logMessage, fmi2Type type, const char *refused) {
    const char *f = type == fmi2ModelExchange ? "fmi3InstantiateModelExchange" : "fmi3InstantiateCoSimulation";
    Env3 *env = calloc(1, sizeof *env);
    if (!env) return NULL;
    env->magic = ENV3_MAGIC;
    env->env = instanceEnvironment;
    env->log = logMessage;
    fmi2CallbackFunctions cb = {0};
    cb.logger = (fmi2CallbackLogger)logger3;
    cb.componentEnvironment = env;
    if (refused) {
        Comp tmp = {0};
        tmp.instance_name = (char *)(instanceName ? instanceName : "?");
        tmp.logger = cb.logger;
        tmp.env = env;
        logmsg(&tmp, fmi2Error, "logStatusError", "%s: %s", f, refused);
        free(env);
        return NULL;
    }
    /* the core takes a file URI: percent-encode the path */
    char *uri = NULL;
    if (resourcePath && resourcePath[0]) {
        size_t n = strlen(resourcePath);
        uri = malloc(3 * n + 16);
        if (!uri) {
            free(env);
            return NULL;
        }
        char *q = uri + sprintf(uri, "file://");
        for (const unsigned char *p = (const unsigned char *)resourcePath; *p; p++) {
            if ((*p >= 'A' && *p <= 'Z') || (*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') || strchr("/-_.~", *p))
                *q++ = (char)*p;
            else q += sprintf(q, "%%%02X", *p);
        }
        *q = 0;
    }
    Comp *c = (Comp *)fmi2Instantiate(instanceName, type, instantiationToken, uri, &cb, visible, loggingOn);
    free(uri);
    if (!c) free(env);
    else c->fmi3 = 1;
    return c;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                         fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)intermediateUpdate;
    const char *refused = NULL;
    if (nRequiredIntermediateVariables > 0) /* no intermediate update: nothing can be provided */
        refused = "required intermediate variables were given, but this FMU provides no intermediate update "
                  "(providesIntermediateUpdate = false)";
    else if (eventModeUsed) /* FMI 3.0.2, 4.3.1: an FMU without event mode must fail to instantiate */
        refused = "eventModeUsed = true, but this FMU has no event mode (hasEventMode = false): instantiate it with "
                  "eventModeUsed = false";
    return instantiate3(instanceName, instantiationToken, resourcePath, visible, loggingOn, instanceEnvironment,
                        logMessage, fmi2CoSimulation, refused);
}

/* Model Exchange: the core refuses it (with a message) unless the model provides it (me_model()). */
fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
                                          fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage) {
    return instantiate3(instanceName, instantiationToken, resourcePath, visible, loggingOn, instanceEnvironment,
                        logMessage, fmi2ModelExchange, NULL);
}

void fmi3FreeInstance(fmi3Instance instance) {
    Comp *c = inst(instance);
    if (!c) return;
    void *env = c->env;
    fmi2FreeInstance(c);
    free(env);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    INST(0);
    fmi2Status s = fmi2SetupExperiment(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime);
    if (s > fmi2Warning) return (fmi3Status)s;
    fmi2Status s2 = fmi2EnterInitializationMode(c);
    return (fmi3Status)(s2 > s ? s2 : s);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    INST(0);
    return (fmi3Status)fmi2ExitInitializationMode(c);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    INST(0);
    if (c->me) return (fmi3Status)fmi2EnterEventMode(c);
    return refuse(c, "fmi3EnterEventMode", "this FMU has no event mode in co-simulation (hasEventMode = false)");
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    INST(0);
    return (fmi3Status)fmi2Terminate(c);
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    INST(0);
    return (fmi3Status)fmi2Reset(c);
}

/* ---- values ---------------------------------------------------------------------------------- */
/* Float64 values in one pass, no allocation: the core's checks per value reference (the FMI 2.0
 * table's variables), then the outputs recomputed once if needed, then every value copied. */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    INST(0);
    const char *f = "fmi3GetFloat64";
    if (!check_state(c, f, get_mask(c))) return fmi3Error;
    NVALUES(f);
    if (nValueReferences == 0) return fmi3OK;
    NULLARG(f, valueReferences);
    NULLARG(f, values);
    int order, plain = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference vr = valueReferences[i];
        if (is_time_vr(c, vr) || derivative_of(c, vr, &order) >= 0) continue;
        if (!check_vr(c, f, vr, 'R')) return fmi3Error;
        plain = 1;
    }
    fmi2Status s = plain ? refresh(c, f) : fmi2OK;
    if (s > fmi2Warning) return (fmi3Status)s;
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference vr = valueReferences[i];
        if (!is_time_vr(c, vr) && derivative_of(c, vr, &order) < 0 && !check_finite(c, f, vr)) return fmi3Error;
    }
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference vr = valueReferences[i];
        int v;
        if (is_time_vr(c, vr)) values[i] = c->time;
        else if ((v = derivative_of(c, vr, &order)) >= 0) values[i] = c->derivs[2 * v + order - 1];
        else values[i] = c->reals[vr];
    }
    return (fmi3Status)s;
}

/* Float64 values in one pass, no allocation: everything checked (the core's checks) before anything
 * changes; setting an input does not clear its derivatives (FMI 3.0), which apply to the next step. */
fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    INST(0);
    const char *f = "fmi3SetFloat64";
    if (!check_state(c, f, M_SET)) return fmi3Error;
    NVALUES(f);
    if (nValueReferences == 0) return fmi3OK;
    NULLARG(f, valueReferences);
    NULLARG(f, values);
    int order, plain = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference vr = valueReferences[i];
        if (is_time_vr(c, vr)) {
            logmsg(c, fmi2Error, "logStatusError", "%s: variable %u (time) is the independent variable: it cannot be set",
                   f, vr);
            return fmi3Error;
        }
        int v = derivative_of(c, vr, &order);
        if (v >= 0) {
            if (!isfinite(values[i])) {
                logmsg(c, fmi2Error, "logStatusError", "%s: value for the derivative of order %d of %s (value reference "
                       "%u) must be finite but was %g", f, order, var_name(c, (unsigned)v), vr, values[i]);
                return fmi3Error;
            }
            continue;
        }
        if (!check_vr(c, f, vr, 'R') || !check_settable(c, f, vr) || !check_value(c, f, vr, values[i], 'R'))
            return fmi3Error;
        plain = 1;
    }
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference vr = valueReferences[i];
        int v = derivative_of(c, vr, &order);
        if (v >= 0) c->derivs[2 * v + order - 1] = values[i];
        else c->reals[vr] = values[i];
    }
    if (plain) c->dirty = 1;
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues) {
    INST(0);
    NVALUES("fmi3GetInt32");
    return (fmi3Status)fmi2GetInteger(c, valueReferences, nValueReferences, values);
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues) {
    INST(0);
    NVALUES("fmi3SetInt32");
    return (fmi3Status)fmi2SetInteger(c, valueReferences, nValueReferences, values);
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Boolean values[], size_t nValues) {
    INST(0);
    NVALUES("fmi3GetBoolean");
    if (nValueReferences == 0) return (fmi3Status)fmi2GetBoolean(c, valueReferences, 0, NULL);
    NULLARG("fmi3GetBoolean", values);
    fmi2Boolean *b = calloc(nValueReferences, sizeof *b);
    if (!b) return refuse(c, "fmi3GetBoolean", "out of memory");
    fmi2Status s = fmi2GetBoolean(c, valueReferences, nValueReferences, b);
    if (s <= fmi2Warning)
        for (size_t i = 0; i < nValueReferences; i++) values[i] = b[i] != 0;
    free(b);
    return (fmi3Status)s;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Boolean values[], size_t nValues) {
    INST(0);
    NVALUES("fmi3SetBoolean");
    if (nValueReferences == 0) return (fmi3Status)fmi2SetBoolean(c, valueReferences, 0, NULL);
    NULLARG("fmi3SetBoolean", values);
    fmi2Boolean *b = calloc(nValueReferences, sizeof *b);
    if (!b) return refuse(c, "fmi3SetBoolean", "out of memory");
    for (size_t i = 0; i < nValueReferences; i++) b[i] = values[i] ? fmi2True : fmi2False;
    fmi2Status s = fmi2SetBoolean(c, valueReferences, nValueReferences, b);
    free(b);
    return (fmi3Status)s;
}

/* Types this FMU declares no variable of: any value reference is invalid. */
static fmi3Status no_such(fmi3Instance instance, const char *f, const fmi3ValueReference vr[], size_t nvr, int set) {
    INST(0);
    if (!check_state(c, f, set ? M_SET : get_mask(c))) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    NULLARG(f, vr);
    logmsg(c, fmi2Error, "logStatusError", "%s: invalid value reference %u (this FMU has no variable of this type)", f,
           vr[0]);
    return fmi3Error;
}
#define NO_SUCH_GET(NAME, CTYPE)                                                                               \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, CTYPE values[], size_t nv) { \
        (void)values; (void)nv;                                                                                \
        return no_such(instance, #NAME, vr, nvr, 0);                                                           \
    }
#define NO_SUCH_SET(NAME, CTYPE)                                                                                     \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const CTYPE values[], size_t nv) { \
        (void)values; (void)nv;                                                                                      \
        return no_such(instance, #NAME, vr, nvr, 1);                                                                 \
    }
NO_SUCH_GET(fmi3GetFloat32, fmi3Float32)
NO_SUCH_GET(fmi3GetInt8, fmi3Int8)
NO_SUCH_GET(fmi3GetUInt8, fmi3UInt8)
NO_SUCH_GET(fmi3GetInt16, fmi3Int16)
NO_SUCH_GET(fmi3GetUInt16, fmi3UInt16)
NO_SUCH_GET(fmi3GetUInt32, fmi3UInt32)
NO_SUCH_GET(fmi3GetInt64, fmi3Int64)
NO_SUCH_GET(fmi3GetUInt64, fmi3UInt64)
NO_SUCH_GET(fmi3GetString, fmi3String)
NO_SUCH_SET(fmi3SetFloat32, fmi3Float32)
NO_SUCH_SET(fmi3SetInt8, fmi3Int8)
NO_SUCH_SET(fmi3SetUInt8, fmi3UInt8)
NO_SUCH_SET(fmi3SetInt16, fmi3Int16)
NO_SUCH_SET(fmi3SetUInt16, fmi3UInt16)
NO_SUCH_SET(fmi3SetUInt32, fmi3UInt32)
NO_SUCH_SET(fmi3SetInt64, fmi3Int64)
NO_SUCH_SET(fmi3SetUInt64, fmi3UInt64)
NO_SUCH_SET(fmi3SetString, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nv) {
    (void)valueSizes; (void)values; (void)nv;
    return no_such(instance, "fmi3GetBinary", vr, nvr, 0);
}
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nv) {
    (void)valueSizes; (void)values; (void)nv;
    return no_such(instance, "fmi3SetBinary", vr, nvr, 1);
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)values;
    return no_such(instance, "fmi3GetClock", vr, nvr, 0);
}
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)values;
    return no_such(instance, "fmi3SetClock", vr, nvr, 1);
}

/* ---- variable dependencies, FMU state, derivatives ------------------------------------------- */
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    INST(0);
    (void)vr; (void)n;
    return refuse(c, "fmi3GetNumberOfVariableDependencies",
                  "not provided (providesPerElementDependencies = false; the dependencies are in modelDescription.xml)");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t ei[],
                                       fmi3ValueReference ind[], size_t ie[], fmi3DependencyKind k[], size_t n) {
    INST(0);
    (void)dependent; (void)ei; (void)ind; (void)ie; (void)k; (void)n;
    return refuse(c, "fmi3GetVariableDependencies",
                  "not provided (providesPerElementDependencies = false; the dependencies are in modelDescription.xml)");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *s) {
    INST(0);
    return (fmi3Status)fmi2GetFMUstate(c, (fmi2FMUstate *)s);
}
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState s) {
    INST(0);
    return (fmi3Status)fmi2SetFMUstate(c, (fmi2FMUstate)s);
}
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *s) {
    INST(0);
    return (fmi3Status)fmi2FreeFMUstate(c, (fmi2FMUstate *)s);
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState s, size_t *size) {
    INST(0);
    return (fmi3Status)fmi2SerializedFMUstateSize(c, (fmi2FMUstate)s, size);
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState s, fmi3Byte bytes[], size_t size) {
    INST(0);
    return (fmi3Status)fmi2SerializeFMUstate(c, (fmi2FMUstate)s, (fmi2Byte *)bytes, size);
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte bytes[], size_t size, fmi3FMUState *s) {
    INST(0);
    return (fmi3Status)fmi2DeSerializeFMUstate(c, (const fmi2Byte *)bytes, size, (fmi2FMUstate *)s);
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    INST(0);
    const char *f = "fmi3GetDirectionalDerivative";
    if (nSeed != nKnowns || nSensitivity != nUnknowns) {
        logmsg(c, fmi2Error, "logStatusError", "%s: nSeed = %zu, nKnowns = %zu, nSensitivity = %zu, nUnknowns = %zu: "
               "every variable of this FMU is a scalar, so nSeed must equal nKnowns and nSensitivity nUnknowns",
               f, nSeed, nKnowns, nSensitivity, nUnknowns);
        return fmi3Error;
    }
    for (size_t i = 0; i < nKnowns; i++) {
        int order;
        if (knowns && (is_time_vr(c, knowns[i]) || derivative_of(c, knowns[i], &order) >= 0)) {
            logmsg(c, fmi2Error, "logStatusError", "%s: known %u is time or an input derivative: not supported as a "
                   "known", f, knowns[i]);
            return fmi3Error;
        }
    }
    return (fmi3Status)fmi2GetDirectionalDerivative(c, unknowns, nUnknowns, knowns, nKnowns, seed, sensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens) {
    INST(0);
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return refuse(c, "fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives = false)");
}

/* ---- configuration, clocks, event mode: not supported ---------------------------------------- */
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    INST(0);
    return refuse(c, "fmi3EnterConfigurationMode", "this FMU has no structural parameters");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    INST(0);
    return refuse(c, "fmi3ExitConfigurationMode", "this FMU has no structural parameters");
}
#define CLOCKS_ONLY(NAME, ARGS)                                                    \
    fmi3Status NAME ARGS {                                                         \
        INST(0);                                                                   \
        return refuse(c, #NAME, "this FMU has no clocks");                         \
    }
CLOCKS_ONLY(fmi3GetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     fmi3Float64 iv[], fmi3IntervalQualifier q[]))
CLOCKS_ONLY(fmi3GetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                      fmi3UInt64 ic[], fmi3UInt64 r[], fmi3IntervalQualifier q[]))
CLOCKS_ONLY(fmi3GetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3Float64 s[]))
CLOCKS_ONLY(fmi3GetShiftFraction, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n, fmi3UInt64 sc[],
                                   fmi3UInt64 r[]))
CLOCKS_ONLY(fmi3SetIntervalDecimal, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     const fmi3Float64 iv[]))
CLOCKS_ONLY(fmi3SetIntervalFraction, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                      const fmi3UInt64 ic[], const fmi3UInt64 r[]))
CLOCKS_ONLY(fmi3SetShiftDecimal, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                  const fmi3Float64 s[]))
CLOCKS_ONLY(fmi3SetShiftFraction, (fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                   const fmi3UInt64 sc[], const fmi3UInt64 r[]))
CLOCKS_ONLY(fmi3ActivateModelPartition, (fmi3Instance instance, fmi3ValueReference cr, fmi3Float64 t))

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    INST(0);
    if (c->me) { /* no discrete state: nothing to evaluate */
        if (!check_state(c, "fmi3EvaluateDiscreteStates", S_EVENT | S_CONT)) return fmi3Error;
        return fmi3OK;
    }
    return refuse(c, "fmi3EvaluateDiscreteStates", "this FMU has no event mode in co-simulation (hasEventMode = false)");
}
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    INST(0);
    const char *f = "fmi3UpdateDiscreteStates";
    if (!c->me) return refuse(c, f, "this FMU has no event mode in co-simulation (hasEventMode = false)");
    NULLARG(f, discreteStatesNeedUpdate);
    NULLARG(f, terminateSimulation);
    NULLARG(f, nominalsOfContinuousStatesChanged);
    NULLARG(f, valuesOfContinuousStatesChanged);
    NULLARG(f, nextEventTimeDefined);
    NULLARG(f, nextEventTime);
    fmi2EventInfo e;
    fmi2Status s = fmi2NewDiscreteStates(c, &e);
    if (s > fmi2Warning) return (fmi3Status)s;
    *discreteStatesNeedUpdate = e.newDiscreteStatesNeeded != fmi2False;
    *terminateSimulation = e.terminateSimulation != fmi2False;
    *nominalsOfContinuousStatesChanged = e.nominalsOfContinuousStatesChanged != fmi2False;
    *valuesOfContinuousStatesChanged = e.valuesOfContinuousStatesChanged != fmi2False;
    *nextEventTimeDefined = e.nextEventTimeDefined != fmi2False;
    *nextEventTime = e.nextEventTime;
    return (fmi3Status)s;
}

/* ---- scheduled execution: not supported ------------------------------------------------------ */
fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean visible,
                                               fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                               fmi3LogMessageCallback log, fmi3ClockUpdateCallback cu,
                                               fmi3LockPreemptionCallback lp, fmi3UnlockPreemptionCallback up) {
    (void)name; (void)token; (void)res; (void)visible; (void)loggingOn; (void)cu; (void)lp; (void)up;
    if (log) log(env, fmi3Error, "logStatusError", "fmi3InstantiateScheduledExecution: this FMU has no scheduled execution");
    return NULL;
}

/* ---- model exchange: the core's (fmi_api.c), which refuses it on a co-simulation instance ------ */
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    INST(0);
    return (fmi3Status)fmi2EnterContinuousTimeMode(c);
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    INST(0);
    const char *f = "fmi3CompletedIntegratorStep";
    NULLARG(f, enterEventMode);
    NULLARG(f, terminateSimulation);
    fmi2Boolean e = fmi2False, t = fmi2False;
    fmi2Status s = fmi2CompletedIntegratorStep(c, noSetFMUStatePriorToCurrentPoint, &e, &t);
    if (s <= fmi2Warning) {
        *enterEventMode = e != fmi2False;
        *terminateSimulation = t != fmi2False;
    }
    return (fmi3Status)s;
}
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) {
    INST(0);
    return (fmi3Status)fmi2SetTime(c, t);
}
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    INST(0);
    return (fmi3Status)fmi2SetContinuousStates(c, x, n);
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    INST(0);
    return (fmi3Status)fmi2GetDerivatives(c, x, n);
}
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    INST(0);
    return (fmi3Status)fmi2GetEventIndicators(c, x, n);
}
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    INST(0);
    return (fmi3Status)fmi2GetContinuousStates(c, x, n);
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    INST(0);
    return (fmi3Status)fmi2GetNominalsOfContinuousStates(c, x, n);
}
static fmi3Status me_count(fmi3Instance instance, const char *f, size_t *n, int states) {
    INST(0);
    NULLARG(f, n);
    if (!me_model()) return refuse(c, f, "model exchange is not supported (co-simulation only)");
    *n = (size_t)(states ? me_model()->nx : me_model()->nz);
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    return me_count(instance, "fmi3GetNumberOfEventIndicators", n, 0);
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    return me_count(instance, "fmi3GetNumberOfContinuousStates", n, 1);
}

/* ---- co-simulation --------------------------------------------------------------------------- */
fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    INST(0);
    return refuse(c, "fmi3EnterStepMode", "this FMU has no event mode: it is in step mode after "
                  "fmi3ExitInitializationMode");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    INST(0);
    (void)nValues;
    return (fmi3Status)fmi2GetRealOutputDerivatives(c, vr, nvr, orders, values);
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    INST(0);
    const char *f = "fmi3DoStep";
    NULLARG(f, eventHandlingNeeded);
    NULLARG(f, terminateSimulation);
    NULLARG(f, earlyReturn);
    NULLARG(f, lastSuccessfulTime);
    fmi2Status s = fmi2DoStep(c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint);
    *eventHandlingNeeded = false;
    *terminateSimulation = s == fmi2Fatal;
    *earlyReturn = false;
    *lastSuccessfulTime = c->time;
    return (fmi3Status)s;
}
