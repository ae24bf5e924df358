/* fmi2Functions.c -- FMI 2.0 Co-Simulation API of an fdid-fmi FMU (written once).
 *
 * Only the FMI 2.0 wrappers live here: types, signatures, the master's callbacks (logger,
 * memory functions) and the FMI 2 status kinds. The instance bookkeeping shared with FMI 3.0
 * (state machine, value references, checks on set values, FMU states, doStep) is in
 * fdid_instance.c. Any call in the wrong state, unknown value reference, non-finite value or
 * step size that is not an integer multiple of the model sample time returns fmi2Error with a
 * logged message and puts the instance in the error state (left by fmi2SetFMUstate or fmi2Reset).
 *
 * Logging: categories logStatusWarning, logStatusError, logStatusFatal and logCalls.
 * Error and fatal messages are logged unless the master switched those categories off with
 * fmi2SetDebugLogging; warnings and the trace of calls (logCalls) only when loggingOn.
 */
#include <string.h>

#include "fmi2Functions.h"
#include "model_data.h"
#include "fdid_instance.h"

/* the FDID_* status codes are the fmi2Status values */
#define SAME(a, b) ((int)(a) == (int)(b))
typedef char fdid_status_check[(SAME(fmi2OK, FDID_OK) && SAME(fmi2Warning, FDID_WARNING) &&
                                SAME(fmi2Discard, FDID_DISCARD) && SAME(fmi2Error, FDID_ERROR) &&
                                SAME(fmi2Fatal, FDID_FATAL)) ? 1 : -1];
#undef SAME

typedef struct {
    FdidInstance base; /* first member: an fmi2Component is an FdidInstance */
    fmi2CallbackFunctions cb;
} Instance;

/* the FMI 2 logger takes the message as a printf format: escape '%' */
static void emit(const FdidInstance *B, int status, const char *category, const char *message) {
    const Instance *I = (const Instance *)B;
    char esc[2048];
    size_t i, k = 0;
    if (!I->cb.logger) return;
    for (i = 0; message[i] && k + 2 < sizeof esc; i++) {
        if (message[i] == '%') esc[k++] = '%';
        esc[k++] = message[i];
    }
    esc[k] = '\0';
    I->cb.logger(I->cb.componentEnvironment, B->name ? B->name : "?", (fmi2Status)status, category, esc);
}

static const FdidApi API = {"fmi2", "step mode (slave initialized)", "FMUstate", 0x46444944u /* "FDID" */, 1, 1, emit};

#define CHECK(c, fn, mask)                        \
    FdidInstance *I = (FdidInstance *)(c);        \
    if (!fdid_begin(I, fn, mask)) return fmi2Error;
#define FAIL(...) ((fmi2Status)fdid_fail(I, __VA_ARGS__))

/* ------------------------------------------------------------ common functions */
FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                           const fmi2String categories[]) {
    return (fmi2Status)fdid_set_debug_logging((FdidInstance *)c, "fmi2SetDebugLogging", loggingOn, nCategories,
                                              categories);
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                          fmi2Boolean loggingOn) {
    Instance tmp;
    FdidInstance *I;
    (void)fmuResourceLocation;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    tmp.base.api = &API;
    if (functions) {
        tmp.cb = *functions;
        tmp.base.allocate_memory = functions->allocateMemory;
        tmp.base.free_memory = functions->freeMemory;
    }
    tmp.base.name = (char *)(instanceName ? instanceName : "?");
    /* errors, and the one note on held inputs, reach the master even with loggingOn = false */
    tmp.base.log_on[FDID_CAT_ERROR] = tmp.base.log_on[FDID_CAT_FATAL] = tmp.base.log_on[FDID_CAT_NOTE] = 1;
    tmp.base.log_on[FDID_CAT_WARNING] = tmp.base.log_on[FDID_CAT_CALLS] = loggingOn ? 1 : 0;
    if (!instanceName || !instanceName[0]) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR, "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR,
                 "fmi2Instantiate: this FMU supports Co-Simulation only (fmuType %d given)", (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, fdid_model.guid) != 0) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR, "fmi2Instantiate: GUID '%s' does not match the FMU's '%s'",
                 fmuGUID ? fmuGUID : "(null)", fdid_model.guid);
        return NULL;
    }
    I = fdid_instantiate(&tmp.base, sizeof tmp, "fmi2Instantiate");
    if (!I) return NULL;
    fdid_log(I, FDID_OK, FDID_CAT_CALLS, "fmi2Instantiate: %s, Ts = %g s", fdid_model.model_identifier,
             fdid_model.Ts);
    return (fmi2Component)I;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) { fdid_free_instance((FdidInstance *)c, "fmi2FreeInstance"); }

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK(c, "fmi2SetupExperiment", FDID_ST_INSTANTIATED)
    (void)toleranceDefined;
    (void)tolerance;
    return (fmi2Status)fdid_setup_experiment(I, "fmi2SetupExperiment", startTime, stopTimeDefined, stopTime);
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2EnterInitializationMode", FDID_ST_INSTANTIATED)
    fdid_enter_initialization(I);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2ExitInitializationMode", FDID_ST_INIT)
    fdid_exit_initialization(I);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(c, "fmi2Terminate", FDID_ST_STEP | FDID_ST_ERROR)
    fdid_terminate(I);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    CHECK(c, "fmi2Reset", FDID_ANY_STATE)
    fdid_reset(I);
    return fmi2OK;
}

/* ------------------------------------------------------------ get / set */
FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    size_t i;
    CHECK(c, "fmi2GetReal", FDID_GET_STATES)
    if (nvr > 0 && (!vr || !value)) return FAIL("fmi2GetReal: NULL argument");
    for (i = 0; i < nvr; i++)
        if (!fdid_get_real(I, "fmi2GetReal", vr[i], &value[i])) return fmi2Error;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Boolean value[]) {
    size_t i;
    int b;
    CHECK(c, "fmi2GetBoolean", FDID_GET_STATES)
    if (nvr > 0 && (!vr || !value)) return FAIL("fmi2GetBoolean: NULL argument");
    for (i = 0; i < nvr; i++) {
        if (!fdid_get_boolean(I, "fmi2GetBoolean", vr[i], &b)) return fmi2Error;
        value[i] = b ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Integer value[]) {
    CHECK(c, "fmi2GetInteger", FDID_GET_STATES)
    (void)value;
    if (nvr > 0) return FAIL("fmi2GetInteger: the model has no Integer variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     fmi2String value[]) {
    CHECK(c, "fmi2GetString", FDID_GET_STATES)
    (void)value;
    if (nvr > 0) return FAIL("fmi2GetString: the model has no String variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    size_t i;
    CHECK(c, "fmi2SetReal", FDID_SET_STATES)
    if (nvr > 0 && (!vr || !value)) return FAIL("fmi2SetReal: NULL argument");
    for (i = 0; i < nvr; i++)
        if (!fdid_set_real(I, "fmi2SetReal", vr[i], value[i])) return fmi2Error;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Boolean value[]) {
    size_t i;
    CHECK(c, "fmi2SetBoolean", FDID_SET_STATES)
    if (nvr > 0 && (!vr || !value)) return FAIL("fmi2SetBoolean: NULL argument");
    for (i = 0; i < nvr; i++)
        if (!fdid_set_boolean(I, "fmi2SetBoolean", vr[i], value[i] != 0)) return fmi2Error;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Integer value[]) {
    CHECK(c, "fmi2SetInteger", FDID_SET_STATES)
    (void)value;
    if (nvr > 0) return FAIL("fmi2SetInteger: the model has no Integer variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2String value[]) {
    CHECK(c, "fmi2SetString", FDID_SET_STATES)
    (void)value;
    if (nvr > 0) return FAIL("fmi2SetString: the model has no String variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

/* ------------------------------------------------------------ FMU state */
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2GetFMUstate", FDID_ANY_STATE)
    return (fmi2Status)fdid_get_state(I, "fmi2GetFMUstate", FMUstate);
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK(c, "fmi2SetFMUstate", FDID_ANY_STATE)
    return (fmi2Status)fdid_set_state(I, "fmi2SetFMUstate", FMUstate);
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2FreeFMUstate", FDID_ANY_STATE)
    return (fmi2Status)fdid_free_state(I, "fmi2FreeFMUstate", FMUstate);
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    CHECK(c, "fmi2SerializedFMUstateSize", FDID_ANY_STATE)
    return (fmi2Status)fdid_serialized_size(I, "fmi2SerializedFMUstateSize", FMUstate, size);
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                             size_t size) {
    CHECK(c, "fmi2SerializeFMUstate", FDID_ANY_STATE)
    return (fmi2Status)fdid_serialize(I, "fmi2SerializeFMUstate", FMUstate, serializedState, size);
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                               fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2DeSerializeFMUstate", FDID_ANY_STATE)
    return (fmi2Status)fdid_deserialize(I, "fmi2DeSerializeFMUstate", serializedState, size, FMUstate);
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                                    size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    CHECK(c, "fmi2GetDirectionalDerivative", FDID_ANY_STATE)
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return FAIL("fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

/* ------------------------------------------------------------ co-simulation */
/* canInterpolateInputs = true: first derivatives of the inputs, used by the next fmi2DoStep
 * (internal sample j of the step gets u + j Ts du/dt); fmi2SetReal of an input clears its
 * derivative */
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
    size_t i;
    CHECK(c, "fmi2SetRealInputDerivatives", FDID_SET_STATES)
    if (nvr > 0 && (!vr || !order || !value)) return FAIL("fmi2SetRealInputDerivatives: NULL argument");
    for (i = 0; i < nvr; i++)
        if (!fdid_set_input_derivative(I, "fmi2SetRealInputDerivatives", vr[i], (int)order[i], value[i]))
            return fmi2Error;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[], fmi2Real value[]) {
    CHECK(c, "fmi2GetRealOutputDerivatives", FDID_ANY_STATE)
    (void)vr; (void)nvr; (void)order; (void)value;
    return FAIL("fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder=0)");
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CHECK(c, "fmi2DoStep", FDID_ST_STEP)
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)fdid_do_step(I, "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
    CHECK(c, "fmi2CancelStep", FDID_ANY_STATE)
    return FAIL("fmi2CancelStep: no step is pending (fmi2DoStep never returns fmi2Pending)");
}

/* status kinds other than fmi2LastSuccessfulTime / fmi2Terminated: fmi2Discard with a warning */
static fmi2Status discard(FdidInstance *I, const char *fn, fmi2StatusKind s, const char *why) {
    fdid_log(I, FDID_DISCARD, FDID_CAT_WARNING, "%s: status kind %d is not available%s", fn, (int)s, why);
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    CHECK(c, "fmi2GetStatus", FDID_GET_STATES)
    (void)value;
    return discard(I, "fmi2GetStatus", s, " (fmi2DoStep never returns fmi2Pending)");
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK(c, "fmi2GetRealStatus", FDID_GET_STATES)
    if (!value) return FAIL("fmi2GetRealStatus: NULL argument");
    if (s != fmi2LastSuccessfulTime) return discard(I, "fmi2GetRealStatus", s, "");
    *value = fdid_time(I);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    CHECK(c, "fmi2GetIntegerStatus", FDID_GET_STATES)
    (void)value;
    return discard(I, "fmi2GetIntegerStatus", s, "");
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK(c, "fmi2GetBooleanStatus", FDID_GET_STATES)
    if (!value) return FAIL("fmi2GetBooleanStatus: NULL argument");
    if (s != fmi2Terminated) return discard(I, "fmi2GetBooleanStatus", s, "");
    *value = fmi2False; /* the FMU never asks to terminate */
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    CHECK(c, "fmi2GetStringStatus", FDID_GET_STATES)
    (void)value;
    return discard(I, "fmi2GetStringStatus", s, "");
}
