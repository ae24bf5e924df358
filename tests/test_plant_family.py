"""The seeded plant family (tests/family) checked on its own physics before it judges the
diagnosis: determinism by seed, plausible closed loops over a sweep of seeds, each effect present
exactly when drawn, and the split by seed."""
import math
from dataclasses import replace

import numpy as np
import pytest

from family import KINDS, AxisPlant, Machine, case, seeds, split_of
from family import paths
from family.cases import _loop_rate, simulate
from family.plant import simulate_axis
from fdid_fmi.trace import Trace

SCALE = 0.2         # short traces: each case builds in about a second
SWEEP = range(0, 16)


def _first_seed(kind, extra=lambda c: True, limit=200):
    """The first seed whose case has an effect of this kind (and passes ``extra``)."""
    for s in range(limit):
        c = case(s, traces=False)
        if kind in c.kinds and extra(c):
            return s, case(s, scale=SCALE)
    raise AssertionError(f"no case with {kind} in seeds 0..{limit - 1}")


def _clean_seed(limit=200):
    for s in range(limit):
        if not case(s, traces=False).kinds:
            return s, case(s, scale=SCALE)
    raise AssertionError("no clean case")


def test_same_seed_gives_bit_identical_traces():
    a, b = case(3, scale=SCALE), case(3, scale=SCALE)
    assert a.machine == b.machine and a.effects == b.effects
    for ta, tb in zip(a.train + a.val, b.train + b.val):
        assert ta.fingerprint() == tb.fingerprint()
    assert case(4, scale=SCALE).train[0].fingerprint() != a.train[0].fingerprint()


def test_split_by_seed_and_seed_lists():
    assert [split_of(s) for s in range(4)] == ["calibration", "held-out", "calibration", "held-out"]
    assert case(6, traces=False).split == "calibration" and case(7, traces=False).split == "held-out"
    assert seeds("held-out", 3) == [1, 3, 5] and seeds("calibration", 2, start=3) == [4, 6]
    assert seeds("all", 3, start=10) == [10, 11, 12]


def test_traces_have_the_roles_of_a_controller_trace():
    for s in (0, 1, 3):
        c = case(s, scale=SCALE)
        for tr in c.train + c.val:
            assert isinstance(tr, Trace)
            assert set(tr.axes) == {a.name for a in c.machine.axes}
            for ax in c.machine.axes:
                r = tr.roles[ax.name]
                assert {"cmd", "act"} <= set(r) <= {"cmd", "act", "vel", "cur", "tool"}
                assert ("vel" in r) == ax.vel_channel and ("tool" in r) == ax.tool_channel
                assert tr.channel(ax.name, "cmd").unit == "mm" and tr.channel(ax.name, "act").unit == "mm"
            assert tr.Ts == pytest.approx(c.machine.Ts)
            assert tr.meta["name"] in ("moves", "strokes", "contour")
            # the axis of interest moves in every trace (diagnosis needs moves)
            assert np.ptp(tr.cmd(c.axis)) > 1.0


@pytest.mark.parametrize("seed", SWEEP)
def test_closed_loop_is_plausible_and_stable(seed):
    """No NaN; the force (current) limit holds; the tracking error stays within what the loop's
    gain allows for the commanded speed; every trace ends settled (except under a measured
    external force, which acts at rest too)."""
    c = case(seed, scale=SCALE)
    Ts = c.machine.Ts
    assert 0.0005 <= Ts <= 0.002
    for tr in c.train + c.val:
        for ax in c.machine.axes:
            assert 20.0 <= ax.mass <= 1250.0 and 300.0 <= ax.current_hz <= 2000.0
            assert 1e-5 <= ax.resolution_mm <= 1e-3
            F = tr.meta["force_N"][ax.name]
            assert np.all(np.isfinite(F)) and np.max(np.abs(F)) <= ax.f_max * (1 + 1e-9)
            if tr.has(ax.name, "cur"):
                assert np.max(np.abs(tr.get(ax.name, "cur"))) <= ax.f_max / ax.kt * (1 + 1e-9)
            e = tr.error(ax.name)
            v = np.abs(np.diff(tr.cmd(ax.name))) / Ts
            vmax = float(v.max())
            assert vmax <= 20000.0 / 60.0 * 1.01          # at most 20 m/min
            lag = vmax / _loop_rate(ax) if ax.vff == 0 else 0.0
            bound = 1.3 * (lag + vmax * ax.record_delay * Ts) + 2e-3 * vmax + 0.05
            assert np.max(np.abs(e)) < bound, (tr.meta["name"], ax.name, np.max(np.abs(e)), bound)
            if ax.name == c.axis and c.machine.disturbance_rms:
                continue
            rest = np.abs(e[-int(0.05 / Ts):])
            assert rest.max() < 0.05 + ax.backlash_mm, (tr.meta["name"], ax.name, rest.max())


def test_following_error_at_constant_speed_is_v_over_kv_plus_the_dead_time():
    """P-PI without feed-forward: the integral action cancels friction at constant speed, leaving
    e = v / kv; a recording delay of d samples adds v d Ts; with full velocity feed-forward e = 0."""
    Ts, v = 0.001, 40.0
    ax = AxisPlant(kv=30.0, kp_vel=20.0, ti_vel=0.02, m_est=100.0, noise_mm=0.0, resolution_mm=1e-6,
                   motor_mass=40.0, table_mass=60.0, f_max=5000.0)
    cmd = paths.line_moves([0.0], [[120.0]], [v], 1000.0, Ts, 0.01, [0.5])
    for changes, expected in (({}, v / 30.0), ({"record_delay": 2}, v / 30.0 + 2 * v * Ts),
                              ({"vff": 1.0}, 0.0)):
        tr = simulate(Machine(Ts=Ts, axes=(replace(ax, **changes),)), cmd, np.random.default_rng(0), "ramp", "test")
        vc = np.gradient(tr.cmd("x"), Ts)
        steady = np.flatnonzero(np.abs(vc - v) < 1e-6)
        steady = steady[steady > steady[0] + int(1.0 / Ts)]      # after the loop settled
        assert steady.size > 300
        assert np.mean(tr.error("x")[steady]) == pytest.approx(expected, abs=2e-4 + 2e-3 * expected)


def test_friction_sticks_below_breakaway_and_slides_above():
    """Controller off, a constant force on a resting axis: held below the Coulomb level (bristle
    presliding only), sliding above it; a Stribeck breakaway holds more than the sliding level."""
    base = AxisPlant(controller="pid", kp_pid=0.0, ki_pid=0.0, kd_pid=0.0, noise_mm=0.0, resolution_mm=1e-7,
                     coulomb=40.0, static=40.0, viscous=0.1, motor_mass=50.0, table_mass=50.0, bristle_mm=5e-4)
    N, Ts = 800, 0.001
    held = simulate_axis(base, Ts, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 0.8 * 40.0))
    assert np.max(np.abs(held["x1"])) < 3 * base.bristle_mm
    slid = simulate_axis(base, Ts, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 1.2 * 40.0))
    assert slid["x1"][-1] > 100 * base.bristle_mm
    strib = replace(base, static=70.0, stribeck_velocity=2.0)
    held2 = simulate_axis(strib, Ts, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 55.0))
    assert np.max(np.abs(held2["x1"])) < 3 * 70.0 / 40.0 * base.bristle_mm
    slid2 = simulate_axis(strib, Ts, np.zeros(N), np.random.default_rng(0), f_ext=np.full(N, 75.0))
    assert slid2["x1"][-1] > 100 * base.bristle_mm


def test_rk4_substeps_converge():
    """Doubling the RK4 steps per sample changes a two-mass run by less than 0.2 um, below the
    coarser encoder steps of the family (the friction held over each step makes the scheme
    first order overall: the change halves, roughly, with each doubling)."""
    import family.plant as fp
    ax = AxisPlant(two_mass=True, lock_hz=60.0, mode_zeta=0.03, motor_mass=60.0, table_mass=30.0, m_est=90.0,
                   kv=25.0, kp_vel=15.0, ti_vel=0.03, noise_mm=0.0, resolution_mm=1e-7, f_max=4000.0)
    Ts = 0.001
    cmd = paths.line_moves([0.0], [[30.0], [0.0]], [100.0, 100.0], 3000.0, Ts, 0.0, [0.2, 0.2])[:, 0]
    a = simulate_axis(ax, Ts, cmd, np.random.default_rng(0))
    orig = fp.substeps
    try:
        fp.substeps = lambda ax_, Ts_: 2 * orig(ax_, Ts_)
        b = simulate_axis(ax, Ts, cmd, np.random.default_rng(0))
    finally:
        fp.substeps = orig
    assert b["n_sub"] == 2 * a["n_sub"]
    assert np.max(np.abs(a["x2"] - b["x2"])) < 2e-4


def test_paths_respect_their_limits_and_land_on_target():
    Ts = 0.001
    p = paths.line_moves([0.0, 0.0], [[50.0, 0.0], [50.0, 30.0]], [200.0, 100.0], 2000.0, Ts, 0.02, [0.1, 0.1])
    assert np.allclose(p[-1], [50.0, 30.0], atol=1e-9)
    v = np.diff(p, axis=0) / Ts
    a = np.diff(v, axis=0) / Ts
    assert np.max(np.abs(v)) <= 200.0 * 1.01 and np.max(np.abs(a)) <= 2000.0 * 1.05
    circ = paths.circle([0.0, 0.0], 20.0, 150.0, 3000.0, Ts, 0.01)
    assert np.allclose(np.hypot(circ[:, 0], circ[:, 1]), 20.0) and np.allclose(circ[-1], [20.0, 0.0], atol=1e-9)


def _pair(kind, extra=lambda c: True):
    s, c = _first_seed(kind, extra)
    return c, case(s, without=(kind,), scale=SCALE)


def test_an_absent_effect_left_out_changes_nothing():
    s, c = _clean_seed()
    for k in KINDS:
        o = case(s, without=(k,), scale=SCALE, validation=False)
        assert o.train[0].fingerprint() == c.train[0].fingerprint() and o.machine == c.machine


def test_visibility_measures_the_shift_an_effect_causes():
    """A recording delay of d samples shifts the encoder channel by about v d Ts while moving: far
    above the noise; the case's other effect, when it has one, is measured on its own."""
    from family import visibility
    s, c = _first_seed("delay")
    v = visibility(c, SCALE)
    assert set(v) == set(c.kinds)
    tr = c.train[0]
    d = int(c.effect("delay").magnitude)
    shift = tr.act("x")[d:] - tr.act("x")[:-d]
    assert v["delay"]["act_rms_um"] == pytest.approx(np.sqrt(np.mean(shift ** 2)) * 1e3, rel=0.3)
    assert v["delay"]["noise_ratio"] > 10


def test_dead_time_delays_every_measured_channel_by_its_samples():
    c, o = _pair("delay")
    d = int(c.effect("delay").magnitude)
    assert 1 <= d <= 3 and c.effect("delay").params["seconds"] == pytest.approx(d * c.machine.Ts)
    tr, tr0 = c.train[0], o.train[0]
    assert np.array_equal(tr.cmd("x"), tr0.cmd("x"))
    for role in ("act", "vel", "cur", "tool"):
        if tr.has("x", role):
            assert np.array_equal(tr.get("x", role)[d:], tr0.get("x", role)[:-d])
            assert not np.array_equal(tr.get("x", role), tr0.get("x", role))


def test_backlash_opens_a_lost_motion_on_the_tool_side_channel():
    c, o = _pair("backlash", lambda c: c.effect("backlash").params["tool"]
                 and c.effect("backlash").magnitude > 20 * c.machine.axes[0].resolution_mm)
    e = c.effect("backlash")
    tr = c.train[0]
    assert tr.has("x", "tool") and c.machine.axes[0].two_mass
    true = tr.meta["true"]["x"]
    lost = true["x1"] - true["x2"]
    # the motor side runs ahead of the tool side by about half the gap in either direction
    assert np.ptp(lost) == pytest.approx(e.magnitude, rel=0.35, abs=2e-4)
    diff = tr.get("x", "tool") - tr.get("x", "act")
    assert np.ptp(diff) > 0.5 * e.magnitude
    assert not o.machine.axes[0].two_mass or o.machine.axes[0].backlash_mm == 0.0


def test_backlash_without_a_tool_encoder_records_no_tool_channel():
    c, _ = _pair("backlash", lambda c: not c.effect("backlash").params["tool"])
    assert not c.train[0].has("x", "tool") and c.machine.axes[0].backlash_mm == c.effect("backlash").magnitude


def test_periodic_force_follows_the_motor_position_with_its_period():
    """Where the force's frequency v / period is well inside the velocity loop's bandwidth, the
    loop cancels it: the motor-force difference to the case without it is
    -A sin(2 pi x1 / period + phase), by amplitude and for the bulk of the samples."""
    c, o = _pair("periodic_position", lambda c: c.effect("periodic_position").magnitude > 2.0)
    e = c.effect("periodic_position")
    tr, tr0 = c.train[0], o.train[0]
    dF = tr.meta["force_N"]["x"] - tr0.meta["force_N"]["x"]
    x1 = tr.meta["true"]["x"]["x1"]
    slow = np.abs(np.gradient(x1, tr.Ts)) / e.params["period_mm"] < c.machine.axes[0].velocity_bandwidth_hz() / 5
    assert slow.sum() > 500
    dF, x1 = dF[slow], x1[slow]
    ph = 2 * np.pi * x1 / e.params["period_mm"] + e.params["phase_rad"]
    X = np.column_stack([np.sin(ph), np.cos(ph), np.ones_like(ph)])
    th, *_ = np.linalg.lstsq(X, dF, rcond=None)
    assert th[0] == pytest.approx(-e.magnitude, rel=0.4)
    # the rest is small but for the short spikes where the two runs' friction switches at
    # slightly different instants (the paths differ by the force's effect)
    assert np.median(np.abs(dF - X @ th)) < 0.2 * e.magnitude


def test_stribeck_raises_the_breakaway_level():
    c, o = _pair("stribeck")
    e = c.effect("stribeck")
    x, x0 = c.machine.axes[0], o.machine.axes[0]
    assert x.static == pytest.approx(x0.coulomb + e.magnitude) and x0.static == x0.coulomb
    assert x.stribeck_velocity == e.params["v_s_mm_s"] and 0.5 <= e.params["v_s_mm_s"] <= 10.0
    assert not np.array_equal(c.train[0].act("x"), o.train[0].act("x"))


def test_mode_oscillates_at_its_frequency():
    c, o = _pair("mode", lambda c: c.effect("mode").params["zeta"] < 0.05 and "backlash" not in c.kinds)
    e = c.effect("mode")
    x = c.machine.axes[0]
    assert x.two_mass and x.table_mass == pytest.approx(e.magnitude) and x.lock_hz == e.params["lock_hz"]
    assert x.mass == pytest.approx(o.machine.axes[0].mass)
    tr = c.train[0]
    t = tr.meta["true"]["x"]
    defl = t["x1"] - t["x2"]
    spec = np.abs(np.fft.rfft(defl - np.mean(defl)))
    f = np.fft.rfftfreq(defl.size, tr.Ts)
    band = f > 0.5 * x.lock_hz        # above the quasi-static deflection under acceleration
    peak = f[band][np.argmax(spec[band])]
    assert 0.8 * x.lock_hz <= peak <= 1.2 * x.free_free_hz()
    assert not tr.has("x", "tool") or x.tool_channel


def test_coupling_moves_x_with_the_acceleration_of_y():
    c, o = _pair("coupling")
    e = c.effect("coupling")
    assert len(c.machine.axes) == 2 and c.machine.coupling_kg == e.magnitude and o.machine.coupling_kg == 0.0
    tr, tr0 = c.train[0], o.train[0]
    assert np.array_equal(tr.act("y"), tr0.act("y"))          # the source is not affected
    assert not np.array_equal(tr.act("x"), tr0.act("x"))
    assert e.params["channel"] in tr.channels


def test_extra_input_is_a_measured_force_that_drives_the_plant():
    c, o = _pair("extra_input")
    e = c.effect("extra_input")
    tr, tr0 = c.train[0], o.train[0]
    ch = e.params["channel"]
    assert ch in tr.extra_channels and tr.channels[ch].unit == "N"
    assert np.std(tr.extra(ch)) == pytest.approx(e.magnitude, rel=0.1)
    assert ch not in tr0.channels or not o.machine.disturbance_rms
    assert not np.array_equal(tr.act("x"), tr0.act("x"))


def test_a_decoy_channel_does_not_act_on_the_plant():
    for s in range(200):
        c = case(s, traces=False)
        if c.machine.decoy_channel and not c.kinds:
            c = case(s, scale=SCALE)
            break
    else:
        raise AssertionError("no clean case with a decoy channel")
    assert c.machine.disturbance_channel in c.train[0].extra_channels and c.machine.disturbance_rms == 0.0
    quiet = simulate(replace(c.machine, decoy_channel=False), np.column_stack(
        [c.train[0].cmd(a.name) for a in c.machine.axes]), np.random.default_rng(0), "moves", "test")
    loud = simulate(c.machine, np.column_stack([c.train[0].cmd(a.name) for a in c.machine.axes]),
                    np.random.default_rng(0), "moves", "test")
    assert np.array_equal(quiet.act("x"), loud.act("x"))


def test_effects_are_drawn_over_the_kinds_and_magnitudes_recorded():
    """Over 60 seeds every kind occurs, no case has more than two, and each effect's magnitude
    is recorded in its unit (not built: only the draws)."""
    from family.cases import UNITS
    counts = {k: 0 for k in KINDS}
    n_clean = 0
    for s in range(60):
        c = case(s, traces=False)
        assert len(c.kinds) <= 2 and len(set(c.kinds)) == len(c.kinds)
        n_clean += not c.kinds
        for e in c.effects:
            counts[e.kind] += 1
            assert e.unit == UNITS[e.kind] and e.magnitude > 0 and math.isfinite(e.relative)
            if e.kind == "coupling":
                assert len(c.machine.axes) == 2
    assert all(v > 0 for v in counts.values()), counts
    assert 5 <= n_clean <= 35
