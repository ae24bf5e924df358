"""Regressors of the pole search: each input filtered through s^m / A(s), Tustin-discretised.

Thesis Eqn 5.4-5.7: for a candidate characteristic polynomial A(s) of order n, the regressors of
input w are phi_l = s^(n-l) / A(s) w, l = 0..n, computed with the Tustin (bilinear) map
s = (2/Ts) (1 - q) / (1 + q), q the backward shift. Multiplying by (Ts/2)^n (1 + q)^n gives

    s^m / A(s)  ->  (Ts/2)^(n-m) (1-q)^m (1+q)^(n-m)  /  sum_j a_j (Ts/2)^j (1-q)^(n-j) (1+q)^j

All n+1 regressors share the denominator, so (the hot loop of the search) each input is filtered
ONCE through the all-pole part 1/den(q) and the regressors are short FIR combinations of the
lagged all-pole output r (Q @ F); both loops run in the compiled core (``kernel_ext/ls_filter.c``,
the same doubles as ``scipy.signal.lfilter`` and the numpy sums they replaced). This is the
SIMO state-space filter G_0,ssd of Figure 5-4 in the realisation whose state is the last n
values of r; :func:`simo_realisation` returns exactly that state space, so the assembled model
reproduces the regressors to rounding.

The denominator is normalised to den(1) = 1 (unit d.c. gain of the all-pole part) so the
internal signal r has the size of the input.

Causality (DESIGN.md): an FMU read after ``doStep`` cannot know the command of the sample it
is read at. The Tustin filters have a same-sample term D0 w[k] (D0 = F[:, 0] / den[0]); for
inputs from outside the drive (commands, measured external inputs) it uses w^[k], predicted
from the samples before (:data:`SAME_SAMPLE`):

``hold``       w^[k] = w[k-1]: a sampled drive without look-ahead answers a command one cycle
               later, and nothing of w[k] is needed;
``quadratic``  w^[k] = 3 w[k-1] - 3 w[k-2] + w[k-3] (exact for constant acceleration, error
               the third difference ~ jerk Ts^3): a CNC's feed-forward looks one sample ahead,
               so the response does depend on w[k], which this predicts;
``cubic``      w^[k] = 4 w[k-1] - 6 w[k-2] + 4 w[k-3] - w[k-4] (exact for constant jerk, the
               segments of a jerk-limited interpolation; twice the noise gain of ``quadratic``).

The LS is fitted on exactly these causal regressors (:func:`same_sample_part`); which of
:data:`CHOSEN_FROM` a drive needs is chosen from its data (``pole_search.identify_mimo``).
Neither look-ahead form wins everywhere: on the virtual drive with feed-forward (4th-order model)
cubic was 2-4 % better on unseen traces after 20 training moves, quadratic 2-7 % better after 8.

Initial conditions: every record may start in motion. The filters start in the steady state of
a ramp w[k] = w0 + k dw extended to k < 0 (w0, dw from the first samples), which for a record at
rest is simply "at rest at the first value". The same steady ramp is used by the simulator.
"""
from __future__ import annotations

import functools

import numpy as np
from numpy.polynomial import polynomial as P

from .. import kernel


def characteristic_polynomial(real_hz, complex_hz_zeta):
    """Monic A(s) coefficients (highest power first) from pole parameters (Eqn 5.2).

    Parameters
    ----------
    real_hz : sequence of float, real poles p_k > 0 in Hz (roots at s = -2 pi p_k)
    complex_hz_zeta : sequence of (omega_n [Hz], zeta)

    Returns
    -------
    a : ndarray, [1, a_1, ..., a_n]
    """
    a = np.array([1.0])
    with np.errstate(over="ignore", invalid="ignore"):   # absurd bounds: non-finite a, refused by lsfit
        for p in real_hz:
            a = np.convolve(a, [1.0, 2 * np.pi * p])
        for w, z in complex_hz_zeta:
            wn = 2 * np.pi * w
            a = np.convolve(a, [1.0, 2 * z * wn, wn * wn])
    return a


def poles_from_parameters(real_hz, complex_hz_zeta):
    """Continuous poles (rad/s) of the parameterisation, as a list of complex numbers."""
    out = [complex(-2 * np.pi * p, 0.0) for p in real_hz]
    for w, z in complex_hz_zeta:
        out.extend(complex(r) for r in np.roots([1.0, 2 * z * 2 * np.pi * w, (2 * np.pi * w) ** 2]))
    return out


def _pow_poly(base, k):
    out = np.array([1.0])
    for _ in range(k):
        out = P.polymul(out, base)
    return out


def tustin_basis(a, Ts):
    """Tustin images of s^m / A(s), m = n..0, in powers of the backward shift q.

    Parameters
    ----------
    a : [1, a_1, ..., a_n] monic A(s), highest power first
    Ts : float, s

    Returns
    -------
    den : (n+1,) denominator in ascending powers of q, normalised to den(1) = 1
    F : (n+1, n+1) F[l] = numerator of phi_l = s^(n-l)/A(s) in ascending powers of q
        (over the same normalised denominator)
    """
    a = np.asarray(a, float)
    n = len(a) - 1
    T, F0 = _tustin_polys(n, float(Ts))
    den = (a * (Ts / 2.0) ** np.arange(n + 1)) @ T
    scale = np.sum(den)  # den at q = 1
    return den / scale, F0 / scale


@functools.lru_cache(maxsize=64)
def _tustin_polys(n, Ts):
    """T[j] = (1-q)^(n-j) (1+q)^j and F0[l] = (Ts/2)^l (1-q)^(n-l) (1+q)^l (cached per n, Ts)."""
    one_m, one_p = np.array([1.0, -1.0]), np.array([1.0, 1.0])
    T = np.array([P.polymul(_pow_poly(one_m, n - j), _pow_poly(one_p, j))[: n + 1] for j in range(n + 1)])
    F0 = np.array([T[l] * (Ts / 2.0) ** l for l in range(n + 1)])
    T.setflags(write=False)
    F0.setflags(write=False)
    return T, F0


def ramp_start(w):
    """(w0, dw) of the steady ramp a signal starts on (first value, first increment)."""
    w = np.asarray(w, float)
    return w[..., 0], (w[..., 1] - w[..., 0]) if w.shape[-1] > 1 else np.zeros_like(w[..., 0])


# w^[k] from w[k-1], w[k-2], ...
SAME_SAMPLE = {"hold": (1.0,), "quadratic": (3.0, -3.0, 1.0), "cubic": (4.0, -6.0, 4.0, -1.0)}
CHOSEN_FROM = ("hold", "quadratic", "cubic")     # the forms the data choose between


def same_sample_part(W, dw, coef):
    """w[k] - w^[k] of each input, from its steady start ramp.

    Parameters
    ----------
    W : (m, N) inputs; dw : (m,) ramp increment before the first sample
    coef : the prediction w^[k] = sum_j coef[j] w[k-1-j] (a value of :data:`SAME_SAMPLE`)

    Returns
    -------
    (m, N): what the prediction misses; a causal regressor is phi_l - D0_l (w - w^)
    """
    W = np.atleast_2d(np.asarray(W, float))
    k = len(coef)
    hist = W[:, :1] + np.asarray(dw, float).reshape(-1, 1) * np.arange(-k, 0)
    ext = np.concatenate([hist, W], axis=1)
    pred = sum(c * ext[:, k - 1 - j: ext.shape[1] - 1 - j] for j, c in enumerate(coef))
    return W - pred


def allpole_filter(den, W, w0=None, dw=None):
    """Filter signals through 1/den(q) from their steady ramp, with n samples of history.

    Parameters
    ----------
    den : (n+1,) normalised denominator (ascending powers of q, den(1) = 1)
    W : (m, N) input signals
    w0, dw : (m,) ramp start of each signal (default: from its first two samples)

    Returns
    -------
    R : (m, N + n) all-pole output; R[:, n + k] belongs to sample k, the first n columns are
        the steady-ramp history r[-n..-1].
    """
    W, out, an, zi = filter_start(den, W, w0, dw)
    if an is None:
        out[:, :] = W / den[0]
        return out
    kernel.allpole(1.0 / den[0], an, W, zi, out)     # scipy.signal.lfilter's recursion, in C
    return out


def filter_start(den, W, w0=None, dw=None):
    """The start of :func:`allpole_filter`: (W as floats, R with its history columns filled,
    the normalised denominator an, the filter state zi); an and zi are None when n = 0."""
    W = np.atleast_2d(np.asarray(W, float))
    m, N = W.shape
    n = len(den) - 1
    if w0 is None or dw is None:
        w0, dw = ramp_start(W)
    w0, dw = np.broadcast_to(w0, (m,)), np.broadcast_to(dw, (m,))
    # steady ramp response of 1/den: r[k] = w0 + k dw + dw * den'(1)   (den(1) = 1)
    dprime = float(np.sum(np.arange(n + 1) * den))
    ks = np.arange(-n, 0)
    hist = w0[:, None] + ks[None, :] * dw[:, None] + (dw * dprime)[:, None]
    out = np.empty((m, N + n))
    out[:, :n] = hist
    if n == 0:
        return W, out, None, None
    # filter state (transposed direct form II, b = [1]) from the past outputs y[-1], y[-2], ..:
    # zi[j] = -sum_i a[j+i+1] y[-i-1]  (a normalised by a[0]); scipy.signal.lfiltic, vectorised
    an = den / den[0]
    H = np.zeros((n, n))
    for i in range(n):
        H[i, : n - i] = an[i + 1:]
    return W, out, an, -(hist[:, ::-1] @ H)


def regressors(R, F, n):
    """phi_l of every input from the all-pole outputs.

    Parameters
    ----------
    R : (m, N + n) from :func:`allpole_filter`
    F : (L, n+1) rows of :func:`tustin_basis` (all n+1 or the ones needed)

    Returns
    -------
    Phi : (m, L, N) Phi[i, l] = phi_l of input i (contiguous rows: the LS works on them)
    """
    m, total = R.shape
    F = np.asarray(F, float).reshape(-1, n + 1)
    L = F.shape[0]
    rows = kernel.regressor_rows(R, n, np.repeat(np.arange(m), L), np.tile(F, (m, 1)))
    return rows.reshape(m, L, total - n)


def simo_realisation(den, F):
    """State space of the SIMO filter w -> [phi_0 .. phi_n] (thesis G_0,ssd, Eqn 5.5-5.7).

    The state is the last n values of the all-pole output r, so it reproduces
    :func:`regressors` exactly.

    Returns
    -------
    A0 (n,n), B0 (n,1), C0 (n+1,n), D0 (n+1,1)
    """
    n = len(den) - 1
    c0 = den[0]
    A0 = np.zeros((n, n))
    A0[0, :] = -den[1:] / c0
    if n > 1:
        A0[1:, :-1] = np.eye(n - 1)
    B0 = np.zeros((n, 1))
    B0[0, 0] = 1.0 / c0
    C0 = F[:, 1:] - np.outer(F[:, 0], den[1:]) / c0
    D0 = (F[:, 0] / c0).reshape(-1, 1)
    return A0, B0, C0, D0
