"""Alignment of raw tool-side sensor files against the virtual drive's known truth.

Two runs of the ``flexible_y`` machine, written as three acquisition systems would
(``fdid_fmi.virtual.sensors``): a calibration run moving X and Y one at a time (thesis ch. 7:
the angles are found on a run where both axes move) and an identification run moving Y only.
Truth: accelerometer at 5 kHz, rotated (2.5, -1.2, 0.8) deg, biased, started 1.2-2.6 s before the
controller, clock 60 / -75 ppm fast; KGM at 1 kHz, plate turned 0.35 deg, origin (12.345, -7.89) mm.
The drive-train mode identified from the aligned acceleration, and its diagnosis residual, are
checks of ``benchmarks/bench_end_to_end.py`` (``checks/align_virtual.py``).
"""
import dataclasses

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from fdid_fmi.align import align, read_accelerometer, read_grid_encoder
from fdid_fmi.io import read_trace
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fdid_fmi.virtual.sensors import AccelerometerTruth, GridEncoderTruth, write_raw_run

CFG = presets.flexible_y()
TS = CFG.Ts


def _align(run, **kw):
    ctrl = read_trace(run["controller"])
    recs = [read_accelerometer(run["sensors"]["acc_tool"], axes=("x", "y")),
            read_grid_encoder(run["sensors"]["kgm"])]
    return align(ctrl, recs, **kw)


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    sim = simulate_machine(CFG, tj.linear_moves(n_moves=16, axes=("x", "y"), Ts=TS, seed=3), seed=2)
    run = write_raw_run(sim, tmp_path_factory.mktemp("calib"))
    return run, _align(run)


@pytest.fixture(scope="module")
def yrun(tmp_path_factory, calibration):
    one = MachineConfig(axes=[CFG.axis("y")], Ts=TS)
    path = tj.linear_moves(n_moves=20, axes=("y",), Ts=TS, seed=1)
    sim = simulate_machine(one, path, seed=1)
    acc = dataclasses.replace(AccelerometerTruth(), start_s=-2.613, drift_ppm=-75.0,
                              bias=(120.0, 80.0, -150.0))
    kgm = dataclasses.replace(GridEncoderTruth(), start_s=-0.731, drift_ppm=35.0)
    run = write_raw_run(sim, tmp_path_factory.mktemp("yrun"), accelerometers=[acc],
                        grid_encoders=[kgm], seed=5)
    return sim, path, run, _align(run, orientation=calibration[1]), _align(run)


def _truth(run, name):
    t = run["truth"]
    return t["accelerometers"].get(name) or t["grid_encoders"][name]


def test_orientation_within_0p2_deg(calibration):
    run, res = calibration
    tr = _truth(run, "acc_tool")
    s = res.sensor("acc_tool")
    for ang in ("alpha", "beta", "gamma"):
        e = s.get(ang)
        err = abs(e.value - tr[f"{ang}_deg"])
        assert err < 0.2, (ang, e.value)                       # measured 0.002-0.07 deg
        assert err < 4 * e.uncertainty, (ang, err, e.uncertainty)  # the stated 1-sigma is honest
    assert not res.missing


@pytest.mark.parametrize("name", ["acc_tool", "kgm"])
def test_time_offset_and_clock_drift(calibration, yrun, name):
    for run, res in ((calibration[0], calibration[1]), (yrun[2], yrun[3])):
        tr = _truth(run, name)
        s = res.sensor(name)
        off, drift = s.get("time_offset"), s.get("clock_drift")
        assert abs(off.value - tr["start_s"]) < TS, (off.value, tr["start_s"])   # within 1 sample
        assert abs(drift.value - tr["drift_ppm"]) < 20.0, (drift.value, tr["drift_ppm"])
        assert drift.uncertainty is not None and drift.uncertainty < 20.0


def test_gravity_and_bias(calibration):
    run, res = calibration
    tr = _truth(run, "acc_tool")
    b = res.sensor("acc_tool").get("bias")
    err = np.abs(np.array(b.value) - tr["bias"])
    assert np.all(err < 3 * np.array(b.uncertainty)), (b.value, tr["bias"], b.uncertainty)
    # gravity + bias gone: the aligned acceleration has no mean error left over the record
    m, T = run["motion"], res.trace
    for ax in "xy":
        e = T.get(ax, "acc") - m.acc(ax, T.t)
        assert abs(e.mean()) < 0.5, (ax, e.mean())              # mm/s^2; bias was ~200


def test_grid_encoder_angle_origin_and_tool_position(calibration):
    run, res = calibration
    tr = _truth(run, "kgm")
    s = res.sensor("kgm")
    assert s.get("angle").value == pytest.approx(tr["angle_deg"], abs=0.01)
    assert np.allclose(s.get("origin").value, tr["offset_mm"], atol=0.005)
    m, T = run["motion"], res.trace
    for ax in "xy":
        e = T.get(ax, "tool") - m.pos(ax, T.t)
        assert np.sqrt(np.mean(e ** 2)) < 2e-3, ax                # mm; measured 0.2-0.5 um


def test_aligned_acceleration_is_truth_plus_sensor_noise(calibration):
    """What is left after alignment is the sensor's own noise below the anti-alias cut-off."""
    run, res = calibration
    noise = _truth(run, "acc_tool")["noise"]
    expected = noise * np.sqrt(res.settings["aa_cutoff_hz"] / 2500.0)
    m, T = run["motion"], res.trace
    for ax in "xy":
        e = T.get(ax, "acc") - m.acc(ax, T.t)
        assert np.sqrt(np.mean(e ** 2)) < 1.15 * expected, ax


def test_one_axis_run_says_what_is_missing_and_still_aligns_that_axis(yrun):
    sim, path, run, with_cal, alone = yrun
    lines = [m for m in alone.missing if "acc_tool" in m]
    assert len(lines) == 1 and "rotation about machine y not estimable" in lines[0]
    assert "of its axes ['x', 'y'] only y is in the controller trace" in lines[0]
    assert not with_cal.missing
    m = run["motion"]
    a1, a2 = alone.trace.get("y", "acc"), with_cal.trace.get("y", "acc")
    truth = m.acc("y", alone.trace.t)
    assert np.sqrt(np.mean((a1 - truth) ** 2)) < 1.05 * np.sqrt(np.mean((a2 - truth) ** 2))


def test_integrated_position_drift_within_stated_bound(yrun):
    """Double integral of the aligned acceleration over each move (start position and velocity
    known) stays within 3x the reported 1-sigma drift (noise random walk + residual bias)."""
    sim, path, run, res, _ = yrun
    m, T = run["motion"], res.trace
    s1 = res.sensor("acc_tool").get("drift_1s_y").value          # mm at 1 s
    vel = m.pos_splines["y"].derivative()
    a = T.get("y", "acc")
    worst = 0.0
    for mv in path.info["moves"]:
        k = (T.t >= mv["t_start"]) & (T.t <= mv["t_end"] + 0.1)
        tt = T.t[k]
        v = vel(tt[0]) + cumulative_trapezoid(a[k], tt, initial=0.0)
        x = m.pos("y", tt[0]) + cumulative_trapezoid(v, tt, initial=0.0)
        dur = tt[-1] - tt[0]
        bound = 3 * s1 * max(dur ** 1.5, dur ** 2)
        err = abs(x[-1] - m.pos("y", tt[-1]))
        assert err < bound, (mv, err, bound)
        worst = max(worst, err / bound)
    assert worst > 0.05  # the bound is not vacuous
