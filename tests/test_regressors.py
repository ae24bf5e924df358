"""Regressors of the pole search (thesis Eqn 5.4-5.7): Tustin images of s^m/A(s)."""
import numpy as np
import pytest
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
