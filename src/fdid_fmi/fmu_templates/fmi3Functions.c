/* fmi3Functions.c -- FMI 3.0 Co-Simulation API of an fdid-fmi FMU (written once).
 *
 * Intermediate update (providesIntermediateUpdate): a master that gives an intermediateUpdate
 * callback and input value references in requiredIntermediateVariables is called back before
 * each internal sample of a doStep after the first, and may set the inputs of that sample.
 *
 * Same behaviour as fmi2Functions.c: both wrap the instance bookkeeping of fdid_instance.c
 * (state machine, value references, checks on set values, FMU states, doStep).
 * Float64 inputs/outputs/parameters and Boolean parameters; no event mode, no clocks, no
 * configuration mode. Every function of fmi3Functions.h is exported; the ones this FMU
 * does not support (Model Exchange, Scheduled Execution, other types) return fmi3Error with
 * a logged message (or fmi3OK when asked for zero values).
 * The independent variable "time" (value reference FDID_TIME_VR) can be read.
 */
#include <string.h>

#include "fmi3Functions.h"
#include "model_data.h"
#include "fdid_instance.h"

#define FDID_TIME_VR 999999u

/* the FDID_* status codes are the fmi3Status values */
#define SAME(a, b) ((int)(a) == (int)(b))
typedef char fdid_status_check[(SAME(fmi3OK, FDID_OK) && SAME(fmi3Warning, FDID_WARNING) &&
                                SAME(fmi3Discard, FDID_DISCARD) && SAME(fmi3Error, FDID_ERROR) &&
                                SAME(fmi3Fatal, FDID_FATAL)) ? 1 : -1];
#undef SAME

typedef struct {
    FdidInstance base; /* first member: an fmi3Instance is an FdidInstance */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logger;
    fmi3IntermediateUpdateCallback update;   /* the master's, when it asked to set inputs in doStep */
} Instance;

static void emit(const FdidInstance *B, int status, const char *category, const char *message) {
    const Instance *I = (const Instance *)B;
    if (I->logger) I->logger(I->env, (fmi3Status)status, category, message);
}

static const FdidApi API = {"fmi3", "step mode", "FMUState", 0x46444933u /* "FDI3" */, 0, 0, emit};

/* intermediate update before an internal sample of a doStep (providesIntermediateUpdate): the
 * master may set the inputs of that sample (FMI 3.0 section 4.2.3, intermediate update mode) */
static void between_samples(FdidInstance *B, double t) {
    Instance *I = (Instance *)B;
    fmi3Boolean early = fmi3False;
    fmi3Float64 early_time = t;
    I->update(I->env, t, fmi3True /* intermediateVariableSetRequested */, fmi3False /* GetAllowed */,
              fmi3True /* intermediateStepFinished */, fmi3False /* canReturnEarly */, &early, &early_time);
}

#define CHECK(c, fn, mask)                        \
    FdidInstance *I = (FdidInstance *)(c);        \
    if (!fdid_begin(I, fn, mask)) return fmi3Error;
#define FAIL(...) ((fmi3Status)fdid_fail(I, __VA_ARGS__))

/* ------------------------------------------------------------ common functions */
FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                                           const fmi3String categories[]) {
    return (fmi3Status)fdid_set_debug_logging((FdidInstance *)instance, "fmi3SetDebugLogging", loggingOn,
                                              nCategories, categories);
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    if (logMessage && loggingOn)    /* FMI 3: with loggingOn false, logMessage is never called */
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU supports Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage && loggingOn)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU supports Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance tmp;
    size_t i;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed;
    memset(&tmp, 0, sizeof tmp);
    tmp.base.api = &API;
    tmp.env = instanceEnvironment;
    tmp.logger = logMessage;
    /* FMI 3: with loggingOn false the FMU never calls logMessage, errors included (FMI 2, by
     * contrast, expects errors to be logged: fmi2Functions.c) */
    tmp.base.log_on[FDID_CAT_ERROR] = tmp.base.log_on[FDID_CAT_FATAL] = loggingOn ? 1 : 0;
    tmp.base.log_on[FDID_CAT_WARNING] = tmp.base.log_on[FDID_CAT_CALLS] = loggingOn ? 1 : 0;
    tmp.base.log_on[FDID_CAT_NOTE] = loggingOn ? 1 : 0;
    if (!instanceName || !instanceName[0]) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR, "fmi3InstantiateCoSimulation: missing instance name");
        return NULL;
    }
    if (eventModeUsed) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR, "fmi3InstantiateCoSimulation: this FMU has no event mode "
                                                        "(hasEventMode=false)");
        return NULL;
    }
    /* intermediate update: inputs only (set by the master before each internal sample of a step) */
    if (nRequiredIntermediateVariables > 0 && !requiredIntermediateVariables) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR,
                 "fmi3InstantiateCoSimulation: requiredIntermediateVariables is NULL");
        return NULL;
    }
    for (i = 0; i < nRequiredIntermediateVariables; i++) {
        if (!fdid_is_input(requiredIntermediateVariables[i])) {
            fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR,
                     "fmi3InstantiateCoSimulation: required intermediate variable %u is not an input (in "
                     "intermediate update mode the master can set inputs only)",
                     (unsigned)requiredIntermediateVariables[i]);
            return NULL;
        }
    }
    if (nRequiredIntermediateVariables > 0 && intermediateUpdate) {
        tmp.update = intermediateUpdate;
        tmp.base.between_samples = between_samples;
    }
    if (!instantiationToken || strcmp(instantiationToken, fdid_model.guid) != 0) {
        fdid_log(&tmp.base, FDID_ERROR, FDID_CAT_ERROR,
                 "fmi3InstantiateCoSimulation: instantiation token '%s' does not match the FMU's '%s'",
                 instantiationToken ? instantiationToken : "(null)", fdid_model.guid);
        return NULL;
    }
    tmp.base.name = (char *)instanceName;
    return (fmi3Instance)fdid_instantiate(&tmp.base, sizeof tmp, "fmi3InstantiateCoSimulation");
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) {
    fdid_free_instance((FdidInstance *)instance, "fmi3FreeInstance");
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK(instance, "fmi3EnterInitializationMode", FDID_ST_INSTANTIATED)
    (void)toleranceDefined; (void)tolerance;
    if (fdid_setup_experiment(I, "fmi3EnterInitializationMode", startTime, stopTimeDefined, stopTime) != FDID_OK)
        return fmi3Error;
    fdid_enter_initialization(I);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK(instance, "fmi3ExitInitializationMode", FDID_ST_INIT)
    fdid_exit_initialization(I);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK(instance, "fmi3EnterEventMode", FDID_ANY_STATE)
    return FAIL("fmi3EnterEventMode: this FMU has no event mode");
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK(instance, "fmi3Terminate", FDID_ST_STEP | FDID_ST_ERROR)
    fdid_terminate(I);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK(instance, "fmi3Reset", FDID_ANY_STATE)
    fdid_reset(I);
    return fmi3OK;
}

/* ------------------------------------------------------------ get / set */
FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3GetFloat64", FDID_GET_STATES_FMI3)
    if (nValues != nValueReferences) return FAIL("fmi3GetFloat64: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return FAIL("fmi3GetFloat64: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        if (valueReferences[i] == FDID_TIME_VR) values[i] = fdid_time(I);
        else if (!fdid_get_real(I, "fmi3GetFloat64", valueReferences[i], &values[i])) return fmi3Error;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3SetFloat64", FDID_SET_STATES | FDID_ST_UPDATE)
    if (nValues != nValueReferences) return FAIL("fmi3SetFloat64: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return FAIL("fmi3SetFloat64: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        if (valueReferences[i] == FDID_TIME_VR) return FAIL("fmi3SetFloat64: time cannot be set");
        if (!fdid_set_real(I, "fmi3SetFloat64", valueReferences[i], values[i])) return fmi3Error;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    size_t i;
    int b;
    CHECK(instance, "fmi3GetBoolean", FDID_GET_STATES_FMI3)
    if (nValues != nValueReferences) return FAIL("fmi3GetBoolean: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return FAIL("fmi3GetBoolean: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        if (!fdid_get_boolean(I, "fmi3GetBoolean", valueReferences[i], &b)) return fmi3Error;
        values[i] = b != 0;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3SetBoolean", FDID_SET_STATES)
    if (nValues != nValueReferences) return FAIL("fmi3SetBoolean: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return FAIL("fmi3SetBoolean: NULL argument");
    for (i = 0; i < nValueReferences; i++)
        if (!fdid_set_boolean(I, "fmi3SetBoolean", valueReferences[i], values[i])) return fmi3Error;
    return fmi3OK;
}

/* types this FMU has no variables of: fine for zero values, an error otherwise */
static fmi3Status no_vars(fmi3Instance instance, const char *fn, int mask, const fmi3ValueReference vr[],
                          size_t nvr) {
    CHECK(instance, fn, mask)
    if (nvr == 0) return fmi3OK;
    return FAIL("%s: the model has no variables of this type (value reference %u)", fn,
                vr ? (unsigned)vr[0] : 0u);
}

#define NO_GET(T, N)                                                                                   \
    FMI3_Export fmi3Status fmi3Get##N(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                                      T values[], size_t nValues) {                                   \
        (void)values; (void)nValues;                                                                  \
        return no_vars(instance, "fmi3Get" #N, FDID_GET_STATES_FMI3, vr, nvr);                             \
    }
#define NO_SET(T, N)                                                                                   \
    FMI3_Export fmi3Status fmi3Set##N(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                                      const T values[], size_t nValues) {                             \
        (void)values; (void)nValues;                                                                  \
        return no_vars(instance, "fmi3Set" #N, FDID_SET_STATES, vr, nvr);                                  \
    }

NO_GET(fmi3Float32, Float32) NO_GET(fmi3Int8, Int8) NO_GET(fmi3UInt8, UInt8) NO_GET(fmi3Int16, Int16)
NO_GET(fmi3UInt16, UInt16) NO_GET(fmi3Int32, Int32) NO_GET(fmi3UInt32, UInt32) NO_GET(fmi3Int64, Int64)
NO_GET(fmi3UInt64, UInt64) NO_GET(fmi3String, String)
NO_SET(fmi3Float32, Float32) NO_SET(fmi3Int8, Int8) NO_SET(fmi3UInt8, UInt8) NO_SET(fmi3Int16, Int16)
NO_SET(fmi3UInt16, UInt16) NO_SET(fmi3Int32, Int32) NO_SET(fmi3UInt32, UInt32) NO_SET(fmi3Int64, Int64)
NO_SET(fmi3UInt64, UInt64) NO_SET(fmi3String, String)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_vars(instance, "fmi3GetBinary", FDID_GET_STATES_FMI3, vr, nvr);
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_vars(instance, "fmi3SetBinary", FDID_SET_STATES, vr, nvr);
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Clock values[]) {
    (void)values;
    return no_vars(instance, "fmi3GetClock", FDID_ANY_STATE, vr, nvr);
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[]) {
    (void)values;
    return no_vars(instance, "fmi3SetClock", FDID_ANY_STATE, vr, nvr);
}

/* ------------------------------------------------------------ unsupported features */
#define UNSUPPORTED(fn, what)                  \
    CHECK(instance, fn, FDID_ANY_STATE)             \
    return FAIL("%s: %s", fn, what);

FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                                           size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies", "not provided (see ModelStructure)")
}

FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                                   size_t elementIndicesOfDependent[],
                                                   fmi3ValueReference independents[],
                                                   size_t elementIndicesOfIndependents[],
                                                   fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies", "not provided (see ModelStructure)")
}

FMI3_Export fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                                    fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetDirectionalDerivative", "not provided (providesDirectionalDerivatives=false)")
}

FMI3_Export fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                size_t nUnknowns, const fmi3ValueReference knowns[],
                                                size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                                fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED("fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives=false)")
}

FMI3_Export fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterConfigurationMode", "the FMU has no structural parameters")
}

FMI3_Export fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3ExitConfigurationMode", "the FMU has no structural parameters")
}

FMI3_Export fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                              fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)intervals; (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalDecimal", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                               fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                               fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers;
    UNSUPPORTED("fmi3GetIntervalFraction", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                           fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED("fmi3GetShiftDecimal", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                            fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3GetShiftFraction", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                              const fmi3Float64 intervals[]) {
    (void)vr; (void)nvr; (void)intervals;
    UNSUPPORTED("fmi3SetIntervalDecimal", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                               const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3SetIntervalFraction", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                           const fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED("fmi3SetShiftDecimal", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED("fmi3SetShiftFraction", "the FMU has no clocks")
}

FMI3_Export fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    UNSUPPORTED("fmi3EvaluateDiscreteStates", "the FMU has no event mode")
}

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                                fmi3Boolean *terminateSimulation,
                                                fmi3Boolean *nominalsOfContinuousStatesChanged,
                                                fmi3Boolean *valuesOfContinuousStatesChanged,
                                                fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate; (void)terminateSimulation; (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged; (void)nextEventTimeDefined; (void)nextEventTime;
    UNSUPPORTED("fmi3UpdateDiscreteStates", "the FMU has no event mode")
}

FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterContinuousTimeMode", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    UNSUPPORTED("fmi3CompletedIntegratorStep", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    UNSUPPORTED("fmi3SetTime", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                               size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    UNSUPPORTED("fmi3SetContinuousStates", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                                         size_t nContinuousStates) {
    (void)derivatives; (void)nContinuousStates;
    UNSUPPORTED("fmi3GetContinuousStateDerivatives", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                              size_t nEventIndicators) {
    (void)eventIndicators; (void)nEventIndicators;
    UNSUPPORTED("fmi3GetEventIndicators", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                               size_t nContinuousStates) {
    (void)continuousStates; (void)nContinuousStates;
    UNSUPPORTED("fmi3GetContinuousStates", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                                         size_t nContinuousStates) {
    (void)nominals; (void)nContinuousStates;
    UNSUPPORTED("fmi3GetNominalsOfContinuousStates", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    UNSUPPORTED("fmi3GetNumberOfEventIndicators", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    UNSUPPORTED("fmi3GetNumberOfContinuousStates", "Model Exchange is not supported")
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterStepMode", "the FMU has no event mode (it is in step mode after initialization)")
}

FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                                const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    UNSUPPORTED("fmi3GetOutputDerivatives", "not provided (maxOutputDerivativeOrder=0)")
}

FMI3_Export fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                                  fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    UNSUPPORTED("fmi3ActivateModelPartition", "Scheduled Execution is not supported")
}

/* ------------------------------------------------------------ FMU state */
FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(instance, "fmi3GetFMUState", FDID_ANY_STATE)
    return (fmi3Status)fdid_get_state(I, "fmi3GetFMUState", FMUState);
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    CHECK(instance, "fmi3SetFMUState", FDID_ANY_STATE)
    return (fmi3Status)fdid_set_state(I, "fmi3SetFMUState", FMUState);
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(instance, "fmi3FreeFMUState", FDID_ANY_STATE)
    return (fmi3Status)fdid_free_state(I, "fmi3FreeFMUState", FMUState);
}

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    CHECK(instance, "fmi3SerializedFMUStateSize", FDID_ANY_STATE)
    return (fmi3Status)fdid_serialized_size(I, "fmi3SerializedFMUStateSize", FMUState, size);
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                             size_t size) {
    CHECK(instance, "fmi3SerializeFMUState", FDID_ANY_STATE)
    return (fmi3Status)fdid_serialize(I, "fmi3SerializeFMUState", FMUState, serializedState, size);
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                               fmi3FMUState *FMUState) {
    CHECK(instance, "fmi3DeserializeFMUState", FDID_ANY_STATE)
    return (fmi3Status)fdid_deserialize(I, "fmi3DeserializeFMUState", serializedState, size, FMUState);
}

/* ------------------------------------------------------------ co-simulation */
FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    CHECK(instance, "fmi3DoStep", FDID_ST_STEP)
    (void)noSetFMUStatePriorToCurrentPoint;
    if (fdid_do_step(I, "fmi3DoStep", currentCommunicationPoint, communicationStepSize) != FDID_OK) return fmi3Error;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = fdid_time(I);
    return fmi3OK;
}
