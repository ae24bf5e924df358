"""The order check of the diagnosis: one more real pole before an effect is named.

Adding a real pole raises the order by one; the search's start point, which the check relies on,
must leave every search method no worse than where it started. The diagnosis that says the
order is too low on a four-pole drive fitted with the three-pole rigid structure is a check of
``benchmarks/bench_end_to_end.py`` (``checks/diagnose_order.py``; where it must not: the clean
virtual-drive runs of ``checks/diagnose_virtual.py`` require their notes to be ``not_observable``
alone).
"""
import warnings

import numpy as np
import pytest
from scipy import signal

from fdid_fmi.diagnose import augment as ag
from fdid_fmi.identify import identify_siso
from fdid_fmi.identify.search import METHODS, run_search
from fdid_fmi.trace import Trace


def four_pole_trace(seed, n=4000, Ts=1e-3):
    """Smooth random moves through a closed loop with a pair (20 Hz, zeta 0.5) and two real poles
    (2 Hz, 80 Hz), answering one cycle late, with 10 nm of measurement noise."""
    rng = np.random.default_rng(seed)
    cmd = np.zeros(n)
    k = 50
    while k < n - 400:
        steps = int(rng.integers(150, 400))
        cmd[k:] = cmd[k - 1] + rng.uniform(-5, 5) * 0.5 * (1 - np.cos(np.pi * np.minimum(np.arange(n - k), steps) / steps))
        k += steps + int(rng.integers(50, 150))
    w = 2 * np.pi * 20
    poles = [-0.5 * w + 1j * w * np.sqrt(0.75), -0.5 * w - 1j * w * np.sqrt(0.75), -2 * np.pi * 2, -2 * np.pi * 80]
    gain = np.real(np.prod(-np.array(poles)))
    A, B, C, D = signal.zpk2ss([], poles, gain)
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, D), Ts, method="zoh")
    _, y, _ = signal.dlsim((Ad, Bd, Cd, Dd, Ts), cmd - cmd[0])
    act = np.r_[0.0, y[:-1, 0]] + cmd[0] + rng.normal(0, 1e-5, n)
    return Trace.from_arrays(np.arange(n) * Ts, {"x": {"cmd": cmd, "act": act}})


def test_add_real_pole_raises_the_order_by_one(small_recipe):
    rec, trs = small_recipe
    r = ag.add_real_pole(rec, 50.0)
    assert r.order == rec.order + 1 and r.real_hz == rec.real_hz + [50.0] and r.effects == rec.effects
    # numerators keep their s-powers; one that reached s^n reaches s^(n+1)
    for key, powers in rec.masks.items():
        assert r.masks[key] == ag._shift_mask(powers, rec.order, r.order)
        assert (rec.order in powers) == (r.order in r.masks[key])
    m = ag.fit(r, trs, search="locked", refine=False)
    assert len(m.poles) == rec.order + 1
    assert any(np.isclose(-p.real / (2 * np.pi), 50.0) and p.imag == 0 for p in m.poles)


@pytest.fixture(scope="module")
def small_recipe():
    tr = four_pole_trace(3, n=2000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = identify_siso(tr, maxiter=5, friction=False)
    return ag.recipe_from_model(model), [tr]


@pytest.mark.parametrize("method", METHODS)
def test_search_ends_no_worse_than_its_start(method):
    """Rastrigin in 3-D, shifted off the box's centre, with a tiny budget: the start point is the
    global minimum, which a search this short does not find by itself."""
    x0 = np.array([1.0, -2.0, 3.0])

    def residuals(x):       # Rastrigin as a sum of squares, for the vp search
        z = x - x0
        return np.sqrt(z * z + 10 * (1 - np.cos(2 * np.pi * z)))

    def f(x):
        return float(np.sum(residuals(x) ** 2))

    lo, hi = -5.12 * np.ones(3), 5.12 * np.ones(3)
    kw = dict(method=method, seed=1, maxiter=2, popsize=4, starts=2, local_polish=False)
    if method == "vp":      # its objective is the residual vector's norm
        kw.update(residuals=residuals)
        f_run = lambda x: float(np.linalg.norm(residuals(x)))   # noqa: E731
    else:
        f_run = f
    blind = run_search(f_run, lo, hi, **kw)
    started = run_search(f_run, lo, hi, x0=x0, **kw)
    assert blind.fun > 0.5                  # the short search alone misses the minimum
    assert started.fun <= f(x0) == 0.0
