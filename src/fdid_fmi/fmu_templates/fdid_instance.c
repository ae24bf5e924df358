/* fdid_instance.c -- the instance bookkeeping of an fdid-fmi FMU (written once for FMI 2 and 3).
 *
 * See fdid_instance.h. No FMI types here: the wrappers in fmi2Functions.c / fmi3Functions.c
 * translate their arguments and return these status codes as fmi2Status / fmi3Status.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#if defined(_WIN32)
#include <windows.h>
#else
#include <pthread.h>
#endif

#include "model_data.h"
#include "fdid_instance.h"

static const char *const CATEGORY_NAMES[FDID_N_CAT] = {"logStatusWarning", "logStatusError",
                                                       "logStatusFatal", "logCalls", "logStatusWarning"};

typedef struct {
    unsigned magic;
    int mode;
    double start_time;
    FdidFlags flags;
    size_t nbuf;
    unsigned long long model_id;  /* model_id(): a state of another fdid FMU of the same size is refused */
    /* followed by nbuf doubles */
} Snapshot;

/* serialized form: GUID (64 bytes, NUL-padded) then the snapshot bytes */
#define GUID_BYTES 64

/* at most this many internal steps in one doStep (a larger communication step is refused
 * with a logged message instead of running for minutes) */
#define FDID_MAX_STEPS_PER_DOSTEP 10000000LL
/* largest step count a state may carry: steps * Ts stays exact in a double */
#define FDID_MAX_TOTAL_STEPS 9007199254740992LL

/* ------------------------------------------------------------------ logging */
void fdid_log(const FdidInstance *I, int status, int cat, const char *fmt, ...) {
    char buf[1024], esc[2048];
    size_t i, k = 0;
    va_list ap;
    if (!I || !I->api->emit || !I->log_on[cat]) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    /* '#' opens a variable reference (#r12# in FMI 2, #12# in FMI 3) that masters such as FMI
     * Library expand; a literal '#' is written "##" (FMI 2.0.4 section 2.1.5, FMI 3.0 section
     * 2.3.1, logMessage). Strings from the master (a GUID, a log category) may hold one. */
    for (i = 0; buf[i] && k + 2 < sizeof esc; i++) {
        if (buf[i] == '#') esc[k++] = '#';
        esc[k++] = buf[i];
    }
    esc[k] = '\0';
    I->api->emit(I, status, CATEGORY_NAMES[cat], esc);
}

int fdid_fail(FdidInstance *I, const char *fmt, ...) {
    char buf[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fdid_log(I, FDID_ERROR, FDID_CAT_ERROR, "%s", buf);
    if (I->mode != FDID_ST_FATAL) I->mode = FDID_ST_ERROR;
    return FDID_ERROR;
}

static const char *state_name(const FdidInstance *I) {
    switch (I->mode) {
    case FDID_ST_INSTANTIATED: return "instantiated";
    case FDID_ST_INIT: return "initialization mode";
    case FDID_ST_STEP: return I->api->step_mode_name;
    case FDID_ST_TERMINATED: return "terminated";
    case FDID_ST_ERROR: return "error";
    case FDID_ST_UPDATE: return "intermediate update mode";
    default: return "fatal";
    }
}

int fdid_begin(FdidInstance *I, const char *fn, int mask) {
    if (!I || !fdid_live(I)) return 0;
    fdid_log(I, FDID_OK, FDID_CAT_CALLS, "%s", fn);
    if (I->mode & mask) return 1;
    fdid_fail(I, "%s may not be called in the %s state", fn, state_name(I));
    return 0;
}

int fdid_set_debug_logging(FdidInstance *I, const char *fn, int on, size_t n, const char *const categories[]) {
    size_t i;
    int k, status = FDID_OK;
    if (!I || !fdid_live(I) || I->mode == FDID_ST_FATAL) return FDID_ERROR;
    if (n == 0) {
        for (k = 0; k < FDID_N_CAT; k++) I->log_on[k] = on ? 1 : 0;
        return FDID_OK;
    }
    if (!categories) return fdid_fail(I, "%s: categories is NULL", fn);
    for (i = 0; i < n; i++) {
        int found = 0;
        if (I->api->accepts_log_all && categories[i] && strcmp(categories[i], "logAll") == 0) {
            for (k = 0; k < FDID_N_CAT; k++) I->log_on[k] = on ? 1 : 0;
            continue;
        }
        for (k = 0; k < FDID_N_CAT; k++) {
            if (categories[i] && strcmp(categories[i], CATEGORY_NAMES[k]) == 0) {
                I->log_on[k] = on ? 1 : 0;
                found = 1;
            }
        }
        if (!found) {   /* the master's mistake, but no reason to stop the simulation */
            fdid_log(I, FDID_WARNING, FDID_CAT_WARNING, "%s: unknown log category '%s' ignored", fn,
                     categories[i] ? categories[i] : "(null)");
            status = FDID_WARNING;
        }
    }
    return status;
}

/* ------------------------------------------------------------------ live instances */
/* The one piece of state shared by the instances of this FMU in a process: the addresses of the
 * live ones, so that an instance freed twice or used after FreeInstance is refused instead of
 * touched. The table lives in the C library's heap (not the master's: it outlives any one
 * instance) and is freed when the last instance goes. */
#if defined(_WIN32)
static SRWLOCK registry_lock = SRWLOCK_INIT;
static void registry_acquire(void) { AcquireSRWLockExclusive(&registry_lock); }
static void registry_release(void) { ReleaseSRWLockExclusive(&registry_lock); }
#else
static pthread_mutex_t registry_lock = PTHREAD_MUTEX_INITIALIZER;
static void registry_acquire(void) { pthread_mutex_lock(&registry_lock); }
static void registry_release(void) { pthread_mutex_unlock(&registry_lock); }
#endif
static const FdidInstance **registry = NULL;
static size_t registry_n = 0, registry_cap = 0;

/* 1 after adding I, 0 when out of memory */
static int registry_add(const FdidInstance *I) {
    int ok = 1;
    registry_acquire();
    if (registry_n == registry_cap) {
        size_t cap = registry_cap ? 2 * registry_cap : 16;
        const FdidInstance **grown = (const FdidInstance **)realloc((void *)registry, cap * sizeof *grown);
        if (grown) {
            registry = grown;
            registry_cap = cap;
        } else {
            ok = 0;
        }
    }
    if (ok) registry[registry_n++] = I;
    registry_release();
    return ok;
}

/* 1 when I was live (and is now removed), 0 when it was not */
static int registry_remove(const FdidInstance *I) {
    size_t i;
    int found = 0;
    registry_acquire();
    for (i = 0; i < registry_n; i++) {
        if (registry[i] == I) {
            registry[i] = registry[--registry_n];
            found = 1;
            break;
        }
    }
    if (registry_n == 0) {
        free((void *)registry);
        registry = NULL;
        registry_cap = 0;
    }
    registry_release();
    return found;
}

int fdid_live(const FdidInstance *I) {
    size_t i;
    int found = 0;
    if (!I) return 0;
    registry_acquire();
    for (i = 0; i < registry_n && !found; i++) found = registry[i] == I;
    registry_release();
    return found;
}

/* ------------------------------------------------------------------ memory, life cycle */
/* the master's memory functions when it gave both, else the C library's */
static int use_callbacks(const FdidInstance *I) { return I->allocate_memory && I->free_memory; }

void *fdid_alloc(const FdidInstance *I, size_t n, size_t size) {
    if (use_callbacks(I)) return I->allocate_memory(n, size);
    return calloc(n, size);
}

void fdid_free(const FdidInstance *I, void *p) {
    if (!p) return;
    if (use_callbacks(I)) I->free_memory(p);
    else free(p);
}

FdidInstance *fdid_instantiate(const FdidInstance *proto, size_t size, const char *fn) {
    size_t nbuf = fdid_buffer_size(&fdid_model), nname = strlen(proto->name) + 1;
    size_t nslope = 2 * (size_t)(fdid_model.n_axes + fdid_model.m);   /* derivatives, then held values */
    FdidInstance *I = (FdidInstance *)fdid_alloc(proto, 1, size);
    double *buf = (double *)fdid_alloc(proto, nbuf ? nbuf : 1, sizeof(double));
    double *slope = (double *)fdid_alloc(proto, nslope ? nslope : 1, sizeof(double));
    char *name = (char *)fdid_alloc(proto, nname, 1);
    if (!I || !buf || !slope || !name || !registry_add(I)) {
        fdid_free(proto, I);
        fdid_free(proto, buf);
        fdid_free(proto, slope);
        fdid_free(proto, name);
        fdid_log(proto, FDID_FATAL, FDID_CAT_FATAL, "%s: out of memory", fn);
        return NULL;
    }
    memcpy(I, proto, size);
    memcpy(name, proto->name, nname);
    memset(slope, 0, (nslope ? nslope : 1) * sizeof(double));
    I->slope = slope;
    I->coarse_noted = 0;
    I->name = name;
    I->mode = FDID_ST_INSTANTIATED;
    I->start_time = 0.0;
    fdid_state_bind(&I->s, &fdid_model, buf);
    fdid_state_defaults(&I->s);
    return I;
}

void fdid_free_instance(FdidInstance *I, const char *fn) {
    FdidInstance copy;
    /* NULL, an instance freed before, or a pointer that never was one: nothing to free, and
     * nothing may be read through it (not even a logger) */
    if (!I || !registry_remove(I)) return;
    fdid_log(I, FDID_OK, FDID_CAT_CALLS, "%s", fn);
    copy = *I; /* the memory functions, for freeing I itself */
    fdid_free(I, I->s.buf);
    fdid_free(I, I->slope);
    fdid_free(I, I->name);
    fdid_free(&copy, I);
}

/* ------------------------------------------------------------------ state machine */
int fdid_setup_experiment(FdidInstance *I, const char *fn, double start_time, int stop_defined, double stop_time) {
    if (!fdid_is_finite(start_time)) return fdid_fail(I, "%s: start time is not finite", fn);
    if (stop_defined && !(fdid_is_finite(stop_time) && stop_time >= start_time))
        return fdid_fail(I, "%s: stop time %g s must be finite and not before the start time %g s", fn, stop_time,
                         start_time);
    I->start_time = start_time;
    I->stop_defined = stop_defined != 0;
    I->stop_time = stop_defined ? stop_time : 0.0;
    return FDID_OK;
}

void fdid_enter_initialization(FdidInstance *I) {
    I->mode = FDID_ST_INIT;
    I->s.f.init_dirty = 1;
}

void fdid_exit_initialization(FdidInstance *I) {
    fdid_initialize(&I->s); /* steady ramp from the inputs and parameters set so far */
    I->mode = FDID_ST_STEP;
}

void fdid_terminate(FdidInstance *I) { I->mode = FDID_ST_TERMINATED; }

void fdid_reset(FdidInstance *I) {
    memset(I->slope, 0, (size_t)(fdid_model.n_axes + fdid_model.m) * sizeof(double));
    fdid_state_defaults(&I->s);
    I->start_time = 0.0;
    I->stop_defined = 0;
    I->mode = FDID_ST_INSTANTIATED;
}

double fdid_time(const FdidInstance *I) {
    return I->start_time + (double)I->s.f.steps * fdid_model.Ts;
}

/* ------------------------------------------------------------------ get / set */
static const FdidVar *lookup(FdidInstance *I, const char *fn, unsigned vr, int type) {
    const FdidVar *v;
    /* value references FDID_FIRST_VR ... FDID_FIRST_VR + n_vars - 1 name the variable table in
     * order (fmu/layout.py, FIRST_VR) */
    if (vr < FDID_FIRST_VR || vr - FDID_FIRST_VR >= (unsigned)fdid_model.n_vars) {
        fdid_fail(I, "%s: unknown value reference %u (the model's variables have value references %u to %u)", fn,
                  vr, (unsigned)FDID_FIRST_VR, (unsigned)FDID_FIRST_VR + (unsigned)fdid_model.n_vars - 1u);
        return NULL;
    }
    v = &fdid_model.vars[vr - FDID_FIRST_VR];
    if (v->type != type) {
        fdid_fail(I, "%s: value reference %u (%s) is not of this type", fn, vr, v->name);
        return NULL;
    }
    return v;
}

/* checks and stores one value; returns 0 after logging when refused */
static int set_value(FdidInstance *I, const char *fn, const FdidVar *v, double x) {
    FdidState *S = &I->s;
    int a = v->index;
    if (!fdid_is_finite(x)) {
        fdid_fail(I, "%s: %s must be finite, got a NaN or infinite value", fn, v->name);
        return 0;
    }
    switch (v->role) {
    case FDID_V_CMD: S->cmd[a] = x; break;
    case FDID_V_EXT: S->ext[a] = x; break;
    case FDID_P_LEVEL:
        if (x < 0.0) {
            fdid_fail(I, "%s: %s must be >= 0, got %g", fn, v->name, x);
            return 0;
        }
        S->level[a] = x;
        break;
    case FDID_P_VTILDE:
        if (!(x > 0.0)) {
            fdid_fail(I, "%s: %s must be > 0 mm/s, got %g", fn, v->name, x);
            return 0;
        }
        S->vtilde[a] = x;
        break;
    case FDID_P_ON: S->on[a] = x != 0.0 ? 1.0 : 0.0; break;
    case FDID_P_V0:
        if (I->mode == FDID_ST_STEP || I->mode == FDID_ST_TERMINATED) {
            fdid_fail(I, "%s: %s is a fixed parameter; set it before %sExitInitializationMode", fn, v->name,
                      I->api->prefix);
            return 0;
        }
        S->v0[a] = x;
        break;
    default:
        fdid_fail(I, "%s: %s is an output or local variable and cannot be set", fn, v->name);
        return 0;
    }
    /* before the first step, inputs and parameters define the initial state */
    if (!S->f.started) S->f.init_dirty = 1;
    S->f.out_dirty = 1;
    return 1;
}

/* refuses (after logging) a v_tilde the friction solve cannot resolve at the level set
 * (fdid_unresolved_friction): checked where the solve runs, not when either is set, so that a
 * master may set level and v_tilde in either order */
static int friction_resolved(FdidInstance *I, const char *fn) {
    int a = fdid_unresolved_friction(&I->s), i;
    const char *name = "v_tilde";
    if (a < 0) return 1;
    for (i = 0; i < fdid_model.n_vars; i++)
        if (fdid_model.vars[i].role == FDID_P_VTILDE && fdid_model.vars[i].index == a) name = fdid_model.vars[i].name;
    fdid_fail(I, "%s: %s = %g mm/s is below %g mm/s, the least the friction solve of this model resolves "
                 "at friction level %g (below it the friction exceeds its level and the outputs grow without "
                 "bound): raise it or lower the level", fn, name, I->s.vtilde[a],
              I->s.level[a] * fdid_model.axis_vtilde_floor[a], I->s.level[a]);
    return 0;
}

int fdid_get_real(FdidInstance *I, const char *fn, unsigned vr, double *value) {
    const FdidVar *v = lookup(I, fn, vr, FDID_T_REAL);
    if (!v) return 0;
    if (v->role >= FDID_V_POS && v->role <= FDID_V_U && !friction_resolved(I, fn)) return 0;
    *value = fdid_var_value(&I->s, v);
    if (!fdid_is_finite(*value)) {     /* a diverged model or a forged state: never a value with OK */
        fdid_fail(I, "%s: %s is not finite (the model diverged or its state is corrupt)", fn, v->name);
        return 0;
    }
    return 1;
}

int fdid_get_boolean(FdidInstance *I, const char *fn, unsigned vr, int *value) {
    const FdidVar *v = lookup(I, fn, vr, FDID_T_BOOLEAN);
    if (!v) return 0;
    *value = fdid_var_value(&I->s, v) != 0.0;
    return 1;
}

/* where the derivative of an input variable is kept (NULL for other variables) */
static double *slope_of(FdidInstance *I, const FdidVar *v) {
    if (v->role == FDID_V_CMD) return &I->slope[v->index];
    if (v->role == FDID_V_EXT) return &I->slope[fdid_model.n_axes + v->index];
    return NULL;
}

int fdid_is_input(unsigned vr) {
    const FdidVar *v;
    if (vr < FDID_FIRST_VR || vr - FDID_FIRST_VR >= (unsigned)fdid_model.n_vars) return 0;
    v = &fdid_model.vars[vr - FDID_FIRST_VR];
    return v->role == FDID_V_CMD || v->role == FDID_V_EXT;
}

int fdid_set_real(FdidInstance *I, const char *fn, unsigned vr, double value) {
    const FdidVar *v = lookup(I, fn, vr, FDID_T_REAL);
    double *slope;
    if (!v) return 0;
    if (I->mode == FDID_ST_UPDATE && v->role != FDID_V_CMD && v->role != FDID_V_EXT) {
        fdid_fail(I, "%s: %s cannot be set in intermediate update mode (inputs only)", fn, v->name);
        return 0;
    }
    if (!set_value(I, fn, v, value)) return 0;
    /* a derivative belongs to the value it was set with, at the start of a communication step
     * (FMI 2.0.4 section 4.2.1): a new value without one is held */
    if ((slope = slope_of(I, v)) != NULL) *slope = 0.0;
    return 1;
}

int fdid_set_input_derivative(FdidInstance *I, const char *fn, unsigned vr, int order, double value) {
    const FdidVar *v = lookup(I, fn, vr, FDID_T_REAL);
    double *slope;
    if (!v) return 0;
    if ((slope = slope_of(I, v)) == NULL) {
        fdid_fail(I, "%s: %s is not an input (derivatives can be set for inputs only)", fn, v->name);
        return 0;
    }
    if (order != 1) {
        fdid_fail(I, "%s: derivative of order %d of %s given; the FMU interpolates its inputs linearly "
                     "and takes first derivatives (order 1) only", fn, order, v->name);
        return 0;
    }
    if (!fdid_is_finite(value)) {
        fdid_fail(I, "%s: the derivative of %s must be finite, got a NaN or infinite value", fn, v->name);
        return 0;
    }
    *slope = value;
    return 1;
}

int fdid_set_boolean(FdidInstance *I, const char *fn, unsigned vr, int value) {
    const FdidVar *v = lookup(I, fn, vr, FDID_T_BOOLEAN);
    return v && set_value(I, fn, v, value ? 1.0 : 0.0);
}

/* ------------------------------------------------------------------ FMU state */
static size_t snapshot_bytes(void) {
    return sizeof(Snapshot) + fdid_buffer_size(&fdid_model) * sizeof(double);
}

/* 64-bit FNV-1a hash of the GUID: tells this model's FMU states from those of another fdid FMU
 * (another model, or the same model exported again) whose states have the same size */
static unsigned long long model_id(void) {
    unsigned long long h = 14695981039346656037ULL;
    const unsigned char *p;
    for (p = (const unsigned char *)fdid_model.guid; *p; p++) h = (h ^ *p) * 1099511628211ULL;
    return h;
}

static int snapshot_valid(const FdidInstance *I, const Snapshot *s) {
    return s && s->magic == I->api->snapshot_magic && s->nbuf == fdid_buffer_size(&fdid_model) &&
           s->model_id == model_id() && (s->mode & FDID_ANY_STATE);
}

static int is_flag(int x) { return x == 0 || x == 1; }

/* field-by-field check of a snapshot's content (a deserialized state comes from outside):
 * NULL when it is a state this FMU can be in, else what is wrong */
static const char *snapshot_content_error(const Snapshot *s) {
    static const int modes[] = {FDID_ST_INSTANTIATED, FDID_ST_INIT, FDID_ST_STEP, FDID_ST_TERMINATED,
                                FDID_ST_ERROR};
    const double *buf = (const double *)((const char *)s + sizeof(Snapshot));
    FdidState view;
    size_t i;
    int k, mode_ok = 0, a;
    for (k = 0; k < (int)(sizeof modes / sizeof modes[0]); k++)
        if (s->mode == modes[k]) mode_ok = 1;
    if (!mode_ok) return "the instance state word is not one state of the FMI state machine";
    if (!fdid_is_finite(s->start_time)) return "the start time is not finite";
    if (s->flags.steps < 0 || s->flags.steps > FDID_MAX_TOTAL_STEPS) return "the step counter is out of range";
    if (!fdid_is_finite(s->start_time + (double)s->flags.steps * fdid_model.Ts))
        return "the FMU time is not finite";
    if (!is_flag(s->flags.init_dirty) || !is_flag(s->flags.out_dirty) || !is_flag(s->flags.started))
        return "a flag is neither 0 nor 1";
    /* what the FMU itself can produce: steps are only counted by doStep (which sets started),
     * the initial state is only recomputed before the first doStep, and there is no doStep
     * before ExitInitializationMode. Otherwise the next output evaluation would re-initialize
     * and set the FMU time back to the start time while the master's time runs on. */
    if (!s->flags.started && s->flags.steps != 0) return "steps are counted but no doStep was taken";
    if (s->flags.started && s->flags.init_dirty) return "the initial state is to be recomputed after a doStep";
    if (s->flags.started && (s->mode == FDID_ST_INSTANTIATED || s->mode == FDID_ST_INIT))
        return "a doStep was taken before initialization ended";
    for (i = 0; i < s->nbuf; i++)
        if (!fdid_is_finite(buf[i])) return "a state variable is NaN or infinite";
    /* the views only read here */
    fdid_state_bind(&view, &fdid_model, (double *)buf);
    for (a = 0; a < fdid_model.n_axes; a++) {
        if (view.level[a] < 0.0) return "a friction level is negative";
        if (!(view.vtilde[a] > 0.0)) return "a friction transition velocity is not positive";
        if (view.on[a] != 0.0 && view.on[a] != 1.0) return "a friction switch is neither 0 nor 1";
    }
    return NULL;
}

int fdid_get_state(FdidInstance *I, const char *fn, void **state) {
    Snapshot *s;
    if (!state) return fdid_fail(I, "%s: NULL argument", fn);
    s = (Snapshot *)*state;
    if (s && !snapshot_valid(I, s)) return fdid_fail(I, "%s: *%s is not a state of this FMU", fn, I->api->state_arg);
    if (!s) {
        s = (Snapshot *)fdid_alloc(I, 1, snapshot_bytes());
        if (!s) return fdid_fail(I, "%s: out of memory", fn);
    }
    s->magic = I->api->snapshot_magic;
    s->mode = I->mode;
    s->start_time = I->start_time;
    s->flags = I->s.f;
    s->nbuf = I->s.nbuf;
    s->model_id = model_id();
    memcpy((char *)s + sizeof(Snapshot), I->s.buf, I->s.nbuf * sizeof(double));
    *state = s;
    return FDID_OK;
}

int fdid_set_state(FdidInstance *I, const char *fn, const void *state) {
    const Snapshot *s = (const Snapshot *)state;
    const char *why;
    if (!snapshot_valid(I, s)) return fdid_fail(I, "%s: not a state of this FMU", fn);
    if ((why = snapshot_content_error(s)) != NULL) return fdid_fail(I, "%s: corrupt state: %s", fn, why);
    I->mode = s->mode;
    I->start_time = s->start_time;
    I->s.f = s->flags;
    memcpy(I->s.buf, (const char *)s + sizeof(Snapshot), I->s.nbuf * sizeof(double));
    return FDID_OK;
}

int fdid_free_state(FdidInstance *I, const char *fn, void **state) {
    (void)fn;
    if (!state) return FDID_OK;   /* "If a null pointer is provided, the call is ignored." */
    fdid_free(I, *state);
    *state = NULL;
    return FDID_OK;
}

int fdid_serialized_size(FdidInstance *I, const char *fn, const void *state, size_t *size) {
    if (!size) return fdid_fail(I, "%s: NULL argument", fn);
    if (!snapshot_valid(I, (const Snapshot *)state)) return fdid_fail(I, "%s: not a state of this FMU", fn);
    *size = GUID_BYTES + snapshot_bytes();
    return FDID_OK;
}

int fdid_serialize(FdidInstance *I, const char *fn, const void *state, void *bytes, size_t size) {
    unsigned char *out = (unsigned char *)bytes;
    if (!out) return fdid_fail(I, "%s: NULL argument", fn);
    if (!snapshot_valid(I, (const Snapshot *)state)) return fdid_fail(I, "%s: not a state of this FMU", fn);
    if (size < GUID_BYTES + snapshot_bytes())
        return fdid_fail(I, "%s: buffer of %lu bytes is too small (%lu needed)", fn, (unsigned long)size,
                         (unsigned long)(GUID_BYTES + snapshot_bytes()));
    memset(out, 0, GUID_BYTES);
    strncpy((char *)out, fdid_model.guid, GUID_BYTES - 1);
    memcpy(out + GUID_BYTES, state, snapshot_bytes());
    return FDID_OK;
}

int fdid_deserialize(FdidInstance *I, const char *fn, const void *bytes, size_t size, void **state) {
    const unsigned char *in = (const unsigned char *)bytes;
    Snapshot *s;
    char guid[GUID_BYTES];
    if (!in || !state) return fdid_fail(I, "%s: NULL argument", fn);
    if (size != GUID_BYTES + snapshot_bytes())
        return fdid_fail(I, "%s: %lu bytes given, a state of this FMU has %lu", fn, (unsigned long)size,
                         (unsigned long)(GUID_BYTES + snapshot_bytes()));
    memcpy(guid, in, GUID_BYTES);
    guid[GUID_BYTES - 1] = '\0';
    if (strcmp(guid, fdid_model.guid) != 0) {
        size_t i;
        /* the bytes come from outside: only printable ASCII reaches the master's log */
        for (i = 0; guid[i]; i++)
            if ((unsigned char)guid[i] < 32 || (unsigned char)guid[i] > 126) guid[i] = '?';
        return fdid_fail(I, "%s: the state belongs to another FMU (GUID %s)", fn, guid);
    }
    s = (Snapshot *)*state;
    if (s && !snapshot_valid(I, s)) return fdid_fail(I, "%s: *%s is not a state of this FMU", fn, I->api->state_arg);
    if (!s) {
        s = (Snapshot *)fdid_alloc(I, 1, snapshot_bytes());
        if (!s) return fdid_fail(I, "%s: out of memory", fn);
    }
    {
        /* checked in a scratch copy first: a refused state leaves *state as it was */
        Snapshot *chk = (Snapshot *)fdid_alloc(I, 1, snapshot_bytes());
        const char *why;
        if (!chk) {
            if (!*state) fdid_free(I, s);
            return fdid_fail(I, "%s: out of memory", fn);
        }
        memcpy(chk, in + GUID_BYTES, snapshot_bytes());
        why = snapshot_valid(I, chk) ? snapshot_content_error(chk) : "not a state of this FMU";
        if (why) {
            fdid_free(I, chk);
            if (!*state) fdid_free(I, s);
            return fdid_fail(I, "%s: corrupt state: %s", fn, why);
        }
        memcpy(s, chk, snapshot_bytes());
        fdid_free(I, chk);
    }
    *state = s;
    return FDID_OK;
}

/* ------------------------------------------------------------------ co-simulation */
static double absd(double x) { return x < 0.0 ? -x : x; }

/* 1 when every x[i] is finite. IEEE 754: a double is inf or NaN exactly when its 11 exponent
 * bits are all ones; adding 1 to that field then carries into bit 63. Integer operations without a
 * branch or a loop-carried floating-point dependency. */
static int all_finite(const double *x, size_t n) {
    const unsigned long long EXP = 0x7ff0000000000000ULL, ONE = 0x0010000000000000ULL;
    unsigned long long bad = 0, bits;
    size_t i;
    for (i = 0; i < n; i++) {
        memcpy(&bits, &x[i], sizeof bits);
        bad |= (bits & EXP) + ONE;
    }
    return (bad >> 63) == 0;
}

/* how far a master's time may be off the sample grid at time t: a millionth of a sample, plus
 * the rounding of grid times computed in doubles (relative 1e-9, at most a hundredth of a
 * sample: an off-grid step is refused at any t) */
static double grid_tolerance(double t) {
    double rounding = 1e-9 * absd(t), cap = 1e-2 * fdid_model.Ts;
    return 1e-6 * fdid_model.Ts + (rounding < cap ? rounding : cap);
}

/* the internal steps of one doStep: inputs held, or set by the master before each sample after
 * the first (FMI 3 intermediate update, I->between_samples), or moved along the derivatives set
 * for this step (FMI 2: sample j of the step gets u + j Ts du/dt). The values set at the start
 * of the step are what the FMU holds afterwards, and the derivatives are used up. */
static int advance_inputs(FdidInstance *I, const char *fn, double h, long long nsteps) {
    FdidState *S = &I->s;
    int na = fdid_model.n_axes, m = fdid_model.m, a, i, sloped = 0;
    double *held;
    long long k;
    for (i = 0; i < na + m; i++) sloped |= I->slope[i] != 0.0;
    if (nsteps > 1 && !I->coarse_noted && !I->between_samples) {
        I->coarse_noted = 1;
        fdid_log(I, FDID_WARNING, FDID_CAT_NOTE,
                 "%s: communication step %.6g s = %lld samples of Ts = %.6g s: each input is held for %lld "
                 "samples%s; step at %.6g s to feed every sample (this note is given once)", fn, h, nsteps,
                 fdid_model.Ts, nsteps,
                 I->api->input_derivatives ? " unless its derivative is set (fmi2SetRealInputDerivatives: "
                                             "then it follows that slope within the step)" : "",
                 fdid_model.Ts);
    }
    if (I->between_samples && nsteps > 1) {
        /* the master sets the inputs of each sample of the step (FMI 3 intermediate update) */
        held = I->slope + na + m;
        for (a = 0; a < na; a++) held[a] = S->cmd[a];
        for (i = 0; i < m; i++) held[na + i] = S->ext[i];
        for (k = 0; k < nsteps; k++) {
            if (k > 0) {
                double t = I->start_time + (double)S->f.steps * fdid_model.Ts;
                S->f.started = 1;       /* inputs set now belong to this sample, not to the start */
                I->mode = FDID_ST_UPDATE;
                I->between_samples(I, t);
                if (I->mode != FDID_ST_UPDATE) return FDID_ERROR;   /* a refused set: logged there */
                I->mode = FDID_ST_STEP;
                S->f.out_dirty = 1;
            }
            fdid_advance(S);
        }
        for (a = 0; a < na; a++) S->cmd[a] = held[a];
        for (i = 0; i < m; i++) S->ext[i] = held[na + i];
        S->f.out_dirty = 1;
        return FDID_OK;
    }
    if (!sloped) {
        for (k = 0; k < nsteps; k++) fdid_advance(S);
        return FDID_OK;
    }
    held = I->slope + na + m;
    for (a = 0; a < na; a++) held[a] = S->cmd[a];
    for (i = 0; i < m; i++) held[na + i] = S->ext[i];
    for (k = 0; k < nsteps; k++) {
        double dt = (double)k * fdid_model.Ts;
        if (k > 0) {
            for (a = 0; a < na; a++) S->cmd[a] = held[a] + dt * I->slope[a];
            for (i = 0; i < m; i++)
                if (fdid_model.inputs[i].kind == FDID_IN_EXTERNAL) S->ext[i] = held[na + i] + dt * I->slope[na + i];
            S->f.out_dirty = 1;
        }
        fdid_advance(S);
    }
    for (a = 0; a < na; a++) S->cmd[a] = held[a];
    for (i = 0; i < m; i++) S->ext[i] = held[na + i];
    for (i = 0; i < na + m; i++) I->slope[i] = 0.0;
    S->f.out_dirty = 1;
    return FDID_OK;
}

int fdid_do_step(FdidInstance *I, const char *fn, double t_comm, double h) {
    double Ts = fdid_model.Ts, t = fdid_time(I), t_end, q, off;
    long long nsteps;
    if (!fdid_is_finite(h) || !(h > 0.0))
        return fdid_fail(I, "%s: communication step size must be a positive number, got %g s", fn, h);
    if (!fdid_is_finite(t_comm)) return fdid_fail(I, "%s: currentCommunicationPoint is not finite", fn);
    if (absd(t_comm - t) > grid_tolerance(t))
        return fdid_fail(I, "%s: currentCommunicationPoint %.17g s differs from the FMU time %.17g s", fn, t_comm,
                         t);
    /* the step ends on the sample grid start + n Ts, n taken from the END time: masters compute
     * h = t_next - t_comm from grid times, whose rounding grows with |t|, not with h */
    t_end = t_comm + h;
    q = (t_end - I->start_time) / Ts;   /* the sample index the step ends on */
    if (!(q > 0.0 && q < (double)FDID_MAX_TOTAL_STEPS))
        return fdid_fail(I, "%s: the step would end at %.17g s, outside the FMU's time range (%.0f samples "
                            "of Ts = %g s from the start time %.17g s)", fn, t_end, (double)FDID_MAX_TOTAL_STEPS,
                         Ts, I->start_time);
    nsteps = (long long)(q + 0.5) - I->s.f.steps;
    off = t_end - (I->start_time + (double)(I->s.f.steps + nsteps) * Ts);
    /* a step that ends on the sample the FMU is at: the sliver a master whose clock adds up its
     * steps takes to reach its stop time (3.049 s - 3.0489999999997752 s = 2.2e-13 s) */
    if (nsteps == 0 && absd(off) <= grid_tolerance(t_end)) return FDID_OK;
    if (nsteps < 1 || absd(off) > grid_tolerance(t_end)) {
        /* a whole number of samples from a point that is off the FMU's time: a master whose clock
         * adds up its steps (t += h) drifts by their rounding, which grows with |t| */
        double n_h = (double)(long long)(h / Ts + 0.5);
        if (n_h >= 1.0 && absd(h - n_h * Ts) <= grid_tolerance(t_end))
            return fdid_fail(I, "%s: currentCommunicationPoint %.17g s is %.3g s %s the FMU time %.17g s, so "
                                "the step of %.0f sample(s) would end %.3g s %s the nearest sample time: the "
                                "master's clock has drifted (compute it as start time + n h, not by adding "
                                "steps)", fn, t_comm, absd(t_comm - t), t_comm < t ? "before" : "after", t, n_h,
                             absd(off), off < 0.0 ? "before" : "after");
        return fdid_fail(I, "%s: communication step size %.17g s is not an integer multiple of the "
                            "model sample time Ts = %.17g s (the step would end %.3g s %s the nearest sample "
                            "time)", fn, h, Ts, absd(off), off < 0.0 ? "before" : "after");
    }
    if (nsteps > FDID_MAX_STEPS_PER_DOSTEP)
        return fdid_fail(I, "%s: communication step size %g s would take %.0f internal steps of Ts = %g s; "
                            "at most %.0f are allowed in one doStep (use smaller communication steps)",
                         fn, h, (double)nsteps, Ts, (double)FDID_MAX_STEPS_PER_DOSTEP);
    if (I->stop_defined && t_end > I->stop_time + grid_tolerance(t_end))
        return fdid_fail(I, "%s: the step would end at %.17g s, past the stop time %.17g s", fn, t_end,
                         I->stop_time);
    if (!friction_resolved(I, fn)) return FDID_ERROR;     /* logged there */
    if (advance_inputs(I, fn, h, nsteps) != FDID_OK) return FDID_ERROR;
    I->s.f.started = 1;
    /* a step that leaves the model's state non-finite failed: report it here, not first at a
     * later fmi*Get (a master that reads other outputs, or none, would go on with OK), and never
     * hand out an FMU state (GetFMUstate) that SetFMUstate refuses. The values a step writes are
     * checked (the rest of the buffer: checked inputs and parameters, their initial-state maps,
     * which reach y, and scratch copies of these); the whole buffer took 20 ns more per doStep. */
    {
        const FdidState *S = &I->s;
        size_t n = (size_t)fdid_model.n, m = (size_t)fdid_model.m, p = (size_t)fdid_model.p,
               a = (size_t)fdid_model.n_axes;
        if (!(all_finite(S->xi, n) & all_finite(S->u, m) & all_finite(S->y, p) & all_finite(S->vel, a) &
              all_finite(S->x_prev, a) & all_finite(S->v_prev, a)))
            return fdid_fail(I, "%s: the model state is not finite after the step to %.17g s (the inputs or "
                                "parameters drive the model out of the range of doubles); restore "
                                "an earlier FMU state or reset", fn, fdid_time(I));
    }
    return FDID_OK;
}
