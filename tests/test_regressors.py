"""Regressors of the pole search (thesis Eqn 5.4-5.7): Tustin images of s^m/A(s)."""
import ls_oracle
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy import signal

from fdid_fmi.identify import regressors as rg

TS = 1e-3


@pytest.fixture
def poly():
    return rg.characteristic_polynomial([20.0], [(15.0, 0.8)])


def test_characteristic_polynomial_roots():
    a = rg.characteristic_polynomial([5.0, 40.0], [(25.8, 0.006)])
    roots = np.sort_complex(np.roots(a))
    expect = np.sort_complex(np.array(rg.poles_from_parameters([5.0, 40.0], [(25.8, 0.006)])))
    np.testing.assert_allclose(roots, expect, rtol=1e-9)
    assert len(a) == 5
    # and the roots are the parameters' poles in rad/s (both functions could share a unit slip)
    wn = 2 * np.pi * 25.8
    pair = -0.006 * wn + 1j * wn * np.sqrt(1 - 0.006 ** 2)
    np.testing.assert_allclose(roots, np.sort_complex([-2 * np.pi * 40.0, -2 * np.pi * 5.0, pair, pair.conjugate()]),
                               rtol=1e-9)


def test_regressors_equal_bilinear_filters(poly):
    n = 3
    den, F = rg.tustin_basis(poly, TS)
    t = np.arange(6000) * TS
    w = np.sin(7 * t) * (t > 1) + 0.3 * (t > 2.5)
    phi = rg.regressors(rg.allpole_filter(den, w[None]), F, n)[0].T
    for l in range(n + 1):
        num = np.zeros(n + 1)
        num[l] = 1.0                       # s^(n-l)
        b, a = signal.bilinear(num, poly, fs=1 / TS)
        ref = signal.lfilter(b, a, w)
        assert np.max(np.abs(ref - phi[:, l])) <= 1e-9 * np.max(np.abs(ref))


def test_ramp_start_is_steady(poly):
    """A record that starts in motion: the regressors start in the ramp's steady state."""
    den, F = rg.tustin_basis(poly, TS)
    w = 5.0 + 0.002 * np.arange(4000)
    phi = rg.regressors(rg.allpole_filter(den, w[None]), F, 3)[0].T
    # s^1/A of a ramp is constant, s^2 and s^3 of it vanish: no start-up transient
    np.testing.assert_allclose(phi[:, 2], phi[-1, 2], rtol=1e-8)
    assert np.max(np.abs(phi[:, :2])) < 1e-9
    np.testing.assert_allclose(phi[-1, 2], 2.0 / poly[-1], rtol=1e-9)  # dw/Ts / a_n


def test_simo_realisation_reproduces_regressors(poly):
    den, F = rg.tustin_basis(poly, TS)
    A0, B0, C0, D0 = rg.simo_realisation(den, F)
    w = np.random.default_rng(0).standard_normal(500).cumsum()
    w -= w[0]
    w[:2] = 0.0
    phi = rg.regressors(rg.allpole_filter(den, w[None], 0.0, 0.0), F, 3)[0].T
    xi = np.zeros(3)
    out = np.empty_like(phi)
    for k, wk in enumerate(w):
        out[k] = C0 @ xi + D0[:, 0] * wk
        xi = A0 @ xi + B0[:, 0] * wk
    np.testing.assert_allclose(out, phi, rtol=1e-8, atol=1e-9 * np.max(np.abs(phi)))
    assert np.max(np.abs(np.linalg.eigvals(A0))) < 1


# ------------------------------------------------------------ the compiled filter (ls_filter.c)
@settings(max_examples=60, deadline=None)
@given(n_real=st.integers(0, 3), n_cplx=st.integers(0, 3), seed=st.integers(0, 2 ** 32 - 1),
       m=st.integers(1, 3), N=st.integers(1, 400), ramp=st.booleans())
def test_compiled_filter_gives_the_array_codes_doubles(n_real, n_cplx, seed, m, N, ramp):
    """The all-pole filter and the regressor sums in C are scipy.signal.lfilter and the numpy
    sums they replaced, operation for operation: the same doubles (any order, any start)."""
    rng = np.random.default_rng(seed)
    real = list(10 ** rng.uniform(-1, 2.6, n_real))
    cplx = [(10 ** rng.uniform(-0.5, 2.6), 10 ** rng.uniform(-2.5, 0.4)) for _ in range(n_cplx)]
    with np.errstate(all="ignore"):
        den, F = rg.tustin_basis(rg.characteristic_polynomial(real, cplx), TS)
    assume(np.all(np.isfinite(den)) and np.all(np.isfinite(F)))
    n = len(den) - 1
    W = rng.standard_normal((m, N)).cumsum(axis=1) * 10 ** rng.uniform(-4, 3)
    w0, dw = (W[:, 0], rng.standard_normal(m)) if ramp else (None, None)
    R = rg.allpole_filter(den, W, w0, dw)
    assert np.array_equal(R, ls_oracle.allpole_filter(den, W, w0, dw), equal_nan=True)
    rows = F[rng.permutation(n + 1)[: rng.integers(1, n + 2)]]
    assert np.array_equal(rg.regressors(R, rows, n), ls_oracle.regressors(R, rows, n), equal_nan=True)


@pytest.mark.parametrize("same_sample", ["hold", "quadratic", "cubic"])
def test_ls_design_is_the_array_codes(same_sample):
    """``LSProblem.design`` (C filter, used rows only, the causal correction of the inputs from
    outside computed once) gives the array code's regressor matrix exactly: two segments, a
    run-up, friction, an external channel and a periodic feature of the command."""
    from fdid_fmi.identify import InputSpec, mimo_structure
    from fdid_fmi.identify.lsfit import LSProblem
    from fdid_fmi.trace import Trace
    t = np.arange(3000) * TS
    cmd = 5.0 * np.sin(2 * np.pi * 0.7 * t) + 2.0 * t
    act = cmd - 0.01 * np.cos(2 * np.pi * 0.7 * t)
    tr = Trace.from_arrays(t, {"x": {"cmd": cmd, "act": act}}, extra={"aux": np.cos(3 * t)})
    st_ = mimo_structure(("x",), ("error", "velocity"), n_real=2, n_complex=1, integral_action=False,
                         same_sample=same_sample, externals=("aux",))
    st_.inputs.append(InputSpec("feature", "x", params={"function": "sin_position", "period_mm": 7.0,
                                                        "source": "command"}, name="x_sin"))
    prob = LSProblem([tr, tr], st_)
    assert prob.late.sum() == 3
    rng = np.random.default_rng(3)
    for _ in range(5):
        a = rg.characteristic_polynomial(list(10 ** rng.uniform(0, 2.5, 2)),
                                         [(10 ** rng.uniform(0.5, 2.5), rng.uniform(0.05, 1.5))])
        vt = {"x": 10 ** rng.uniform(-3, 0)}
        assert np.array_equal(prob.design(a, vt), ls_oracle.design(prob, a, vt))


def test_normal_equations_solved_as_scipy_solve():
    """Cholesky through LAPACK posv: scipy.linalg.solve(assume_a="pos")'s doubles; a singular
    system (collinear regressors) falls back to least squares."""
    from scipy import linalg

    from fdid_fmi.identify.lsfit import _solve_normal
    rng = np.random.default_rng(5)
    for _ in range(50):
        M = rng.standard_normal((6, 200)) * 10 ** rng.uniform(-3, 3, (6, 1))
        G, b = M @ M.T, rng.standard_normal(6)
        assert np.array_equal(_solve_normal(G, b), linalg.solve(G, b, assume_a="pos", check_finite=False))
    M = rng.standard_normal((3, 50))
    M = np.vstack([M, M[:1]])                       # a repeated regressor: G is singular
    G = M @ M.T
    b = M @ rng.standard_normal(50)
    x = _solve_normal(G, b)
    assert np.all(np.isfinite(x)) and np.allclose(G @ x, b)


def test_collinear_regressors_get_the_same_coefficients_whatever_the_rounding():
    """Two identical regressor rows (a backlash feature sat(v / v_b) at v_b = v_tilde beside the
    friction row): G is singular only to rounding, Cholesky succeeds and returns rounding along the
    null direction, different for each BLAS kernel (on plant2 +-0.48 on AVX-512 against 1e-3 on
    AVX2, a tool side 2.9 mm off held out). Whatever the last bits of G, the solution is the
    minimum-norm one: the repeated row's coefficient split in two equal halves."""
    from fdid_fmi.identify.lsfit import _solve_normal
    rng = np.random.default_rng(7)
    M3 = rng.standard_normal((3, 400))
    M = np.vstack([M3, M3[2:3]])
    G, b = M @ M.T, M @ rng.standard_normal(400)
    x3 = np.linalg.solve(M3 @ M3.T, b[:3])
    expected = np.r_[x3[:2], x3[2] / 2, x3[2] / 2]
    for _ in range(20):
        E = rng.standard_normal((4, 4)) * 4 * np.finfo(float).eps * np.abs(G).max()
        x = _solve_normal(G + (E + E.T) / 2, b)
        assert np.allclose(x, expected, rtol=1e-9, atol=1e-12), (x, expected)   # Cholesky alone: 0.2 off
