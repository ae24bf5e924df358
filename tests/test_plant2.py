"""The second plant (tests/plant2) validated on its own physics, before it is used to judge
identification and diagnosis: following error of the P loop, LuGre sticking, the two-mass mode,
encoder quantisation, trajectory limits, integration convergence, delays and coupling."""
import math
from dataclasses import replace

import numpy as np
import pytest

from plant2 import Axis, Coupling, Machine, circle, diamond, point_to_point, random_moves, rigid, simulate
from plant2.plant import simulate_axis


def _ramp_path(Ts, v, dist=60.0):
    return point_to_point(Ts, [np.array([dist])], [v], [0.2], acc=2000.0, jerk=1e5, axes=("x",))


@pytest.mark.parametrize("Ts", [0.0005, 0.002])
def test_following_error_of_the_p_loop_is_v_over_kv(Ts):
    """At constant velocity v the integral action cancels friction: e = v / kv exactly (and 0
    with full velocity feed-forward)."""
    ax = Axis("x", kv=40.0, noise=0.0)
    v = 50.0
    p = _ramp_path(Ts, v)
    for vff, expected in ((0.0, v / 40.0), (1.0, 0.0)):
        tr = simulate(Machine(Ts=Ts, axes=(replace(ax, vff=vff),)), p)
        vc = np.gradient(tr.cmd("x"), Ts)
        steady = np.abs(vc - v) < 1e-6
        steady[: np.argmax(steady) + int(0.15 / Ts)] = False        # let the loop settle
        assert steady.sum() > 200
        e = tr.error("x")[steady]
        assert np.mean(e) == pytest.approx(expected, abs=2e-4 + 2e-3 * expected)
    # and the axis ends on the target within a few encoder steps
    assert abs(tr.error("x")[-1]) < 5e-4


def test_lugre_axis_sticks_below_breakaway_and_slides_above():
    """Controller off, a constant force on a resting axis: below the Coulomb level only
    presliding of the bristles (a few um), above it the axis slides away."""
    ax = Axis("x", kv=0.0, kp_vel=0.0, ti_vel=math.inf, coulomb=40.0, static=40.0, noise=0.0,
              resolution=1e-6, viscous=0.3)
    Ts, N = 0.001, 1000
    rng = np.random.default_rng(0)
    held = simulate_axis(ax, Ts, np.zeros(N), rng, f_ext=np.full(N, 0.8 * 40.0))
    assert np.max(np.abs(held["motor"])) < 3 * ax.bristle                     # presliding only
    assert np.max(np.abs(held["motor"][N // 2:] - held["motor"][-1])) < 1e-5  # and it stays put
    assert held["friction"][-1] == pytest.approx(0.8 * 40.0, abs=0.5)        # friction holds the force
    slid = simulate_axis(ax, Ts, np.zeros(N), rng, f_ext=np.full(N, 1.2 * 40.0))
    assert slid["motor"][-1] > 50 * ax.bristle                               # slides (~ 0.03 m/s^2 net)


def test_stribeck_breakaway_holds_more_than_the_sliding_level():
    """With static > coulomb a resting axis holds a force between the two levels (after LuGre
    presliding of -z_s ln(1 - F / F_s), z_s = F_s / sigma_0, a few um) and slides above F_s."""
    ax = Axis("x", kv=0.0, kp_vel=0.0, ti_vel=math.inf, coulomb=40.0, static=60.0, noise=0.0, resolution=1e-6)
    N = 800
    out = simulate_axis(ax, 0.001, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 50.0))
    z_s = 60.0 / (40.0 / ax.bristle)
    assert np.max(np.abs(out["motor"])) < 2 * (-z_s * math.log(1 - 50.0 / 60.0))
    assert np.ptp(out["motor"][N // 2:]) < 1e-7
    out = simulate_axis(ax, 0.001, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 62.0))
    assert out["motor"][-1] > 0.5                                    # breaks away, then slides (F > F_c)


def test_two_mass_mode_appears_in_the_tool_side_response():
    """Open loop, no friction: after a force pulse motor and table swing against each other at
    the free-free frequency sqrt(k (1/m1 + 1/m2)); in closed loop the tool side rings between the
    locked-motor and the free-free frequency."""
    Ts, N = 0.0005, 2000
    ax = Axis("y", two_mass=True, motor_mass=40.0, table_mass=70.0, lock_hz=38.0, mode_zeta=0.01,
              coulomb=0.0, static=0.0, viscous=0.0, noise=0.0, kv=0.0, kp_vel=0.0, ti_vel=math.inf)
    f = np.zeros(N)
    f[:4] = 500.0
    out = simulate_axis(ax, Ts, np.zeros(N), np.random.default_rng(0), f_ext=f)
    d = out["motor"] - out["table"]
    spec = np.abs(np.fft.rfft((d - d.mean()) * np.hanning(N), 16 * N))
    fr = np.fft.rfftfreq(16 * N, Ts)
    f_peak = fr[np.argmax(spec)]
    free = ax.derived()["free_free_mode_hz"]
    assert f_peak == pytest.approx(free, rel=0.01)
    # closed loop (a light tool-side mass on a heavy motor-side body): the tool side rings after a
    # fast short move between the locked-motor and the free-free frequency
    y = Axis("y", two_mass=True, motor_mass=100.0, table_mass=20.0, lock_hz=38.0, mode_zeta=0.01, kv=30.0,
             kp_vel=45.0, ti_vel=0.012, noise=0.0, table_share=0.3)
    p = point_to_point(0.001, [np.array([2.0])], [80.0], [1.0], acc=2e4, jerk=2e7, axes=("y",))
    tr = simulate(Machine(Ts=0.001, axes=(y,)), p)
    w = (tr.get("y", "tool") - tr.act("y"))[40:540]                 # 40 ms after the start, 0.5 s
    spec = np.abs(np.fft.rfft((w - w.mean()) * np.hanning(w.size), 16 * w.size))
    fr = np.fft.rfftfreq(16 * w.size, 0.001)
    band = fr > 10.0
    f_cl = fr[band][np.argmax(spec[band])]
    free = y.derived()["free_free_mode_hz"]
    assert 0.95 * 38.0 <= f_cl <= 1.05 * free
    assert np.ptp(w[60:160]) > 2e-3                                # still ringing 0.1 s later (> 2 um)


def test_encoder_quantisation_step_is_visible():
    """Without noise every recorded position is a multiple of the resolution and a slow move
    advances in single steps of it."""
    q = 1e-3
    m = Machine(Ts=0.001, axes=(Axis("x", resolution=q, noise=0.0),))
    p = point_to_point(0.001, [np.array([0.05])], [0.5], [0.1], acc=500.0, jerk=1e4, axes=("x",))
    tr = simulate(m, p)
    x = tr.act("x")
    assert np.allclose(x / q, np.round(x / q), atol=1e-9)
    steps = np.abs(np.diff(x))
    steps = steps[steps > 0]
    assert steps.size >= 40 and np.allclose(steps, q, atol=1e-9)
    # with noise the readings still sit on the grid but dither
    tr2 = simulate(Machine(Ts=0.001, axes=(Axis("x", resolution=q, noise=q),)), p)
    x2 = tr2.act("x")
    assert np.allclose(x2 / q, np.round(x2 / q), atol=1e-9) and np.sum(np.diff(x2) != 0) > steps.size


def test_trajectories_respect_limits_and_land_on_targets():
    Ts, acc, jerk = 0.001, 3000.0, 2e5
    p = random_moves(Ts, n_moves=15, seed=3, acc=acc, jerk=jerk)
    for c in p.cmd.values():
        a = np.diff(c, 2) / Ts ** 2
        assert np.max(np.abs(a)) <= acc * (1 + 1e-6)
        assert np.max(np.abs(np.diff(a)) / Ts) <= jerk * (1 + 1e-6)
    tgt = p.info["targets"][-1]
    assert [p.cmd["x"][-1], p.cmd["y"][-1]] == pytest.approx(tgt, abs=1e-9)
    c = circle(Ts, radius=20.0, feed=100.0, acc=acc, jerk=jerk)
    r = np.hypot(c.cmd["x"] + 20.0, c.cmd["y"])
    assert np.max(np.abs(r - 20.0)) < 1e-9 and abs(c.cmd["x"][-1]) < 1e-9
    d = diamond(Ts, half_diagonal=20.0, feed=120.0, acc=acc, jerk=jerk)
    for v in d.cmd.values():
        assert np.max(np.abs(np.diff(v, 2))) / Ts ** 2 <= acc * (1 + 1e-6)
        assert abs(v[-1]) < 1e-9


def test_integration_converges_and_is_deterministic():
    """The fixed-step scheme at the default step agrees with 4x finer steps to well below the
    encoder resolution relative to the tracking error; the same seed gives the same trace."""
    m = rigid(0.001, noise=0.0, resolution=1e-7)
    p = random_moves(0.001, n_moves=3, seed=5, axes=("x",))
    a = simulate(m, p, truth_channels=True)
    b = simulate(replace(m, integration_steps=4), p, truth_channels=True)
    dx = a.extra("x_motor_true") - b.extra("x_motor_true")
    e = a.error("x")
    assert np.max(np.abs(dx)) < 1e-3 * np.max(np.abs(e))
    c = simulate(m, p, truth_channels=True)
    assert np.array_equal(a.act("x"), c.act("x"))


def test_record_delay_shifts_the_recorded_channels():
    m = rigid(0.001)
    p = random_moves(0.001, n_moves=2, seed=2, axes=("x",))
    a = simulate(m, p, seed=4)
    b = simulate(m.with_axis("x", record_delay=2), p, seed=4)
    assert np.array_equal(b.act("x")[2:], a.act("x")[:-2])
    assert np.array_equal(b.cmd("x"), a.cmd("x"))
    assert "delay" in b.meta["truth"]["axes"]["x"]["effects"]


def test_cross_axis_coupling_moves_the_resting_axis():
    """Y accelerates, X is commanded to stand still: the coupling force shows in X's error only
    when the coupling is present."""
    Ts = 0.001
    p = point_to_point(Ts, [np.array([0.0, 40.0]), np.array([0.0, 0.0])], [200.0, 200.0], [0.1, 0.1],
                       acc=5000.0, jerk=5e5, axes=("x", "y"))
    base = rigid(Ts, noise=0.0, resolution=1e-6)
    free = simulate(base, p)
    coupled = simulate(replace(base, couplings=(Coupling("y", "x", 5.0),)), p)
    assert np.max(np.abs(free.act("x"))) < 1e-5
    assert np.max(np.abs(coupled.act("x"))) > 1e-4            # 5 kg x 5 m/s^2 = 25 N pushes X
    assert coupled.meta["truth"]["couplings"][0]["gain_kg"] == 5.0


def test_backlash_scenario_records_the_lost_motion_on_the_tool_side():
    """Scenario sets: one training and three named validation traces with the truth; in the
    backlash scenario the tool side lags the motor by the backlash after every reversal, and the
    motor-only variant records no tool channel."""
    from plant2 import scenario
    train, val, truth = scenario("backlash_tool", n_moves=3)
    assert len(train) == 1 and [v.meta["name"] for v in val] == ["circle", "diamond", "reversals"]
    assert truth["effect"] == "backlash" and truth["effect_params"]["backlash_mm"] == 0.015
    assert truth["Ts"] == 0.002 and val[2].Ts == pytest.approx(0.002)
    tr = val[2]
    cmd, off = tr.cmd("x"), tr.get("x", "tool") - tr.act("x")
    v = np.gradient(cmd, tr.Ts)
    moving = np.abs(v) > 1e-6
    last = np.zeros_like(v)
    s, since = 0.0, 0
    for k in range(v.size):                       # sign of the last move and time since it stopped
        if moving[k]:
            s, since = np.sign(v[k]), 0
        else:
            since += 1
        last[k] = s if since * tr.Ts > 0.05 else 0.0
    lost = np.median(off[last < 0]) - np.median(off[last > 0])
    assert lost == pytest.approx(0.015, abs=0.003)               # 15 um lost motion, within 3 um
    train_m, _, truth_m = scenario("backlash_motor", n_moves=3)
    assert not train_m[0].has("x", "tool") and truth_m["tool_recorded"] == []


def test_closed_loop_pairs_are_the_ringing_of_the_loop():
    """The truth a fitted mode is compared with (plant2.linear): the ARX poles of the
    friction-free closed loop converge with the order, and the lightly damped pair is the
    frequency at which the noise-free closed loop rings after a step (measured: 37.2 Hz, zeta 0.09
    on the flexible_y axis)."""
    from plant2 import flexible_y
    from plant2.linear import closed_loop_pairs, linear_axis
    m = flexible_y(0.001)
    ax = m.axis("y")
    lo, hi = (closed_loop_pairs(ax, m.Ts, order=k, n=12000)[0] for k in (12, 18))
    assert abs(lo[0] - hi[0]) < 0.05 and abs(lo[1] - hi[1]) < 0.005
    assert 0.9 * ax.lock_hz <= hi[0] <= 1.1 * ax.lock_hz and 0.02 < hi[1] < 0.3
    # the step response of the same linear loop rings at the pair's damped frequency
    x = simulate_axis(linear_axis(ax), m.Ts, np.r_[np.zeros(10), np.full(1990, 1e-3)], np.random.default_rng(0))["motor"]
    w = np.diff(x[60:1000])
    spec = np.abs(np.fft.rfft((w - w.mean()) * np.hanning(w.size), 16 * w.size))
    fr = np.fft.rfftfreq(16 * w.size, m.Ts)
    band = fr > 15.0
    assert fr[band][np.argmax(spec[band])] == pytest.approx(hi[0] * np.sqrt(1 - hi[1] ** 2), rel=0.05)
