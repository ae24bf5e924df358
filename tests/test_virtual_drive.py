"""The virtual feed drive against its own stated truth (no mocks: real simulations)."""
import dataclasses
import json

import numpy as np
import pytest
from scipy import signal

from fdid_fmi.errors import InputError
from fdid_fmi.trace import Trace
from fdid_fmi.virtual import (AxisConfig, Coupling, MachineConfig, PRESETS, coupled_xy,
                              deckel_maho_like, emps_like, flexible_y, linear_moves, linear_truth,
                              point_to_point, simulate_drive, simulate_machine, with_feedforward)

NONLINEAR_OFF = dict(coulomb=0.0, coulomb_neg=None, stribeck=0.0, backlash=0.0, periodic_amplitude=0.0,
                     force_offset=0.0, resolution=0.0, noise_std=0.0, force_limit=float("inf"))


def linearised(cfg):
    for a in cfg.axes:
        for k, v in NONLINEAR_OFF.items():
            setattr(a, k, v)
    return cfg


def moves(cfg, seed=2, **kw):
    args = dict(n_moves=10, axes=tuple(cfg.axis_names), v=100, acc=2000, jerk=1e5, Ts=cfg.Ts, seed=seed)
    args.update(kw)
    return linear_moves(**args)


def dlsim_outputs(cfg, traj, truth):
    """Sampled-truth state space driven by the command (input r_{k+1}, offsets removed)."""
    ss = truth["sampled"]["state_space"]
    A, B, C, D = (np.array(ss[k]) for k in "ABCD")
    R = np.column_stack([traj[a] for a in cfg.axis_names])
    W = np.vstack([R[1:], R[-1:]]) - R[0]
    _, Y, _ = signal.dlsim((A, B, C, D, cfg.Ts), W)
    return Y, R


# --------------------------------------------------------------------------- linear truth
@pytest.mark.parametrize("preset", ["deckel_maho_like", "with_feedforward", "flexible_y", "coupled_xy",
                                    "emps_like"])
def test_linear_simulation_is_the_sampled_truth(preset):
    """Friction and nonlinearities off: the simulator IS the stated discrete closed loop."""
    cfg = linearised(PRESETS[preset]())
    traj = moves(cfg)
    out = simulate_machine(cfg, traj)
    truth = out.meta["truth"]["linear"]
    Y, R = dlsim_outputs(cfg, traj, truth)
    for j, a in enumerate(cfg.axis_names):
        assert np.abs(Y[:, 3 * j] - out.error(a)).max() < 1e-9            # mm
        assert np.abs(Y[:, 3 * j + 1] + R[0, j] - out.extra(f"{a}_act_true")).max() < 1e-9
        if cfg.axis(a).two_mass:
            assert np.abs(Y[:, 3 * j + 2] + R[0, j] - out.get(a, "tool")).max() < 1e-9


@pytest.mark.parametrize("preset, tol", [("deckel_maho_like", 0.01), ("flexible_y", 0.01),
                                         ("coupled_xy", 0.01), ("emps_like", 0.025)])
def test_continuous_truth_tf_matches_simulation(preset, tol):
    """G_er(s) num/den (controller treated as continuous) simulated with lsim reproduces the
    sampled simulation's tracking error to ``tol`` of its peak (Ts 0.6-1 ms, tens of Hz)."""
    cfg = linearised(PRESETS[preset]())
    traj = moves(cfg, n_moves=8)
    out = simulate_machine(cfg, traj)
    G = out.meta["truth"]["linear"]["continuous"]["G_er"]
    R = np.column_stack([traj[a] for a in cfg.axis_names])
    for j, a in enumerate(cfg.axis_names):
        e = out.error(a)
        pred = np.zeros_like(e)
        for i, b in enumerate(cfg.axis_names):
            g = G[a][b]
            if np.any(g["num"]):
                pred += signal.lsim((g["num"], g["den"]), R[:, i] - R[0, i], traj.t)[1]
        assert np.abs(pred - e).max() < tol * np.abs(e).max()
        if cfg.axis(a).two_mass:
            g = out.meta["truth"]["linear"]["continuous"]["G_er_tool"][a][a]
            et = traj[a] - out.get(a, "tool")
            pt = signal.lsim((g["num"], g["den"]), R[:, j] - R[0, j], traj.t)[1]
            assert np.abs(pt - et).max() < tol * np.abs(et).max()


def test_taylor_coefficients_match_quasi_static_fit():
    """Thesis Eqn 3.5 LS fit on a gentle trajectory recovers the truth K_vel, K_acc (Eqn 3.2)."""
    cfg = linearised(deckel_maho_like())
    one = MachineConfig([cfg.axes[0]], Ts=cfg.Ts)
    traj = linear_moves(n_moves=12, v=100, acc=300, jerk=1500, Ts=cfg.Ts, seed=2, d_min=10, d_max=50)
    out = simulate_machine(one, traj)
    r, e, Ts = traj["x"], out.error("x"), cfg.Ts
    rd = np.gradient(r, Ts)
    rdd = np.gradient(rd, Ts)
    rddd = np.gradient(rdd, Ts)
    K_vel, K_acc, _ = np.linalg.lstsq(np.column_stack([rd, rdd, rddd]), e, rcond=None)[0]
    Ks = out.meta["truth"]["linear"]["sampled"]["K"]["x"]["x"]
    Kc = out.meta["truth"]["linear"]["continuous"]["K"]["x"]["x"]
    assert Kc["K_vel"] == pytest.approx(1 / 80.0, rel=1e-9) == Ks["K_vel"]   # type-1 loop: 1/Kp
    assert K_vel == pytest.approx(Ks["K_vel"], rel=0.005)
    assert K_acc == pytest.approx(Ks["K_acc"], rel=0.025)
    assert K_acc == pytest.approx(Kc["K_acc"], rel=0.025)
    # the sampled loop lags the continuous one by the ZOH's half sample: dK_acc = -K_vel Ts/2
    assert Ks["K_acc"] - Kc["K_acc"] == pytest.approx(-Kc["K_vel"] * Ts / 2, rel=0.02)


def test_taylor_coefficients_of_a_known_tf():
    """P-PI, no lag, no ff: G_er = s (m Ti s^2 + Kv Ti s + Kv) / (m Ti s^3 + Kv Ti s^2 + Kv (1+Ti Kp) s + Kv Kp)."""
    m, Kp, Kv, Ti = 0.2, 50.0, 60.0, 0.02     # N/(mm/s^2), 1/s, N/(mm/s), s
    cfg = MachineConfig([AxisConfig("x", Kp=Kp, Kv=Kv, Ti=Ti, mass=m * 1000)], Ts=1e-4)
    K = linear_truth(cfg)["continuous"]["K"]["x"]["x"]
    num = np.array([m * Ti, Kv * Ti, Kv, 0.0])
    den = np.array([m * Ti, Kv * Ti, Kv * (1 + Ti * Kp), Kv * Kp])
    # series division num/den at s = 0 (ascending powers)
    a, b = num[::-1], den[::-1]
    c = np.zeros(4)
    for k in range(4):
        c[k] = (a[k] - sum(c[i] * b[k - i] for i in range(k))) / b[0]
    assert K["K_vel"] == pytest.approx(c[1], rel=1e-10)
    assert K["K_acc"] == pytest.approx(c[2], rel=1e-9)
    assert K["K_jerk"] == pytest.approx(c[3], rel=1e-8)


def test_truth_contents_and_json():
    cfg = flexible_y()
    out = simulate_machine(cfg, moves(cfg, n_moves=3))
    truth = out.meta["truth"]
    assert set(truth) >= {"machine", "effects", "seed", "integration", "linear", "steps"}
    assert "two_mass" in truth["effects"]["y"] and "coulomb_friction" in truth["effects"]["x"]
    lin = truth["linear"]
    assert set(lin["continuous"]) >= {"poles", "G_er", "G_er_tool", "K", "K_tool", "modes", "state_space"}
    assert set(lin["sampled"]) >= {"poles", "poles_z", "K", "K_tool", "state_space"}
    mode = lin["continuous"]["modes"]["y"]
    assert abs(mode["hz"] - 25.8) < 0.5 and mode["zeta"] < 0.05
    assert all(p["re"] < 0 for p in lin["continuous"]["poles"])          # stable loop
    assert all(np.hypot(*z) < 1 for z in lin["sampled"]["poles_z"])
    json.dumps(out.meta)  # provenance must be serialisable


# --------------------------------------------------------------------------- effects
def test_flexible_mode_visible_on_tool_channel():
    cfg = flexible_y()
    traj = moves(cfg, n_moves=8, acc=4000, jerk=4e5, seed=5)
    out = simulate_machine(cfg, traj)
    d = out.get("y", "tool") - out.extra("y_act_true")
    d = d - d.mean()
    f = np.fft.rfftfreq(d.size, cfg.Ts)
    S = np.abs(np.fft.rfft(d * np.hanning(d.size)))
    band = f > 5
    peak = f[band][np.argmax(S[band])]
    mode = out.meta["truth"]["linear"]["continuous"]["modes"]["y"]["hz"]
    assert abs(peak - mode) < 2 * (f[1] - f[0]) + 0.1
    assert abs(peak - 25.8) < 0.5
    # the rigid X axis has no tool channel; Y's acc is the tool-side acceleration
    assert not out.has("x", "tool")
    acc_fd = np.gradient(np.gradient(out.get("y", "tool"), cfg.Ts), cfg.Ts)
    assert np.corrcoef(acc_fd[5:-5], out.get("y", "acc")[5:-5])[0, 1] > 0.99


def test_record_delay_shifts_exactly():
    cfg = deckel_maho_like()
    traj = moves(cfg, n_moves=4)
    base = simulate_machine(cfg, traj, truth=False)
    cfg.axes[0].record_delay = 7
    late = simulate_machine(cfg, traj, truth=False)
    assert np.array_equal(late.act("x")[7:], base.act("x")[:-7])
    assert np.all(late.act("x")[:7] == base.act("x")[0])
    assert np.array_equal(late.act("y"), base.act("y"))          # only the axis asked for


def test_in_loop_delay_measures_k_samples_old_position():
    cfg = deckel_maho_like()
    cfg.axes[0].delay = 3
    out = simulate_machine(cfg, moves(cfg, n_moves=4), truth=False)
    q = cfg.axes[0].resolution
    expected = q * np.floor(out.extra("x_act_true") / q + 0.5)
    assert np.array_equal(out.act("x")[3:], expected[:-3])
    # the loop sees it: the delayed loop's truth K_vel is 1/Kp (the controller regulates y)
    K = linear_truth(cfg)["sampled"]["K"]["x"]["x"]
    assert K["K_vel"] == pytest.approx(1 / 80.0, rel=1e-9)


def test_quantisation_grid_and_noise_seed():
    cfg = deckel_maho_like()
    for a in cfg.axes:
        a.resolution = 1e-3
    out = simulate_machine(cfg, moves(cfg, n_moves=4), truth=False)
    for a in cfg.axes:
        k = out.act(a.name) / 1e-3
        assert np.abs(k - np.round(k)).max() < 1e-6
        assert np.abs(out.act(a.name) - out.extra(f"{a.name}_act_true")).max() <= 0.5e-3 + 1e-12
    cfg.axes[0].noise_std = 2e-3
    traj = moves(cfg, n_moves=4)
    a1 = simulate_machine(cfg, traj, seed=11, truth=False)
    a2 = simulate_machine(cfg, traj, seed=11, truth=False)
    a3 = simulate_machine(cfg, traj, seed=12, truth=False)
    assert a1.fingerprint() == a2.fingerprint()
    assert not np.array_equal(a1.act("x"), a3.act("x"))
    resid = a1.act("x") - a1.extra("x_act_true")
    assert 1.5e-3 < resid.std() < 2.5e-3


def test_friction_sticks_at_rest_and_sub_steps_converge():
    cfg = with_feedforward()
    traj = moves(cfg, n_moves=6)
    out = simulate_machine(cfg, traj, truth=False)
    # stuck at the end: velocity exactly zero and friction below breakaway
    a = cfg.axes[0]
    v = out.extra("x_vel_true")
    assert np.count_nonzero(np.abs(v[-200:]) < 1e-9) > 150
    assert np.abs(out.extra("x_friction")).max() <= a.coulomb + a.stribeck + 1e-9
    # friction shows up as the dominant error with feed-forward (reversal transients)
    lin = simulate_machine(linearised(with_feedforward()), traj, truth=False)
    friction_part = out.error("x") - lin.error("x")
    assert np.abs(friction_part).max() > np.abs(lin.error("x")).max()
    # sub-step convergence and whole-sample shortcuts agree to a few percent of the friction
    # effect (first-order convergence in the sub-step: ~0.1 um here)
    fine = with_feedforward()
    fine.n_sub, fine.adaptive = 64, False
    ref = simulate_machine(fine, traj, truth=False)
    for ax in ("x", "y"):
        diff = np.abs(ref.extra(f"{ax}_act_true") - out.extra(f"{ax}_act_true")).max()
        assert diff < 0.03 * np.abs(friction_part).max()


def test_asymmetric_coulomb_and_backlash():
    base = dict(name="x", Kp=60.0, Kv=120.0, Ti=0.02, mass=300.0, viscous=0.2)
    traj = point_to_point(0, 20, v=50, acc=1000, jerk=5e4, Ts=1e-3, dwell=(0.05, 0.3))
    r = np.concatenate([traj["x"], traj["x"][::-1]])   # there and back
    up = simulate_drive(AxisConfig(**base, coulomb=100.0, coulomb_neg=300.0), r, truth=False)
    f = up.extra("x_friction")
    v = up.extra("x_vel_true")
    assert f[v > 10].max() == pytest.approx(-100.0) and f[v < -10].min() == pytest.approx(300.0)
    bl = simulate_drive(AxisConfig(**base, backlash=0.02), r, truth=False)
    gap = bl.get("x", "tool") - bl.extra("x_act_true")
    assert gap.max() == pytest.approx(0.01) and gap.min() == pytest.approx(-0.01)
    # two-mass backlash: the dead zone lets the tool lag the motor by about half the play more
    cfg = flexible_y()
    cfg.axes[1].backlash = 0.05
    out = simulate_machine(cfg, moves(cfg, n_moves=4), truth=False)
    assert "backlash" in out.meta["truth"]["effects"]["y"]
    assert np.abs(out.get("y", "tool") - out.extra("y_act_true")).max() > 0.025


def test_periodic_force_and_force_limit():
    ax = AxisConfig(name="x", Kp=60.0, Kv=120.0, Ti=0.02, mass=300.0, periodic_amplitude=80.0,
                    periodic_period=5.0)
    traj = point_to_point(0, 60, v=50, acc=1000, jerk=5e4, Ts=1e-3, dwell=(0.2, 1.5))
    out = simulate_drive(ax, traj, truth=False)
    e = out.error("x")
    cruise = (np.abs(np.gradient(traj["x"], 1e-3) - 50) < 1e-6)
    ripple = e[cruise] - e[cruise].mean()
    f = np.fft.rfftfreq(ripple.size, 1e-3)
    peak = f[1:][np.argmax(np.abs(np.fft.rfft(ripple))[1:])]
    assert peak == pytest.approx(50 / 5.0, abs=1.0)       # v / period = 10 Hz
    lim = dataclasses.replace(ax, periodic_amplitude=0.0, force_limit=150.0, kt=2.0)
    out = simulate_drive(lim, traj, truth=False)
    assert np.abs(out.extra("x_force")).max() <= 150.0 + 1e-9
    assert np.abs(out.get("x", "cur")).max() == pytest.approx(75.0)   # limited, in A = N / kt
    e = out.error("x")
    assert np.abs(e[-50:]).max() < 1e-4                               # anti-windup: settles
    overshoot = -e[np.argmax(traj["x"] == 60.0):].min()
    # (without the conditional integration this case overshoots by ~50 mm and keeps ringing)
    assert overshoot < 1.0 and np.abs(e).max() < 2.0


def test_coupling_drives_the_other_axis():
    cfg = linearised(coupled_xy())
    traj = linear_moves(n_moves=4, axes=("x",), Ts=cfg.Ts, seed=1)
    cmd = {"x": traj["x"], "y": np.zeros(traj.n)}
    out = simulate_machine(cfg, cmd)
    ey = out.error("y")
    assert np.abs(ey).max() > 2e-3                                   # X acceleration pushes Y
    unc = linearised(deckel_maho_like())
    assert np.abs(simulate_machine(unc, cmd, truth=False).error("y")).max() == 0.0
    K = out.meta["truth"]["linear"]["continuous"]["K"]
    assert K["y"]["x"]["K_acc"] == pytest.approx(0.0, abs=1e-12)      # no static push...
    assert abs(K["y"]["x"]["K_jerk"]) > 0                            # ...a dynamic one


def test_emps_like_is_pd_with_known_error_level():
    cfg = emps_like()
    assert not np.isfinite(cfg.axes[0].Ti)
    traj = linear_moves(n_moves=8, v=130, acc=1500, jerk=5e4, d_min=20, d_max=60, stroke=150,
                        speed_range=(1, 1), Ts=cfg.Ts, seed=4)
    out = simulate_machine(cfg, traj)
    e = out.error("x")
    assert 0.5 < np.abs(e).max() < 1.2          # ~0.9 mm peak in the real EMPS data
    q = 5e-5
    assert np.abs(out.act("x") / q - np.round(out.act("x") / q)).max() < 1e-6
    assert np.abs(out.get("x", "cur")).max() <= 10.0 + 1e-9   # volts, saturates at 10 V


def test_bad_input_raises_input_error():
    cfg = deckel_maho_like()
    with pytest.raises(InputError, match="no command for axis 'y'"):
        simulate_machine(cfg, {"x": np.zeros(10)})
    with pytest.raises(InputError, match="NaN"):
        simulate_machine(cfg, {"x": np.r_[0.0, np.nan, 0.0], "y": np.zeros(3)})
    cfg.axes[0].Kp = -1
    with pytest.raises(InputError, match="Kp"):
        simulate_machine(cfg, {"x": np.zeros(10), "y": np.zeros(10)})
    with pytest.raises(InputError, match="tool_mass"):
        MachineConfig([AxisConfig(tool_mass=10.0)]).validate()
    with pytest.raises(InputError, match="coupling"):
        MachineConfig([AxisConfig("x")], couplings=[Coupling("x", "z")]).validate()


def test_returns_trace_with_roles_and_units():
    cfg = flexible_y()
    out = simulate_machine(cfg, moves(cfg, n_moves=2), truth=False)
    assert isinstance(out, Trace) and out.Ts == pytest.approx(cfg.Ts)
    assert set(out.roles["y"]) == {"cmd", "act", "vel", "cur", "tool", "acc"}
    assert set(out.roles["x"]) == {"cmd", "act", "vel", "cur"}
    assert out.channels["y_tool"].unit == "mm" and out.channels["x_force"].unit == "N"
