"""Quasi-static model (thesis ch. 3) against the virtual drive's analytic Taylor coefficients."""
import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.identify import feed_limits, identify_quasi_static
from fdid_fmi.simulate import simulate
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj


@pytest.fixture(scope="module")
def linear_axis():
    cfg = presets.deckel_maho_like()
    ax = cfg.axis("x")
    ax.coulomb, ax.viscous, ax.resolution = 0.0, 0.0, 0.0      # the linear plant
    return MachineConfig(axes=[ax], Ts=cfg.Ts)


def test_recovers_taylor_coefficients_within_2_percent(linear_axis):
    """G_er(s) = K_vel s + K_acc s^2 + K_jerk s^3 + ... (Eqn 3.2). A gentle trajectory keeps the
    content inside the series' radius of convergence; four extra terms absorb the rest of the
    truncation bias."""
    tr = simulate_machine(linear_axis, tj.linear_moves(n_moves=20, axes=("x",), v=10, acc=20, jerk=100,
                                                      Ts=linear_axis.Ts, seed=1), seed=1)
    truth = tr.meta["truth"]["linear"]["sampled"]["K"]["x"]["x"]
    g = identify_quasi_static(tr, cutoff_hz=20, terms=7).gains["x"]
    for k in ("K_vel", "K_acc", "K_jerk"):
        assert g[k] == pytest.approx(truth[k], rel=0.02), k


def test_three_term_model_on_a_fast_trajectory(linear_axis):
    """The thesis's 3-term model: K_vel stays within 1 %; the prediction error is small."""
    tr = simulate_machine(linear_axis, tj.linear_moves(n_moves=12, axes=("x",), Ts=linear_axis.Ts, seed=2),
                          seed=2)
    truth = tr.meta["truth"]["linear"]["sampled"]["K"]["x"]["x"]
    m = identify_quasi_static(tr)
    assert m.gains["x"]["K_vel"] == pytest.approx(truth["K_vel"], rel=0.01)
    e = tr.error("x")
    pred = simulate(m, tr).axes["x"]["error"]
    assert np.sqrt(np.mean((pred - e) ** 2)) < 0.05 * np.sqrt(np.mean(e ** 2))


def test_feed_limits_eqn_3_6(linear_axis):
    tr = simulate_machine(linear_axis, tj.linear_moves(n_moves=8, axes=("x",), Ts=linear_axis.Ts, seed=3),
                          seed=3)
    m = identify_quasi_static(tr)
    g = m.gains["x"]
    out = feed_limits(m, "x", e_max_mm=0.5, a_max=1000.0, j_max=5e4)
    used = abs(g["K_acc"]) * 1000.0 + abs(g["K_jerk"]) * 5e4
    assert out["allowed"]["v_max"] == pytest.approx((0.5 - used) / abs(g["K_vel"]))
    full = feed_limits(m, "x", 0.5, v_max=out["allowed"]["v_max"], a_max=1000.0, j_max=5e4)
    assert full["within"] and full["predicted_max_error_mm"] == pytest.approx(0.5)
    assert not feed_limits(m, "x", 0.5, v_max=2 * out["allowed"]["v_max"], a_max=1000.0, j_max=5e4)["within"]
    with pytest.raises(InputError, match="e_max"):
        feed_limits(m, "x", -1.0)
    with pytest.raises(InputError, match="axis"):
        feed_limits(m, "z", 1.0)
