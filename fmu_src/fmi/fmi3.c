/* FMI 3.0 Co-Simulation over the generic instance (instance.h): argument translation and
 * the state machine of FMI 3.0.1 section 4.2, nothing else. Model Exchange and Scheduled
 * Execution are not provided (their instantiate functions return NULL). */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "instance.h"

enum {
    ANY_LIVE = MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR,
    GETTABLE = MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR,
    SETTABLE = MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP,
};

static void log3(Instance *inst, Status status, const char *category, const char *message) {
    fmi3LogMessageCallback cb = (fmi3LogMessageCallback)(size_t)inst->log_fn;
    if (cb) cb(inst->log_env, (fmi3Status)status, category, message);
}

#define CHECK(call, modes)                                \
    Instance *inst = inst_check(instance, call, modes); \
    if (!inst) return fmi3Error

FMI3_Export const char *fmi3GetVersion(void) { return "3.0"; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                                          size_t nCategories, const fmi3String categories[]) {
    (void)nCategories, (void)categories;
    CHECK("fmi3SetDebugLogging", ANY_LIVE);
    inst->logging_on = loggingOn;
    return fmi3OK;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                                     fmi3String instantiationToken,
                                                     fmi3String resourcePath,
                                                     fmi3Boolean visible,
                                                     fmi3Boolean loggingOn,
                                                     fmi3InstanceEnvironment env,
                                                     fmi3LogMessageCallback logMessage) {
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage)
        logMessage(env, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU is Co-Simulation only");
    (void)instanceName;
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables,
        (void)intermediateUpdate;
    void *fn = (void *)(size_t)logMessage;
    if (eventModeUsed || nRequiredIntermediateVariables) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateCoSimulation: this FMU has no event mode and no "
                       "intermediate variables (hasEventMode=false)");
        return NULL;
    }
    return inst_new(&GYRO_MODEL, 3, instanceName, instantiationToken, resourcePath, log3, fn,
                    instanceEnvironment, loggingOn);
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible,
        (void)loggingOn, (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage)
        logMessage(env, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU is Co-Simulation only");
    return NULL;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { inst_free(instance); }

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance,
                                                  fmi3Boolean toleranceDefined,
                                                  fmi3Float64 tolerance, fmi3Float64 startTime,
                                                  fmi3Boolean stopTimeDefined,
                                                  fmi3Float64 stopTime) {
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    CHECK("fmi3EnterInitializationMode", MODE_INSTANTIATED);
    return (fmi3Status)inst_enter_initialization(inst, startTime);
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK("fmi3ExitInitializationMode", MODE_INITIALIZATION);
    return (fmi3Status)inst_exit_initialization(inst);
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK("fmi3EnterEventMode", ANY_LIVE);
    return (fmi3Status)inst_unsupported(inst, "fmi3EnterEventMode (hasEventMode=false)");
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK("fmi3Terminate", MODE_STEP | MODE_ERROR);
    return (fmi3Status)inst_terminate(inst);
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK("fmi3Reset", ANY_LIVE);
    return (fmi3Status)inst_reset(inst);
}

/* fmi3Get<T>/fmi3Set<T> for the types this FMU has variables of (t: the layer's inst_get_t,
 * inst_set_t; scalars only). */
#define SCALAR_ACCESS(T, t)                                                                 \
    FMI3_Export fmi3Status fmi3Get##T(fmi3Instance instance, const fmi3ValueReference vr[], \
                                      size_t nvr, fmi3##T values[], size_t nValues) {       \
        CHECK("fmi3Get" #T, GETTABLE);                                                      \
        if (nValues != nvr)                                                                 \
            return (fmi3Status)inst_unsupported(inst, "arrays (nValues != nvr)");           \
        return (fmi3Status)inst_get_##t(inst, vr, nvr, values);                             \
    }                                                                                       \
    FMI3_Export fmi3Status fmi3Set##T(fmi3Instance instance, const fmi3ValueReference vr[], \
                                      size_t nvr, const fmi3##T values[], size_t nValues) { \
        CHECK("fmi3Set" #T, SETTABLE);                                                      \
        if (nValues != nvr)                                                                 \
            return (fmi3Status)inst_unsupported(inst, "arrays (nValues != nvr)");           \
        return (fmi3Status)inst_set_##t(inst, vr, nvr, values);                             \
    }

SCALAR_ACCESS(Float64, float64)
SCALAR_ACCESS(Int32, int32)

/* Types this FMU has no variables of: an empty call is fine, any value reference is not. */
#define NO_VARIABLES(T, Get, Set)                                                           \
    FMI3_Export fmi3Status fmi3##Get(fmi3Instance instance, const fmi3ValueReference vr[],  \
                                    size_t nvr, T values[], size_t nValues) {              \
        (void)vr, (void)values, (void)nValues;                                             \
        CHECK("fmi3" #Get, GETTABLE);                                                      \
        return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3" #Get " (no such variables)") \
                   : fmi3OK;                                                               \
    }                                                                                      \
    FMI3_Export fmi3Status fmi3##Set(fmi3Instance instance, const fmi3ValueReference vr[],  \
                                    size_t nvr, const T values[], size_t nValues) {        \
        (void)vr, (void)values, (void)nValues;                                             \
        CHECK("fmi3" #Set, SETTABLE);                                                      \
        return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3" #Set " (no such variables)") \
                   : fmi3OK;                                                               \
    }

NO_VARIABLES(fmi3Float32, GetFloat32, SetFloat32)
NO_VARIABLES(fmi3Int8, GetInt8, SetInt8)
NO_VARIABLES(fmi3UInt8, GetUInt8, SetUInt8)
NO_VARIABLES(fmi3Int16, GetInt16, SetInt16)
NO_VARIABLES(fmi3UInt16, GetUInt16, SetUInt16)
NO_VARIABLES(fmi3UInt32, GetUInt32, SetUInt32)
NO_VARIABLES(fmi3Int64, GetInt64, SetInt64)
NO_VARIABLES(fmi3UInt64, GetUInt64, SetUInt64)
NO_VARIABLES(fmi3Boolean, GetBoolean, SetBoolean)
NO_VARIABLES(fmi3String, GetString, SetString)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t nvr, size_t valueSizes[], fmi3Binary values[],
                                    size_t nValues) {
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    CHECK("fmi3GetBinary", GETTABLE);
    return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3GetBinary (no such variables)") : fmi3OK;
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[],
                                    size_t nvr, const size_t valueSizes[],
                                    const fmi3Binary values[], size_t nValues) {
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    CHECK("fmi3SetBinary", SETTABLE);
    return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3SetBinary (no such variables)") : fmi3OK;
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[],
                                   size_t nvr, fmi3Clock values[]) {
    (void)vr, (void)values;
    CHECK("fmi3GetClock", ANY_LIVE);
    return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3GetClock (no clocks)") : fmi3OK;
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[],
                                   size_t nvr, const fmi3Clock values[]) {
    (void)vr, (void)values;
    CHECK("fmi3SetClock", ANY_LIVE);
    return nvr ? (fmi3Status)inst_unsupported(inst, "fmi3SetClock (no clocks)") : fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                                          fmi3ValueReference vr, size_t *n) {
    (void)vr, (void)n;
    CHECK("fmi3GetNumberOfVariableDependencies", ANY_LIVE);
    return (fmi3Status)inst_unsupported(inst, "fmi3GetNumberOfVariableDependencies");
}

FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dep,
                                                  size_t elementIndicesOfDependent[],
                                                  fmi3ValueReference independents[],
                                                  size_t elementIndicesOfIndependents[],
                                                  fmi3DependencyKind dependencyKinds[],
                                                  size_t nDependencies) {
    (void)dep, (void)elementIndicesOfDependent, (void)independents,
        (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
    CHECK("fmi3GetVariableDependencies", ANY_LIVE);
    return (fmi3Status)inst_unsupported(inst, "fmi3GetVariableDependencies");
}

FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state) {
    CHECK("fmi3GetFMUState", ANY_LIVE);
    return (fmi3Status)inst_get_state(inst, state);
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state) {
    CHECK("fmi3SetFMUState", ANY_LIVE);
    return (fmi3Status)inst_set_state(inst, state);
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state) {
    CHECK("fmi3FreeFMUState", ANY_LIVE);
    return (fmi3Status)inst_free_state(inst, state);
}

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState state,
                                                 size_t *size) {
    CHECK("fmi3SerializedFMUStateSize", ANY_LIVE);
    return (fmi3Status)inst_serialized_size(inst, state, size);
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState state,
                                            fmi3Byte serializedState[], size_t size) {
    CHECK("fmi3SerializeFMUState", ANY_LIVE);
    return (fmi3Status)inst_serialize(inst, state, serializedState, size);
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance instance,
                                              const fmi3Byte serializedState[], size_t size,
                                              fmi3FMUState *state) {
    CHECK("fmi3DeserializeFMUState", ANY_LIVE);
    return (fmi3Status)inst_deserialize(inst, serializedState, size, state);
}

#define UNSUPPORTED(name, ...)                                  \
    FMI3_Export fmi3Status name(fmi3Instance instance, __VA_ARGS__) { \
        CHECK(#name, ANY_LIVE);                                 \
        return (fmi3Status)inst_unsupported(inst, #name);       \
    }
#define UNSUPPORTED0(name)                                      \
    FMI3_Export fmi3Status name(fmi3Instance instance) {         \
        CHECK(#name, ANY_LIVE);                                 \
        return (fmi3Status)inst_unsupported(inst, #name);       \
    }

#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
UNSUPPORTED(fmi3GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
UNSUPPORTED(fmi3GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
            size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
UNSUPPORTED0(fmi3EnterConfigurationMode)
UNSUPPORTED0(fmi3ExitConfigurationMode)
UNSUPPORTED(fmi3GetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr,
            fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t nvr,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetShiftDecimal, const fmi3ValueReference vr[], size_t nvr,
            fmi3Float64 shifts[])
UNSUPPORTED(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t nvr,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Float64 intervals[])
UNSUPPORTED(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t nvr,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Float64 shifts[])
UNSUPPORTED(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t nvr,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED0(fmi3EvaluateDiscreteStates)
UNSUPPORTED(fmi3UpdateDiscreteStates, fmi3Boolean *discreteStatesNeedUpdate,
            fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsChanged,
            fmi3Boolean *valuesChanged, fmi3Boolean *nextEventTimeDefined,
            fmi3Float64 *nextEventTime)
UNSUPPORTED0(fmi3EnterContinuousTimeMode)
UNSUPPORTED(fmi3CompletedIntegratorStep, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
            fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
UNSUPPORTED(fmi3SetTime, fmi3Float64 time)
UNSUPPORTED(fmi3SetContinuousStates, const fmi3Float64 x[], size_t nx)
UNSUPPORTED(fmi3GetContinuousStateDerivatives, fmi3Float64 derivatives[], size_t nx)
UNSUPPORTED(fmi3GetEventIndicators, fmi3Float64 eventIndicators[], size_t ni)
UNSUPPORTED(fmi3GetContinuousStates, fmi3Float64 x[], size_t nx)
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t nx)
UNSUPPORTED(fmi3GetNumberOfEventIndicators, size_t *n)
UNSUPPORTED(fmi3GetNumberOfContinuousStates, size_t *n)
UNSUPPORTED(fmi3GetOutputDerivatives, const fmi3ValueReference vr[], size_t nvr,
            const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
UNSUPPORTED(fmi3ActivateModelPartition, fmi3ValueReference clockReference,
            fmi3Float64 activationTime)

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    CHECK("fmi3EnterStepMode", ANY_LIVE);
    return (fmi3Status)inst_unsupported(inst, "fmi3EnterStepMode (hasEventMode=false)");
}

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                 fmi3Float64 communicationStepSize,
                                 fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                 fmi3Boolean *eventHandlingNeeded,
                                 fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                                 fmi3Float64 *lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi3DoStep", MODE_STEP);
    const Status s = inst_do_step(inst, currentCommunicationPoint, communicationStepSize);
    if (eventHandlingNeeded) *eventHandlingNeeded = false;
    if (terminateSimulation) *terminateSimulation = inst->mode == MODE_ERROR;
    if (earlyReturn) *earlyReturn = false;
    if (lastSuccessfulTime) *lastSuccessfulTime = inst->time;
    return (fmi3Status)s;
}
