/* The FMI 3.0 co-simulation interface, shared by every calbench model. It mirrors fmi2_layer.c:
 * all physics lives in the model's own model.c behind model_instance.h, and everything that
 * FMI 2 does alike (the state machine, argument checks, values, FMU states) in fmi_common.c;
 * this file maps the FMI 3 signatures onto them. Everything FMI 3 declares but a calbench FMU
 * does not offer (model exchange, scheduled execution, event mode, clocks, other variable
 * types, derivatives) exists, logs why and returns fmi3Error. */
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

/* Refuse the call unless the instance exists and is in one of the modes of mask. */
#define ALLOW(mask)                                                                           \
    do {                                                                                      \
        if (!fmi_allowed(CORE(c), (mask), __func__)) return fmi3Error;                        \
    } while (0)

static void fmi3_log(ModelInstance *m, ModelStatus status, const char *category, const char *msg) {
    Fmi3Instance *self = (Fmi3Instance *)m;
    if (!self->log_message) return;
    /* FMI 3 messages are plain strings, not format strings: no '%' escaping needed */
    self->log_message(self->env, (fmi3Status)status, category, msg);
}

static fmi3Status bad_call(fmi3Instance c, const char *what) {
    return (fmi3Status)fmi_refuse(CORE(c), what);
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

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "this FMU supports co-simulation only (no model exchange)");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "this FMU supports co-simulation only (no scheduled execution)");
    return NULL;
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

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    return bad_call(c, "fmi3EnterEventMode: this FMU has no event mode");
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

/* Getters and setters of the types this FMU has no variables of: an empty call is harmless,
 * any value reference is an error. */
#define NO_VARIABLES_OF(TYPE, CTYPE)                                                         \
    fmi3Status fmi3Get##TYPE(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,       \
                             CTYPE value[], size_t nValues) {                                \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        (void)nValues;                                                                       \
        ALLOW(MASK_GET);                                                                     \
        return (fmi3Status)fmi_no_variables(CORE(c), nvr, #TYPE);                            \
    }                                                                                        \
    fmi3Status fmi3Set##TYPE(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,       \
                             const CTYPE value[], size_t nValues) {                          \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        (void)nValues;                                                                       \
        ALLOW(MASK_SET);                                                                     \
        return (fmi3Status)fmi_no_variables(CORE(c), nvr, #TYPE);                            \
    }

NO_VARIABLES_OF(Float32, fmi3Float32)
NO_VARIABLES_OF(Int8, fmi3Int8)
NO_VARIABLES_OF(UInt8, fmi3UInt8)
NO_VARIABLES_OF(Int16, fmi3Int16)
NO_VARIABLES_OF(UInt16, fmi3UInt16)
NO_VARIABLES_OF(UInt32, fmi3UInt32)
NO_VARIABLES_OF(Int64, fmi3Int64)
NO_VARIABLES_OF(UInt64, fmi3UInt64)
NO_VARIABLES_OF(Boolean, fmi3Boolean)
NO_VARIABLES_OF(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary value[], size_t nValues) {
    (void)vr;
    (void)valueSizes;
    (void)value;
    (void)nValues;
    ALLOW(MASK_GET);
    return (fmi3Status)fmi_no_variables(CORE(c), nvr, "Binary");
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary value[], size_t nValues) {
    (void)vr;
    (void)valueSizes;
    (void)value;
    (void)nValues;
    ALLOW(MASK_SET);
    return (fmi3Status)fmi_no_variables(CORE(c), nvr, "Binary");
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock value[]) {
    (void)vr;
    (void)value;
    (void)nvr;
    return bad_call(c, "fmi3GetClock: this FMU has no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock value[]) {
    (void)vr;
    (void)value;
    (void)nvr;
    return bad_call(c, "fmi3SetClock: this FMU has no clocks");
}

/* ------------------------------------------------------------------ dependencies */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return bad_call(c, "fmi3GetNumberOfVariableDependencies: dependencies are declared in "
                       "modelDescription.xml only");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return bad_call(c, "fmi3GetVariableDependencies: dependencies are declared in "
                       "modelDescription.xml only");
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

/* ------------------------------------------------------------------ derivatives */

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                        size_t nUnknowns, const fmi3ValueReference knowns[],
                                        size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return bad_call(c, "directional derivatives are not provided");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return bad_call(c, "adjoint derivatives are not provided");
}

/* ------------------------------------------------------------------ configuration, clocks */

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return bad_call(c, "fmi3EnterConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return bad_call(c, "fmi3ExitConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)nvr;
    (void)intervals;
    (void)qualifiers;
    return bad_call(c, "fmi3GetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return bad_call(c, "fmi3GetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr;
    (void)nvr;
    (void)shifts;
    return bad_call(c, "fmi3GetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return bad_call(c, "fmi3GetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr;
    (void)nvr;
    (void)intervals;
    return bad_call(c, "fmi3SetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return bad_call(c, "fmi3SetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr;
    (void)nvr;
    (void)shifts;
    return bad_call(c, "fmi3SetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return bad_call(c, "fmi3SetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return bad_call(c, "fmi3EvaluateDiscreteStates: this FMU has no event mode");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate;
    (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined;
    (void)nextEventTime;
    return bad_call(c, "fmi3UpdateDiscreteStates: this FMU has no event mode");
}

/* ------------------------------------------------------------------ model exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return bad_call(c, "fmi3EnterContinuousTimeMode: this FMU supports co-simulation only");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return bad_call(c, "fmi3CompletedIntegratorStep: this FMU supports co-simulation only");
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    return bad_call(c, "fmi3SetTime: this FMU supports co-simulation only");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return bad_call(c, "fmi3SetContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives;
    (void)nContinuousStates;
    return bad_call(c, "fmi3GetContinuousStateDerivatives: this FMU supports co-simulation only");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators;
    (void)nEventIndicators;
    return bad_call(c, "fmi3GetEventIndicators: this FMU supports co-simulation only");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return bad_call(c, "fmi3GetContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals;
    (void)nContinuousStates;
    return bad_call(c, "fmi3GetNominalsOfContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return bad_call(c, "fmi3GetNumberOfEventIndicators: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return bad_call(c, "fmi3GetNumberOfContinuousStates: this FMU supports co-simulation only");
}

/* ------------------------------------------------------------------ co-simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    return bad_call(c, "fmi3EnterStepMode: this FMU has no event mode; exitInitializationMode "
                       "enters Step Mode directly");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)vr;
    (void)nvr;
    (void)orders;
    (void)values;
    (void)nValues;
    return bad_call(c, "output derivatives are not provided");
}

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

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return bad_call(c, "fmi3ActivateModelPartition: this FMU supports co-simulation only");
}
