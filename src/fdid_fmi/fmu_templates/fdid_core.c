/* fdid_core.c -- the simulation semantics of fdid_fmi.simulate, in C99.
 *
 * Written once for every model; the model enters only through the FdidModel constant data
 * generated in model_data.c. Each routine mirrors a block of fdid_fmi/simulate.py
 * (same operations in the same order, so that FMU and reference agree to rounding).
 */
#include "model_data.h"
#include "fdid_model.h"

#if FDID_USE_LIBM
#include <math.h>
#endif

#define FDID_TOL 1e-12
#define FDID_PI 3.141592653589793

int fdid_is_finite(double x) {
    /* x - x is 0 for finite x and NaN for inf / NaN (IEEE 754; no -ffast-math) */
    volatile double d = x - x;
    return d == 0.0;
}

static double fdid_sat(double x) {
    if (x > 1.0) return 1.0;
    if (x < -1.0) return -1.0;
    return x;
}

static double fdid_abs(double x) { return x < 0.0 ? -x : x; }

/* ------------------------------------------------------------------ layout */
size_t fdid_buffer_size(const FdidModel *M) {
    size_t n = (size_t)M->n, m = (size_t)M->m, p = (size_t)M->p, a = (size_t)M->n_axes;
    /* xi, u, x_prev, v_prev, cmd, ext, uref, yoff, y, vel, level, vtilde, on, v0, hold, work_n,
     * work_m */
    return n + m + a + a + a + m + m + p + p + a + a + a + a + a + m + n + m;
}

void fdid_state_bind(FdidState *S, const FdidModel *M, double *buf) {
    size_t n = (size_t)M->n, m = (size_t)M->m, p = (size_t)M->p, a = (size_t)M->n_axes;
    double *q = buf;
    S->M = M;
    S->buf = buf;
    S->nbuf = fdid_buffer_size(M);
    S->xi = q; q += n;
    S->u = q; q += m;     /* right after xi: the step multiplies z = [xi; u] */
    S->x_prev = q; q += a;
    S->v_prev = q; q += a;
    S->cmd = q; q += a;
    S->ext = q; q += m;
    S->uref = q; q += m;
    S->yoff = q; q += p;
    S->y = q; q += p;
    S->vel = q; q += a;
    S->level = q; q += a;
    S->vtilde = q; q += a;
    S->on = q; q += a;
    S->v0 = q; q += a;
    S->hold = q; q += m;
    S->work_n = q; q += n;
    S->work_m = q;
}

/* start values of inputs and parameters; the state is marked for initialisation */
void fdid_state_defaults(FdidState *S) {
    const FdidModel *M = S->M;
    size_t i;
    int a;
    for (i = 0; i < S->nbuf; i++) S->buf[i] = 0.0;
    for (a = 0; a < M->n_axes; a++) {
        S->level[a] = M->axis_level0[a];
        S->vtilde[a] = M->axis_vtilde0[a];
        S->on[a] = 1.0;
        S->v0[a] = 0.0;
    }
    S->f.steps = 0;
    S->f.init_dirty = 1;
    S->f.out_dirty = 1;
    S->f.started = 0;
}

/* -------------------------------------------------------------- building blocks */
/* Every matrix-vector product sums its terms left to right (res = 0; res += a_j b_j for
 * j = 0, 1, ...), with plain IEEE products (no FMA: -std=c99 implies -ffp-contract=off).
 * A term whose coefficient is zero adds an exact zero, so the per-step products run over the
 * nonzero terms only (FdidRows) and give the same doubles as the dense sum: the realisations
 * of drive models are sparse (a 9-state axis: 20 of 81 entries of A). */
#if defined(__GNUC__)
#define FDID_INLINE static inline __attribute__((always_inline))
#else
#define FDID_INLINE static inline
#endif

FDID_INLINE double fdid_dot(const double *a, const double *b, int n) {
    int i;
    double res = 0.0;
    for (i = 0; i < n; i++) res += a[i] * b[i];
    return res;
}

/* row i of a sparse matrix times v (the step's matrices act on z = [xi; u], which are adjacent
 * in the state buffer) */
FDID_INLINE double fdid_row_dot(const FdidRows *X, int i, const double *v) {
    int k, end = X->start[i + 1];
    double res = 0.0;
    for (k = X->start[i]; k < end; k++) res += X->val[k] * v[X->col[k]];
    return res;
}

/* out = X v (X row-major r x c) */
static void matvec(const double *X, int r, int c, const double *v, double *out) {
    int i;
    for (i = 0; i < r; i++) out[i] = fdid_dot(X + (size_t)i * (size_t)c, v, c);
}

/* effective friction level / v_tilde of friction input j (simulate._Plan) */
static double fric_level(const FdidState *S, int j) {
    int a = S->M->inputs[S->M->fric_input[j]].axis;
    return S->on[a] != 0.0 ? S->level[a] : 0.0;
}

static double fric_vtilde(const FdidState *S, int j) {
    return S->vtilde[S->M->inputs[S->M->fric_input[j]].axis];
}

/* a feature with a play operator's state h (model.PLAY_FUNCTIONS) */
static int is_play(const FdidInput *in) {
    return in->kind == FDID_IN_FEATURE
        && (in->function == FDID_F_PLAY || in->function == FDID_F_PLAY_STRIBECK);
}

static double sign_of(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

/* the play's value: exactly +-1 once slid through (h is then x_prev -+ b to the bit) */
static double play_value(const FdidInput *in, double x_prev, double h) {
    if (h <= x_prev - in->width_mm) return 1.0;
    if (h >= x_prev + in->width_mm) return -1.0;
    return (x_prev - h) / in->width_mm;
}

/* simulate.feature_value; h: the play operator's state of this input */
static double feature_value(const FdidInput *in, double v_prev, double x_cmd, double x_prev,
                            double h) {
    double s;
    switch (in->function) {
    case FDID_F_PLAY:
        return play_value(in, x_prev, h);
#if FDID_USE_LIBM
    case FDID_F_PLAY_STRIBECK: {
        double q = v_prev / in->v_s;
        return play_value(in, x_prev, h) * exp(-(q * q));
    }
    case FDID_F_SIN_POSITION:
    case FDID_F_COS_POSITION: {
        double x = in->source_position ? x_prev : x_cmd;
        double arg = 2.0 * FDID_PI * x / in->period_mm;
        return in->function == FDID_F_SIN_POSITION ? sin(arg) : cos(arg);
    }
#endif
    default:
        break;
    }
    s = fdid_sat(v_prev / in->v_tilde);
    if (in->function == FDID_F_SAT) return s;
    if (in->function == FDID_F_ABS_SAT) return fdid_abs(s);
#if FDID_USE_LIBM
    if (in->function == FDID_F_STRIBECK) {
        double q = v_prev / in->v_s;
        return s * exp(-(q * q));
    }
#endif
    (void)x_cmd;
    return 0.0; /* unreachable: the exporter sets FDID_USE_LIBM for these functions */
}

/* LU solve with partial pivoting (LAPACK dgesv); returns 0 when singular */
static int lu_solve(double *Mx, double *rhs, int k) {
    int c, r, j;
    for (c = 0; c < k; c++) {
        int piv = c;
        double best = fdid_abs(Mx[c * k + c]);
        for (r = c + 1; r < k; r++) {
            double v = fdid_abs(Mx[r * k + c]);
            if (v > best) { best = v; piv = r; }
        }
        if (Mx[piv * k + c] == 0.0) return 0;
        if (piv != c) {
            double t;
            for (j = 0; j < k; j++) { t = Mx[c * k + j]; Mx[c * k + j] = Mx[piv * k + j]; Mx[piv * k + j] = t; }
            t = rhs[c]; rhs[c] = rhs[piv]; rhs[piv] = t;
        }
        for (r = c + 1; r < k; r++) {
            double f = Mx[r * k + c] / Mx[c * k + c];
            for (j = c + 1; j < k; j++) Mx[r * k + j] -= f * Mx[c * k + j];
            rhs[r] -= f * rhs[c];
        }
    }
    for (r = k - 1; r >= 0; r--) {
        double s = rhs[r];
        for (j = r + 1; j < k; j++) s -= Mx[r * k + j] * rhs[j];
        rhs[r] = s / Mx[r * k + r];
    }
    return 1;
}

/* The friction inputs of one step, exactly: d_i = L_i sat(v_i / vt_i) with v = alpha + beta d
 * (alpha: velocity with the friction at zero; beta = dv/dd, from the feed-through D). Branches
 * per input, tried in this order (the last input varies fastest), the first consistent wins:
 *   stick   v_i = 0 with |d_i| <= L_i and beta_ii < 0: the friction holds the axis at rest
 *           (a sampled Coulomb model without this creeps through its viscous band);
 *   linear  |v_i| <= vt_i, d_i = L_i v_i / vt_i;   +1 / -1   d_i = +-L_i (sliding). */
enum { BR_STICK = 2, BR_LINEAR = 0 };
static const int branch_code[4] = {BR_STICK, BR_LINEAR, 1, -1};

static void solve_friction(int m, const double *alpha, const double *beta, const double *level,
                           const double *vt, double *d) {
    int br[FDID_MAX_FRICTION];
    int nb = 1, b, i, j;
    if (m == 1) {
        double L = level[0], v = vt[0], a = alpha[0], bb = beta[0], den;
        if (L == 0.0) { d[0] = 0.0; return; }
        if (bb < 0.0) {
            double x = -a / bb;
            if (fdid_abs(x) <= L) { d[0] = x; return; }
        }
        den = v - L * bb;
        if (den > 0) {
            double x = L * a / den;
            if (fdid_abs(x) <= L) { d[0] = x; return; }
        }
        if (1.0 * (a + bb * 1.0 * L) >= v * (1 - FDID_TOL)) { d[0] = L; return; }
        if (-1.0 * (a + bb * -1.0 * L) >= v * (1 - FDID_TOL)) { d[0] = -L; return; }
        d[0] = L * fdid_sat(a / v);
        return;
    }
    for (i = 0; i < m; i++) nb *= 4;
    for (b = 0; b < nb; b++) {
        int code = b, ok = 1, nu = 0, un[FDID_MAX_FRICTION], sl[FDID_MAX_FRICTION], nsl = 0;
        double z;
        for (i = m - 1; i >= 0; i--) {
            br[i] = branch_code[code % 4];
            code /= 4;
        }
        for (i = 0; i < m; i++) {
            d[i] = 0.0;
            if (br[i] == BR_STICK || br[i] == BR_LINEAR) un[nu++] = i;
            else { sl[nsl++] = i; d[i] = br[i] * level[i]; }
        }
        if (nu > 0) {
            /* stick rows: sum_c beta_rc d_c = -(alpha_r + sliding part);
             * linear rows: d_r - g_r sum_c beta_rc d_c = g_r (alpha_r + sliding part) */
            double Mx[FDID_MAX_FRICTION * FDID_MAX_FRICTION], rhs[FDID_MAX_FRICTION];
            int r, c;
            for (r = 0; r < nu; r++) {
                int q = un[r];
                double s = 0.0, g = level[q] / vt[q];
                for (c = 0; c < nsl; c++) s += beta[q * m + sl[c]] * d[sl[c]];
                for (c = 0; c < nu; c++) {
                    double bqc = beta[q * m + un[c]];
                    Mx[r * nu + c] = br[q] == BR_STICK ? bqc : (r == c ? 1.0 : 0.0) - g * bqc;
                }
                rhs[r] = br[q] == BR_STICK ? -(alpha[q] + s) : g * (alpha[q] + s);
            }
            if (!lu_solve(Mx, rhs, nu)) continue;
            for (r = 0; r < nu; r++) d[un[r]] = rhs[r];
        }
        for (i = 0; i < m && ok; i++) {
            double s = 0.0;
            if (br[i] == BR_STICK) {
                ok = level[i] > 0.0 && beta[i * m + i] < 0.0 && fdid_abs(d[i]) <= level[i];
                continue;
            }
            if (level[i] == 0.0) continue;
            for (j = 0; j < m; j++) s += beta[i * m + j] * d[j];
            z = (alpha[i] + s) / vt[i];
            if (br[i] == BR_LINEAR && fdid_abs(z) > 1 + FDID_TOL) ok = 0;
            else if (br[i] == 1 && z < 1 - FDID_TOL) ok = 0;
            else if (br[i] == -1 && z > -1 + FDID_TOL) ok = 0;
        }
        if (ok) return;
    }
    for (i = 0; i < m; i++) d[i] = level[i] * fdid_sat(alpha[i] / vt[i]);
}

/* ------------------------------------------------------------ initial state */
/* steady ramp at the start velocity v0 from the current inputs (simulate._run, first block) */
void fdid_initialize(FdidState *S) {
    const FdidModel *M = S->M;
    int n = M->n, m = M->m, p = M->p, i, a, j;
    double *u0 = S->u, *du = S->work_m, *s2du = S->work_n;
    for (i = 0; i < m; i++) S->uref[i] = 0.0;
    for (a = 0; a < M->n_axes; a++) S->uref[M->axis_cmd_input[a]] = S->cmd[a];
    matvec(M->G1, p, m, S->uref, S->yoff);
    for (i = 0; i < m; i++) { u0[i] = 0.0; du[i] = 0.0; }
    for (a = 0; a < M->n_axes; a++) du[M->axis_cmd_input[a]] = S->v0[a] * M->Ts;
    for (j = 0; j < M->n_fric; j++) {
        int in = M->fric_input[j];
        u0[in] = fric_level(S, j) * fdid_sat(S->v0[M->inputs[in].axis] / fric_vtilde(S, j));
    }
    for (i = 0; i < m; i++) {
        const FdidInput *in = &M->inputs[i];
        if (in->kind == FDID_IN_EXTERNAL) u0[i] = S->ext[i];
        else if (in->kind == FDID_IN_FEATURE) /* a steady ramp has slid through a play: h = x - b sign(v0) */
            u0[i] = feature_value(in, S->v0[in->axis], S->cmd[in->axis], S->cmd[in->axis],
                                  S->cmd[in->axis] - sign_of(S->v0[in->axis]) * in->width_mm);
    }
    /* xi = S u0 - S2 du */
    matvec(M->S, n, m, u0, S->xi);
    matvec(M->S2, n, m, du, s2du);
    for (i = 0; i < n; i++) S->xi[i] = S->xi[i] - s2du[i];
    /* y0 = C xi + D u0 + yoff; x[-1] = x[0] - v0 Ts, v[-1] = v0 */
    for (a = 0; a < M->n_axes; a++) {
        int o = M->axis_pos_output[a];
        double c = fdid_dot(M->C + (size_t)o * (size_t)n, S->xi, n);
        double dd = fdid_dot(M->D + (size_t)o * (size_t)m, u0, m);
        S->x_prev[a] = ((c + dd) + S->yoff[o]) - S->v0[a] * M->Ts;
        S->v_prev[a] = S->v0[a];
    }
    for (i = 0; i < m; i++)
        if (is_play(&M->inputs[i]))
            S->hold[i] = S->x_prev[M->inputs[i].axis]
                         - sign_of(S->v0[M->inputs[i].axis]) * M->inputs[i].width_mm;
    S->f.steps = 0;
    S->f.init_dirty = 0;
    S->f.out_dirty = 1;
}

/* ------------------------------------------------------------------ one step */
/* outputs at the current time from the current inputs (simulate._run, loop body, 1.-3.) */
FDID_INLINE void compute_outputs(FdidState *S) {
    const FdidModel *M = S->M;
    int m = M->m, p = M->p, nf = M->n_fric, i, j, a, o;
    double *u = S->u, *y = S->y;
    for (a = 0; a < M->n_axes; a++) {
        int ci = M->axis_cmd_input[a];
        u[ci] = S->cmd[a] - S->uref[ci];
    }
    for (i = 0; i < m; i++) {
        const FdidInput *in = &M->inputs[i];
        if (in->kind == FDID_IN_EXTERNAL) u[i] = S->ext[i];
        else if (in->kind == FDID_IN_FEATURE)
            u[i] = feature_value(in, S->v_prev[in->axis], S->cmd[in->axis], S->x_prev[in->axis],
                                 S->hold[i]);
        else if (in->kind == FDID_IN_FRICTION) u[i] = 0.0;
    }
    /* y = [C D] [xi; u] + yoff (the friction inputs are still 0 here) */
    for (o = 0; o < p; o++) y[o] = fdid_row_dot(&M->CD_rows, o, S->xi) + S->yoff[o];
    if (nf > 0) {
        double alpha[FDID_MAX_FRICTION], beta[FDID_MAX_FRICTION * FDID_MAX_FRICTION];
        double lev[FDID_MAX_FRICTION], vt[FDID_MAX_FRICTION], d[FDID_MAX_FRICTION];
        for (j = 0; j < nf; j++) {
            int ov = M->fric_vel_output[j], jj;
            int ax = M->inputs[M->fric_input[j]].axis;
            alpha[j] = M->fric_vel_diff[j] ? (y[ov] - S->x_prev[ax]) / M->Ts : y[ov];
            for (jj = 0; jj < nf; jj++) {
                double dv = M->D[(size_t)ov * (size_t)m + (size_t)M->fric_input[jj]];
                beta[j * nf + jj] = M->fric_vel_diff[j] ? dv / M->Ts : dv;
            }
            lev[j] = fric_level(S, j);
            vt[j] = fric_vtilde(S, j);
        }
        solve_friction(nf, alpha, beta, lev, vt, d);
        for (j = 0; j < nf; j++) u[M->fric_input[j]] = d[j];
        for (o = 0; o < p; o++) {
            double s = 0.0;
            for (j = 0; j < nf; j++) s += M->D[(size_t)o * (size_t)m + (size_t)M->fric_input[j]] * d[j];
            y[o] = y[o] + s;
        }
    }
    for (a = 0; a < M->n_axes; a++) {
        int vo = M->axis_vel_output[a], po = M->axis_pos_output[a];
        S->vel[a] = vo >= 0 ? y[vo] : (y[po] - S->x_prev[a]) / M->Ts;
    }
}

/* memory and state update after the outputs of the current time */
FDID_INLINE void update_state(FdidState *S) {
    const FdidModel *M = S->M;
    int n = M->n, i, a;
    for (a = 0; a < M->n_axes; a++) {
        S->v_prev[a] = S->vel[a];
        S->x_prev[a] = S->y[M->axis_pos_output[a]];
    }
    /* play operator: h <- min(max(h, x - b), x + b) with the new position x */
    for (i = 0; i < M->m; i++) {
        const FdidInput *in = &M->inputs[i];
        if (is_play(in)) {
            double x = S->x_prev[in->axis], h = S->hold[i];
            if (h < x - in->width_mm) h = x - in->width_mm;
            if (h > x + in->width_mm) h = x + in->width_mm;
            S->hold[i] = h;
        }
    }
    /* xi <- [A B] [xi; u] (into the scratch vector first: every row needs the old xi) */
    for (i = 0; i < n; i++) S->work_n[i] = fdid_row_dot(&M->AB_rows, i, S->xi);
    for (i = 0; i < n; i++) S->xi[i] = S->work_n[i];
    S->f.steps += 1;
}

void fdid_outputs(FdidState *S) {
    if (S->f.init_dirty) fdid_initialize(S);
    if (!S->f.out_dirty) return;
    compute_outputs(S);
    S->f.out_dirty = 0;
}

/* one internal step: outputs of the current time, then memory and state update */
void fdid_advance(FdidState *S) {
    fdid_outputs(S);
    update_state(S);
    S->f.out_dirty = 1;
}

/* the first axis whose friction is on with a v_tilde below level x axis_vtilde_floor, the least
 * the coupled friction solve resolves (model.vtilde_floor_per_level), or -1. Below it the
 * friction exceeds its level and the outputs grow without bound: the FMU refuses to step or
 * to evaluate outputs there rather than hand them out. */
int fdid_unresolved_friction(const FdidState *S) {
    int a;
    for (a = 0; a < S->M->n_axes; a++)
        if (S->on[a] != 0.0 && S->vtilde[a] < S->level[a] * S->M->axis_vtilde_floor[a]) return a;
    return -1;
}

/* value of a Real / Boolean variable (outputs are brought up to date first) */
double fdid_var_value(FdidState *S, const FdidVar *v) {
    const FdidModel *M = S->M;
    int a = v->index;
    switch (v->role) {
    case FDID_V_CMD: return S->cmd[a];
    case FDID_V_EXT: return S->ext[a];
    case FDID_P_LEVEL: return S->level[a];
    case FDID_P_VTILDE: return S->vtilde[a];
    case FDID_P_ON: return S->on[a];
    case FDID_P_V0: return S->v0[a];
    default: break;
    }
    fdid_outputs(S);
    switch (v->role) {
    case FDID_V_POS: return S->y[M->axis_pos_output[a]];
    case FDID_V_VEL: return S->vel[a];
    case FDID_V_TOOL: return S->y[M->axis_tool_output[a]];
    case FDID_V_Y: return S->y[a];
    case FDID_V_U: return S->u[a];
    default: return 0.0;
    }
}

/* ------------------------------------------------------------ a whole record */
/* Free run over N samples (fdid_fmi.simulate): the same steps a co-simulation master takes
 * (set the inputs of sample k, read the outputs of sample k, advance), without the FMI layer.
 * cmd: N x n_axes commanded positions; ext: N x m (only the external-input columns are read).
 * Y (N x p), U (N x m), V (N x n_axes) receive outputs, applied inputs and axis velocities.
 * The caller sets level / vtilde / on / v0 before; the state is initialised from sample 0
 * (the caller checks the outputs for non-finite values). */
void fdid_run(FdidState *S, long long N, const double *cmd, const double *ext, double *Y,
              double *U, double *V) {
    const FdidModel *M = S->M;
    int m = M->m, p = M->p, na = M->n_axes, i, a;
    long long k;
    for (k = 0; k < N; k++) {
        for (a = 0; a < na; a++) S->cmd[a] = cmd[k * na + a];
        for (i = 0; i < m; i++)
            if (M->inputs[i].kind == FDID_IN_EXTERNAL) S->ext[i] = ext[k * m + i];
        if (k == 0) fdid_initialize(S);
        compute_outputs(S);
        for (i = 0; i < p; i++) Y[k * p + i] = S->y[i];
        for (i = 0; i < m; i++) U[k * m + i] = S->u[i];
        for (a = 0; a < na; a++) V[k * na + a] = S->vel[a];
        update_state(S);
    }
    S->f.out_dirty = 1;
}

size_t fdid_sizeof_state(void) { return sizeof(FdidState); }
size_t fdid_sizeof_model(void) { return sizeof(FdidModel); }
