/* FMI 2.0 Co-Simulation over the generic instance (instance.h): argument translation and
 * the state machine of FMI 2.0.4 section 4.2.4, nothing else. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"

enum {
    ANY_LIVE = MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR,
    GETTABLE = MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR,
    SETTABLE = MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP,
    STATEFUL = MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR
};

/* The FMI 2.0 logger takes a format string: '#' and '%' are escaped. */
static void log2(Instance *inst, Status status, const char *category, const char *message) {
    const fmi2CallbackFunctions *cb = inst->log_fn;
    if (!cb || !cb->logger) return;
    char escaped[4 * GYRO_MESSAGE_SIZE];
    size_t j = 0;
    for (const char *p = message; *p && j + 3 < sizeof escaped; p++) {
        if (*p == '#' || *p == '%') escaped[j++] = *p;
        escaped[j++] = *p;
    }
    escaped[j] = '\0';
    cb->logger(cb->componentEnvironment, inst->name, (fmi2Status)status, category, escaped);
}

FMI2_Export const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_Export const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                                          size_t nCategories, const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    Instance *inst = inst_check(c, "fmi2SetDebugLogging", ANY_LIVE);
    if (!inst) return fmi2Error;
    inst->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                         fmi2String fmuGUID, fmi2String fmuResourceLocation,
                                         const fmi2CallbackFunctions *functions,
                                         fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    Instance probe = {0};
    probe.model = &GYRO_MODEL;
    probe.name = (char *)(instanceName ? instanceName : "");
    probe.log = log2;
    probe.log_fn = (void *)functions;
    probe.fmi_version = 2;
    if (fmuType != fmi2CoSimulation) {
        inst_logf(&probe, ST_ERROR, "fmi2Instantiate: this FMU is Co-Simulation only");
        return NULL;
    }
    char *resources = decode_file_uri(fmuResourceLocation);
    Instance *inst = inst_new(&GYRO_MODEL, 2, instanceName, fmuGUID, resources, log2,
                              (void *)functions, NULL, loggingOn != fmi2False);
    free(resources);
    return inst;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) { inst_free(c); }

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                          fmi2Real tolerance, fmi2Real startTime,
                                          fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    Instance *inst = inst_check(c, "fmi2SetupExperiment", MODE_INSTANTIATED);
    if (!inst) return fmi2Error;
    if (!(startTime == startTime && startTime - startTime == 0.0)) {
        inst_logf(inst, ST_ERROR, "fmi2SetupExperiment: start time %g s is not finite", startTime);
        return fmi2Error;
    }
    inst->start_time = inst->time = startTime;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = inst_check(c, "fmi2EnterInitializationMode", MODE_INSTANTIATED);
    if (!inst) return fmi2Error;
    return (fmi2Status)inst_enter_initialization(inst, inst->start_time);
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = inst_check(c, "fmi2ExitInitializationMode", MODE_INITIALIZATION);
    return inst ? (fmi2Status)inst_exit_initialization(inst) : fmi2Error;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = inst_check(c, "fmi2Terminate", MODE_STEP | MODE_ERROR);
    return inst ? (fmi2Status)inst_terminate(inst) : fmi2Error;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = inst_check(c, "fmi2Reset", ANY_LIVE);
    return inst ? (fmi2Status)inst_reset(inst) : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                  fmi2Real value[]) {
    Instance *inst = inst_check(c, "fmi2GetReal", GETTABLE);
    return inst ? (fmi2Status)inst_get_float64(inst, vr, nvr, value) : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, fmi2Integer value[]) {
    Instance *inst = inst_check(c, "fmi2GetInteger", GETTABLE);
    return inst ? (fmi2Status)inst_get_int32(inst, vr, nvr, (int32_t *)value) : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, fmi2Boolean value[]) {
    (void)vr, (void)value;
    Instance *inst = inst_check(c, "fmi2GetBoolean", GETTABLE);
    if (!inst) return fmi2Error;
    return nvr ? (fmi2Status)inst_unsupported(inst, "fmi2GetBoolean (no Boolean variables)")
               : fmi2OK;
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                                    size_t nvr, fmi2String value[]) {
    (void)vr, (void)value;
    Instance *inst = inst_check(c, "fmi2GetString", GETTABLE);
    if (!inst) return fmi2Error;
    return nvr ? (fmi2Status)inst_unsupported(inst, "fmi2GetString (no String variables)")
               : fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                  const fmi2Real value[]) {
    Instance *inst = inst_check(c, "fmi2SetReal", SETTABLE);
    return inst ? (fmi2Status)inst_set_float64(inst, vr, nvr, value) : fmi2Error;
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, const fmi2Integer value[]) {
    Instance *inst = inst_check(c, "fmi2SetInteger", SETTABLE);
    return inst ? (fmi2Status)inst_set_int32(inst, vr, nvr, (const int32_t *)value) : fmi2Error;
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, const fmi2Boolean value[]) {
    (void)vr, (void)value;
    Instance *inst = inst_check(c, "fmi2SetBoolean", SETTABLE);
    if (!inst) return fmi2Error;
    return nvr ? (fmi2Status)inst_unsupported(inst, "fmi2SetBoolean (no Boolean variables)")
               : fmi2OK;
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                                    size_t nvr, const fmi2String value[]) {
    (void)vr, (void)value;
    Instance *inst = inst_check(c, "fmi2SetString", SETTABLE);
    if (!inst) return fmi2Error;
    return nvr ? (fmi2Status)inst_unsupported(inst, "fmi2SetString (no String variables)")
               : fmi2OK;
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *inst = inst_check(c, "fmi2GetFMUstate", STATEFUL);
    return inst ? (fmi2Status)inst_get_state(inst, state) : fmi2Error;
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Instance *inst = inst_check(c, "fmi2SetFMUstate", STATEFUL);
    return inst ? (fmi2Status)inst_set_state(inst, state) : fmi2Error;
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *inst = inst_check(c, "fmi2FreeFMUstate", STATEFUL);
    return inst ? (fmi2Status)inst_free_state(inst, state) : fmi2Error;
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state,
                                                 size_t *size) {
    Instance *inst = inst_check(c, "fmi2SerializedFMUstateSize", STATEFUL);
    return inst ? (fmi2Status)inst_serialized_size(inst, state, size) : fmi2Error;
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state,
                                            fmi2Byte serializedState[], size_t size) {
    Instance *inst = inst_check(c, "fmi2SerializeFMUstate", STATEFUL);
    return inst ? (fmi2Status)inst_serialize(inst, state, (unsigned char *)serializedState, size)
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                              size_t size, fmi2FMUstate *state) {
    Instance *inst = inst_check(c, "fmi2DeSerializeFMUstate", STATEFUL);
    return inst ? (fmi2Status)inst_deserialize(inst, (const unsigned char *)serializedState,
                                               size, state)
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(
    fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
    const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
    fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown,
        (void)dvUnknown;
    Instance *inst = inst_check(c, "fmi2GetDirectionalDerivative", ANY_LIVE);
    return inst ? (fmi2Status)inst_unsupported(inst, "fmi2GetDirectionalDerivative")
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
                                                  const fmi2ValueReference vr[], size_t nvr,
                                                  const fmi2Integer order[],
                                                  const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    Instance *inst = inst_check(c, "fmi2SetRealInputDerivatives", ANY_LIVE);
    return inst ? (fmi2Status)inst_unsupported(inst, "fmi2SetRealInputDerivatives")
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
                                                   const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[],
                                                   fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    Instance *inst = inst_check(c, "fmi2GetRealOutputDerivatives", ANY_LIVE);
    return inst ? (fmi2Status)inst_unsupported(inst, "fmi2GetRealOutputDerivatives")
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                 fmi2Real communicationStepSize,
                                 fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Instance *inst = inst_check(c, "fmi2DoStep", MODE_STEP);
    return inst ? (fmi2Status)inst_do_step(inst, currentCommunicationPoint,
                                           communicationStepSize)
                : fmi2Error;
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
    Instance *inst = inst_check(c, "fmi2CancelStep", MODE_STEP);
    return inst ? (fmi2Status)inst_unsupported(inst, "fmi2CancelStep (steps are synchronous)")
                : fmi2Error;
}

/* fmi2Get<Name>Status: the one status kind each answers (known: answer); others refused. */
#define GET_STATUS(Name, Type, known, answer)                                               \
    FMI2_Export fmi2Status fmi2Get##Name##Status(fmi2Component c, const fmi2StatusKind s,    \
                                                 Type *value) {                             \
        Instance *inst = inst_check(c, "fmi2Get" #Name "Status", ANY_LIVE);                 \
        if (!inst || !value) return fmi2Error;                                              \
        if (s != (known)) return (fmi2Status)inst_unsupported(inst, "fmi2Get" #Name "Status"); \
        *value = (answer);                                                                  \
        return fmi2OK;                                                                      \
    }

/* fmi2Get<Name>Status of a type no status kind of this FMU has. */
#define NO_STATUS(Name, Type)                                                               \
    FMI2_Export fmi2Status fmi2Get##Name##Status(fmi2Component c, const fmi2StatusKind s,    \
                                                 Type *value) {                             \
        (void)s, (void)value;                                                               \
        Instance *inst = inst_check(c, "fmi2Get" #Name "Status", ANY_LIVE);                 \
        return inst ? (fmi2Status)inst_unsupported(inst, "fmi2Get" #Name "Status") : fmi2Error; \
    }

GET_STATUS(, fmi2Status, fmi2DoStepStatus, inst->mode == MODE_ERROR ? fmi2Error : fmi2OK)
GET_STATUS(Real, fmi2Real, fmi2LastSuccessfulTime, inst->time)
GET_STATUS(Boolean, fmi2Boolean, fmi2Terminated, inst->mode == MODE_ERROR ? fmi2True : fmi2False)
NO_STATUS(Integer, fmi2Integer)
NO_STATUS(String, fmi2String)
