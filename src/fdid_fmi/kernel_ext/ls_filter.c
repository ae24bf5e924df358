/* ls_filter.c -- the hot loop of the pole search (identify/regressors.py, thesis Eqn 5.4-5.7):
 * every input filtered through the all-pole part 1/den(q), then the regressors phi_l as short
 * FIR combinations of the lagged all-pole output r.
 *
 * Built into the extension fdid_fmi._kernel with the simulation core and called through ctypes.
 * Each operation is the one the numpy/scipy code it replaced performed, in the same order, so
 * the results are the same doubles (tests/ls_oracle.py keeps that code; the tests require
 * equality): the filter is scipy.signal.lfilter's transposed direct form II with b = [b0, 0..0],
 * and each regressor sample is summed over the lags j = 0..n from 0.0, left to right. The
 * extension is compiled with -ffp-contract=off (no fused multiply-add). */
#include <stddef.h>

/* The regressor sums are element-wise over the samples: let GCC vectorise them (it does not at
 * the extension's -O2). Vectorising element-wise operations does not change their results. */
#if defined(__GNUC__) && !defined(__clang__)
#define FDID_VECTORISE __attribute__((optimize("tree-vectorize")))
#else
#define FDID_VECTORISE
#endif

/* R[i, n + k] = y_i[k] = lfilter([b0], an, W[i], zi[i]) for k = 0..N-1 (R rows are N + n long;
 * the first n columns, the steady-ramp history, are the caller's). an[0] = 1. zi (m x n) is
 * overwritten with the final filter state. The recursion is latency-bound, so two rows are run
 * together (independent chains; each row's operations unchanged). */
static void allpole_row(int n, double b0, const double *an, long long N, const double *restrict x,
                        double *restrict z, double *restrict y)
{
    for (long long k = 0; k < N; k++) {
        const double xk = x[k];
        const double yk = z[0] + b0 * xk;
        for (int j = 0; j < n - 1; j++)
            z[j] = z[j + 1] + xk * 0.0 - yk * an[j + 1];       /* b[j+1] = 0, as lfilter pads b */
        z[n - 1] = xk * 0.0 - yk * an[n];
        y[k] = yk;
    }
}

#define FDID_MAX_ORDER 32

static void allpole_pair(int n, double b0, const double *an, long long N, const double *restrict x1,
                         const double *restrict x2, double *restrict z1, double *restrict z2,
                         double *restrict y1, double *restrict y2)
{
    double a[FDID_MAX_ORDER + 1], u[FDID_MAX_ORDER], v[FDID_MAX_ORDER];
    for (int j = 0; j <= n; j++)
        a[j] = an[j];
    for (int j = 0; j < n; j++) {
        u[j] = z1[j];
        v[j] = z2[j];
    }
    for (long long k = 0; k < N; k++) {
        const double p = x1[k], q = x2[k];
        const double yp = u[0] + b0 * p, yq = v[0] + b0 * q;
        for (int j = 0; j < n - 1; j++) {
            u[j] = u[j + 1] + p * 0.0 - yp * a[j + 1];
            v[j] = v[j + 1] + q * 0.0 - yq * a[j + 1];
        }
        u[n - 1] = p * 0.0 - yp * a[n];
        v[n - 1] = q * 0.0 - yq * a[n];
        y1[k] = yp;
        y2[k] = yq;
    }
    for (int j = 0; j < n; j++) {
        z1[j] = u[j];
        z2[j] = v[j];
    }
}

void fdid_allpole(int n, double b0, const double *an, int m, long long N, const double *W,
                  double *zi, double *R)
{
    int i = 0;
    if (n < 1)              /* order 0 is a gain, not a filter: the caller divides by den[0] */
        return;
    if (n <= FDID_MAX_ORDER)
        for (; i + 1 < m; i += 2)
            allpole_pair(n, b0, an, N, W + (size_t)i * (size_t)N, W + (size_t)(i + 1) * (size_t)N,
                         zi + (size_t)i * (size_t)n, zi + (size_t)(i + 1) * (size_t)n,
                         R + (size_t)i * (size_t)(N + n) + n, R + (size_t)(i + 1) * (size_t)(N + n) + n);
    for (; i < m; i++)
        allpole_row(n, b0, an, N, W + (size_t)i * (size_t)N, zi + (size_t)i * (size_t)n,
                    R + (size_t)i * (size_t)(N + n) + n);
}

#define FDID_BLOCK 512       /* samples of a row summed together: 4 kB, in the L1 cache */

/* out[r, k - start] = sum_{j=0..n} F[r, j] R[input[r], n - j + k]  (- late_c[r] S[input[r], k]
 * when late[r]) for k = start .. start + Nout - 1; R rows are N + n long, S rows N. */
FDID_VECTORISE void fdid_regressor_rows(int n, long long N, long long start, long long Nout,
                                        const double *R, int nrows, const int *input,
                                        const double *F, const int *late, const double *late_c,
                                        const double *S, double *out)
{
    for (int r = 0; r < nrows; r++) {
        const double *restrict f = F + (size_t)r * (size_t)(n + 1);
        /* in blocks of samples that stay in the L1 cache through the n + 1 passes over them */
        for (long long k0 = 0; k0 < Nout; k0 += FDID_BLOCK) {
            const long long nk = Nout - k0 < FDID_BLOCK ? Nout - k0 : FDID_BLOCK;
            const double *restrict Ri = R + (size_t)input[r] * (size_t)(N + n) + n + start + k0;
            double *restrict o = out + (size_t)r * (size_t)Nout + k0;
            for (long long k = 0; k < nk; k++)
                o[k] = 0.0;
            for (int j = 0; j <= n; j++) {      /* lag by lag, as the array code: vectorises */
                const double fj = f[j];
                const double *restrict Rj = Ri - j;
                for (long long k = 0; k < nk; k++)
                    o[k] = o[k] + fj * Rj[k];
            }
            if (late[r]) {
                const double c = late_c[r];
                const double *restrict s = S + (size_t)input[r] * (size_t)N + start + k0;
                for (long long k = 0; k < nk; k++)
                    o[k] = o[k] - c * s[k];
            }
        }
    }
}
