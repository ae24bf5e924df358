"""The ``vp`` method of search.run_search (Sobol screen + Gauss-Newton searches on the residual
vector) and the warm starts the structure choice gives it."""
import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.identify.choose_structure import candidate, warm_starts
from fdid_fmi.identify.record import PoleSearchRecord
from fdid_fmi.identify.search import run_search


def _residuals(x):
    """Two basins of |r|: 0 at (1, 1), 0.5 at (-1, -1) (the nearer one counts)."""
    a = x - 1.0
    b = x + 1.0
    return a if a @ a <= b @ b + 0.25 else np.append(b, 0.5)


def _fun(x):
    r = _residuals(x)
    return float(np.sqrt(r @ r))


def _pad(fun_or_res):
    """The residual vector at a fixed length (least_squares needs one)."""
    def f(x):
        r = fun_or_res(x)
        return np.append(r, np.zeros(3 - r.size))
    return f


def test_vp_finds_the_global_basin_deterministically():
    runs = [run_search(_fun, [-2, -2], [2, 2], method="vp", residuals=_pad(_residuals), seed=3) for _ in range(2)]
    np.testing.assert_allclose(runs[0].x, [1, 1], atol=1e-3)
    assert runs[0].fun < 1e-3
    assert runs[0].fun == runs[1].fun and np.array_equal(runs[0].x, runs[1].x)
    # its minima: distinct, best first, the best is the result
    fs = [f for f, _ in runs[0].minima]
    assert fs == sorted(fs) and fs[0] == runs[0].fun


def test_vp_from_a_warm_start_is_no_worse_than_the_start():
    start = np.array([-0.7, -1.2])
    res = run_search(_fun, [-2, -2], [2, 2], method="vp", residuals=_pad(_residuals), warm=[start])
    assert res.fun <= _fun(start)


def test_vp_needs_the_residual_vector():
    with pytest.raises(InputError, match="residual vector"):
        run_search(_fun, [-2, -2], [2, 2], method="vp")


def _model_with(real, cplx, vt):
    """A stand-in for a fitted model: what warm_starts reads (its record and Ts)."""
    class M:
        Ts = 1e-3
        identification = {"real_hz": real, "complex_hz_zeta": [list(c) for c in cplx],
                          "v_tilde_regressor_mm_s": vt}
    return M()


def test_warm_starts_drop_or_add_poles_to_the_candidates_counts(monkeypatch):
    def from_dict(d):
        return type("R", (), {"real_hz": d["real_hz"], "complex_hz_zeta": d["complex_hz_zeta"],
                              "extra": {"v_tilde_regressor_mm_s": d["v_tilde_regressor_mm_s"]}})()
    monkeypatch.setattr(PoleSearchRecord, "from_dict", staticmethod(from_dict))
    r2c1 = _model_with([3.0, 40.0], [(6.0, 1.0)], {"x": 0.5})
    rigid = warm_starts(candidate("rigid"), r2c1)
    # either real pole may be the rigid body's
    assert [r for r, _, _ in rigid] == [[40.0], [3.0]] or [r for r, _, _ in rigid] == [[3.0], [40.0]]
    assert all(c == [(6.0, 1.0)] and vt == {"x": 0.5} for _, c, vt in rigid)
    (real, cplx, _), = warm_starts(candidate("r2c2"), r2c1)
    # the added pair sits at a quarter of the sampling rate: the r2c1 fit nearly as it was
    assert real == [3.0, 40.0] and cplx == [(6.0, 1.0), (250.0, 0.7)]
    assert len(warm_starts(candidate("r1c2-noI"), r2c1)) == 2


def test_vp_refuses_when_no_objective_is_finite():
    with pytest.raises(InputError, match="no candidate with a finite prediction error"):
        run_search(lambda x: float("nan"), [0.0, 0.0], [1.0, 1.0], method="vp",
                   residuals=lambda x: np.full(3, np.nan))
