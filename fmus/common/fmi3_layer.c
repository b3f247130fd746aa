/* The FMI 3.0 co-simulation interface, shared by every calbench model. It mirrors fmi2_layer.c:
 * all physics lives in the model's own C files behind model_instance.h, and everything that
 * FMI 2 does alike (the state machine, argument checks, values, FMU states) in fmi_common.c;
 * this file maps the FMI 3 signatures onto them. What FMI 3 declares but a calbench FMU does
 * not offer is refused in fmi3_unsupported.c. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi_common.h"

typedef struct {
    FmiCore core; /* first member: the fmi3Instance is an FmiCore* (CORE) */
    fmi3LogMessageCallback log_message;
    fmi3InstanceEnvironment env;
} Fmi3Instance;

static const FmiVersion FMI3 = {"Float64", "Int32", 1};

#define ALLOW(mask) FMI_ALLOW(c, mask, fmi3Error)

static void fmi3_log(ModelInstance *m, ModelStatus status, const char *category, const char *msg) {
    Fmi3Instance *self = (Fmi3Instance *)m;
    if (!self->log_message) return;
    /* FMI 3 messages are plain strings, not format strings: no '%' escaping needed */
    self->log_message(self->env, (fmi3Status)status, category, msg);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    ALLOW(MASK_SET_DEBUG_LOGGING);
    return (fmi3Status)fmi_set_debug_logging(CORE(c), loggingOn);
}

/* ------------------------------------------------------------------ instantiation */

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Fmi3Instance *self;
    const char *why = NULL;
    (void)resourcePath;
    (void)visible;
    (void)earlyReturnAllowed; /* never returns early: steps are atomic */
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    if (!instanceName || !instantiationToken) return NULL;
    if (strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0)
        why = "instantiationToken does not match this binary (stale modelDescription?)";
    else if (eventModeUsed)
        why = "this FMU has no event mode (hasEventMode is false): instantiate with "
              "eventModeUsed = false";
    else if (nRequiredIntermediateVariables > 0)
        why = "this FMU provides no intermediate variables";
    if (why) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", why);
        return NULL;
    }
    self = (Fmi3Instance *)calloc(1, sizeof *self);
    if (!self) return NULL;
    self->log_message = logMessage;
    self->env = instanceEnvironment;
    fmi_instantiated(&self->core, &FMI3, instanceName, fmi3_log, instanceEnvironment, loggingOn);
    return self;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

/* ------------------------------------------------------------------ modes */

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    ModelStatus st;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    ALLOW(MASK_ENTER_INITIALIZATION);
    st = fmi_set_start_time(CORE(c), startTime);
    if (st >= MS_ERROR) return (fmi3Status)st;
    return (fmi3Status)fmi_enter_initialization(CORE(c));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    ALLOW(MASK_EXIT_INITIALIZATION);
    return (fmi3Status)fmi_exit_initialization(CORE(c));
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    ALLOW(MASK_TERMINATE);
    return (fmi3Status)fmi_terminate(CORE(c));
}

fmi3Status fmi3Reset(fmi3Instance c) {
    ALLOW(MASK_RESET);
    return (fmi3Status)fmi_reset(CORE(c));
}

/* ------------------------------------------------------------------ get / set */

/* Every variable is a scalar: one value per value reference. */
static int counts_match(fmi3Instance c, size_t nvr, size_t nValues, const char *fn) {
    if (nvr == nValues) return 1;
    model_log(&CORE(c)->m, MS_ERROR, "%s: nValues = %zu but %zu value references (all "
              "variables are scalars)", fn, nValues, nvr);
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 value[], size_t nValues) {
    ALLOW(MASK_GET);
    if (!counts_match(c, nvr, nValues, __func__)) return fmi3Error;
    return (fmi3Status)fmi_get_reals(CORE(c), vr, nvr, value);
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 value[], size_t nValues) {
    ALLOW(MASK_SET);
    if (!counts_match(c, nvr, nValues, __func__)) return fmi3Error;
    return (fmi3Status)fmi_set_reals(CORE(c), vr, nvr, value);
}

fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Int32 value[], size_t nValues) {
    ALLOW(MASK_GET);
    if (!counts_match(c, nvr, nValues, __func__)) return fmi3Error;
    return (fmi3Status)fmi_get_integers(CORE(c), vr, nvr, value);
}

fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 value[], size_t nValues) {
    ALLOW(MASK_SET);
    if (!counts_match(c, nvr, nValues, __func__)) return fmi3Error;
    return (fmi3Status)fmi_set_integers(CORE(c), vr, nvr, value);
}

/* ------------------------------------------------------------------ FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_get_state(CORE(c), state);
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_set_state(CORE(c), state);
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_free_state(CORE(c), state);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    (void)state;
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_serialized_state_size(CORE(c), size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[],
                                 size_t size) {
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_serialize_state(CORE(c), state, bytes, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size,
                                   fmi3FMUState *state) {
    ALLOW(MASK_FMU_STATE);
    return (fmi3Status)fmi_deserialize_state(CORE(c), bytes, size, state);
}

/* ------------------------------------------------------------------ co-simulation */

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    ModelStatus st;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!c) return fmi3Error;
    /* the outputs are defined whatever happens below, a refused call included */
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = CORE(c)->m.s.time;
    ALLOW(MASK_DO_STEP);
    st = fmi_do_step(CORE(c), t, h, __func__);
    if (terminateSimulation) *terminateSimulation = st == MS_FATAL ? fmi3True : fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = CORE(c)->m.s.time;
    return (fmi3Status)st;
}

