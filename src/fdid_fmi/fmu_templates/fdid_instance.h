/* fdid_instance.h -- the instance bookkeeping of an fdid-fmi FMU, independent of the FMI version.
 *
 * Written once for FMI 2.0 and FMI 3.0 (like the modelica Reference-FMUs' cosimulation.c):
 * the state machine, logging categories, value-reference lookup and the checks on set values,
 * FMU state snapshots and their serialized form, memory, time and the step-size checks of
 * doStep. fmi2Functions.c and fmi3Functions.c keep only the API wrappers (types, signatures,
 * callbacks, the logger glue) and call these with plain C types:
 *   - status codes are ints with the values of fmi2Status / fmi3Status (OK ... Fatal);
 *   - value references are unsigned;
 *   - `fn` is the name of the FMI function being served (it prefixes every message).
 * Any refused call logs an error (category logStatusError) and puts the instance in the error
 * state, left by SetFMUstate or Reset.
 *
 * A wrapper's instance struct starts with an FdidInstance (first member), followed by what
 * the FMI version needs (the master's callbacks); `FdidApi.emit` gets the whole struct back.
 */
#ifndef FDID_INSTANCE_H
#define FDID_INSTANCE_H

#include <stddef.h>

#include "fdid_model.h"

/* status codes: the values of fmi2Status and fmi3Status */
enum { FDID_OK = 0, FDID_WARNING = 1, FDID_DISCARD = 2, FDID_ERROR = 3, FDID_FATAL = 4 };

/* instance states (bit masks, FMI 2.0.4 section 4.2.4 / FMI 3.0 section 4.2.1) */
enum {
    FDID_ST_INSTANTIATED = 1, FDID_ST_INIT = 2, FDID_ST_STEP = 4, FDID_ST_TERMINATED = 8,
    FDID_ST_ERROR = 16, FDID_ST_FATAL = 32,
    FDID_ST_UPDATE = 64   /* FMI 3 intermediate update mode, inside doStep: only inputs may be set */
};
#define FDID_ANY_STATE (FDID_ST_INSTANTIATED | FDID_ST_INIT | FDID_ST_STEP | FDID_ST_TERMINATED | FDID_ST_ERROR)
#define FDID_GET_STATES (FDID_ST_INIT | FDID_ST_STEP | FDID_ST_TERMINATED | FDID_ST_ERROR)
/* FMI 3.0 also allows getting (start) values in the instantiated state (section 4.2.1) */
#define FDID_GET_STATES_FMI3 (FDID_GET_STATES | FDID_ST_INSTANTIATED)
#define FDID_SET_STATES (FDID_ST_INSTANTIATED | FDID_ST_INIT | FDID_ST_STEP)

/* log categories (declared in modelDescription.xml). FDID_CAT_NOTE is logged under the name
 * logStatusWarning too (switched with it by SetDebugLogging) but starts on like the errors in
 * FMI 2: the one note on held inputs (fdid_do_step) reaches a master that did not ask for
 * debug logging */
enum { FDID_CAT_WARNING = 0, FDID_CAT_ERROR, FDID_CAT_FATAL, FDID_CAT_CALLS, FDID_CAT_NOTE, FDID_N_CAT };

typedef struct FdidInstance FdidInstance;

/* what differs between the FMI versions, one constant per wrapper file */
typedef struct {
    const char *prefix;          /* "fmi2" / "fmi3": names API functions in messages */
    const char *step_mode_name;  /* name of the step state in messages */
    const char *state_arg;       /* name of the FMU state argument in messages */
    unsigned snapshot_magic;     /* first word of an FMU state of this API */
    int accepts_log_all;         /* SetDebugLogging accepts the category "logAll" */
    int input_derivatives;       /* the API can set input derivatives (FMI 2 canInterpolateInputs) */
    /* passes one formatted message to the master's logger (if it gave one) */
    void (*emit)(const FdidInstance *I, int status, const char *category, const char *message);
} FdidApi;

struct FdidInstance {
    const FdidApi *api;
    void *(*allocate_memory)(size_t n, size_t size);  /* the master's (FMI 2), or NULL: calloc */
    void (*free_memory)(void *p);                     /* the master's (FMI 2), or NULL: free */
    char *name;
    int log_on[FDID_N_CAT];
    int mode;                                         /* FDID_ST_* */
    double start_time;                                /* s */
    int stop_defined;                                 /* the master gave a stop time */
    double stop_time;                                 /* s; doStep may not pass it */
    double *slope;        /* input derivatives (FMI 2 SetRealInputDerivatives), per unit of
                             time: n_axes commands then m model inputs (external ones used);
                             used by the next doStep only */
    int coarse_noted;     /* the note on coarse steps was logged (once per instance) */
    /* FMI 3 intermediate update: when set, called (in FDID_ST_UPDATE) before each internal
     * sample of a doStep after its first, with that sample's time, so that the master can set
     * the inputs of that sample */
    void (*between_samples)(FdidInstance *I, double t);
    FdidState s;
};

/* logging: `fmt` is a printf format; fdid_fail logs an error, enters the error state and
 * returns FDID_ERROR */
void fdid_log(const FdidInstance *I, int status, int cat, const char *fmt, ...);
int fdid_fail(FdidInstance *I, const char *fmt, ...);
/* start of every API call on an instance: 0 for NULL or a pointer that is not a live instance
 * of this FMU (freed, or never returned by Instantiate: nothing is read through it); logs the
 * call (logCalls); 0 after logging when the current state is not in `mask` */
int fdid_begin(FdidInstance *I, const char *fn, int mask);
int fdid_set_debug_logging(FdidInstance *I, const char *fn, int on, size_t n, const char *const categories[]);

/* 1 when I is an instance returned by Instantiate and not yet freed (a registry of live
 * instances, shared by FMI 2 and FMI 3, guarded by a lock) */
int fdid_live(const FdidInstance *I);

/* life cycle. `proto` is the start of a wrapper instance of `size` bytes with api, memory
 * functions, callbacks, log switches and name set; returns a copy owning its buffers (the
 * name copied), or NULL after logging */
FdidInstance *fdid_instantiate(const FdidInstance *proto, size_t size, const char *fn);
void fdid_free_instance(FdidInstance *I, const char *fn);
void *fdid_alloc(const FdidInstance *I, size_t n, size_t size);
void fdid_free(const FdidInstance *I, void *p);
/* start time, and the stop time doStep may not pass (when stop_defined) */
int fdid_setup_experiment(FdidInstance *I, const char *fn, double start_time, int stop_defined, double stop_time);
void fdid_enter_initialization(FdidInstance *I);
void fdid_exit_initialization(FdidInstance *I);
void fdid_terminate(FdidInstance *I);
void fdid_reset(FdidInstance *I);
double fdid_time(const FdidInstance *I);

/* one value; 1 on success, 0 after logging (unknown reference, wrong type, refused value) */
int fdid_get_real(FdidInstance *I, const char *fn, unsigned vr, double *value);
int fdid_get_boolean(FdidInstance *I, const char *fn, unsigned vr, int *value);
int fdid_set_real(FdidInstance *I, const char *fn, unsigned vr, double value);
int fdid_set_boolean(FdidInstance *I, const char *fn, unsigned vr, int value);

/* FMU states (snapshots) and their serialized form: GUID (64 bytes) then the snapshot */
int fdid_get_state(FdidInstance *I, const char *fn, void **state);
int fdid_set_state(FdidInstance *I, const char *fn, const void *state);
int fdid_free_state(FdidInstance *I, const char *fn, void **state);
int fdid_serialized_size(FdidInstance *I, const char *fn, const void *state, size_t *size);
int fdid_serialize(FdidInstance *I, const char *fn, const void *state, void *bytes, size_t size);
int fdid_deserialize(FdidInstance *I, const char *fn, const void *bytes, size_t size, void **state);

/* 1 when vr names an input variable (commanded position or external input) */
int fdid_is_input(unsigned vr);

/* first derivative (order 1) of an input for the next doStep; 1 on success, 0 after logging */
int fdid_set_input_derivative(FdidInstance *I, const char *fn, unsigned vr, int order, double value);

/* co-simulation step from `t` over `h` seconds: h an integer multiple of Ts, t the FMU time
 * (both within the grid tolerance); a step that ends on the current sample is a no-op */
int fdid_do_step(FdidInstance *I, const char *fn, double t, double h);

#endif
