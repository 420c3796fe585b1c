/*
 * twin_fmi3.c - the FMI 3.0 API (co-simulation and model exchange) on the model core (twin_core.c).
 * Compiled as part of twin_lti.c. The variables are Float64 (reals), Int32 (the node and the seeds) and
 * Boolean (steady_start); the other types, clocks and scheduled execution are refused with a message.
 */
#include "fmi3Functions.h"

#define C3 ((Lti *)instance)

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories; /* errors only, always */
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)visible; (void)loggingOn;
    return lti_new(instanceName, instantiationToken, resourcePath, 0, 1, 3, instanceEnvironment,
                   (void (*)(void))logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible; (void)loggingOn; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    Lti *s = lti_new(instanceName, instantiationToken, resourcePath, 0, 0, 3, instanceEnvironment,
                     (void (*)(void))logMessage);
    if (s && eventModeUsed) {
        logmsg(s, TWIN_ERROR, "fmi3InstantiateCoSimulation: the FMU has no event mode in co-simulation "
                              "(hasEventMode is false)");
        free_lti(s);
        return NULL;
    }
    return s;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn; (void)clockUpdate;
    (void)lockPreemption; (void)unlockPreemption;
    Lti tmp = {0};
    tmp.fmi_version = 3; tmp.env = instanceEnvironment; tmp.logger = (void (*)(void))logMessage;
    snprintf(tmp.name, sizeof tmp.name, "%s", instanceName ? instanceName : "twin");
    logmsg(&tmp, TWIN_ERROR, "fmi3InstantiateScheduledExecution: the FMU supports model exchange and co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free_lti(C3); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    lti_setup(C3, startTime);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    return (fmi3Status)lti_start(C3, "fmi3ExitInitializationMode");
}
fmi3Status fmi3EnterEventMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3Reset(fmi3Instance instance) {
    to_start_values(C3);
    return fmi3OK;
}

/* ---- values -------------------------------------------------------------------------- */
static fmi3Status count_check(Lti *s, const char *fn, size_t nvr, size_t nvalues) {
    return nvr == nvalues ? fmi3OK
                          : (fmi3Status)fail(s, fn, "one value per value reference (no arrays); values given:", (long)nvalues);
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    if (count_check(C3, "fmi3GetFloat64", nvr, nValues)) return fmi3Error;
    lti_refresh(C3);
    for (size_t i = 0; i < nvr; i++)
        if (get_real(C3, "fmi3GetFloat64", vr[i], &values[i])) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    if (count_check(C3, "fmi3SetFloat64", nvr, nValues)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++)
        if (set_real(C3, "fmi3SetFloat64", vr[i], values[i])) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues) {
    if (count_check(C3, "fmi3GetInt32", nvr, nValues)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        long v = 0;
        if (get_int(C3, "fmi3GetInt32", vr[i], &v)) return fmi3Error;
        values[i] = (fmi3Int32)v;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues) {
    if (count_check(C3, "fmi3SetInt32", nvr, nValues)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++)
        if (set_int(C3, "fmi3SetInt32", vr[i], values[i])) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues) {
    if (count_check(C3, "fmi3GetBoolean", nvr, nValues)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        int b = 0;
        if (get_bool(C3, "fmi3GetBoolean", vr[i], &b)) return fmi3Error;
        values[i] = b ? fmi3True : fmi3False;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t nValues) {
    if (count_check(C3, "fmi3SetBoolean", nvr, nValues)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++)
        if (set_bool(C3, "fmi3SetBoolean", vr[i], values[i] ? 1 : 0)) return fmi3Error;
    return fmi3OK;
}

/* The types the FMU has no variables of: any value reference is an error. */
#define NO_VARIABLES(get, set, T, what)                                                                        \
    fmi3Status get(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, T values[], size_t n) {   \
        (void)values; (void)n;                                                                                 \
        return nvr ? (fmi3Status)fail(C3, #get, "the FMU has no " what " variables; value reference", (long)vr[0]) \
                   : fmi3OK;                                                                                   \
    }                                                                                                          \
    fmi3Status set(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const T values[], size_t n) { \
        (void)values; (void)n;                                                                                 \
        return nvr ? (fmi3Status)fail(C3, #set, "the FMU has no " what " variables; value reference", (long)vr[0]) \
                   : fmi3OK;                                                                                   \
    }
NO_VARIABLES(fmi3GetFloat32, fmi3SetFloat32, fmi3Float32, "Float32")
NO_VARIABLES(fmi3GetInt8, fmi3SetInt8, fmi3Int8, "Int8")
NO_VARIABLES(fmi3GetUInt8, fmi3SetUInt8, fmi3UInt8, "UInt8")
NO_VARIABLES(fmi3GetInt16, fmi3SetInt16, fmi3Int16, "Int16")
NO_VARIABLES(fmi3GetUInt16, fmi3SetUInt16, fmi3UInt16, "UInt16")
NO_VARIABLES(fmi3GetUInt32, fmi3SetUInt32, fmi3UInt32, "UInt32")
NO_VARIABLES(fmi3GetInt64, fmi3SetInt64, fmi3Int64, "Int64")
NO_VARIABLES(fmi3GetUInt64, fmi3SetUInt64, fmi3UInt64, "UInt64")
NO_VARIABLES(fmi3GetString, fmi3SetString, fmi3String, "String")

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return nvr ? (fmi3Status)fail(C3, "fmi3GetBinary", "the FMU has no Binary variables; value reference", (long)vr[0]) : fmi3OK;
}
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return nvr ? (fmi3Status)fail(C3, "fmi3SetBinary", "the FMU has no Binary variables; value reference", (long)vr[0]) : fmi3OK;
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)values;
    return nvr ? (fmi3Status)fail(C3, "fmi3GetClock", "the FMU has no clocks; value reference", (long)vr[0]) : fmi3OK;
}
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)values;
    return nvr ? (fmi3Status)fail(C3, "fmi3SetClock", "the FMU has no clocks; value reference", (long)vr[0]) : fmi3OK;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)n;
    return (fmi3Status)fail(C3, "fmi3GetNumberOfVariableDependencies",
                            "not provided (the modelDescription lists the dependencies); value reference", (long)vr);
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents; (void)dependencyKinds;
    (void)nDependencies;
    return (fmi3Status)fail(C3, "fmi3GetVariableDependencies",
                            "not provided (the modelDescription lists the dependencies); value reference", (long)dependent);
}

/* ---- FMU state ------------------------------------------------------------------------ */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *st) {
    if (!st) return (fmi3Status)fail(C3, "fmi3GetFMUState", "no place to put the state (NULL pointer)", -1);
    void *q = lti_get_state(C3, "fmi3GetFMUState", *st);
    if (!q) return fmi3Error;
    *st = q;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState st) {
    if (!st) return (fmi3Status)fail(C3, "fmi3SetFMUState", "no state given (NULL)", -1);
    give(C3, (const Snapshot *)st);
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *st) {
    (void)instance;
    if (st) {
        free_snapshot((Snapshot *)*st);
        *st = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState st, size_t *size) {
    (void)st;
    *size = state_bytes(C3);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState st, fmi3Byte b[], size_t size) {
    return (fmi3Status)lti_serialize(C3, "fmi3SerializeFMUState", (const Snapshot *)st, (unsigned char *)b, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte b[], size_t size, fmi3FMUState *st) {
    if (!st) return (fmi3Status)fail(C3, "fmi3DeserializeFMUState", "no place to put the state (NULL pointer)", -1);
    Snapshot *q = lti_deserialize(C3, "fmi3DeserializeFMUState", (const unsigned char *)b, size);
    if (!q) return fmi3Error;
    if (*st) free_snapshot((Snapshot *)*st);
    *st = q;
    return fmi3OK;
}

/* ---- derivatives --------------------------------------------------------------------- */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    if (nSeed != nKnowns || nSensitivity != nUnknowns)
        return (fmi3Status)fail(C3, "fmi3GetDirectionalDerivative", "one seed per known and one sensitivity per unknown", -1);
    return (fmi3Status)lti_directional(C3, "fmi3GetDirectionalDerivative", unknowns, nUnknowns, knowns, nKnowns, seed,
                                       sensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return (fmi3Status)fail(C3, "fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives is false)", -1);
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    return (fmi3Status)fail(C3, "fmi3GetOutputDerivatives", "not provided (maxOutputDerivativeOrder is 0)", -1);
}

/* ---- configuration and clocks: none ----------------------------------------------------------- */
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return (fmi3Status)fail(C3, "fmi3EnterConfigurationMode", "the FMU has no structural parameters", -1);
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return (fmi3Status)fail(C3, "fmi3ExitConfigurationMode", "the FMU has no structural parameters", -1);
}
#define NO_CLOCKS(name, ...)                                                                                   \
    fmi3Status name(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, __VA_ARGS__) {           \
        (void)vr;                                                                                              \
        return nvr ? (fmi3Status)fail(C3, #name, "the FMU has no clocks; value reference", (long)vr[0]) : fmi3OK; \
    }
NO_CLOCKS(fmi3GetIntervalDecimal, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
NO_CLOCKS(fmi3GetIntervalFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NO_CLOCKS(fmi3GetShiftDecimal, fmi3Float64 shifts[])
NO_CLOCKS(fmi3GetShiftFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetIntervalDecimal, const fmi3Float64 intervals[])
NO_CLOCKS(fmi3SetIntervalFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetShiftDecimal, const fmi3Float64 shifts[])
NO_CLOCKS(fmi3SetShiftFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    *discreteStatesNeedUpdate = fmi3False;
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = C3->model_exchange ? fmi3True : fmi3False;
    *nextEventTime = lti_next_event(C3);
    return fmi3OK;
}

/* ---- model exchange --------------------------------------------------------------------- */
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)instance; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    lti_set_time(C3, time);
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx) {
    if (lti_check_states(C3, "fmi3SetContinuousStates", nx)) return fmi3Error;
    memcpy(C3->z, x, nx * 8);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t nx) {
    if (lti_check_states(C3, "fmi3GetContinuousStateDerivatives", nx)) return fmi3Error;
    derivatives_now(C3, dx);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t nz) {
    (void)z;
    return nz ? (fmi3Status)fail(C3, "fmi3GetEventIndicators", "the FMU has no event indicators; asked for", (long)nz) : fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx) {
    if (lti_check_states(C3, "fmi3GetContinuousStates", nx)) return fmi3Error;
    memcpy(x, C3->z, nx * 8);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx) {
    if (lti_check_states(C3, "fmi3GetNominalsOfContinuousStates", nx)) return fmi3Error;
    lti_nominals(C3, x);
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    (void)instance;
    *n = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    *n = 2 * (size_t)C3->r;
    return fmi3OK;
}

/* ---- co-simulation ---------------------------------------------------------------------- */
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    (void)currentCommunicationPoint; (void)noSetFMUStatePriorToCurrentPoint; /* the FMU keeps its own time */
    fmi3Status st = (fmi3Status)lti_step(C3, "fmi3DoStep", communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = lti_time(C3);
    return st;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)activationTime;
    return (fmi3Status)fail(C3, "fmi3ActivateModelPartition", "no scheduled execution; clock", (long)clockReference);
}
