"""The alignment steps one by one on synthetic arrays with exact answers."""
import numpy as np
import pytest

from fdid_fmi.align.orientation import (euler_angles, integration_drift, plate_alignment,
                                        rotation_from_directions, static_constant)
from fdid_fmi.align.resample import to_controller_grid
from fdid_fmi.align.timing import MIN_DRIFT_WINDOWS, fit_clock
from fdid_fmi.virtual.sensors import euler_rotation


def test_euler_convention_is_eqn_7_1():
    a, b, g = np.radians([2.5, -1.2, 0.8])
    Rx = np.array([[1, 0, 0], [0, np.cos(g), -np.sin(g)], [0, np.sin(g), np.cos(g)]])
    Ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rot = euler_rotation(2.5, -1.2, 0.8)
    assert np.allclose(rot.as_matrix(), Rx @ Ry @ Rz, atol=1e-15)
    assert np.allclose(euler_angles(rot), [2.5, -1.2, 0.8], atol=1e-12)


def test_rotation_from_two_directions_is_exact():
    rot = euler_rotation(-7.0, 4.0, 1.5)
    dirs = {a: {"d": rot.inv().apply(e), "sigma_rad": 1e-4} for a, e in (("x", [1, 0, 0]), ("y", [0, 1, 0]))}
    r, ang, sig = rotation_from_directions(dirs, n_mc=50)
    assert np.allclose(ang, [-7.0, 4.0, 1.5], atol=1e-9)
    assert np.all((sig > 0.002) & (sig < 0.02))   # 1e-4 rad direction scatter -> ~0.006 deg


def test_plate_alignment_exact_and_from_one_axis():
    th, o = np.radians(0.7), np.array([3.0, -4.0])
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    s = np.linspace(0, 30, 400)
    for Q in (np.column_stack([s, np.sin(s)]), np.column_stack([np.zeros_like(s) + 2.0, s])):
        P = (Q - o) @ R   # = R^T (q - o) per row
        deg, sdeg, oo, so, res = plate_alignment(P, Q)
        assert deg == pytest.approx(0.7, abs=1e-9) and np.allclose(oo, o, atol=1e-9) and res < 1e-9


def test_static_constant_is_exact_from_rest_to_rest():
    tau = np.arange(0, 4, 1e-3)
    a = np.where((tau > 1) & (tau < 2), np.sin(2 * np.pi * (tau - 1)), 0.0) * 500  # integrates to 0
    c_true = np.array([100.0, -50.0, 9800.0])
    rot = euler_rotation(5, 2, -1)
    f = rot.inv().apply(np.column_stack([a, 0.5 * a, 0 * a])) + c_true
    c, sc = static_constant(tau, f, (0.0, 1.0), (2.0, 4.0))
    assert np.allclose(c, c_true, atol=1e-6) and np.all(sc < 1e-6)


def test_fit_clock_recovers_offset_and_drift_and_refuses_a_weak_slope():
    a0, true_a, true_b = 0.0, 0.0012, 1.0 - 80e-6
    tw = np.linspace(0.5, 9.5, 10)
    rng = np.random.default_rng(0)
    # an event at mapped time t = a0 + tau really happened at true_a + true_b tau: lag = difference
    lags = [{"t": t, "lag": t - (true_a + true_b * (t - a0)) + 1e-6 * rng.normal(), "corr": 1.0}
            for t in tw]
    (a, b), (sa, sb), info = fit_clock(lags, (a0, 1.0))
    assert info["drift_estimated"]
    assert a == pytest.approx(true_a, abs=5e-6) and b == pytest.approx(true_b, abs=1e-6)
    few = lags[:MIN_DRIFT_WINDOWS - 1]
    (a, b), _, info = fit_clock(few, (a0, 1.0))
    assert not info["drift_estimated"] and b == 1.0
    flat = [{"t": t, "lag": 2e-4 + 1e-5 * rng.normal(), "corr": 1.0} for t in tw]
    (a, b), _, info = fit_clock(flat, (a0, 1.0))
    assert not info["drift_estimated"] and b == 1.0 and a == pytest.approx(-2e-4, abs=2e-5)


def test_resampling_undoes_offset_and_drift():
    fs, off, scale = 5000.0, -1.3, 1 - 60e-6
    tau = np.arange(0, 6, 1 / fs)
    true_t = off + scale * tau
    x = np.sin(2 * np.pi * 7 * true_t) + 0.3 * np.sin(2 * np.pi * 1200 * true_t)  # 1.2 kHz aliases
    t = np.arange(0, 4, 6e-4)
    y = to_controller_grid(tau, x, (off, scale), t, cutoff_hz=0.8 * 0.5 / 6e-4)
    assert np.nanmax(np.abs(y - np.sin(2 * np.pi * 7 * t))) < 2e-3  # 1.2 kHz removed, 7 Hz kept
    assert np.all(np.isfinite(y))
    out = to_controller_grid(tau, x, (off + 3.0, scale), t)
    start = off + 3.0                           # the record begins at controller time 1.7 s
    assert np.isnan(out[t < start - 1e-9]).all() and np.isfinite(out[t > start + 1e-3]).all()


def test_integration_drift_matches_monte_carlo():
    fs, T, noise, n = 5000.0, 0.5, 50.0, 300
    rng = np.random.default_rng(1)
    a = rng.normal(0, noise, (n, int(T * fs)))
    x_end = np.cumsum(np.cumsum(a, axis=1), axis=1)[:, -1] / fs ** 2
    assert np.std(x_end) == pytest.approx(integration_drift(noise, 0.0, 1 / fs, T), rel=0.15)
    assert integration_drift(0.0, 2.0, 1 / fs, 1.0) == pytest.approx(1.0)


def test_written_trace_keeps_late_time_stamps_apart(tmp_path):
    """A controller trace starting at t = 123456 s with Ts = 0.4 ms: written with 9 digits, the
    aligned CSV's time stamps would collide and the file could not be read back."""
    import numpy as np
    from fdid_fmi.align.writer import write_trace_csv
    from fdid_fmi.io import read_trace
    from fdid_fmi.trace import Channel, Trace
    t = 123456.0 + np.arange(50) * 4e-4
    x = np.linspace(0.0, 1.0, 50)
    tr = Trace(t=t, channels={"x_cmd": Channel("x_cmd", "mm", x), "x_act": Channel("x_act", "mm", 0.9 * x)},
               roles={"x": {"cmd": "x_cmd", "act": "x_act"}}, source="mem")
    back = read_trace(write_trace_csv(tr, tmp_path / "aligned.csv"))
    np.testing.assert_array_equal(back.t, t)
    np.testing.assert_array_equal(back.act("x"), tr.act("x"))
