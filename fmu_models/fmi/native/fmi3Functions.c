/* FMI 3.0 front end (Co-Simulation and Model Exchange) of the uavfmu native FMUs, shared by every vehicle.
 *
 * Thin, in the style of modelica/Reference-FMUs' src/fmi3Functions.c: each function checks the state
 * machine (uavfmu_states.h, generated from fmu_models/fmi/statemachine.py) and maps onto uavfmu_core.h.
 * Co-Simulation without event mode, early return or clocks; Model Exchange without event indicators (the
 * physics is smooth); no structural parameters; only Float64 and Boolean variables. For a source-code build
 * of several models into one program, compile with -DFMI3_FUNCTION_PREFIX=<model identifier>_.
 */
#include "fmi3Functions.h"
#include "uavfmu_core.h"

#ifndef UAVFMU_HAS_CS
#define UAVFMU_HAS_CS 1
#endif
#ifndef UAVFMU_HAS_ME
#define UAVFMU_HAS_ME 0
#endif

typedef struct { fmi3LogMessageCallback log; } Callbacks3;

static void emit3(Instance* c, int status, const char* category, const char* text) {
    const Callbacks3* cb = (const Callbacks3*)c->callbacks;
    if (cb && cb->log) cb->log((fmi3InstanceEnvironment)c->env, (fmi3Status)status, category, text);
}

#define BEGIN(fn, mask)                                                    \
    Instance* c = uav_enter(comp, UAV_MASK(mask), fn);                     \
    if (!c || uav_wrong_interface(c, INTERFACE_##mask, fn)) return fmi3Error;

#define CALL(fn, mask, expr) \
    BEGIN(fn, mask)          \
    return (fmi3Status)(expr);

/* ------------------------------------------------------------------ life cycle */

static fmi3Instance instantiate(fmi3String name, fmi3String token, fmi3Boolean loggingOn,
                                fmi3InstanceEnvironment env, fmi3LogMessageCallback log, int me, int offered,
                                const char* refusal) {
    Instance tmp;
    memset(&tmp, 0, sizeof tmp);
    Callbacks3* keep = (Callbacks3*)malloc(sizeof(Callbacks3));
    if (!keep) return NULL;
    keep->log = log;
    tmp.emit = emit3;
    tmp.env = env;
    tmp.callbacks = keep;
    tmp.logging_on = loggingOn ? 1 : 0;
    tmp.name = (char*)(name && name[0] ? name : "?");
    if (!offered || refusal) {
        uav_fail(&tmp, UAV_ERROR, "fmi3Instantiate: %s", refusal ? refusal : "this interface is not provided by this FMU");
        free(keep);
        return NULL;
    }
    Instance* c = uav_new(&tmp, name, token, me);
    if (!c) free(keep);
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)resourcePath; (void)visible; /* no resources are needed: NULL is accepted */
    return instantiate(instanceName, instantiationToken, loggingOn, instanceEnvironment, logMessage, 1,
                       UAVFMU_HAS_ME, NULL);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    return instantiate(instanceName, instantiationToken, loggingOn, instanceEnvironment, logMessage, 0,
                       UAVFMU_HAS_CS, eventModeUsed ? "eventModeUsed is not supported (hasEventMode is false)" : NULL);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)resourcePath; (void)visible; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    return instantiate(instanceName, instantiationToken, loggingOn, instanceEnvironment, logMessage, 0, 0,
                       "Scheduled Execution is not provided by this FMU");
}

void fmi3FreeInstance(fmi3Instance comp) {
    Instance* c = uav_ours(comp);
    if (!c) return;
    void* keep = (void*)c->callbacks;
    uav_free(c);
    free(keep);
}

const char* fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance comp, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    BEGIN("fmi3SetDebugLogging", SetDebugLogging)
    if (!uavfmu_rule_categories(c->why, sizeof c->why, nCategories, categories))
        return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3SetDebugLogging: %s", c->why);
    c->logging_on = loggingOn ? 1 : 0;
    return fmi3OK;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance comp, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    BEGIN("fmi3EnterInitializationMode", EnterInitializationMode)
    if (uav_setup(c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime, "fmi3EnterInitializationMode"))
        return fmi3Error;
    c->state = InitializationMode;
    c->init_valid = 0;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance comp) {
    CALL("fmi3ExitInitializationMode", ExitInitializationMode, uav_exit_init(c))
}

fmi3Status fmi3EnterEventMode(fmi3Instance comp) {
    BEGIN("fmi3EnterEventMode", EnterEventMode)
    c->state = EventMode;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance comp) {
    BEGIN("fmi3Terminate", Terminate)
    c->state = Terminated;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance comp) {
    BEGIN("fmi3Reset", Reset)
    uav_reset(c);
    return fmi3OK;
}

/* ------------------------------------------------------------------ get / set */

static int scalars(Instance* c, size_t nvr, size_t n_values, const char* fn) {
    if (nvr != n_values)
        return uav_fail(c, UAV_ERROR, "%s: nValues = %zu but %zu scalar value references", fn, n_values, nvr);
    return UAV_OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    BEGIN("fmi3GetFloat64", GetStart)
    if (scalars(c, nvr, nValues, "fmi3GetFloat64")) return fmi3Error;
    return (fmi3Status)uav_get(c, vr, nvr, values, 0, "fmi3GetFloat64");
}

fmi3Status fmi3SetFloat64(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 values[],
                          size_t nValues) {
    BEGIN("fmi3SetFloat64", SetInput)
    if (scalars(c, nvr, nValues, "fmi3SetFloat64")) return fmi3Error;
    return (fmi3Status)uav_set_real(c, vr, nvr, values, "fmi3SetFloat64");
}

fmi3Status fmi3GetBoolean(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues) {
    BEGIN("fmi3GetBoolean", GetStart)
    if (scalars(c, nvr, nValues, "fmi3GetBoolean")) return fmi3Error;
    if (nvr && !values) return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3GetBoolean: values is NULL");
    for (size_t i = 0; i < nvr; ++i) {
        double v;
        if (uav_get(c, vr ? &vr[i] : NULL, 1, &v, 1, "fmi3GetBoolean")) return fmi3Error;
        values[i] = v > 0.5;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean values[],
                          size_t nValues) {
    (void)values;
    BEGIN("fmi3SetBoolean", SetInput)
    if (scalars(c, nvr, nValues, "fmi3SetBoolean")) return fmi3Error;
    return (fmi3Status)uav_boolean_output(c, vr, nvr, "fmi3SetBoolean");
}

/* the types this FMU has no variable of (nValues is still checked: a mismatch is an argument error) */
#define NO_GET(T, CT)                                                                                        \
    fmi3Status fmi3Get##T(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, CT values[],        \
                          size_t nValues) {                                                                  \
        (void)values;                                                                                        \
        BEGIN("fmi3Get" #T, GetStart)                                                                        \
        if (scalars(c, nvr, nValues, "fmi3Get" #T)) return fmi3Error;                                        \
        return (fmi3Status)uav_no_such_type(c, vr, nvr, "fmi3Get" #T);                                       \
    }                                                                                                        \
    fmi3Status fmi3Set##T(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, const CT values[],  \
                          size_t nValues) {                                                                  \
        (void)values;                                                                                        \
        BEGIN("fmi3Set" #T, SetInput)                                                                        \
        if (scalars(c, nvr, nValues, "fmi3Set" #T)) return fmi3Error;                                        \
        return (fmi3Status)uav_no_such_type(c, vr, nvr, "fmi3Set" #T);                                       \
    }
NO_GET(Float32, fmi3Float32)
NO_GET(Int8, fmi3Int8)
NO_GET(UInt8, fmi3UInt8)
NO_GET(Int16, fmi3Int16)
NO_GET(UInt16, fmi3UInt16)
NO_GET(Int32, fmi3Int32)
NO_GET(UInt32, fmi3UInt32)
NO_GET(Int64, fmi3Int64)
NO_GET(UInt64, fmi3UInt64)
NO_GET(String, fmi3String)
#undef NO_GET

fmi3Status fmi3GetBinary(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values;
    BEGIN("fmi3GetBinary", GetStart)
    if (scalars(c, nvr, nValues, "fmi3GetBinary")) return fmi3Error;
    return (fmi3Status)uav_no_such_type(c, vr, nvr, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values;
    BEGIN("fmi3SetBinary", SetInput)
    if (scalars(c, nvr, nValues, "fmi3SetBinary")) return fmi3Error;
    return (fmi3Status)uav_no_such_type(c, vr, nvr, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)values;
    CALL("fmi3GetClock", GetStart, uav_no_such_type(c, vr, nvr, "fmi3GetClock"))
}

fmi3Status fmi3SetClock(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)values;
    CALL("fmi3SetClock", SetInput, uav_no_such_type(c, vr, nvr, "fmi3SetClock"))
}

/* ------------------------------------------------------------------ not provided (declared so) */

#define UNSUPPORTED(fn, mask, why) CALL(fn, mask, uav_fail(c, UAV_ERROR, "%s: not supported (%s)", fn, why))

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance comp, fmi3ValueReference valueReference,
                                               size_t* nDependencies) {
    (void)valueReference; (void)nDependencies;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies", GetNumber, "dependencies are in the modelDescription")
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance comp, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies", GetNumber, "dependencies are in the modelDescription")
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance comp, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetDirectionalDerivative", GetDirectionalDerivative, "providesDirectionalDerivatives is false")
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance comp, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetAdjointDerivative", GetDirectionalDerivative, "providesAdjointDerivatives is false")
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance comp) {
    UNSUPPORTED("fmi3EnterConfigurationMode", EnterConfigurationMode, "this FMU has no structural parameters")
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance comp) {
    UNSUPPORTED("fmi3ExitConfigurationMode", ExitConfigurationMode, "this FMU has no structural parameters")
}

#define NO_CLOCK(fn, ...)                                                                                     \
    fmi3Status fn(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr, __VA_ARGS__) {              \
        (void)vr; (void)nvr;                                                                                 \
        UNSUPPORTED(#fn, Clock, "this FMU has no clocks")                                                    \
    }
NO_CLOCK(fmi3GetIntervalDecimal, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
NO_CLOCK(fmi3GetIntervalFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NO_CLOCK(fmi3GetShiftDecimal, fmi3Float64 shifts[])
NO_CLOCK(fmi3GetShiftFraction, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
NO_CLOCK(fmi3SetIntervalDecimal, const fmi3Float64 intervals[])
NO_CLOCK(fmi3SetIntervalFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
NO_CLOCK(fmi3SetShiftDecimal, const fmi3Float64 shifts[])
NO_CLOCK(fmi3SetShiftFraction, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
#undef NO_CLOCK

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance comp) {
    BEGIN("fmi3EvaluateDiscreteStates", NewDiscreteStates)
    return fmi3OK; /* no discrete states */
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance comp, fmi3Boolean* discreteStatesNeedUpdate,
                                    fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged,
                                    fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined,
                                    fmi3Float64* nextEventTime) {
    BEGIN("fmi3UpdateDiscreteStates", NewDiscreteStates)
    /* no events: the physics is smooth (every output pointer may be NULL, FMI 3.0 section 3.2.2) */
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (nominalsOfContinuousStatesChanged) *nominalsOfContinuousStatesChanged = fmi3False;
    if (valuesOfContinuousStatesChanged) *valuesOfContinuousStatesChanged = fmi3False;
    if (nextEventTimeDefined) *nextEventTimeDefined = fmi3False;
    if (nextEventTime) *nextEventTime = 0.0;
    return fmi3OK;
}

/* ------------------------------------------------------------------ FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance comp, fmi3FMUState* FMUState) {
    CALL("fmi3GetFMUState", FMUState, uav_get_state(c, FMUState, "fmi3GetFMUState"))
}

fmi3Status fmi3SetFMUState(fmi3Instance comp, fmi3FMUState FMUState) {
    CALL("fmi3SetFMUState", FMUState, uav_set_state(c, FMUState, "fmi3SetFMUState"))
}

fmi3Status fmi3FreeFMUState(fmi3Instance comp, fmi3FMUState* FMUState) {
    CALL("fmi3FreeFMUState", FMUState, uav_free_fmu_state(c, FMUState, "fmi3FreeFMUState"))
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance comp, fmi3FMUState FMUState, size_t* size) {
    CALL("fmi3SerializedFMUStateSize", FMUState, uav_serialized_size(c, FMUState, size, "fmi3SerializedFMUStateSize"))
}

fmi3Status fmi3SerializeFMUState(fmi3Instance comp, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size) {
    CALL("fmi3SerializeFMUState", FMUState,
         uav_serialize(c, FMUState, (unsigned char*)serializedState, size, "fmi3SerializeFMUState"))
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance comp, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState* FMUState) {
    CALL("fmi3DeserializeFMUState", FMUState,
         uav_deserialize(c, (const unsigned char*)serializedState, size, FMUState, "fmi3DeserializeFMUState"))
}

/* ------------------------------------------------------------------ Model Exchange */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance comp) {
    BEGIN("fmi3EnterContinuousTimeMode", EnterContinuousTimeMode)
    c->state = ContinuousTimeMode;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance comp, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    BEGIN("fmi3CompletedIntegratorStep", CompletedIntegratorStep)
    if (!enterEventMode || !terminateSimulation)
        return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3CompletedIntegratorStep: NULL argument");
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return (fmi3Status)uav_completed_integrator_step(c, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance comp, fmi3Float64 time) {
    CALL("fmi3SetTime", SetTime, uav_set_time(c, time, "fmi3SetTime"))
}

fmi3Status fmi3SetContinuousStates(fmi3Instance comp, const fmi3Float64 x[], size_t nx) {
    CALL("fmi3SetContinuousStates", SetContinuousStates, uav_set_states(c, x, nx, "fmi3SetContinuousStates"))
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance comp, fmi3Float64 derivatives[], size_t nx) {
    CALL("fmi3GetContinuousStateDerivatives", GetDerivatives,
         uav_get_derivatives(c, derivatives, nx, "fmi3GetContinuousStateDerivatives"))
}

fmi3Status fmi3GetEventIndicators(fmi3Instance comp, fmi3Float64 eventIndicators[], size_t ni) {
    (void)eventIndicators;
    BEGIN("fmi3GetEventIndicators", GetEventIndicators)
    if (ni != 0) return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3GetEventIndicators: %zu asked, this model has none", ni);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance comp, fmi3Float64 x[], size_t nx) {
    CALL("fmi3GetContinuousStates", GetContinuousStates, uav_get_states(c, x, nx, "fmi3GetContinuousStates"))
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance comp, fmi3Float64 nominals[], size_t nx) {
    CALL("fmi3GetNominalsOfContinuousStates", GetNominals,
         uav_get_nominals(c, nominals, nx, "fmi3GetNominalsOfContinuousStates"))
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance comp, size_t* n) {
    BEGIN("fmi3GetNumberOfEventIndicators", GetNumberOfStates)
    if (!n) return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3GetNumberOfEventIndicators: NULL argument");
    *n = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance comp, size_t* n) {
    BEGIN("fmi3GetNumberOfContinuousStates", GetNumberOfStates)
    if (!n) return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3GetNumberOfContinuousStates: NULL argument");
    *n = (size_t)c->model->nx;
    return fmi3OK;
}

/* ------------------------------------------------------------------ Co-Simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance comp) {
    BEGIN("fmi3EnterStepMode", EnterStepMode)
    c->state = StepComplete;
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance comp, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    UNSUPPORTED("fmi3GetOutputDerivatives", GetOutputDerivatives, "maxOutputDerivativeOrder is 0")
}

fmi3Status fmi3DoStep(fmi3Instance comp, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* eventHandlingNeeded,
                      fmi3Boolean* terminateSimulation, fmi3Boolean* earlyReturn, fmi3Float64* lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    BEGIN("fmi3DoStep", DoStep)
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        return (fmi3Status)uav_fail(c, UAV_ERROR, "fmi3DoStep: NULL output argument");
    int s = uav_do_step(c, currentCommunicationPoint, communicationStepSize, "fmi3DoStep");
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = c->time;
    return (fmi3Status)s;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance comp, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    UNSUPPORTED("fmi3ActivateModelPartition", Clock, "Scheduled Execution is not provided")
}
