"""The reference simulator: exact friction solve, steady-ramp start, offsets, JSON round trip."""
import itertools

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.identify import regressors as rg
from fdid_fmi.identify.lsfit import Fit
from fdid_fmi.identify.pole_search import assemble
from fdid_fmi.identify.structure import mimo_structure, siso_structure
from fdid_fmi.model import DriveModel, load_model
from fdid_fmi.simulate import simulate
from sim_oracle import STICK, solve_friction

TS = 1e-3


def siso_model(d0=800.0, v_tilde=0.5):
    a = rg.characteristic_polynomial([40.0], [(12.0, 0.9)])
    st = siso_structure("x", same_sample="hold")
    b = {("x_error", "x_cmd"): np.array([0.05, 0.7 * a[1], 0.9 * a[2], 0.0]),
         ("x_error", "x_dnf"): np.array([0.0, 0.0, d0, 0.0])}
    return assemble(st, Fit(J=0, a=a, b=b, rms=None, feasible=True, v_tilde={"x": v_tilde}), TS)


def moves(n=3000, seed=0):
    from scipy import signal
    rng = np.random.default_rng(seed)
    steps = np.repeat(rng.uniform(-10, 10, n // 500 + 1).cumsum(), 500)[:n]
    steps[:300] = steps[300]
    return signal.sosfiltfilt(signal.butter(3, 3.0, fs=1 / TS, output="sos"), steps)


def _karnopp_consistent(alpha, beta, d, L, vt):
    """Each friction input either holds its axis (v = 0, |d| <= L) or is L sat(v / v_tilde)."""
    v = alpha + beta @ d
    stuck = (np.abs(v) <= 1e-9 * np.maximum(1.0, np.abs(alpha))) & (np.abs(d) <= L + 1e-12)
    sliding = np.abs(d - L * np.clip(v / vt, -1, 1)) < 1e-9
    return bool(np.all(stuck | sliding)), stuck


def test_friction_solve_is_exact_for_one_input():
    rng = np.random.default_rng(1)
    n_stuck = 0
    for _ in range(500):
        alpha, beta = rng.normal(0, 50), -abs(rng.normal(0, 50))      # sticking and sliding cases
        L, vt = rng.uniform(0.1, 2), rng.uniform(0.01, 1)
        d = solve_friction(np.array([alpha]), np.array([[beta]]), [L], [vt], [(STICK,), (0,), (1,), (-1,)])
        ok, stuck = _karnopp_consistent(np.array([alpha]), np.array([[beta]]), d, np.array([L]), np.array([vt]))
        assert ok and abs(d[0]) <= L + 1e-12
        # it sticks exactly when the friction can hold the axis
        assert bool(stuck[0]) == (abs(alpha / beta) <= L)
        n_stuck += bool(stuck[0])
    assert 100 < n_stuck < 400


def test_friction_solve_two_coupled_inputs():
    rng = np.random.default_rng(2)
    branches = list(itertools.product((STICK, 0, 1, -1), repeat=2))
    for _ in range(300):
        alpha = rng.normal(0, 3, 2)
        beta = -np.diag(np.abs(rng.normal(0, 30, 2))) + rng.normal(0, 2, (2, 2)) * (1 - np.eye(2))
        L, vt = rng.uniform(0.1, 2, 2), rng.uniform(0.05, 1, 2)
        d = solve_friction(alpha, beta, L, vt, branches)
        assert _karnopp_consistent(alpha, beta, d, L, vt)[0]


def test_stick_invariants_on_a_stiff_axis():
    """Stiff friction (L |beta| / v_tilde >> 1) after a move: whenever the friction can hold the
    axis it does, exactly (stick branch; no creep through the transition band), and the axis
    moves again only from the friction limit (a breakaway). This extreme model stick-slips at
    rest every few samples (its integral action winds up against the holding force); identified
    twins rest (benchmarks/checks/pole_search_virtual.py)."""
    m = siso_model(d0=5000.0, v_tilde=0.05)
    xr = np.concatenate([moves(2000), np.full(3000, moves(2000)[-1])])
    sim = simulate(m, {"x": xr}, Ts=TS)
    v, d = sim.axes["x"]["velocity"][2000:], sim.u[2000:, 1]
    still = np.abs(v) < 1e-9
    assert still.any() and not still.all()
    x = sim.axes["x"]["position"][2000:]
    assert np.all(np.abs(np.diff(x))[still[1:] & still[:-1]] < 1e-12)      # still means still
    assert np.all(np.abs(d[still]) <= 1.0 + 1e-12)                          # held by |d| <= L


def test_steady_ramp_start_has_no_transient():
    m = siso_model()
    xr = 100.0 + 50.0 * TS * np.arange(2000)       # 50 mm/s from the first sample on
    sim = simulate(m, {"x": xr}, Ts=TS, start_velocity={"x": 50.0})
    e = sim.axes["x"]["error"]
    assert np.ptp(e) < 1e-9 * max(1.0, abs(e[0]))
    assert abs(e[0]) > 1e-4                         # a real following error, constant
    np.testing.assert_allclose(sim.axes["x"]["velocity"], 50.0, rtol=1e-9)


def test_offset_invariance():
    m = siso_model()
    xr = moves()
    a = simulate(m, {"x": xr}, Ts=TS)
    b = simulate(m, {"x": xr + 1234.5}, Ts=TS)
    np.testing.assert_allclose(b.axes["x"]["error"], a.axes["x"]["error"], atol=1e-9)
    np.testing.assert_allclose(b.axes["x"]["position"] - 1234.5, a.axes["x"]["position"], atol=1e-9)


def test_friction_parameters_switch_friction():
    m = siso_model()
    xr = moves()
    on = simulate(m, {"x": xr}, Ts=TS)
    off = simulate(m, {"x": xr}, Ts=TS, params={"x_friction_on": False})
    half = simulate(m, {"x": xr}, Ts=TS, params={"x_friction_level": 0.5})
    assert np.all(off.u[:, 1] == 0) and np.max(np.abs(on.u[:, 1])) == pytest.approx(1.0)
    assert np.max(np.abs(half.u[:, 1])) == pytest.approx(0.5)
    assert np.max(np.abs(on.axes["x"]["error"] - off.axes["x"]["error"])) > 1e-3


def test_json_round_trip(tmp_path):
    m = siso_model()
    p = m.save(tmp_path / "m.json")
    m2 = load_model(p)
    xr = moves()
    np.testing.assert_array_equal(simulate(m, {"x": xr}, Ts=TS).y, simulate(m2, {"x": xr}, Ts=TS).y)
    assert [q.name for q in m2.inputs] == ["x_cmd", "x_dnf"]


def test_bad_models_are_rejected(tmp_path):
    m = siso_model()
    d = m.to_dict()
    d["A"][0][0] = 5.0
    with pytest.raises(InputError, match="not stable"):
        DriveModel.from_dict(d)
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(InputError, match="bad.json"):
        load_model(tmp_path / "bad.json")
    d = m.to_dict()
    d["format_version"] = 99
    with pytest.raises(InputError, match="newer"):
        DriveModel.from_dict(d)


def test_commands_at_other_sample_time_are_refused():
    m = siso_model()
    with pytest.raises(InputError, match="resample"):
        simulate(m, {"x": moves()}, Ts=2e-3)


def test_two_axis_coupled_model_simulates():
    st = mimo_structure(("x", "y"), ("error",), 2, 2, coupled=True, same_sample="quadratic")
    a = rg.characteristic_polynomial([5.0, 60.0], [(20.0, 0.5), (30.0, 0.3)])
    rng = np.random.default_rng(3)
    b = {}
    for o in st.outputs:
        for s in st.inputs:
            bb = np.zeros(7)
            allowed = list(st.mask[(o.name, s.name)])
            bb[allowed] = rng.normal(0, 1, len(allowed)) * a[np.array(allowed)] * 0.1
            b[(o.name, s.name)] = bb
    m = assemble(st, Fit(J=0, a=a, b=b, rms=None, feasible=True, v_tilde={"x": 0.5, "y": 0.5}), TS)
    sim = simulate(m, {"x": moves(seed=1), "y": moves(seed=2)}, Ts=TS)
    assert np.all(np.isfinite(sim.y)) and set(sim.axes) == {"x", "y"}
    assert np.max(np.abs(sim.u[:, [1, 3]])) <= 1.0 + 1e-12


def _trace_of(cmds, Ts):
    from fdid_fmi.trace import Channel, Trace
    n = len(next(iter(cmds.values())))
    ch = {f"{a}_cmd": Channel(f"{a}_cmd", "mm", np.asarray(c, float)) for a, c in cmds.items()}
    return Trace(t=np.arange(n) * Ts, channels=ch, roles={a: {"cmd": f"{a}_cmd"} for a in cmds}, source="mem")


def test_run_up_keeps_a_steadily_moving_axis_moving():
    """A two-axis record: x starts accelerating (a run-up from rest is prepended), y moves
    steadily at 10 mm/s. y starts in its steady ramp, as with start='ramp' (started at rest, its
    error would be 0, 0.006, 0.012 mm ... instead of 0.143 mm)."""
    import fmu_support as fs
    m = fs.coupled_model(kxy=0.0, kyx=0.0)                  # two independent axes
    t = np.arange(600) * m.Ts
    tr = _trace_of({"x": 5 + 14 * t + 420 * t ** 2, "y": 2 + 10 * t}, m.Ts)
    auto, ramp = simulate(m, tr), simulate(m, tr, start="ramp")
    e = auto.axes["y"]["error"]
    assert abs(e[0]) > 1e-3                                            # a real following error
    np.testing.assert_allclose(e, ramp.axes["y"]["error"], rtol=0, atol=1e-12)
    assert auto.axes["x"]["velocity"][0] != ramp.axes["x"]["velocity"][0]   # x: its run-up


def test_simulate_refuses_what_it_would_ignore():
    """Unknown axes, parameters or externals, a negative friction level, a NaN sample time and
    options a quasi-static model does not take are errors, not ignored;
    a given start velocity means a steady ramp start, no run-up."""
    m = siso_model()
    xr = moves()
    for kw, words in (({"start_velocity": {"z": 50.0}}, "start_velocity"),
                      ({"params": {"x_friction_levle": 5.0}}, "unknown parameter"),
                      ({"params": {"x_friction_level": -3.0}}, ">= 0"),
                      ({"params": {"x_friction_level": "abc"}}, "finite number"),
                      ({"externals": {"foo": xr}}, "not external inputs")):
        with pytest.raises(InputError, match=words):
            simulate(m, {"x": xr}, Ts=TS, **kw)
    with pytest.raises(InputError, match="resample"):
        simulate(m, {"x": xr}, Ts=float("nan"))
    t = np.arange(600) * TS
    x = 5 + 14 * t + 420 * t ** 2
    tr = _trace_of({"x": x}, TS)
    given = simulate(m, tr, start_velocity={"x": (x[1] - x[0]) / TS})
    np.testing.assert_array_equal(given.y, simulate(m, tr, start="ramp").y)
    assert not np.array_equal(given.y, simulate(m, tr).y)          # auto: the run-up from rest
    from fdid_fmi.identify import identify_quasi_static
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    qs = identify_quasi_static(simulate_machine(one, tj.linear_moves(n_moves=3, axes=("x",), Ts=cfg.Ts,
                                                                     seed=1), seed=1), ["x"])
    for kw, words in (({"start_velocity": {"x": 1.0}}, "quasi-static"), ({"start": "bogus"}, "start must")):
        with pytest.raises(InputError, match=words):
            simulate(qs, {"x": np.zeros(50)}, Ts=cfg.Ts, **kw)
    with pytest.raises(InputError, match="at least 2"):
        simulate(qs, {"x": np.zeros(1)}, Ts=cfg.Ts)


def test_prediction_csv_keeps_epoch_time_stamps_distinct(tmp_path):
    """A record on an epoch clock (1.7e9 s at 0.6 ms) written with 12 significant digits would
    have 3252 rows and 196 distinct time stamps, which no reader accepts. Times on an ordinary
    clock keep 12 digits."""
    from fdid_fmi.cli.simulate import write_prediction_csv
    from fdid_fmi.simulate import SimResult
    n = 3000
    for t0, digits in ((1.7e9, 17), (0.0, 12)):
        t = t0 + 6e-4 * np.arange(n)
        x = np.linspace(0.0, 1.0, n)
        sim = SimResult(t=t, y=np.zeros((n, 0)), u=np.zeros((n, 0)), axes={"x": {"position": x, "error": -x}},
                        output_names=[])
        out = write_prediction_csv(tmp_path / f"p{digits}.csv", sim, ["x"])
        back = np.loadtxt(out, delimiter=",", skiprows=1)
        assert np.all(np.diff(back[:, 0]) > 0)
        assert np.abs(back[:, 0] - t).max() <= 1e-6 * 6e-4 + 1e-16 * abs(t0)
        if t0 == 0.0:
            assert open(out).read().splitlines()[2].split(",")[0] == "0.0006"
