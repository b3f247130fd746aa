/* The FMI 2.0 co-simulation interface, shared by every calbench model. All physics lives in
 * the model's own model.c behind model_instance.h; this file only guards the FMI state
 * machine, moves values in and out of the flat ModelState, and reports errors by name. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model_instance.h"

typedef struct {
    ModelInstance m;
    fmi2CallbackFunctions cb;
    int failed; /* a step or the initialisation returned error/fatal */
} Fmi2Instance;

#define SELF ((Fmi2Instance *)c)

static void fmi2_log(ModelInstance *m, ModelStatus status, const char *category, const char *msg) {
    Fmi2Instance *self = (Fmi2Instance *)m;
    char clean[1024];
    size_t k;
    if (!self->cb.logger) return;
    /* the message is the logger's format string: neutralise '%' */
    for (k = 0; msg[k] && k < sizeof clean - 1; k++) clean[k] = msg[k] == '%' ? '#' : msg[k];
    clean[k] = 0;
    self->cb.logger(self->cb.componentEnvironment, m->instance_name, (fmi2Status)status, category,
                    clean);
}

static fmi2Status bad_call(fmi2Component c, const char *what) {
    model_log(&SELF->m, MS_ERROR, "%s", what);
    return fmi2Error;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    if (!c) return fmi2Error;
    SELF->m.logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

static void reset_state(ModelInstance *m) {
    memset(&m->s, 0, sizeof m->s);
    memcpy(m->s.r, REAL_START, sizeof REAL_START);
    memcpy(m->s.i, INTEGER_START, sizeof INTEGER_START);
    m->initialized = 0;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Fmi2Instance *self;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !instanceName || !fmuGUID) return NULL;
    if (fmuType != fmi2CoSimulation || strcmp(fmuGUID, INSTANTIATION_TOKEN) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError",
                              fmuType != fmi2CoSimulation
                                  ? "this FMU supports co-simulation only"
                                  : "GUID does not match this binary (stale modelDescription?)");
        return NULL;
    }
    self = (Fmi2Instance *)calloc(1, sizeof *self);
    if (!self) return NULL;
    self->cb = *functions;
    strncpy(self->m.instance_name, instanceName, sizeof self->m.instance_name - 1);
    self->m.log_fn = fmi2_log;
    self->m.env = functions->componentEnvironment;
    self->m.logging_on = loggingOn ? 1 : 0;
    reset_state(&self->m);
    return self;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!c) return fmi2Error;
    if (SELF->m.initialized) return bad_call(c, "fmi2SetupExperiment after initialisation");
    SELF->m.s.time = startTime;
    SELF->m.s.start_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ModelStatus st;
    if (!c) return fmi2Error;
    st = model_initialize(&SELF->m);
    if (st >= MS_ERROR) {
        SELF->failed = 1;
        return (fmi2Status)st;
    }
    SELF->m.initialized = 1;
    SELF->failed = 0; /* a corrected retry after a refused parameter is a fresh start */
    return (fmi2Status)st;
}

fmi2Status fmi2Terminate(fmi2Component c) { return c ? fmi2OK : fmi2Error; }

fmi2Status fmi2Reset(fmi2Component c) {
    if (!c) return fmi2Error;
    reset_state(&SELF->m);
    SELF->failed = 0;
    return fmi2OK;
}

/* ------------------------------------------------------------------ get / set */

static int real_index(fmi2Component c, fmi2ValueReference vr) {
    if (vr >= N_REAL) {
        model_log(&SELF->m, MS_ERROR, "value reference %u is not a Real variable", vr);
        return -1;
    }
    return (int)vr;
}

static int integer_index(fmi2Component c, fmi2ValueReference vr) {
    if (vr < INTEGER_VR_BASE || vr >= INTEGER_VR_BASE + N_INTEGER_USED) {
        model_log(&SELF->m, MS_ERROR, "value reference %u is not an Integer variable", vr);
        return -1;
    }
    return (int)(vr - INTEGER_VR_BASE);
}

/* May the master set a variable of this causality/variability now? */
static int settable(fmi2Component c, unsigned char caus, unsigned char var, const char *name) {
    if (caus == CAUS_INPUT) return 1;
    if (caus == CAUS_PARAMETER && (!SELF->m.initialized || var == VAR_TUNABLE)) return 1;
    model_log(&SELF->m, MS_ERROR, "variable %s cannot be set %s", name,
              caus == CAUS_PARAMETER ? "after initialisation (fixed parameter)"
                                     : "(it is not an input or parameter)");
    return 0;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    size_t k;
    if (!c || (nvr && (!vr || !value))) return fmi2Error;
    if (!SELF->m.initialized && nvr) {
        /* Initialization Mode: outputs are "calculated" from the parameters and inputs set so
         * far, so a master that propagates initial values (libcosim) sees real ones */
        ModelStatus st = model_initialize(&SELF->m);
        if (st >= MS_ERROR) return (fmi2Status)st;
    }
    for (k = 0; k < nvr; k++) {
        int j = real_index(c, vr[k]);
        if (j < 0) return fmi2Error;
        value[k] = SELF->m.s.r[j];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    size_t k;
    int changed = 0;
    if (!c || (nvr && (!vr || !value))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        int j = real_index(c, vr[k]);
        if (j < 0) return fmi2Error;
        if (!settable(c, REAL_CAUSALITY[j], REAL_VARIABILITY[j], REAL_NAME[j])) return fmi2Error;
        SELF->m.s.r[j] = value[k];
        memset(SELF->m.s.rder[j], 0, sizeof SELF->m.s.rder[j]);
        changed = 1;
    }
    if (changed && SELF->m.initialized) return (fmi2Status)model_inputs_changed(&SELF->m);
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    size_t k;
    if (!c || (nvr && (!vr || !value))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0) return fmi2Error;
        value[k] = SELF->m.s.i[j];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    size_t k;
    int changed = 0;
    if (!c || (nvr && (!vr || !value))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0) return fmi2Error;
        if (!settable(c, INTEGER_CAUSALITY[j], INTEGER_VARIABILITY[j], INTEGER_NAME[j]))
            return fmi2Error;
        SELF->m.s.i[j] = value[k];
        changed = 1;
    }
    if (changed && SELF->m.initialized) return (fmi2Status)model_inputs_changed(&SELF->m);
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)value;
    return nvr ? bad_call(c, "this FMU has no Boolean variables") : fmi2OK;
    (void)vr;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    return nvr ? bad_call(c, "this FMU has no Boolean variables") : fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    return nvr ? bad_call(c, "this FMU has no String variables") : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    return nvr ? bad_call(c, "this FMU has no String variables") : fmi2OK;
}

/* ------------------------------------------------------------------ FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    ModelState *copy;
    if (!c || !state) return fmi2Error;
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return bad_call(c, "out of memory saving the FMU state");
    memcpy(copy, &SELF->m.s, sizeof *copy);
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    if (!c || !state) return fmi2Error;
    memcpy(&SELF->m.s, state, sizeof SELF->m.s);
    SELF->failed = 0;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (!c || !state) return fmi2Error;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

#define STATE_MAGIC "calbench-state:" MODEL_IDENTIFIER_STRING

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state;
    if (!c || !size) return fmi2Error;
    *size = sizeof STATE_MAGIC + sizeof(ModelState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                 size_t size) {
    if (!c || !state || !bytes) return fmi2Error;
    if (size < sizeof STATE_MAGIC + sizeof(ModelState))
        return bad_call(c, "buffer too small to serialise the FMU state");
    memcpy(bytes, STATE_MAGIC, sizeof STATE_MAGIC);
    memcpy(bytes + sizeof STATE_MAGIC, state, sizeof(ModelState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    ModelState *copy;
    if (!c || !bytes || !state) return fmi2Error;
    if (size != sizeof STATE_MAGIC + sizeof(ModelState) ||
        memcmp(bytes, STATE_MAGIC, sizeof STATE_MAGIC) != 0)
        return bad_call(c, "serialised state is not from this model and build");
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return bad_call(c, "out of memory restoring the FMU state");
    memcpy(copy, bytes + sizeof STATE_MAGIC, sizeof *copy);
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[],
                                        size_t nUnknown, const fmi2ValueReference vKnown[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown;
    (void)nUnknown;
    (void)vKnown;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return bad_call(c, "directional derivatives are not provided");
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    size_t k;
    if (!c || (nvr && (!vr || !order || !value))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        int j = real_index(c, vr[k]);
        if (j < 0) return fmi2Error;
        if (REAL_CAUSALITY[j] != CAUS_INPUT) {
            model_log(&SELF->m, MS_ERROR, "derivative set for %s, which is not an input",
                      REAL_NAME[j]);
            return fmi2Error;
        }
        if (order[k] < 1 || order[k] > MAX_INPUT_DERIVATIVE_ORDER) {
            model_log(&SELF->m, MS_ERROR, "derivative order %d for %s: expected 1..%d", order[k],
                      REAL_NAME[j], MAX_INPUT_DERIVATIVE_ORDER);
            return fmi2Error;
        }
        SELF->m.s.rder[j][order[k] - 1] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)order;
    (void)value;
    return nvr ? bad_call(c, "output derivatives are not provided") : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    ModelStatus st;
    (void)noSetPrior;
    if (!c) return fmi2Error;
    if (!SELF->m.initialized) return bad_call(c, "fmi2DoStep before initialisation");
    if (SELF->failed) return bad_call(c, "fmi2DoStep after a failed step; reset or restore a state");
    if (!(h > 0.0) || !isfinite(h)) {
        model_log(&SELF->m, MS_ERROR, "communication step size %g: expected > 0", h);
        return fmi2Error;
    }
    if (fabs(t - SELF->m.s.time) > 1e-9 * (1.0 + fabs(t))) {
        model_log(&SELF->m, MS_ERROR, "doStep at t = %.12g but the FMU is at t = %.12g", t,
                  SELF->m.s.time);
        return fmi2Error;
    }
    st = model_do_step(&SELF->m, h);
    if (st >= MS_ERROR) {
        SELF->failed = 1;
        return (fmi2Status)st;
    }
    if (st != MS_DISCARD) SELF->m.s.time = t + h;
    return (fmi2Status)st;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return bad_call(c, "fmi2CancelStep: steps are never asynchronous");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return bad_call(c, "fmi2GetStatus: no asynchronous status");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (!c || !value) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = SELF->m.s.time;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return c ? fmi2Discard : fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (!c || !value) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return c ? fmi2Discard : fmi2Error;
}
