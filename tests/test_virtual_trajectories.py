"""Jerk-limited trajectories of the virtual feed drive: limits, targets, reproducibility."""
import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.virtual import trajectories as T

REL = 1e-9  # finite differences never exceed the true derivative peak; only rounding allowed


def slack(tr, k):
    """Rounding bound of a k-th difference quotient of positions of size max|x| (mm)."""
    P = np.column_stack([tr[a] for a in tr.axes])
    return 2 ** k * 8 * np.finfo(float).eps * max(1.0, np.abs(P).max()) / tr.Ts ** k


def fd_peaks(tr):
    """Per-axis and vector peaks of |v|, |a|, |j| by finite differences at Ts.

    A k-th difference / Ts^k is a positively weighted average of the k-th derivative
    (B-spline kernel), so these are lower bounds of the true peaks: a limit violation
    of the true profile larger than the averaging shows up here.
    """
    P = np.column_stack([tr[a] for a in tr.axes])
    d1 = np.diff(P, axis=0) / tr.Ts
    d2 = np.diff(d1, axis=0) / tr.Ts
    d3 = np.diff(d2, axis=0) / tr.Ts
    axis = [np.abs(d).max(axis=0) for d in (d1, d2, d3)]
    vec = [np.linalg.norm(d, axis=1).max() for d in (d1, d2, d3)]
    return axis, vec


@pytest.mark.parametrize("dist, v, a, j", [(50.0, 100.0, 2000.0, 1e5),   # cruise phase
                                           (1.0, 100.0, 2000.0, 1e5),    # a_max not reached
                                           (8.0, 100.0, 2000.0, 1e6),    # no cruise, a_max reached
                                           (0.0, 10.0, 10.0, 10.0)])
def test_scurve_reaches_distance_within_limits(dist, v, a, j):
    p = T.scurve(dist, v, a, j)
    tau = np.linspace(0, p.duration, 20001)
    s, vv, aa, jj = p.evaluate(tau)
    assert s[-1] == dist and vv[-1] == 0.0 and aa[-1] == 0.0
    assert np.all(np.diff(s) >= -1e-12)  # never moves backwards
    assert vv.max() <= v * (1 + REL) and np.abs(aa).max() <= a * (1 + REL)
    assert np.abs(jj).max() <= j * (1 + REL)
    if dist == 50.0:
        assert p.v_peak == pytest.approx(v) and p.durations[3] > 0
    if dist == 1.0:
        assert p.a_peak < a and p.v_peak < v
    # continuity of s, v, a at the segment joins (jerk-limited means C2 position)
    assert np.abs(np.diff(vv)).max() < 1e-2 * max(v, 1) and np.abs(np.diff(aa)).max() <= j * p.duration / 20000 * 1.01 + 1e-9


def test_point_to_point_reaches_target_and_dwells():
    tr = T.point_to_point(-3.0, 47.0, v=120, acc=3000, jerk=2e5, Ts=1e-3, dwell=(0.1, 0.2))
    x = tr["x"]
    assert x[0] == -3.0 and x[-1] == 47.0
    assert np.all(x[:100] == -3.0)           # 0.1 s dwell at the start
    assert np.all(x[-150:] == 47.0)          # at rest at the end (>= 0.15 s of the 0.2 s dwell)
    (v, a, j), _ = fd_peaks(tr)
    assert v[0] <= 120 + slack(tr, 1) and a[0] <= 3000 + slack(tr, 2) and j[0] <= 2e5 + slack(tr, 3)
    assert v[0] > 0.99 * 120                 # and it does use the feed


def test_linear_moves_limits_targets_and_seed():
    kw = dict(n_moves=12, d_min=2, d_max=30, stroke=60, v=150, acc=4000, jerk=3e5, Ts=5e-4,
              axes=("x", "y"))
    tr = T.linear_moves(seed=7, **kw)
    (v, a, j), _ = fd_peaks(tr)
    assert (v <= 150 + slack(tr, 1)).all() and (a <= 4000 + slack(tr, 2)).all()
    assert (j <= 3e5 + slack(tr, 3)).all()
    for ax in tr.axes:
        assert np.abs(tr[ax]).max() <= 30 + 1e-12          # inside the stroke
    # every move reaches its logged target and only one axis moves at a time
    for mv in tr.info["moves"]:
        k_end = int(np.ceil(mv["t_end"] / tr.Ts))
        assert tr[mv["axis"]][k_end] == pytest.approx(mv["target"], abs=1e-12)
    P = np.column_stack([tr[a] for a in tr.axes])
    moving = np.abs(np.diff(P, axis=0)) > 0
    assert not np.any(moving.all(axis=1))
    # back and forth: consecutive moves of one axis alternate direction (or turn at the stroke)
    assert len({mv["axis"] for mv in tr.info["moves"]}) == 2
    pos, last, reversals = {a: 0.0 for a in tr.axes}, {}, 0
    for mv in tr.info["moves"]:
        a = mv["axis"]
        s = np.sign(mv["target"] - pos[a])
        if a in last:
            # the same direction again only when reversing had less than d_min of room left
            assert s != last[a] or 30 + last[a] * pos[a] < 2, (mv, pos[a])
            reversals += s != last[a]
        pos[a], last[a] = mv["target"], s
    assert reversals >= 8                                   # 10 consecutive pairs; measured 10
    same = T.linear_moves(seed=7, **kw)
    other = T.linear_moves(seed=8, **kw)
    assert all(np.array_equal(tr[a], same[a]) for a in tr.axes)
    assert not np.array_equal(tr["x"], other["x"]) or not np.array_equal(tr["y"], other["y"])


def test_diamond_corners_and_limits():
    tr = T.diamond(edge=20, v=100, acc=2000, jerk=1e5, Ts=1e-3, loops=2)
    x, y = tr["x"], tr["y"]
    h = 20 / np.sqrt(2)
    assert (x[0], y[0]) == pytest.approx((-h, 0.0)) and (x[-1], y[-1]) == pytest.approx((-h, 0.0), abs=1e-12)
    assert x.max() == pytest.approx(h) and y.min() == pytest.approx(-h)
    # on the diamond |x| + |y| = h all the time
    assert np.abs(np.abs(x) + np.abs(y) - h).max() < 1e-9
    _, (v, a, j) = fd_peaks(tr)
    assert v <= 100 + slack(tr, 1) and a <= 2000 + slack(tr, 2) and j <= 1e5 + slack(tr, 3)


@pytest.mark.parametrize("make, check", [
    (lambda: T.circle(radius=20, v=150, acc=3000, jerk=2e5, Ts=1e-3, turns=1.5), "circle"),
    (lambda: T.spiral(r_start=2, r_end=20, turns=3, v=100, acc=2000, jerk=1e5, Ts=1e-3), "spiral"),
    (lambda: T.figure_eight(width=40, height=20, v=120, acc=2500, jerk=1e5, Ts=1e-3), "eight"),
])
def test_curves_vector_limits_and_geometry(make, check):
    tr = make()
    info = tr.info
    _, (v, a, j) = fd_peaks(tr)
    assert v <= info["v"] + slack(tr, 1) and a <= info["acc"] + slack(tr, 2)
    assert j <= info["jerk"] + slack(tr, 3)
    assert 0.3 < info["time_scale"] <= 1.0
    x, y = tr["x"], tr["y"]
    r = np.hypot(x, y)
    if check == "circle":
        assert np.abs(r - 20).max() < 1e-6
        ang = np.unwrap(np.arctan2(y, x))
        assert ang[-1] - ang[0] == pytest.approx(1.5 * 2 * np.pi, abs=1e-6)
    elif check == "spiral":
        assert r[0] == pytest.approx(2.0) and r[-1] == pytest.approx(20.0, abs=1e-6)
    else:
        assert (x[-1], y[-1]) == pytest.approx((0.0, 0.0), abs=1e-9)
        assert x.max() == pytest.approx(20, abs=1e-3) and y.max() == pytest.approx(10, abs=1e-3)
    # at rest during the dwells at both ends
    n_dw = int(0.25 / tr.Ts)
    assert np.ptp(x[:n_dw]) == 0 and np.ptp(x[-n_dw:]) == 0


def test_bad_limits_raise_input_error():
    with pytest.raises(InputError, match="v"):
        T.point_to_point(0, 10, v=-1)
    with pytest.raises(InputError, match="d_min"):
        T.linear_moves(d_min=0)
    with pytest.raises(InputError, match="speed_range"):
        T.linear_moves(speed_range=(0.5, 1.5))


def test_as_trace_has_cmd_roles():
    tr = T.circle(Ts=1e-3)
    trace = tr.as_trace()
    assert trace.axes == ["x", "y"] and trace.Ts == pytest.approx(1e-3)
    assert np.array_equal(trace.cmd("y"), tr["y"])
