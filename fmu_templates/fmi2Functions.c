/* fmi2Functions.c -- FMI 2.0 Co-Simulation plumbing of an fdid-fmi FMU (written once).
 *
 * State machine (FMI 2.0.4, section 4.2.4), logging through the callback, FMU state
 * get/set/serialize, value references from the generated variable table (model_data.c).
 * Any call in the wrong state, unknown value reference, non-finite value or step size that
 * is not an integer multiple of the model sample time returns fmi2Error with a logged
 * message and puts the instance in the error state (left by fmi2SetFMUstate or fmi2Reset).
 *
 * Logging: categories logStatusWarning, logStatusError, logStatusFatal and logCalls.
 * Error and fatal messages are logged unless the master switched those categories off with
 * fmi2SetDebugLogging; warnings and the trace of calls (logCalls) only when loggingOn.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>

#include "fmi2Functions.h"
#include "model_data.h"
#include "fdid_model.h"

#define SNAPSHOT_MAGIC 0x46444944u /* "FDID" */

enum { ST_INSTANTIATED = 1, ST_INIT = 2, ST_STEP = 4, ST_TERMINATED = 8, ST_ERROR = 16, ST_FATAL = 32 };
enum { CAT_WARNING = 0, CAT_ERROR, CAT_FATAL, CAT_CALLS, N_CAT };
static const char *const CATEGORY_NAMES[N_CAT] = {"logStatusWarning", "logStatusError",
                                                  "logStatusFatal", "logCalls"};

typedef struct {
    fmi2CallbackFunctions cb;
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
    /* followed by nbuf doubles */
} Snapshot;

/* ------------------------------------------------------------------ helpers */
/* the master's memory functions when it gave both, else the C library's */
static int use_callbacks(const Instance *I) { return I->cb.allocateMemory && I->cb.freeMemory; }

static void *mem_alloc(const Instance *I, size_t n, size_t size) {
    if (use_callbacks(I)) return I->cb.allocateMemory(n, size);
    return calloc(n, size);
}

static void mem_free(const Instance *I, void *p) {
    if (!p) return;
    if (use_callbacks(I)) I->cb.freeMemory(p);
    else free(p);
}

static void log_msg(const Instance *I, fmi2Status status, int cat, const char *fmt, ...) {
    char buf[1024], esc[2048];
    size_t i, k = 0;
    va_list ap;
    if (!I || !I->cb.logger || !I->log_on[cat]) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    /* the message is a printf format for the logger: escape '%' */
    for (i = 0; buf[i] && k + 2 < sizeof esc; i++) {
        if (buf[i] == '%') esc[k++] = '%';
        esc[k++] = buf[i];
    }
    esc[k] = '\0';
    I->cb.logger(I->cb.componentEnvironment, I->name ? I->name : "?", status,
                 CATEGORY_NAMES[cat], esc);
}

#define LOG_CALL(I, ...) log_msg((I), fmi2OK, CAT_CALLS, __VA_ARGS__)

static fmi2Status fail(Instance *I, const char *fmt, ...) {
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    log_msg(I, fmi2Error, CAT_ERROR, "%s", buf);
    if (I->mode != ST_FATAL) I->mode = ST_ERROR;
    return fmi2Error;
}

static const char *state_name(int mode) {
    switch (mode) {
    case ST_INSTANTIATED: return "instantiated";
    case ST_INIT: return "initialization mode";
    case ST_STEP: return "step mode (slave initialized)";
    case ST_TERMINATED: return "terminated";
    case ST_ERROR: return "error";
    default: return "fatal";
    }
}

/* returns 1 when allowed; otherwise logs and moves to the error state */
static int allowed(Instance *I, const char *fn, int mask) {
    if (I->mode & mask) return 1;
    fail(I, "%s may not be called in the %s state", fn, state_name(I->mode));
    return 0;
}

#define CHECK(c, fn, mask)                                  \
    Instance *I = (Instance *)(c);                          \
    if (!I) return fmi2Error;                               \
    LOG_CALL(I, "%s", fn);                                  \
    if (!allowed(I, fn, mask)) return fmi2Error;

static double current_time(const Instance *I) {
    return I->start_time + (double)I->s.f.steps * fdid_model.Ts;
}

static const FdidVar *lookup(Instance *I, const char *fn, fmi2ValueReference vr, int type) {
    const FdidVar *v;
    if (vr >= (fmi2ValueReference)fdid_model.n_vars) {
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

static char *copy_string(const Instance *I, const char *s) {
    size_t n = strlen(s) + 1;
    char *r = (char *)mem_alloc(I, n, 1);
    if (r) memcpy(r, s, n);
    return r;
}

/* ------------------------------------------------------------ common functions */
FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                           const fmi2String categories[]) {
    size_t i;
    int k;
    Instance *I = (Instance *)c;
    if (!I) return fmi2Error;
    if (I->mode == ST_FATAL) return fmi2Error;
    if (nCategories == 0) {
        for (k = 0; k < N_CAT; k++) I->log_on[k] = loggingOn ? 1 : 0;
        return fmi2OK;
    }
    if (!categories) return fail(I, "fmi2SetDebugLogging: categories is NULL");
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        if (categories[i] && strcmp(categories[i], "logAll") == 0) {
            for (k = 0; k < N_CAT; k++) I->log_on[k] = loggingOn ? 1 : 0;
            continue;
        }
        for (k = 0; k < N_CAT; k++) {
            if (categories[i] && strcmp(categories[i], CATEGORY_NAMES[k]) == 0) {
                I->log_on[k] = loggingOn ? 1 : 0;
                found = 1;
            }
        }
        if (!found)
            return fail(I, "fmi2SetDebugLogging: unknown log category '%s'",
                        categories[i] ? categories[i] : "(null)");
    }
    return fmi2OK;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                          fmi2Boolean loggingOn) {
    Instance tmp, *I;
    double *buf;
    size_t nbuf = fdid_buffer_size(&fdid_model);
    (void)fmuResourceLocation;
    (void)visible;
    memset(&tmp, 0, sizeof tmp);
    if (functions) tmp.cb = *functions;
    tmp.name = (char *)(instanceName ? instanceName : "?");
    tmp.log_on[CAT_ERROR] = tmp.log_on[CAT_FATAL] = 1;
    tmp.log_on[CAT_WARNING] = tmp.log_on[CAT_CALLS] = loggingOn ? 1 : 0;
    if (!instanceName || !instanceName[0]) {
        log_msg(&tmp, fmi2Error, CAT_ERROR, "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        log_msg(&tmp, fmi2Error, CAT_ERROR,
                "fmi2Instantiate: this FMU supports Co-Simulation only (fmuType %d given)", (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, fdid_model.guid) != 0) {
        log_msg(&tmp, fmi2Error, CAT_ERROR, "fmi2Instantiate: GUID '%s' does not match the FMU's '%s'",
                fmuGUID ? fmuGUID : "(null)", fdid_model.guid);
        return NULL;
    }
    I = (Instance *)mem_alloc(&tmp, 1, sizeof(Instance));
    buf = (double *)mem_alloc(&tmp, nbuf ? nbuf : 1, sizeof(double));
    if (!I || !buf) {
        mem_free(&tmp, I);
        mem_free(&tmp, buf);
        log_msg(&tmp, fmi2Fatal, CAT_FATAL, "fmi2Instantiate: out of memory");
        return NULL;
    }
    *I = tmp;
    I->name = copy_string(I, instanceName);
    if (!I->name) {
        mem_free(&tmp, buf);
        mem_free(&tmp, I);
        return NULL;
    }
    I->mode = ST_INSTANTIATED;
    I->start_time = 0.0;
    fdid_state_bind(&I->s, &fdid_model, buf);
    fdid_state_defaults(&I->s);
    LOG_CALL(I, "fmi2Instantiate: %s, Ts = %g s", fdid_model.model_identifier, fdid_model.Ts);
    return (fmi2Component)I;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) {
    Instance *I = (Instance *)c, copy;
    if (!I) return;
    LOG_CALL(I, "fmi2FreeInstance");
    copy = *I;
    copy.name = NULL;
    mem_free(I, I->s.buf);
    mem_free(I, I->name);
    mem_free(&copy, I);
}

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK(c, "fmi2SetupExperiment", ST_INSTANTIATED)
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!fdid_is_finite(startTime)) return fail(I, "fmi2SetupExperiment: start time is not finite");
    I->start_time = startTime;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2EnterInitializationMode", ST_INSTANTIATED)
    I->mode = ST_INIT;
    I->s.f.init_dirty = 1;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK(c, "fmi2ExitInitializationMode", ST_INIT)
    fdid_initialize(&I->s); /* steady ramp from the inputs and parameters set so far */
    I->mode = ST_STEP;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK(c, "fmi2Terminate", ST_STEP | ST_ERROR)
    I->mode = ST_TERMINATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    CHECK(c, "fmi2Reset", ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)
    fdid_state_defaults(&I->s);
    I->start_time = 0.0;
    I->mode = ST_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------ get / set */
#define GET_STATES (ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    size_t i;
    CHECK(c, "fmi2GetReal", GET_STATES)
    if (nvr > 0 && (!vr || !value)) return fail(I, "fmi2GetReal: NULL argument");
    for (i = 0; i < nvr; i++) {
        const FdidVar *v = lookup(I, "fmi2GetReal", vr[i], FDID_T_REAL);
        if (!v) return fmi2Error;
        value[i] = fdid_var_value(&I->s, v);
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Boolean value[]) {
    size_t i;
    CHECK(c, "fmi2GetBoolean", GET_STATES)
    if (nvr > 0 && (!vr || !value)) return fail(I, "fmi2GetBoolean: NULL argument");
    for (i = 0; i < nvr; i++) {
        const FdidVar *v = lookup(I, "fmi2GetBoolean", vr[i], FDID_T_BOOLEAN);
        if (!v) return fmi2Error;
        value[i] = fdid_var_value(&I->s, v) != 0.0 ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Integer value[]) {
    CHECK(c, "fmi2GetInteger", GET_STATES)
    (void)value;
    if (nvr > 0) return fail(I, "fmi2GetInteger: the model has no Integer variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     fmi2String value[]) {
    CHECK(c, "fmi2GetString", GET_STATES)
    (void)value;
    if (nvr > 0) return fail(I, "fmi2GetString: the model has no String variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

/* checks and stores one value; returns 0 after logging when refused */
static int set_value(Instance *I, const char *fn, const FdidVar *v, double x) {
    FdidState *S = &I->s;
    int a = v->index;
    int before_start = !S->f.started;
    if (!fdid_is_finite(x)) {
        fail(I, "%s: %s must be finite, got a NaN or infinite value", fn, v->name);
        return 0;
    }
    switch (v->role) {
    case FDID_V_CMD:
    case FDID_V_EXT:
        if (v->role == FDID_V_CMD) S->cmd[a] = x;
        else S->ext[a] = x;
        break;
    case FDID_P_LEVEL:
    case FDID_P_VTILDE:
    case FDID_P_ON:
        if (v->role == FDID_P_LEVEL && x < 0.0) {
            fail(I, "%s: %s must be >= 0, got %g", fn, v->name, x);
            return 0;
        }
        if (v->role == FDID_P_VTILDE && !(x > 0.0)) {
            fail(I, "%s: %s must be > 0 mm/s, got %g", fn, v->name, x);
            return 0;
        }
        if (v->role == FDID_P_LEVEL) S->level[a] = x;
        else if (v->role == FDID_P_VTILDE) S->vtilde[a] = x;
        else S->on[a] = x != 0.0 ? 1.0 : 0.0;
        break;
    case FDID_P_V0:
        if (I->mode == ST_STEP || I->mode == ST_TERMINATED) {
            fail(I, "%s: %s is a fixed parameter; set it before fmi2ExitInitializationMode", fn, v->name);
            return 0;
        }
        S->v0[a] = x;
        break;
    default:
        fail(I, "%s: %s is an output or local variable and cannot be set", fn, v->name);
        return 0;
    }
    /* before the first step, inputs and parameters define the initial state */
    if (before_start) S->f.init_dirty = 1;
    S->f.out_dirty = 1;
    return 1;
}

#define SET_STATES (ST_INSTANTIATED | ST_INIT | ST_STEP)

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    size_t i;
    CHECK(c, "fmi2SetReal", SET_STATES)
    if (nvr > 0 && (!vr || !value)) return fail(I, "fmi2SetReal: NULL argument");
    for (i = 0; i < nvr; i++) {
        const FdidVar *v = lookup(I, "fmi2SetReal", vr[i], FDID_T_REAL);
        if (!v || !set_value(I, "fmi2SetReal", v, value[i])) return fmi2Error;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Boolean value[]) {
    size_t i;
    CHECK(c, "fmi2SetBoolean", SET_STATES)
    if (nvr > 0 && (!vr || !value)) return fail(I, "fmi2SetBoolean: NULL argument");
    for (i = 0; i < nvr; i++) {
        const FdidVar *v = lookup(I, "fmi2SetBoolean", vr[i], FDID_T_BOOLEAN);
        if (!v || !set_value(I, "fmi2SetBoolean", v, value[i] ? 1.0 : 0.0)) return fmi2Error;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Integer value[]) {
    CHECK(c, "fmi2SetInteger", SET_STATES)
    (void)value;
    if (nvr > 0) return fail(I, "fmi2SetInteger: the model has no Integer variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2String value[]) {
    CHECK(c, "fmi2SetString", SET_STATES)
    (void)value;
    if (nvr > 0) return fail(I, "fmi2SetString: the model has no String variables (value reference %u)",
                             vr ? (unsigned)vr[0] : 0u);
    return fmi2OK;
}

/* ------------------------------------------------------------ FMU state */
#define ANY_STATE (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR)

static size_t snapshot_bytes(void) {
    return sizeof(Snapshot) + fdid_buffer_size(&fdid_model) * sizeof(double);
}

static void snapshot_take(const Instance *I, Snapshot *s) {
    s->magic = SNAPSHOT_MAGIC;
    s->mode = I->mode;
    s->start_time = I->start_time;
    s->flags = I->s.f;
    s->nbuf = I->s.nbuf;
    memcpy((char *)s + sizeof(Snapshot), I->s.buf, I->s.nbuf * sizeof(double));
}

static int snapshot_valid(const Snapshot *s) {
    return s && s->magic == SNAPSHOT_MAGIC && s->nbuf == fdid_buffer_size(&fdid_model) &&
           (s->mode & (ST_INSTANTIATED | ST_INIT | ST_STEP | ST_TERMINATED | ST_ERROR));
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Snapshot *s;
    CHECK(c, "fmi2GetFMUstate", ANY_STATE)
    if (!FMUstate) return fail(I, "fmi2GetFMUstate: NULL argument");
    s = (Snapshot *)*FMUstate;
    if (s && !snapshot_valid(s)) return fail(I, "fmi2GetFMUstate: *FMUstate is not a state of this FMU");
    if (!s) {
        s = (Snapshot *)mem_alloc(I, 1, snapshot_bytes());
        if (!s) return fail(I, "fmi2GetFMUstate: out of memory");
    }
    snapshot_take(I, s);
    *FMUstate = (fmi2FMUstate)s;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const Snapshot *s = (const Snapshot *)FMUstate;
    CHECK(c, "fmi2SetFMUstate", ANY_STATE)
    if (!snapshot_valid(s)) return fail(I, "fmi2SetFMUstate: not a state of this FMU");
    I->mode = s->mode;
    I->start_time = s->start_time;
    I->s.f = s->flags;
    memcpy(I->s.buf, (const char *)s + sizeof(Snapshot), I->s.nbuf * sizeof(double));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK(c, "fmi2FreeFMUstate", ANY_STATE)
    if (!FMUstate) return fail(I, "fmi2FreeFMUstate: NULL argument");
    mem_free(I, *FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

/* serialized form: GUID (64 bytes, NUL-padded) then the snapshot bytes */
#define GUID_BYTES 64

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    CHECK(c, "fmi2SerializedFMUstateSize", ANY_STATE)
    if (!size) return fail(I, "fmi2SerializedFMUstateSize: NULL argument");
    if (!snapshot_valid((const Snapshot *)FMUstate))
        return fail(I, "fmi2SerializedFMUstateSize: not a state of this FMU");
    *size = GUID_BYTES + snapshot_bytes();
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                             size_t size) {
    CHECK(c, "fmi2SerializeFMUstate", ANY_STATE)
    if (!serializedState) return fail(I, "fmi2SerializeFMUstate: NULL argument");
    if (!snapshot_valid((const Snapshot *)FMUstate)) return fail(I, "fmi2SerializeFMUstate: not a state of this FMU");
    if (size < GUID_BYTES + snapshot_bytes())
        return fail(I, "fmi2SerializeFMUstate: buffer of %lu bytes is too small (%lu needed)",
                    (unsigned long)size, (unsigned long)(GUID_BYTES + snapshot_bytes()));
    memset(serializedState, 0, GUID_BYTES);
    strncpy((char *)serializedState, fdid_model.guid, GUID_BYTES - 1);
    memcpy(serializedState + GUID_BYTES, FMUstate, snapshot_bytes());
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                               fmi2FMUstate *FMUstate) {
    Snapshot *s;
    char guid[GUID_BYTES];
    CHECK(c, "fmi2DeSerializeFMUstate", ANY_STATE)
    if (!serializedState || !FMUstate) return fail(I, "fmi2DeSerializeFMUstate: NULL argument");
    if (size != GUID_BYTES + snapshot_bytes())
        return fail(I, "fmi2DeSerializeFMUstate: %lu bytes given, a state of this FMU has %lu",
                    (unsigned long)size, (unsigned long)(GUID_BYTES + snapshot_bytes()));
    memcpy(guid, serializedState, GUID_BYTES);
    guid[GUID_BYTES - 1] = '\0';
    if (strcmp(guid, fdid_model.guid) != 0)
        return fail(I, "fmi2DeSerializeFMUstate: the state belongs to another FMU (GUID %s)", guid);
    s = (Snapshot *)*FMUstate;
    if (s && !snapshot_valid(s)) return fail(I, "fmi2DeSerializeFMUstate: *FMUstate is not a state of this FMU");
    if (!s) {
        s = (Snapshot *)mem_alloc(I, 1, snapshot_bytes());
        if (!s) return fail(I, "fmi2DeSerializeFMUstate: out of memory");
    }
    memcpy(s, serializedState + GUID_BYTES, snapshot_bytes());
    if (!snapshot_valid(s)) {
        if (!*FMUstate) mem_free(I, s);
        return fail(I, "fmi2DeSerializeFMUstate: corrupt state");
    }
    *FMUstate = (fmi2FMUstate)s;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                                    size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    CHECK(c, "fmi2GetDirectionalDerivative", ANY_STATE)
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return fail(I, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

/* ------------------------------------------------------------ co-simulation */
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
    CHECK(c, "fmi2SetRealInputDerivatives", ANY_STATE)
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(I, "fmi2SetRealInputDerivatives: inputs are held constant over a step "
                   "(canInterpolateInputs=false)");
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[], fmi2Real value[]) {
    CHECK(c, "fmi2GetRealOutputDerivatives", ANY_STATE)
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(I, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder=0)");
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    double Ts = fdid_model.Ts, h = communicationStepSize, t, q, tol;
    long long k, nsteps;
    CHECK(c, "fmi2DoStep", ST_STEP)
    (void)noSetFMUStatePriorToCurrentPoint;
    t = current_time(I);
    if (!fdid_is_finite(h) || !(h > 0.0))
        return fail(I, "fmi2DoStep: communication step size must be a positive number, got %g s", h);
    if (!fdid_is_finite(currentCommunicationPoint))
        return fail(I, "fmi2DoStep: currentCommunicationPoint is not finite");
    q = h / Ts;
    if (q > 1e15) return fail(I, "fmi2DoStep: communication step size %g s is too large", h);
    nsteps = (long long)(q + 0.5);
    if (nsteps < 1 || (h - (double)nsteps * Ts > 1e-9 * h) || ((double)nsteps * Ts - h > 1e-9 * h))
        return fail(I, "fmi2DoStep: communication step size %.17g s is not an integer multiple of the "
                       "model sample time Ts = %.17g s (relative tolerance 1e-9)", h, Ts);
    tol = 1e-6 * Ts + 1e-9 * (t < 0 ? -t : t);
    if (currentCommunicationPoint - t > tol || t - currentCommunicationPoint > tol)
        return fail(I, "fmi2DoStep: currentCommunicationPoint %.17g s differs from the FMU time %.17g s", 
                    currentCommunicationPoint, t);
    for (k = 0; k < nsteps; k++) fdid_advance(&I->s);
    I->s.f.started = 1;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
    CHECK(c, "fmi2CancelStep", ANY_STATE)
    return fail(I, "fmi2CancelStep: no step is pending (fmi2DoStep never returns fmi2Pending)");
}

FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    CHECK(c, "fmi2GetStatus", GET_STATES)
    (void)value;
    log_msg(I, fmi2Discard, CAT_WARNING, "fmi2GetStatus: status kind %d is not available "
            "(fmi2DoStep never returns fmi2Pending)", (int)s);
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK(c, "fmi2GetRealStatus", GET_STATES)
    if (!value) return fail(I, "fmi2GetRealStatus: NULL argument");
    if (s == fmi2LastSuccessfulTime) {
        *value = current_time(I);
        return fmi2OK;
    }
    log_msg(I, fmi2Discard, CAT_WARNING, "fmi2GetRealStatus: status kind %d is not available", (int)s);
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    CHECK(c, "fmi2GetIntegerStatus", GET_STATES)
    (void)value;
    log_msg(I, fmi2Discard, CAT_WARNING, "fmi2GetIntegerStatus: status kind %d is not available", (int)s);
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK(c, "fmi2GetBooleanStatus", GET_STATES)
    if (!value) return fail(I, "fmi2GetBooleanStatus: NULL argument");
    if (s == fmi2Terminated) {
        *value = fmi2False; /* the FMU never asks to terminate */
        return fmi2OK;
    }
    log_msg(I, fmi2Discard, CAT_WARNING, "fmi2GetBooleanStatus: status kind %d is not available", (int)s);
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    CHECK(c, "fmi2GetStringStatus", GET_STATES)
    (void)value;
    log_msg(I, fmi2Discard, CAT_WARNING, "fmi2GetStringStatus: status kind %d is not available", (int)s);
    return fmi2Discard;
}
