/* fmi3Functions.c -- FMI 3.0 Co-Simulation plumbing of an fdid-fmi FMU (written once).
 *
 * Same behaviour as fmi2Functions.c (same simulation core, same checks and messages):
 * Float64 inputs/outputs/parameters and Boolean parameters; no event mode, no clocks, no
 * configuration mode. Every function of fmi3Functions.h is exported; the ones this FMU
 * does not support (Model Exchange, Scheduled Execution, other types) return fmi3Error with
 * a logged message (or fmi3OK when asked for zero values).
 * The independent variable "time" (value reference FDID_TIME_VR) can be read.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>

#include "fmi3Functions.h"
#include "model_data.h"
#include "fdid_model.h"

#define FDID_TIME_VR 999999u
#define SNAPSHOT_MAGIC 0x46444933u /* "FDI3" */

enum { ST_INSTANTIATED = 1, ST_INIT = 2, ST_STEP = 4, ST_TERMINATED = 8, ST_ERROR = 16, ST_FATAL = 32 };
enum { CAT_WARNING = 0, CAT_ERROR, CAT_FATAL, CAT_CALLS, N_CAT };
static const char *const CATEGORY_NAMES[N_CAT] = {"logStatusWarning", "logStatusError",
                                                  "logStatusFatal", "logCalls"};

typedef struct {
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logger;
    char *name;
    int log_on[N_CAT];
    int mode;
    double start_time;
    FdidState s;
} Instance;

typedef struct {
    unsigned magic;
    int mode;
    double start_time;
    FdidFlags flags;
    size_t nbuf;
} Snapshot;

static void log_msg(const Instance *I, fmi3Status status, int cat, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    if (!I || !I->logger || !I->log_on[cat]) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    I->logger(I->env, status, CATEGORY_NAMES[cat], buf);
}

#define LOG_CALL(I, ...) log_msg((I), fmi3OK, CAT_CALLS, __VA_ARGS__)

static fmi3Status fail(Instance *I, const char *fmt, ...) {
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    log_msg(I, fmi3Error, CAT_ERROR, "%s", buf);
    if (I->mode != ST_FATAL) I->mode = ST_ERROR;
    return fmi3Error;
}

static const char *state_name(int mode) {
    switch (mode) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INIT: return "initialization mode";
    case ST_STEP: return "step mode";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    default: return "fatal";
    }
}

static int allowed(Instance *I, const char *fn, int mask) {
    if (I->mode & mask) return 1;
    fail(I, "%s may not be called in the %s state", fn, state_name(I->mode));
    return 0;
}

#define CHECK(c, fn, mask)                                  \
    Instance *I = (Instance *)(c);                          \
    if (!I) return fmi3Error;                               \
    LOG_CALL(I, "%s", fn);                                  \
    if (!allowed(I, fn, mask)) return fmi3Error;

#define ANY_STATE (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
#define GET_STATES (ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
#define SET_STATES (ST_INSTANTIATED | ST_INIT | ST_STEP)

static double current_time(const Instance *I) {
    return I->start_time + (double)I->s.f.steps * fdid_model.Ts;
}

static const FdidVar *lookup(Instance *I, const char *fn, fmi3ValueReference vr, int type) {
    const FdidVar *v;
    if (vr >= (fmi3ValueReference)fdid_model.n_vars) {
        fail(I, "%s: unknown value reference %u (the model has %d variables)", fn, (unsigned)vr,
             fdid_model.n_vars);
        return NULL;
    }
    v = &fdid_model.vars[vr];
    if (v->type != type) {
        fail(I, "%s: value reference %u (%s) is not of this type", fn, (unsigned)vr, v->name);
        return NULL;
    }
    return v;
}

/* ------------------------------------------------------------ common functions */
FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                                           const fmi3String categories[]) {
    size_t i;
    int k;
    Instance *I = (Instance *)instance;
    if (!I || I->mode == ST_FATAL) return fmi3Error;
    if (nCategories == 0) {
        for (k = 0; k < N_CAT; k++) I->log_on[k] = loggingOn ? 1 : 0;
        return fmi3OK;
    }
    if (!categories) return fail(I, "fmi3SetDebugLogging: categories is NULL");
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < N_CAT; k++) {
            if (categories[i] && strcmp(categories[i], CATEGORY_NAMES[k]) == 0) {
                I->log_on[k] = loggingOn ? 1 : 0;
                found = 1;
            }
        }
        if (!found)
            return fail(I, "fmi3SetDebugLogging: unknown log category '%s'", categories[i] ? categories[i] : "(null)");
    }
    return fmi3OK;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                                      fmi3String resourcePath, fmi3Boolean visible,
                                                      fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                                      fmi3LogMessageCallback logMessage) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                               "fmi3InstantiateModelExchange: this FMU supports Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lockPreemption,
    fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                               "fmi3InstantiateScheduledExecution: this FMU supports Co-Simulation only");
    return NULL;
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath, fmi3Boolean visible,
    fmi3Boolean loggingOn, fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
    const fmi3ValueReference requiredIntermediateVariables[], size_t nRequiredIntermediateVariables,
    fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
    fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance tmp, *I;
    double *buf;
    size_t nbuf = fdid_buffer_size(&fdid_model), n;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)intermediateUpdate;
    memset(&tmp, 0, sizeof tmp);
    tmp.env = instanceEnvironment;
    tmp.logger = logMessage;
    tmp.log_on[CAT_ERROR] = tmp.log_on[CAT_FATAL] = 1;
    tmp.log_on[CAT_WARNING] = tmp.log_on[CAT_CALLS] = loggingOn ? 1 : 0;
    if (!instanceName || !instanceName[0]) {
        log_msg(&tmp, fmi3Error, CAT_ERROR, "fmi3InstantiateCoSimulation: missing instance name");
        return NULL;
    }
    if (eventModeUsed) {
        log_msg(&tmp, fmi3Error, CAT_ERROR, "fmi3InstantiateCoSimulation: this FMU has no event mode "
                                            "(hasEventMode=false)");
        return NULL;
    }
    if (nRequiredIntermediateVariables > 0) {
        log_msg(&tmp, fmi3Error, CAT_ERROR, "fmi3InstantiateCoSimulation: intermediate update is not provided");
        return NULL;
    }
    if (!instantiationToken || strcmp(instantiationToken, fdid_model.guid) != 0) {
        log_msg(&tmp, fmi3Error, CAT_ERROR,
                "fmi3InstantiateCoSimulation: instantiation token '%s' does not match the FMU's '%s'",
                instantiationToken ? instantiationToken : "(null)", fdid_model.guid);
        return NULL;
    }
    I = (Instance *)calloc(1, sizeof(Instance));
    buf = (double *)calloc(nbuf ? nbuf : 1, sizeof(double));
    n = strlen(instanceName) + 1;
    if (I) I->name = (char *)malloc(n);
    if (!I || !buf || !I->name) {
        if (I) free(I->name);
        free(I);
        free(buf);
        log_msg(&tmp, fmi3Fatal, CAT_FATAL, "fmi3InstantiateCoSimulation: out of memory");
        return NULL;
    }
    {
        char *name = I->name;
        *I = tmp;
        I->name = name;
        memcpy(I->name, instanceName, n);
    }
    I->mode = ST_INSTANTIATED;
    fdid_state_bind(&I->s, &fdid_model, buf);
    fdid_state_defaults(&I->s);
    return (fmi3Instance)I;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) {
    Instance *I = (Instance *)instance;
    if (!I) return;
    LOG_CALL(I, "fmi3FreeInstance");
    free(I->s.buf);
    free(I->name);
    free(I);
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK(instance, "fmi3EnterInitializationMode", ST_INSTANTIATED)
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!fdid_is_finite(startTime)) return fail(I, "fmi3EnterInitializationMode: start time is not finite");
    I->start_time = startTime;
    I->mode = ST_INIT;
    I->s.f.init_dirty = 1;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK(instance, "fmi3ExitInitializationMode", ST_INIT)
    fdid_initialize(&I->s);
    I->mode = ST_STEP;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK(instance, "fmi3EnterEventMode", ANY_STATE)
    return fail(I, "fmi3EnterEventMode: this FMU has no event mode");
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK(instance, "fmi3Terminate", ST_STEP | ST_ERROR)
    I->mode = ST_TERMINATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK(instance, "fmi3Reset", ANY_STATE)
    fdid_state_defaults(&I->s);
    I->start_time = 0.0;
    I->mode = ST_INSTANTIATED;
    return fmi3OK;
}

/* ------------------------------------------------------------ get / set */
static int set_value(Instance *I, const char *fn, const FdidVar *v, double x) {
    FdidState *S = &I->s;
    int a = v->index;
    if (!fdid_is_finite(x)) {
        fail(I, "%s: %s must be finite, got a NaN or infinite value", fn, v->name);
        return 0;
    }
    switch (v->role) {
    case FDID_V_CMD: S->cmd[a] = x; break;
    case FDID_V_EXT: S->ext[a] = x; break;
    case FDID_P_LEVEL:
        if (x < 0.0) { fail(I, "%s: %s must be >= 0, got %g", fn, v->name, x); return 0; }
        S->level[a] = x;
        break;
    case FDID_P_VTILDE:
        if (!(x > 0.0)) { fail(I, "%s: %s must be > 0 mm/s, got %g", fn, v->name, x); return 0; }
        S->vtilde[a] = x;
        break;
    case FDID_P_ON: S->on[a] = x != 0.0 ? 1.0 : 0.0; break;
    case FDID_P_V0:
        if (I->mode == ST_STEP || I->mode == ST_TERMINATED) {
            fail(I, "%s: %s is a fixed parameter; set it before fmi3ExitInitializationMode", fn, v->name);
            return 0;
        }
        S->v0[a] = x;
        break;
    default:
        fail(I, "%s: %s is an output or local variable and cannot be set", fn, v->name);
        return 0;
    }
    if (!S->f.started) S->f.init_dirty = 1;
    S->f.out_dirty = 1;
    return 1;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3GetFloat64", GET_STATES)
    if (nValues != nValueReferences) return fail(I, "fmi3GetFloat64: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return fail(I, "fmi3GetFloat64: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        const FdidVar *v;
        if (valueReferences[i] == FDID_TIME_VR) { values[i] = current_time(I); continue; }
        v = lookup(I, "fmi3GetFloat64", valueReferences[i], FDID_T_REAL);
        if (!v) return fmi3Error;
        values[i] = fdid_var_value(&I->s, v);
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3SetFloat64", SET_STATES)
    if (nValues != nValueReferences) return fail(I, "fmi3SetFloat64: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return fail(I, "fmi3SetFloat64: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        const FdidVar *v;
        if (valueReferences[i] == FDID_TIME_VR) return fail(I, "fmi3SetFloat64: time cannot be set");
        v = lookup(I, "fmi3SetFloat64", valueReferences[i], FDID_T_REAL);
        if (!v || !set_value(I, "fmi3SetFloat64", v, values[i])) return fmi3Error;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3GetBoolean", GET_STATES)
    if (nValues != nValueReferences) return fail(I, "fmi3GetBoolean: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return fail(I, "fmi3GetBoolean: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        const FdidVar *v = lookup(I, "fmi3GetBoolean", valueReferences[i], FDID_T_BOOLEAN);
        if (!v) return fmi3Error;
        values[i] = fdid_var_value(&I->s, v) != 0.0;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    size_t i;
    CHECK(instance, "fmi3SetBoolean", SET_STATES)
    if (nValues != nValueReferences) return fail(I, "fmi3SetBoolean: nValues must equal nValueReferences");
    if (nValueReferences > 0 && (!valueReferences || !values)) return fail(I, "fmi3SetBoolean: NULL argument");
    for (i = 0; i < nValueReferences; i++) {
        const FdidVar *v = lookup(I, "fmi3SetBoolean", valueReferences[i], FDID_T_BOOLEAN);
        if (!v || !set_value(I, "fmi3SetBoolean", v, values[i] ? 1.0 : 0.0)) return fmi3Error;
    }
    return fmi3OK;
}

/* types this FMU has no variables of: fine for zero values, an error otherwise */
static fmi3Status no_vars(fmi3Instance instance, const char *fn, int mask, const fmi3ValueReference vr[],
                          size_t nvr) {
    CHECK(instance, fn, mask)
    if (nvr == 0) return fmi3OK;
    return fail(I, "%s: the model has no variables of this type (value reference %u)", fn,
                vr ? (unsigned)vr[0] : 0u);
}

#define NO_GET(T, N)                                                                                   \
    FMI3_Export fmi3Status fmi3Get##N(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                                      T values[], size_t nValues) {                                   \
        (void)values; (void)nValues;                                                                  \
        return no_vars(instance, "fmi3Get" #N, GET_STATES, vr, nvr);                                  \
    }
#define NO_SET(T, N)                                                                                   \
    FMI3_Export fmi3Status fmi3Set##N(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                                      const T values[], size_t nValues) {                             \
        (void)values; (void)nValues;                                                                  \
        return no_vars(instance, "fmi3Set" #N, SET_STATES, vr, nvr);                                  \
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
    return no_vars(instance, "fmi3GetBinary", GET_STATES, vr, nvr);
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_vars(instance, "fmi3SetBinary", SET_STATES, vr, nvr);
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Clock values[]) {
    (void)values;
    return no_vars(instance, "fmi3GetClock", ANY_STATE, vr, nvr);
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[]) {
    (void)values;
    return no_vars(instance, "fmi3SetClock", ANY_STATE, vr, nvr);
}

/* ------------------------------------------------------------ unsupported features */
#define UNSUPPORTED(fn, what)                  \
    CHECK(instance, fn, ANY_STATE)             \
    return fail(I, "%s: %s", fn, what);

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
static size_t snapshot_bytes(void) {
    return sizeof(Snapshot) + fdid_buffer_size(&fdid_model) * sizeof(double);
}

static int snapshot_valid(const Snapshot *s) {
    return s && s->magic == SNAPSHOT_MAGIC && s->nbuf == fdid_buffer_size(&fdid_model) && (s->mode & ANY_STATE);
}

FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Snapshot *s;
    CHECK(instance, "fmi3GetFMUState", ANY_STATE)
    if (!FMUState) return fail(I, "fmi3GetFMUState: NULL argument");
    s = (Snapshot *)*FMUState;
    if (s && !snapshot_valid(s)) return fail(I, "fmi3GetFMUState: *FMUState is not a state of this FMU");
    if (!s) {
        s = (Snapshot *)calloc(1, snapshot_bytes());
        if (!s) return fail(I, "fmi3GetFMUState: out of memory");
    }
    s->magic = SNAPSHOT_MAGIC;
    s->mode = I->mode;
    s->start_time = I->start_time;
    s->flags = I->s.f;
    s->nbuf = I->s.nbuf;
    memcpy((char *)s + sizeof(Snapshot), I->s.buf, I->s.nbuf * sizeof(double));
    *FMUState = (fmi3FMUState)s;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    const Snapshot *s = (const Snapshot *)FMUState;
    CHECK(instance, "fmi3SetFMUState", ANY_STATE)
    if (!snapshot_valid(s)) return fail(I, "fmi3SetFMUState: not a state of this FMU");
    I->mode = s->mode;
    I->start_time = s->start_time;
    I->s.f = s->flags;
    memcpy(I->s.buf, (const char *)s + sizeof(Snapshot), I->s.nbuf * sizeof(double));
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK(instance, "fmi3FreeFMUState", ANY_STATE)
    if (!FMUState) return fail(I, "fmi3FreeFMUState: NULL argument");
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

#define GUID_BYTES 64

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    CHECK(instance, "fmi3SerializedFMUStateSize", ANY_STATE)
    if (!size) return fail(I, "fmi3SerializedFMUStateSize: NULL argument");
    if (!snapshot_valid((const Snapshot *)FMUState)) return fail(I, "fmi3SerializedFMUStateSize: not a state of this FMU");
    *size = GUID_BYTES + snapshot_bytes();
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                             size_t size) {
    CHECK(instance, "fmi3SerializeFMUState", ANY_STATE)
    if (!serializedState) return fail(I, "fmi3SerializeFMUState: NULL argument");
    if (!snapshot_valid((const Snapshot *)FMUState)) return fail(I, "fmi3SerializeFMUState: not a state of this FMU");
    if (size < GUID_BYTES + snapshot_bytes()) return fail(I, "fmi3SerializeFMUState: buffer too small");
    memset(serializedState, 0, GUID_BYTES);
    strncpy((char *)serializedState, fdid_model.guid, GUID_BYTES - 1);
    memcpy(serializedState + GUID_BYTES, FMUState, snapshot_bytes());
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                               fmi3FMUState *FMUState) {
    Snapshot *s;
    char guid[GUID_BYTES];
    CHECK(instance, "fmi3DeserializeFMUState", ANY_STATE)
    if (!serializedState || !FMUState) return fail(I, "fmi3DeserializeFMUState: NULL argument");
    if (size != GUID_BYTES + snapshot_bytes()) return fail(I, "fmi3DeserializeFMUState: wrong size %lu",
                                                           (unsigned long)size);
    memcpy(guid, serializedState, GUID_BYTES);
    guid[GUID_BYTES - 1] = '\0';
    if (strcmp(guid, fdid_model.guid) != 0)
        return fail(I, "fmi3DeserializeFMUState: the state belongs to another FMU (%s)", guid);
    s = (Snapshot *)*FMUState;
    if (s && !snapshot_valid(s)) return fail(I, "fmi3DeserializeFMUState: *FMUState is not a state of this FMU");
    if (!s) {
        s = (Snapshot *)calloc(1, snapshot_bytes());
        if (!s) return fail(I, "fmi3DeserializeFMUState: out of memory");
    }
    memcpy(s, serializedState + GUID_BYTES, snapshot_bytes());
    if (!snapshot_valid(s)) {
        if (!*FMUState) free(s);
        return fail(I, "fmi3DeserializeFMUState: corrupt state");
    }
    *FMUState = (fmi3FMUState)s;
    return fmi3OK;
}

/* ------------------------------------------------------------ co-simulation */
FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    double Ts = fdid_model.Ts, h = communicationStepSize, t, q, tol;
    long long k, nsteps;
    CHECK(instance, "fmi3DoStep", ST_STEP)
    (void)noSetFMUStatePriorToCurrentPoint;
    t = current_time(I);
    if (!fdid_is_finite(h) || !(h > 0.0))
        return fail(I, "fmi3DoStep: communication step size must be a positive number, got %g s", h);
    if (!fdid_is_finite(currentCommunicationPoint))
        return fail(I, "fmi3DoStep: currentCommunicationPoint is not finite");
    q = h / Ts;
    if (q > 1e15) return fail(I, "fmi3DoStep: communication step size %g s is too large", h);
    nsteps = (long long)(q + 0.5);
    if (nsteps < 1 || (h - (double)nsteps * Ts > 1e-9 * h) || ((double)nsteps * Ts - h > 1e-9 * h))
        return fail(I, "fmi3DoStep: communication step size %.17g s is not an integer multiple of the "
                       "model sample time Ts = %.17g s (relative tolerance 1e-9)", h, Ts);
    tol = 1e-6 * Ts + 1e-9 * (t < 0 ? -t : t);
    if (currentCommunicationPoint - t > tol || t - currentCommunicationPoint > tol)
        return fail(I, "fmi3DoStep: currentCommunicationPoint %.17g s differs from the FMU time %.17g s",
                    currentCommunicationPoint, t);
    for (k = 0; k < nsteps; k++) fdid_advance(&I->s);
    I->s.f.started = 1;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = current_time(I);
    return fmi3OK;
}
