/* The FMI 3.0 co-simulation interface, shared by every calbench model. It mirrors fmi2_layer.c:
 * all physics lives in the model's own model.c behind model_instance.h; this file only guards
 * the FMI state machine, moves values in and out of the flat ModelState, and reports errors by
 * name. Everything FMI 3 declares but a calbench FMU does not offer (model exchange, scheduled
 * execution, event mode, clocks, other variable types, derivatives) exists, logs why and
 * returns fmi3Error. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model_instance.h"

typedef enum {
    MODE_INSTANTIATED = 0, /* after instantiate or reset */
    MODE_INITIALIZATION,   /* between enter and exit initialization mode */
    MODE_STEP,             /* after a successful exitInitializationMode */
    MODE_TERMINATED
} Fmi3Mode;

typedef struct {
    ModelInstance m; /* first member: a ModelInstance* is an Fmi3Instance* */
    fmi3LogMessageCallback log_message;
    fmi3InstanceEnvironment env;
    Fmi3Mode mode;
    int failed; /* a step or the initialisation returned error/fatal */
} Fmi3Instance;

#define SELF ((Fmi3Instance *)c)

static const char *const MODE_NAME[] = {"Instantiated", "Initialization Mode", "Step Mode",
                                        "Terminated"};

static void fmi3_log(ModelInstance *m, ModelStatus status, const char *category, const char *msg) {
    Fmi3Instance *self = (Fmi3Instance *)m;
    if (!self->log_message) return;
    /* FMI 3 messages are plain strings, not format strings: no '%' escaping needed */
    self->log_message(self->env, (fmi3Status)status, category, msg);
}

static fmi3Status bad_call(fmi3Instance c, const char *what) {
    if (!c) return fmi3Error;
    model_log(&SELF->m, MS_ERROR, "%s", what);
    return fmi3Error;
}

/* Is the instance in one of the modes of the bit mask? Logs and returns 0 if not. */
#define IN(mode) (1u << (mode))
static int allowed(fmi3Instance c, unsigned modes, const char *fn) {
    if (modes & IN(SELF->mode)) return 1;
    model_log(&SELF->m, MS_ERROR, "%s is not allowed in %s", fn, MODE_NAME[SELF->mode]);
    return 0;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    if (!c) return fmi3Error;
    SELF->m.logging_on = loggingOn ? 1 : 0;
    return fmi3OK;
}

static void reset_state(Fmi3Instance *self) {
    memset(&self->m.s, 0, sizeof self->m.s);
    memcpy(self->m.s.r, REAL_START, sizeof REAL_START);
    memcpy(self->m.s.i, INTEGER_START, sizeof INTEGER_START);
    self->m.initialized = 0;
    self->mode = MODE_INSTANTIATED;
    self->failed = 0;
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
    strncpy(self->m.instance_name, instanceName, sizeof self->m.instance_name - 1);
    self->m.log_fn = fmi3_log;
    self->m.env = instanceEnvironment;
    self->m.logging_on = loggingOn ? 1 : 0;
    reset_state(self);
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
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!c) return fmi3Error;
    if (!allowed(c, IN(MODE_INSTANTIATED), "fmi3EnterInitializationMode")) return fmi3Error;
    if (!isfinite(startTime)) {
        model_log(&SELF->m, MS_ERROR, "start time %g: expected a finite value", startTime);
        return fmi3Error;
    }
    SELF->m.s.time = startTime;
    SELF->m.s.start_time = startTime;
    SELF->mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    ModelStatus st;
    if (!c) return fmi3Error;
    if (!allowed(c, IN(MODE_INITIALIZATION), "fmi3ExitInitializationMode")) return fmi3Error;
    /* as in FMI 2: a failed attempt may be retried after the master corrected a parameter */
    st = model_initialize(&SELF->m);
    if (st >= MS_ERROR) {
        SELF->failed = 1;
        return (fmi3Status)st;
    }
    SELF->failed = 0;
    SELF->m.initialized = 1;
    SELF->mode = MODE_STEP;
    return (fmi3Status)st;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    return bad_call(c, "fmi3EnterEventMode: this FMU has no event mode");
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    if (!c) return fmi3Error;
    if (!allowed(c, IN(MODE_INITIALIZATION) | IN(MODE_STEP) | IN(MODE_TERMINATED),
                 "fmi3Terminate"))
        return fmi3Error;
    SELF->mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    if (!c) return fmi3Error;
    reset_state(SELF);
    return fmi3OK;
}

/* ------------------------------------------------------------------ get / set */

static int real_index(fmi3Instance c, fmi3ValueReference vr) {
    if (vr >= N_REAL) {
        model_log(&SELF->m, MS_ERROR, "value reference %u is not a Float64 variable", vr);
        return -1;
    }
    return (int)vr;
}

static int integer_index(fmi3Instance c, fmi3ValueReference vr) {
    if (vr < INTEGER_VR_BASE || vr >= INTEGER_VR_BASE + N_INTEGER_USED) {
        model_log(&SELF->m, MS_ERROR, "value reference %u is not an Int32 variable", vr);
        return -1;
    }
    return (int)(vr - INTEGER_VR_BASE);
}

static int counts_match(fmi3Instance c, size_t nvr, size_t nValues, const char *fn) {
    if (nvr == nValues) return 1;
    model_log(&SELF->m, MS_ERROR, "%s: nValues = %zu but %zu value references (all variables "
              "are scalars)", fn, nValues, nvr);
    return 0;
}

/* May the master set a variable of this causality/variability now? */
static int settable(fmi3Instance c, unsigned char caus, unsigned char var, const char *name) {
    if (SELF->mode == MODE_TERMINATED) {
        model_log(&SELF->m, MS_ERROR, "variable %s cannot be set after fmi3Terminate", name);
        return 0;
    }
    if (caus == CAUS_INPUT) return 1;
    if (caus == CAUS_PARAMETER && (!SELF->m.initialized || var == VAR_TUNABLE)) return 1;
    model_log(&SELF->m, MS_ERROR, "variable %s cannot be set %s", name,
              caus == CAUS_PARAMETER ? "after initialisation (fixed parameter)"
                                     : "(it is not an input or parameter)");
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          fmi3Float64 value[], size_t nValues) {
    size_t k;
    if (!c || (nvr && (!vr || !value))) return fmi3Error;
    if (!counts_match(c, nvr, nValues, "fmi3GetFloat64")) return fmi3Error;
    if (SELF->mode == MODE_INITIALIZATION && nvr) {
        /* outputs are "calculated" from the parameters and inputs set so far */
        ModelStatus st = model_initialize(&SELF->m);
        if (st >= MS_ERROR) return (fmi3Status)st;
    }
    for (k = 0; k < nvr; k++) {
        int j;
        if (vr[k] == TIME_VR) {
            value[k] = SELF->m.s.time;
            continue;
        }
        j = real_index(c, vr[k]);
        if (j < 0) return fmi3Error;
        value[k] = SELF->m.s.r[j];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 value[], size_t nValues) {
    size_t k;
    int changed = 0;
    if (!c || (nvr && (!vr || !value))) return fmi3Error;
    if (!counts_match(c, nvr, nValues, "fmi3SetFloat64")) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        int j;
        if (vr[k] == TIME_VR) return bad_call(c, "variable time is the independent variable "
                                                 "and cannot be set");
        j = real_index(c, vr[k]);
        if (j < 0) return fmi3Error;
        if (!settable(c, REAL_CAUSALITY[j], REAL_VARIABILITY[j], REAL_NAME[j])) return fmi3Error;
        SELF->m.s.r[j] = value[k];
        memset(SELF->m.s.rder[j], 0, sizeof SELF->m.s.rder[j]);
        changed = 1;
    }
    if (changed && SELF->m.initialized) return (fmi3Status)model_inputs_changed(&SELF->m);
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Int32 value[], size_t nValues) {
    size_t k;
    if (!c || (nvr && (!vr || !value))) return fmi3Error;
    if (!counts_match(c, nvr, nValues, "fmi3GetInt32")) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0) return fmi3Error;
        value[k] = (fmi3Int32)SELF->m.s.i[j];
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Int32 value[], size_t nValues) {
    size_t k;
    int changed = 0;
    if (!c || (nvr && (!vr || !value))) return fmi3Error;
    if (!counts_match(c, nvr, nValues, "fmi3SetInt32")) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        int j = integer_index(c, vr[k]);
        if (j < 0) return fmi3Error;
        if (!settable(c, INTEGER_CAUSALITY[j], INTEGER_VARIABILITY[j], INTEGER_NAME[j]))
            return fmi3Error;
        SELF->m.s.i[j] = (int)value[k];
        changed = 1;
    }
    if (changed && SELF->m.initialized) return (fmi3Status)model_inputs_changed(&SELF->m);
    return fmi3OK;
}

/* Getters and setters of the types this FMU has no variables of: an empty call is harmless,
 * any value reference is an error. */
#define NO_VARIABLES_OF(TYPE, CTYPE, CONST)                                                    \
    fmi3Status fmi3Get##TYPE(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,       \
                             CTYPE value[], size_t nValues) {                                \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        (void)nValues;                                                                       \
        if (!c) return fmi3Error;                                                            \
        return nvr ? bad_call(c, "this FMU has no " #TYPE " variables") : fmi3OK;            \
    }                                                                                        \
    fmi3Status fmi3Set##TYPE(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,       \
                             CONST CTYPE value[], size_t nValues) {                          \
        (void)vr;                                                                            \
        (void)value;                                                                         \
        (void)nValues;                                                                       \
        if (!c) return fmi3Error;                                                            \
        return nvr ? bad_call(c, "this FMU has no " #TYPE " variables") : fmi3OK;            \
    }

NO_VARIABLES_OF(Float32, fmi3Float32, const)
NO_VARIABLES_OF(Int8, fmi3Int8, const)
NO_VARIABLES_OF(UInt8, fmi3UInt8, const)
NO_VARIABLES_OF(Int16, fmi3Int16, const)
NO_VARIABLES_OF(UInt16, fmi3UInt16, const)
NO_VARIABLES_OF(UInt32, fmi3UInt32, const)
NO_VARIABLES_OF(Int64, fmi3Int64, const)
NO_VARIABLES_OF(UInt64, fmi3UInt64, const)
NO_VARIABLES_OF(Boolean, fmi3Boolean, const)
NO_VARIABLES_OF(String, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary value[], size_t nValues) {
    (void)vr;
    (void)valueSizes;
    (void)value;
    (void)nValues;
    if (!c) return fmi3Error;
    return nvr ? bad_call(c, "this FMU has no Binary variables") : fmi3OK;
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary value[], size_t nValues) {
    (void)vr;
    (void)valueSizes;
    (void)value;
    (void)nValues;
    if (!c) return fmi3Error;
    return nvr ? bad_call(c, "this FMU has no Binary variables") : fmi3OK;
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
    ModelState *copy;
    if (!c || !state) return fmi3Error;
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return bad_call(c, "out of memory saving the FMU state");
    memcpy(copy, &SELF->m.s, sizeof *copy);
    *state = copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    if (!c || !state) return fmi3Error;
    memcpy(&SELF->m.s, state, sizeof SELF->m.s);
    SELF->failed = 0;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    if (!c || !state) return fmi3Error;
    free(*state);
    *state = NULL;
    return fmi3OK;
}

#define STATE_MAGIC "calbench-state:" MODEL_IDENTIFIER_STRING

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    (void)state;
    if (!c || !size) return fmi3Error;
    *size = sizeof STATE_MAGIC + sizeof(ModelState);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[],
                                 size_t size) {
    if (!c || !state || !bytes) return fmi3Error;
    if (size < sizeof STATE_MAGIC + sizeof(ModelState))
        return bad_call(c, "buffer too small to serialise the FMU state");
    memcpy(bytes, STATE_MAGIC, sizeof STATE_MAGIC);
    memcpy(bytes + sizeof STATE_MAGIC, state, sizeof(ModelState));
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size,
                                   fmi3FMUState *state) {
    ModelState *copy;
    if (!c || !bytes || !state) return fmi3Error;
    if (size != sizeof STATE_MAGIC + sizeof(ModelState) ||
        memcmp(bytes, STATE_MAGIC, sizeof STATE_MAGIC) != 0)
        return bad_call(c, "serialised state is not from this model and build");
    copy = *state ? (ModelState *)*state : (ModelState *)malloc(sizeof *copy);
    if (!copy) return bad_call(c, "out of memory restoring the FMU state");
    memcpy(copy, bytes + sizeof STATE_MAGIC, sizeof *copy);
    *state = copy;
    return fmi3OK;
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
    /* the outputs are defined whatever happens below */
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = SELF->m.s.time;
    if (SELF->mode != MODE_STEP || !SELF->m.initialized) {
        model_log(&SELF->m, MS_ERROR, "fmi3DoStep is not allowed in %s%s", MODE_NAME[SELF->mode],
                  SELF->mode == MODE_STEP ? "" : " (call fmi3ExitInitializationMode first)");
        return fmi3Error;
    }
    if (SELF->failed) return bad_call(c, "fmi3DoStep after a failed step; reset or restore a state");
    if (!(h > 0.0) || !isfinite(h)) {
        model_log(&SELF->m, MS_ERROR, "communication step size %g: expected > 0", h);
        return fmi3Error;
    }
    if (fabs(t - SELF->m.s.time) > 1e-9 * (1.0 + fabs(t))) {
        model_log(&SELF->m, MS_ERROR, "doStep at t = %.12g but the FMU is at t = %.12g", t,
                  SELF->m.s.time);
        return fmi3Error;
    }
    st = model_do_step(&SELF->m, h);
    if (st >= MS_ERROR) {
        SELF->failed = 1;
        if (terminateSimulation) *terminateSimulation = st == MS_FATAL ? fmi3True : fmi3False;
        return (fmi3Status)st;
    }
    if (st != MS_DISCARD) SELF->m.s.time = t + h;
    if (lastSuccessfulTime) *lastSuccessfulTime = SELF->m.s.time;
    return (fmi3Status)st;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return bad_call(c, "fmi3ActivateModelPartition: this FMU supports co-simulation only");
}
