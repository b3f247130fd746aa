/* The FMI 2.0 co-simulation interface, shared by every calbench model. All physics lives in
 * the model's own C files behind model_instance.h, and everything that FMI 3 does alike (the
 * state machine, argument checks, values, FMU states) in fmi_common.c; this file maps the FMI 2
 * signatures onto them and holds what only FMI 2 has (its logger, the status queries). */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi_common.h"

typedef struct {
    FmiCore core; /* first member: the fmi2Component is an FmiCore* (CORE) */
    fmi2CallbackFunctions cb;
} Fmi2Instance;

static const FmiVersion FMI2 = {"Real", "Integer", 0};

#define ALLOW(mask) FMI_ALLOW(c, mask, fmi2Error)

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

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    ALLOW(MASK_SET_DEBUG_LOGGING);
    return (fmi2Status)fmi_set_debug_logging(CORE(c), loggingOn);
}

/* ------------------------------------------------------------------ instantiation, modes */

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
    fmi_instantiated(&self->core, &FMI2, instanceName, fmi2_log, functions->componentEnvironment,
                     loggingOn);
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
    ALLOW(MASK_SETUP_EXPERIMENT);
    return (fmi2Status)fmi_set_start_time(CORE(c), startTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ALLOW(MASK_ENTER_INITIALIZATION);
    return (fmi2Status)fmi_enter_initialization(CORE(c));
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ALLOW(MASK_EXIT_INITIALIZATION);
    return (fmi2Status)fmi_exit_initialization(CORE(c));
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ALLOW(MASK_TERMINATE);
    return (fmi2Status)fmi_terminate(CORE(c));
}

fmi2Status fmi2Reset(fmi2Component c) {
    ALLOW(MASK_RESET);
    return (fmi2Status)fmi_reset(CORE(c));
}

/* ------------------------------------------------------------------ get / set */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    ALLOW(MASK_GET);
    return (fmi2Status)fmi_get_reals(CORE(c), vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    ALLOW(MASK_SET);
    return (fmi2Status)fmi_set_reals(CORE(c), vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    ALLOW(MASK_GET);
    return (fmi2Status)fmi_get_integers(CORE(c), vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    ALLOW(MASK_SET);
    return (fmi2Status)fmi_set_integers(CORE(c), vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    ALLOW(MASK_GET);
    return (fmi2Status)fmi_no_variables(CORE(c), nvr, "Boolean");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    (void)vr;
    (void)value;
    ALLOW(MASK_SET);
    return (fmi2Status)fmi_no_variables(CORE(c), nvr, "Boolean");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    (void)vr;
    (void)value;
    ALLOW(MASK_GET);
    return (fmi2Status)fmi_no_variables(CORE(c), nvr, "String");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    (void)vr;
    (void)value;
    ALLOW(MASK_SET);
    return (fmi2Status)fmi_no_variables(CORE(c), nvr, "String");
}

/* ------------------------------------------------------------------ FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_get_state(CORE(c), state);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_set_state(CORE(c), state);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_free_state(CORE(c), state);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state;
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_serialized_state_size(CORE(c), size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                 size_t size) {
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_serialize_state(CORE(c), state, bytes, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi2Status)fmi_deserialize_state(CORE(c), bytes, size, state);
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
    return (fmi2Status)fmi_refuse(CORE(c), "directional derivatives are not provided");
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    ALLOW(MASK_SET_INPUT_DERIVATIVES);
    return (fmi2Status)fmi_set_input_derivatives(CORE(c), vr, nvr, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)order;
    (void)value;
    ALLOW(MASK_GET);
    return nvr ? (fmi2Status)fmi_refuse(CORE(c), "output derivatives are not provided") : fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)noSetPrior;
    ALLOW(MASK_DO_STEP);
    return (fmi2Status)fmi_do_step(CORE(c), t, h, __func__);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return (fmi2Status)fmi_refuse(CORE(c), "fmi2CancelStep: steps are never asynchronous");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return (fmi2Status)fmi_refuse(CORE(c), "fmi2GetStatus: no asynchronous status");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    ALLOW(MASK_GET_STATUS);
    if (!value) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = CORE(c)->m.s.time;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    ALLOW(MASK_GET_STATUS);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    ALLOW(MASK_GET_STATUS);
    if (!value) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    ALLOW(MASK_GET_STATUS);
    return fmi2Discard;
}
