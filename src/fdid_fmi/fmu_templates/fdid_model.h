/* fdid_model.h -- model-independent types and the simulation core of an fdid-fmi FMU.
 *
 * The FMU is split like the modelica Reference-FMUs: FMI plumbing written once
 * (fdid_instance.c, wrapped by fmi2Functions.c and fmi3Functions.c), the simulation
 * semantics written once (fdid_core.c), and one generated file per model (model_data.c)
 * holding the matrices, the port table and the variable table as constant data.
 *
 * Semantics: exactly those of fdid_fmi.simulate (the numpy reference simulator):
 *   offsets     commands enter as deviations from their value at initialisation, u_ref;
 *               the d.c. response G1 u_ref is added to the outputs (G1 = C (I-A)^-1 B + D);
 *   start       steady state of a ramp at the axis start velocity v0:
 *               xi0 = S u0 - S2 du, du = v0 Ts on the command inputs, friction inputs at
 *               L sat(v0 / v_tilde), play inputs slid through, sign(v0), with
 *               h = x[-1] - b sign(v0); x[-1] = x[0] - v0 Ts; v[-1] = v0;
 *   step k      feature inputs from the previous step's velocity / position (the play feature
 *               from its operator state h, updated with each new position); friction inputs
 *               d = L sat(v / v_tilde) solved exactly with stiction (v = alpha + beta d is
 *               affine in d: branches stick (v = 0, |d| <= L) / linear / +1 / -1 per friction
 *               input, in that order, the first consistent one wins); with z = [xi; u],
 *               y = [C D] z + G1 u_ref (the friction part of D u added after the solve) and
 *               xi <- [A B] z. Position-type outputs have no D from commands (causal).
 *   sums        each matrix-vector product left to right along the row, plain IEEE products
 *               (no fused multiply-add).
 * The velocity of an axis is its model velocity output, or the backward difference
 * (x[k] - x[k-1]) / Ts of its position output when the model has none.
 *
 * C99, no global mutable state: every instance owns its FdidState. libm is used only when
 * FDID_USE_LIBM is 1 (models with sin/cos/stribeck/play_stribeck feature inputs), see model_data.h.
 */
#ifndef FDID_MODEL_H
#define FDID_MODEL_H

#include <stddef.h>

#define FDID_MAX_FRICTION 4

/* input kinds (model.INPUT_KINDS) */
enum { FDID_IN_COMMAND = 0, FDID_IN_EXTERNAL = 1, FDID_IN_FRICTION = 2, FDID_IN_FEATURE = 3 };
/* feature functions (model.FEATURE_FUNCTIONS) */
enum { FDID_F_SAT = 0, FDID_F_ABS_SAT = 1, FDID_F_STRIBECK = 2, FDID_F_SIN_POSITION = 3,
       FDID_F_COS_POSITION = 4, FDID_F_PLAY = 5, FDID_F_PLAY_STRIBECK = 6 };
/* FMI variable types */
enum { FDID_T_REAL = 0, FDID_T_BOOLEAN = 1 };
/* roles of FMI variables; `index` is an axis index or a model port index as noted */
enum {
    FDID_V_CMD = 0,     /* input  <axis>_x_cmd, index = axis                                   */
    FDID_V_EXT,         /* input  external model input, index = model input                    */
    FDID_V_POS,         /* output <axis>_x, index = axis                                       */
    FDID_V_VEL,         /* output <axis>_v, index = axis                                       */
    FDID_V_TOOL,        /* output <axis>_x_tool, index = axis                                  */
    FDID_V_Y,           /* output any other model output, index = model output                 */
    FDID_V_U,           /* local  applied friction / feature input value, index = model input  */
    FDID_P_LEVEL,       /* parameter <axis>_friction_level (tunable), index = axis             */
    FDID_P_VTILDE,      /* parameter <axis>_v_tilde [mm/s] (tunable), index = axis             */
    FDID_P_ON,          /* parameter <axis>_friction_on, Boolean (tunable), index = axis       */
    FDID_P_V0           /* parameter <axis>_v0 [mm/s] start velocity (fixed), index = axis     */
};

typedef struct {
    int kind;             /* FDID_IN_* */
    int axis;             /* axis index, -1 for none */
    int function;         /* feature: FDID_F_* */
    int source_position;  /* feature sin/cos: 1 = measured-position source, 0 = command */
    double v_tilde;       /* feature sat/abs_sat/stribeck: transition velocity, mm/s */
    double v_s;           /* feature stribeck / play_stribeck: Stribeck velocity, mm/s */
    double period_mm;     /* feature sin/cos: spatial period, mm */
    double width_mm;      /* feature play / play_stribeck: half-width b of the play operator, mm */
} FdidInput;

typedef struct {
    int type;             /* FDID_T_* */
    int role;             /* FDID_V_* / FDID_P_* */
    int index;
    const char *name;
} FdidVar;

/* A matrix's nonzero entries by row (compressed sparse rows): row i holds val[k] at column
 * col[k] for start[i] <= k < start[i + 1], columns ascending (fmu/layout.py: sparse_rows). */
typedef struct {
    const int *start;                 /* rows + 1 */
    const int *col;
    const double *val;
} FdidRows;

typedef struct {
    const char *model_identifier;
    const char *guid;
    double Ts;                        /* internal step, s */
    int n, m, p, n_axes;              /* states, model inputs, model outputs, axes */
    const double *C, *D;              /* row-major p*n, p*m (start and friction solve) */
    const double *S, *S2, *G1;        /* steady-state maps n*m, n*m, p*m */
    FdidRows AB_rows, CD_rows;        /* [A B] n*(n+m), [C D] p*(n+m) for the step */
    const FdidInput *inputs;          /* m */
    int n_fric;                       /* friction inputs, <= FDID_MAX_FRICTION */
    const int *fric_input;            /* model input index of each friction input */
    const int *fric_vel_output;       /* output giving its velocity (velocity or position) */
    const int *fric_vel_diff;         /* 1: backward difference of a position output */
    const int *axis_cmd_input;        /* per axis: command input index */
    const int *axis_pos_output;       /* per axis: position output index */
    const int *axis_err_output;       /* per axis: error output index or -1 (in-process runs only:
                                         no FMU variable) */
    const int *axis_vel_output;       /* per axis: velocity output index or -1 */
    const int *axis_tool_output;      /* per axis: tool_position output index or -1 */
    const double *axis_level0;        /* per axis: default friction level (0 if no friction) */
    const double *axis_vtilde0;       /* per axis: default v_tilde, mm/s (1 if no friction) */
    const double *axis_vtilde_floor;  /* per axis: least v_tilde per unit friction level, mm/s
                                         (0: any v_tilde > 0; model.vtilde_floor_per_level) */
    int n_vars;
    const FdidVar *vars;              /* value reference = FDID_FIRST_VR + position in this table */
} FdidModel;

/* Dynamic state of one instance; every double lives in `buf` so that FMU states are one copy.
 * Pointers below point into buf (see fdid_state_layout). */
typedef struct {
    long long steps;      /* internal steps taken since the start time */
    int init_dirty;       /* initial state must be (re)computed before use */
    int out_dirty;        /* outputs at the current time must be recomputed */
    int started;          /* a doStep has been taken */
} FdidFlags;

typedef struct {
    const FdidModel *M;
    FdidFlags f;
    size_t nbuf;
    double *buf;
    /* views into buf */
    double *xi, *x_prev, *v_prev, *cmd, *ext, *uref, *yoff, *u, *y, *vel;
    double *level, *vtilde, *on, *v0;
    double *hold;             /* per model input: the play operator's output h (play features) */
    double *work_n, *work_m;  /* scratch */
} FdidState;

size_t fdid_buffer_size(const FdidModel *M);
void fdid_state_bind(FdidState *S, const FdidModel *M, double *buf);
void fdid_state_defaults(FdidState *S);
void fdid_initialize(FdidState *S);
void fdid_outputs(FdidState *S);
void fdid_advance(FdidState *S);
double fdid_var_value(FdidState *S, const FdidVar *v);
int fdid_unresolved_friction(const FdidState *S);
void fdid_run(FdidState *S, long long N, const double *cmd, const double *ext, double *Y,
              double *U, double *V);
size_t fdid_sizeof_state(void);
size_t fdid_sizeof_model(void);
int fdid_is_finite(double x);

#endif
