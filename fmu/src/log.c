/* Messages to the host's logger and the FMI 2.0 state-machine check. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyfmu.h"

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

void logmsg(Comp *c, fmi2Status st, const char *cat, const char *fmt, ...) {
    if (!c || !c->logger) return;
    if (st == fmi2OK && !c->logging_on) return;
    char buf[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    emit(c, st, cat, buf, NULL);
}

void loglong(Comp *c, fmi2Status st, const char *cat, const char *prefix, const char *text) {
    if (!c || !c->logger) return;
    emit(c, st, cat, prefix, text);
}

const char *state_name(int s) {
    switch (s) {
    case S_INSTANTIATED: return "Instantiated";
    case S_INIT: return "InitializationMode";
    case S_STEP_COMPLETE: return "StepComplete";
    case S_STEP_FAILED: return "StepFailed";
    case S_TERMINATED: return "Terminated";
    case S_ERROR: return "Error";
    case S_EVENT: return "EventMode";
    case S_CONT: return "ContinuousTimeMode";
    default: return "Fatal";
    }
}

int check_state(Comp *c, const char *f, int mask) {
    if (!c || c->magic != COMP_MAGIC) return 0; /* not an instance of this FMU: nothing to log to */
    if (!(c->state & mask)) {
        logmsg(c, fmi2Error, "logStatusError", "%s: not allowed in state %s", f, state_name(c->state));
        return 0;
    }
    return 1;
}
