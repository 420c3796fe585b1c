/*
 * twin_fmi2.c - the FMI 2.0 API (co-simulation and model exchange) on the model core (twin_core.c).
 * Compiled as part of twin_lti.c.
 */
#include "fmi2Functions.h"

#define C2 ((Lti *)c)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    (void)c; (void)on; (void)n; (void)cat; /* the FMU logs errors only, and always: nothing to switch */
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging) {
    (void)visible; (void)logging;
    void (*logger)(void) = functions ? (void (*)(void))functions->logger : NULL;
    void *env = functions ? functions->componentEnvironment : NULL;
    if (type != fmi2CoSimulation && type != fmi2ModelExchange) {
        Lti tmp = {0};
        tmp.fmi_version = 2; tmp.env = env; tmp.logger = logger;
        snprintf(tmp.name, sizeof tmp.name, "%s", name ? name : "twin");
        logmsg(&tmp, TWIN_ERROR, "fmi2Instantiate: the type is neither fmi2ModelExchange nor fmi2CoSimulation");
        return NULL;
    }
    return lti_new(name, guid, resources, 1, type == fmi2ModelExchange, 2, env, logger);
}

void fmi2FreeInstance(fmi2Component c) { free_lti(C2); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop) {
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    lti_setup(C2, start);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return (fmi2Status)lti_start(C2, "fmi2ExitInitializationMode"); }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) {
    to_start_values(C2);
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)t; (void)noSetPrior; /* the FMU keeps its own time: t0 + pos h0 */
    return (fmi2Status)lti_step(C2, "fmi2DoStep", h);
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return (fmi2Status)fail(C2, "fmi2CancelStep", "steps are synchronous: there is none to cancel", -1);
}

/* ---- values -------------------------------------------------------------------------- */
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    lti_refresh(C2);
    for (size_t i = 0; i < nvr; i++)
        if (get_real(C2, "fmi2GetReal", vr[i], &value[i])) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    for (size_t i = 0; i < nvr; i++)
        if (set_real(C2, "fmi2SetReal", vr[i], value[i])) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    for (size_t i = 0; i < nvr; i++) {
        long v = 0;
        if (get_int(C2, "fmi2GetInteger", vr[i], &v)) return fmi2Error;
        value[i] = (fmi2Integer)v;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    for (size_t i = 0; i < nvr; i++)
        if (set_int(C2, "fmi2SetInteger", vr[i], value[i])) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean v[]) {
    for (size_t i = 0; i < nvr; i++) {
        int b = 0;
        if (get_bool(C2, "fmi2GetBoolean", vr[i], &b)) return fmi2Error;
        v[i] = b ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean v[]) {
    for (size_t i = 0; i < nvr; i++)
        if (set_bool(C2, "fmi2SetBoolean", vr[i], v[i] != fmi2False)) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String v[]) {
    (void)v;
    return nvr ? (fmi2Status)fail(C2, "fmi2GetString", "the FMU has no String variables; value reference", (long)vr[0]) : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String v[]) {
    (void)v;
    return nvr ? (fmi2Status)fail(C2, "fmi2SetString", "the FMU has no String variables; value reference", (long)vr[0]) : fmi2OK;
}

/* ---- FMU state ------------------------------------------------------------------------ */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    if (!st) return (fmi2Status)fail(C2, "fmi2GetFMUstate", "no place to put the state (NULL pointer)", -1);
    void *q = lti_get_state(C2, "fmi2GetFMUstate", *st);
    if (!q) return fmi2Error;
    *st = q;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    if (!st) return (fmi2Status)fail(C2, "fmi2SetFMUstate", "no state given (NULL)", -1);
    give(C2, (const Snapshot *)st);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)c;
    if (st) {
        free_snapshot((Snapshot *)*st);
        *st = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)st;
    *n = state_bytes(C2);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t n) {
    return (fmi2Status)lti_serialize(C2, "fmi2SerializeFMUstate", (const Snapshot *)st, (unsigned char *)b, n);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *st) {
    if (!st) return (fmi2Status)fail(C2, "fmi2DeSerializeFMUstate", "no place to put the state (NULL pointer)", -1);
    Snapshot *q = lti_deserialize(C2, "fmi2DeSerializeFMUstate", (const unsigned char *)b, n);
    if (!q) return fmi2Error;
    if (*st) free_snapshot((Snapshot *)*st);
    *st = q;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[], size_t n_unknown,
                                        const fmi2ValueReference known[], size_t n_known, const fmi2Real seed[],
                                        fmi2Real out[]) {
    return (fmi2Status)lti_directional(C2, "fmi2GetDirectionalDerivative", unknown, n_unknown, known, n_known, seed, out);
}

/* ---- model exchange --------------------------------------------------------------------- */
fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2True;
    info->nextEventTime = lti_next_event(C2);
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetPrior, fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation) {
    (void)c; (void)noSetPrior;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    lti_set_time(C2, t);
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    if (lti_check_states(C2, "fmi2SetContinuousStates", nx)) return fmi2Error;
    memcpy(C2->z, x, nx * 8);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (lti_check_states(C2, "fmi2GetContinuousStates", nx)) return fmi2Error;
    memcpy(x, C2->z, nx * 8);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    if (lti_check_states(C2, "fmi2GetDerivatives", nx)) return fmi2Error;
    derivatives_now(C2, dx);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    (void)z;
    return nz ? (fmi2Status)fail(C2, "fmi2GetEventIndicators", "the FMU has no event indicators; asked for", (long)nz) : fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    if (lti_check_states(C2, "fmi2GetNominalsOfContinuousStates", nx)) return fmi2Error;
    lti_nominals(C2, x);
    return fmi2OK;
}

/* ---- not provided -------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return (fmi2Status)fail(C2, "fmi2SetRealInputDerivatives", "inputs are held over a step; no derivatives", -1);
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    return (fmi2Status)fail(C2, "fmi2GetRealOutputDerivatives", "not provided by this FMU", -1);
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    if (k == fmi2LastSuccessfulTime) { *v = lti_time(C2); return fmi2OK; }
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)c; (void)k; (void)v; return fmi2Discard; }
