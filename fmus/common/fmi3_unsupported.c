/* The functions of FMI 3 for what a calbench FMU does not offer: model exchange and scheduled
 * execution, event mode, clocks, structural parameters, derivatives, variable types other than
 * Float64 and Int32. The standard makes every FMU export them all, so they exist; each logs why
 * it refuses and returns fmi3Error, in every mode. The one exception: a getter or setter of a
 * type with no variables accepts an empty call, in the modes of any getter or setter. */
#include "fmi3Functions.h"
#include "fmi_common.h"

#define ALLOW(mask) FMI_ALLOW(c, mask, fmi3Error)

static fmi3Status refuse(fmi3Instance c, const char *why) {
    return (fmi3Status)fmi_refuse(CORE(c), why);
}

/* ------------------------------------------------------------------ other interface types */

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

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference;
    (void)activationTime;
    return refuse(c, "fmi3ActivateModelPartition: this FMU supports co-simulation only");
}

/* ------------------------------------------------------------------ event mode, step mode */

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    return refuse(c, "fmi3EnterEventMode: this FMU has no event mode");
}

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    return refuse(c, "fmi3EnterStepMode: this FMU has no event mode; exitInitializationMode "
                       "enters Step Mode directly");
}

/* ------------------------------------------------------------------ variable types */

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
    return refuse(c, "fmi3GetClock: this FMU has no clocks");
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock value[]) {
    (void)vr;
    (void)value;
    (void)nvr;
    return refuse(c, "fmi3SetClock: this FMU has no clocks");
}

/* ------------------------------------------------------------------ dependencies */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference;
    (void)nDependencies;
    return refuse(c, "fmi3GetNumberOfVariableDependencies: dependencies are declared in "
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
    return refuse(c, "fmi3GetVariableDependencies: dependencies are declared in "
                       "modelDescription.xml only");
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
    return refuse(c, "directional derivatives are not provided");
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
    return refuse(c, "adjoint derivatives are not provided");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    (void)vr;
    (void)nvr;
    (void)orders;
    (void)values;
    (void)nValues;
    return refuse(c, "output derivatives are not provided");
}

/* ------------------------------------------------------------------ configuration, clocks */

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) {
    return refuse(c, "fmi3EnterConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) {
    return refuse(c, "fmi3ExitConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)nvr;
    (void)intervals;
    (void)qualifiers;
    return refuse(c, "fmi3GetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return refuse(c, "fmi3GetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr;
    (void)nvr;
    (void)shifts;
    return refuse(c, "fmi3GetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return refuse(c, "fmi3GetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr;
    (void)nvr;
    (void)intervals;
    return refuse(c, "fmi3SetIntervalDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return refuse(c, "fmi3SetIntervalFraction: this FMU has no clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr;
    (void)nvr;
    (void)shifts;
    return refuse(c, "fmi3SetShiftDecimal: this FMU has no clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr;
    (void)nvr;
    (void)counters;
    (void)resolutions;
    return refuse(c, "fmi3SetShiftFraction: this FMU has no clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    return refuse(c, "fmi3EvaluateDiscreteStates: this FMU has no event mode");
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
    return refuse(c, "fmi3UpdateDiscreteStates: this FMU has no event mode");
}

/* ------------------------------------------------------------------ model exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    return refuse(c, "fmi3EnterContinuousTimeMode: this FMU supports co-simulation only");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return refuse(c, "fmi3CompletedIntegratorStep: this FMU supports co-simulation only");
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    (void)time;
    return refuse(c, "fmi3SetTime: this FMU supports co-simulation only");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return refuse(c, "fmi3SetContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives;
    (void)nContinuousStates;
    return refuse(c, "fmi3GetContinuousStateDerivatives: this FMU supports co-simulation only");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators) {
    (void)eventIndicators;
    (void)nEventIndicators;
    return refuse(c, "fmi3GetEventIndicators: this FMU supports co-simulation only");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates;
    (void)nContinuousStates;
    return refuse(c, "fmi3GetContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals;
    (void)nContinuousStates;
    return refuse(c, "fmi3GetNominalsOfContinuousStates: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return refuse(c, "fmi3GetNumberOfEventIndicators: this FMU supports co-simulation only");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return refuse(c, "fmi3GetNumberOfContinuousStates: this FMU supports co-simulation only");
}
