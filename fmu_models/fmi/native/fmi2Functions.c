/* FMI 2.0 front end (Co-Simulation and Model Exchange) of the uavfmu native FMUs, shared by every vehicle.
 *
 * Thin, in the style of modelica/Reference-FMUs' src/fmi2Functions.c: each function checks the state
 * machine (uavfmu_states.h, generated from fmu_models/fmi/statemachine.py) and maps onto uavfmu_core.h.
 * The FMU kinds this binary serves are those of its modelDescription (uavfmu_config.h: UAVFMU_HAS_CS,
 * UAVFMU_HAS_ME). For a source-code build of several models into one program, compile with
 * -DFMI2_FUNCTION_PREFIX=<model identifier>_.
 */
#include "fmi2Functions.h"
#include "uavfmu_core.h"

#ifndef UAVFMU_HAS_CS
#define UAVFMU_HAS_CS 1
#endif
#ifndef UAVFMU_HAS_ME
#define UAVFMU_HAS_ME 0
#endif

static void emit2(Instance* c, int status, const char* category, const char* text) {
    const fmi2CallbackFunctions* cb = (const fmi2CallbackFunctions*)c->callbacks;
    if (!cb || !cb->logger) return;
    /* the logger takes a printf format: escape '%' so any text is safe */
    char buf[1100];
    size_t j = 0;
    for (size_t i = 0; text[i] && j + 2 < sizeof buf; ++i) {
        if (text[i] == '%') buf[j++] = '%';
        buf[j++] = text[i];
    }
    buf[j] = 0;
    cb->logger(cb->componentEnvironment, c->name, (fmi2Status)status, category, buf);
}

#define BEGIN(fn, mask)                                                    \
    Instance* c = uav_enter(comp, UAV_MASK(mask), fn);                     \
    if (!c || uav_wrong_interface(c, INTERFACE_##mask, fn)) return fmi2Error;

#define CALL(fn, mask, expr) \
    BEGIN(fn, mask)          \
    return (fmi2Status)(expr);

/* ------------------------------------------------------------------ life cycle */

typedef struct { fmi2CallbackFunctions cb; } Callbacks2;

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions* functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation; /* no resources are needed: NULL is accepted */
    (void)visible;
    if (!functions) return NULL;
    Instance tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.emit = emit2;
    tmp.logging_on = loggingOn ? 1 : 0;
    /* the callbacks are kept by copy: the importer's struct need not outlive this call */
    Callbacks2* keep = (Callbacks2*)malloc(sizeof(Callbacks2));
    if (!keep) return NULL;
    keep->cb = *functions;
    tmp.callbacks = keep;
    int me = fmuType == fmi2ModelExchange;
    if (!((me && UAVFMU_HAS_ME) || (fmuType == fmi2CoSimulation && UAVFMU_HAS_CS))) {
        tmp.name = (char*)(instanceName ? instanceName : "?");
        uav_fail(&tmp, UAV_ERROR, "fmi2Instantiate: %s does not provide fmuType %d (Model Exchange %s, "
                 "Co-Simulation %s)", uavfmu_model.name, (int)fmuType, UAVFMU_HAS_ME ? "yes" : "no",
                 UAVFMU_HAS_CS ? "yes" : "no");
        free(keep);
        return NULL;
    }
    Instance* c = uav_new(&tmp, instanceName, fmuGUID, me);
    if (!c) free(keep);
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance* c = uav_ours(comp);
    if (!c) return;
    void* keep = (void*)c->callbacks;
    uav_free(c);
    free(keep);
}

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    BEGIN("fmi2SetDebugLogging", SetDebugLogging)
    if (!uavfmu_rule_categories(c->why, sizeof c->why, nCategories, categories))
        return (fmi2Status)uav_fail(c, UAV_ERROR, "fmi2SetDebugLogging: %s", c->why);
    c->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CALL("fmi2SetupExperiment", SetupExperiment,
         uav_setup(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime, "fmi2SetupExperiment"))
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    BEGIN("fmi2EnterInitializationMode", EnterInitializationMode)
    c->state = InitializationMode;
    c->init_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    CALL("fmi2ExitInitializationMode", ExitInitializationMode, uav_exit_init(c))
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    BEGIN("fmi2Terminate", Terminate)
    c->state = Terminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    BEGIN("fmi2Reset", Reset)
    uav_reset(c);
    return fmi2OK;
}

/* ------------------------------------------------------------------ get / set */

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    CALL("fmi2GetReal", GetValue, uav_get(c, vr, nvr, value, 0, "fmi2GetReal"))
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    BEGIN("fmi2GetBoolean", GetValue)
    if (nvr && !value) return (fmi2Status)uav_fail(c, UAV_ERROR, "fmi2GetBoolean: value is NULL with nvr = %zu", nvr);
    for (size_t i = 0; i < nvr; ++i) {
        double v;
        if (uav_get(c, vr ? &vr[i] : NULL, 1, &v, 1, "fmi2GetBoolean")) return fmi2Error;
        value[i] = v > 0.5 ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)value;
    CALL("fmi2GetInteger", GetValue, uav_no_such_type(c, vr, nvr, "fmi2GetInteger"))
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)value;
    CALL("fmi2GetString", GetValue, uav_no_such_type(c, vr, nvr, "fmi2GetString"))
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    CALL("fmi2SetReal", SetInput, uav_set_real(c, vr, nvr, value, "fmi2SetReal"))
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)value;
    CALL("fmi2SetInteger", SetInput, uav_no_such_type(c, vr, nvr, "fmi2SetInteger"))
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)value;
    CALL("fmi2SetBoolean", SetInput, uav_boolean_output(c, vr, nvr, "fmi2SetBoolean"))
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)value;
    CALL("fmi2SetString", SetInput, uav_no_such_type(c, vr, nvr, "fmi2SetString"))
}

/* ------------------------------------------------------------------ FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate* FMUstate) {
    CALL("fmi2GetFMUstate", FMUState, uav_get_state(c, FMUstate, "fmi2GetFMUstate"))
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    CALL("fmi2SetFMUstate", FMUState, uav_set_state(c, FMUstate, "fmi2SetFMUstate"))
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate* FMUstate) {
    CALL("fmi2FreeFMUstate", FMUState, uav_free_fmu_state(c, FMUstate, "fmi2FreeFMUstate"))
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t* size) {
    CALL("fmi2SerializedFMUstateSize", FMUState, uav_serialized_size(c, FMUstate, size, "fmi2SerializedFMUstateSize"))
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    CALL("fmi2SerializeFMUstate", FMUState,
         uav_serialize(c, FMUstate, (unsigned char*)serializedState, size, "fmi2SerializeFMUstate"))
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate* FMUstate) {
    CALL("fmi2DeSerializeFMUstate", FMUState,
         uav_deserialize(c, (const unsigned char*)serializedState, size, FMUstate, "fmi2DeSerializeFMUstate"))
}

/* ------------------------------------------------------------------ not provided (declared so) */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    CALL("fmi2GetDirectionalDerivative", GetDirectionalDerivative,
         uav_fail(c, UAV_ERROR, "fmi2GetDirectionalDerivative: not supported (providesDirectionalDerivative is false)"))
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    CALL("fmi2SetRealInputDerivatives", SetInputDerivatives,
         uav_fail(c, UAV_ERROR, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs is false)"))
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)nvr; (void)order; (void)value;
    CALL("fmi2GetRealOutputDerivatives", GetOutputDerivatives,
         uav_fail(c, UAV_ERROR, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder is 0)"))
}

/* ------------------------------------------------------------------ Co-Simulation */

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CALL("fmi2DoStep", DoStep, uav_do_step(c, currentCommunicationPoint, communicationStepSize, "fmi2DoStep"))
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    /* fmi2DoStep is synchronous: StepInProgress is never entered, so this is always a state error */
    CALL("fmi2CancelStep", CancelStep, UAV_ERROR)
}

/* FMI 2.0.4 section 4.2.3: fmi2DoStepStatus and fmi2PendingStatus are about a pending asynchronous step
   (never here: fmi2Discard, "not available"); fmi2LastSuccessfulTime and fmi2Terminated are answered;
   fmi2GetIntegerStatus has no status kind. */
static fmi2Status get_status(fmi2Component comp, const char* fn, fmi2StatusKind s, int kind, void* value) {
    BEGIN(fn, GetStatus)
    if (!value) return (fmi2Status)uav_fail(c, UAV_ERROR, "%s: value is NULL", fn);
    if (!uavfmu_status_available(kind, (int)s))
        return (fmi2Status)uav_fail(c, UAV_DISCARD, "%s: status kind %d is not available (no asynchronous step)",
                                    fn, (int)s);
    if (s == fmi2LastSuccessfulTime) *(fmi2Real*)value = c->time;
    else *(fmi2Boolean*)value = fmi2False; /* fmi2Terminated: the FMU never ends the simulation */
    return fmi2OK;
}

#define GET_STATUS(Type, TypeName, kind)                                                             \
    fmi2Status fmi2Get##Type##Status(fmi2Component comp, const fmi2StatusKind s, TypeName* value) { \
        return get_status(comp, "fmi2Get" #Type "Status", s, kind, value);                          \
    }
GET_STATUS(, fmi2Status, fmi2DoStepStatus)
GET_STATUS(Real, fmi2Real, fmi2LastSuccessfulTime)
GET_STATUS(Integer, fmi2Integer, -1)
GET_STATUS(Boolean, fmi2Boolean, fmi2Terminated)
GET_STATUS(String, fmi2String, fmi2PendingStatus)
#undef GET_STATUS

/* ------------------------------------------------------------------ Model Exchange */

fmi2Status fmi2EnterEventMode(fmi2Component comp) {
    BEGIN("fmi2EnterEventMode", EnterEventMode)
    c->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo* eventInfo) {
    BEGIN("fmi2NewDiscreteStates", NewDiscreteStates)
    if (!eventInfo) return (fmi2Status)uav_fail(c, UAV_ERROR, "fmi2NewDiscreteStates: eventInfo is NULL");
    memset(eventInfo, 0, sizeof *eventInfo); /* no events: the physics is smooth */
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp) {
    BEGIN("fmi2EnterContinuousTimeMode", EnterContinuousTimeMode)
    c->state = ContinuousTimeMode;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean* enterEventMode, fmi2Boolean* terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    BEGIN("fmi2CompletedIntegratorStep", CompletedIntegratorStep)
    if (!enterEventMode || !terminateSimulation)
        return (fmi2Status)uav_fail(c, UAV_ERROR, "fmi2CompletedIntegratorStep: NULL argument");
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return (fmi2Status)uav_completed_integrator_step(c, "fmi2CompletedIntegratorStep");
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time) {
    CALL("fmi2SetTime", SetTime, uav_set_time(c, time, "fmi2SetTime"))
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx) {
    CALL("fmi2SetContinuousStates", SetContinuousStates, uav_set_states(c, x, nx, "fmi2SetContinuousStates"))
}

fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real derivatives[], size_t nx) {
    CALL("fmi2GetDerivatives", GetDerivatives, uav_get_derivatives(c, derivatives, nx, "fmi2GetDerivatives"))
}

fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    BEGIN("fmi2GetEventIndicators", GetEventIndicators)
    if (ni != 0) return (fmi2Status)uav_fail(c, UAV_ERROR, "fmi2GetEventIndicators: %zu asked, this model has none", ni);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx) {
    CALL("fmi2GetContinuousStates", GetContinuousStates, uav_get_states(c, x, nx, "fmi2GetContinuousStates"))
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx) {
    CALL("fmi2GetNominalsOfContinuousStates", GetNominals,
         uav_get_nominals(c, x_nominal, nx, "fmi2GetNominalsOfContinuousStates"))
}
