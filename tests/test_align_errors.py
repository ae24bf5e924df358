"""fdid align: what cannot be estimated is said in one line; bad sensor files are refused clearly;
the command line end to end."""
import dataclasses

import numpy as np
import pytest

from fdid_fmi.align import align, read_accelerometer, read_grid_encoder
from fdid_fmi.cli import main
from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fdid_fmi.virtual.sensors import AccelerometerTruth, GridEncoderTruth, write_raw_run

CFG = presets.flexible_y()


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    """A 4.6 s two-axis run with the default sensors, and the simulated trace."""
    sim = simulate_machine(CFG, tj.linear_moves(n_moves=8, axes=("x", "y"), Ts=CFG.Ts, seed=4,
                                                d_max=20.0), seed=4)
    return sim, write_raw_run(sim, tmp_path_factory.mktemp("short"))


def _ctrl(run):
    return read_trace(run["controller"])


def test_sensor_after_the_controller_record_is_refused(short, tmp_path):
    sim, _ = short
    late = write_raw_run(sim, tmp_path, accelerometers=[dataclasses.replace(AccelerometerTruth(),
                                                                            start_s=30.0, duration_s=5.0)],
                         grid_encoders=[])
    with pytest.raises(InputError) as ei:
        align(_ctrl(late), [read_accelerometer(late["sensors"]["acc_tool"])])
    msg = str(ei.value)
    assert "acc_tool" in msg and "at rest throughout" in msg and "\n" not in msg


def test_sensor_of_another_run_has_no_common_motion(short, tmp_path):
    sim, run = short
    other = simulate_machine(CFG, tj.circle(radius=5.0, Ts=CFG.Ts), seed=9)
    o = write_raw_run(other, tmp_path, accelerometers=[], grid_encoders=[GridEncoderTruth()])
    with pytest.raises(InputError) as ei:
        align(_ctrl(run), [read_grid_encoder(o["sensors"]["kgm"])])
    assert "no common motion" in str(ei.value)


def test_partial_overlap_is_cropped(short, tmp_path):
    sim, _ = short
    late = write_raw_run(sim, tmp_path, accelerometers=[],
                         grid_encoders=[dataclasses.replace(GridEncoderTruth(), start_s=1.2)])
    res = align(_ctrl(late), [read_grid_encoder(late["sensors"]["kgm"])])
    assert res.trace.t[0] >= 1.2 and res.trace.t[-1] == pytest.approx(sim.t[-1], abs=1e-9)
    assert abs(res.sensor("kgm").get("time_offset").value - 1.2) < CFG.Ts


def test_drift_without_spread_motion_is_reported_missing(tmp_path):
    one = MachineConfig(axes=[CFG.axis("x")], Ts=CFG.Ts)
    sim = simulate_machine(one, tj.point_to_point(0.0, 30.0, Ts=CFG.Ts, dwell=0.15, axis="x"), seed=1)
    run = write_raw_run(sim, tmp_path, accelerometers=[], grid_encoders=[GridEncoderTruth()])
    res = align(_ctrl(run), [read_grid_encoder(run["sensors"]["kgm"])], window_s=1.0)
    lines = [m for m in res.missing if "clock drift not estimable" in m]
    assert len(lines) == 1 and "kgm" in lines[0]
    assert res.sensor("kgm").get("clock_drift").value == 0.0
    assert abs(res.sensor("kgm").get("time_offset").value - GridEncoderTruth().start_s) < CFG.Ts


def test_sensor_axes_not_in_the_controller(short):
    _, run = short
    with pytest.raises(InputError, match="none of which is in the controller trace"):
        align(_ctrl(run), [read_accelerometer(run["sensors"]["acc_tool"], axes=("z",))])


def _write(path, text):
    path.write_text(text)
    return path


def test_reader_errors(tmp_path):
    t = np.arange(40) * 2e-4
    rows = "\n".join(f"{v:.4f},{v:.3f},0.1,9.8" for v in t)
    with pytest.raises(InputError, match=r"column 'ax'.*acceleration unit"):
        read_accelerometer(_write(tmp_path / "a.csv", "t_s,ax,ay,az\n" + rows))
    assert read_accelerometer(_write(tmp_path / "b.csv", "t_s,ax,ay,az\n" + rows),
                              unit="m_s2").data[0, 2] == pytest.approx(9800.0)
    with pytest.raises(InputError, match="expected 3 accelerometer columns besides time, found 4"):
        read_accelerometer(_write(tmp_path / "c.csv", "t_s,ax_g,ay_g,az_g,temp_C\n" +
                                  "\n".join(f"{v:.4f},0,0,1,20" for v in t)))
    bad = rows.splitlines()
    bad[7] = bad[5]
    with pytest.raises(InputError, match=r"row 9.*not strictly increasing"):
        read_accelerometer(_write(tmp_path / "d.csv", "t_s,ax_g,ay_g,az_g\n" + "\n".join(bad)))
    with pytest.raises(InputError, match=r"column 'kgm_y_um', row 3.*'x' is not a number"):
        read_grid_encoder(_write(tmp_path / "e.csv", "t_s,kgm_x_um,kgm_y_um\n0,1,1\n0.001,1,x\n"))
    with pytest.raises(InputError, match="no column 'bz'"):
        read_accelerometer(_write(tmp_path / "f.csv", "t_s,ax_g,ay_g,az_g\n" + rows), columns=["ax_g", "ay_g", "bz"])
    # the name says mm, unit=g says acceleration: refused (not read as g, 9806.65x)
    with pytest.raises(InputError, match="column name says unit 'mm' but unit=g"):
        read_accelerometer(_write(tmp_path / "g.csv", "t_s,ax_mm,ay_mm,az_mm\n" + rows), unit="g")


def test_cli_end_to_end(short, tmp_path, capsys):
    _, run = short
    out, js = tmp_path / "aligned.csv", tmp_path / "al.json"
    rc = main(["align", str(run["controller"]), "--acc", str(run["sensors"]["acc_tool"]), "axes=x,y",
               "--kgm", str(run["sensors"]["kgm"]), "-o", str(out), "--json", str(js)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "| acc_tool | orientation | alpha |" in printed and "aligned trace:" in printed
    tr = read_trace(out)
    assert all(tr.has(a, r) for a in "xy" for r in ("cmd", "act", "tool", "acc"))
    truth = run["truth"]["accelerometers"]["acc_tool"]
    import json
    d = json.loads(js.read_text())
    alpha = [e for s in d["sensors"] if s["name"] == "acc_tool" for e in s["estimates"]
             if e["name"] == "alpha"][0]
    assert abs(alpha["value"] - truth["alpha_deg"]) < 0.3
    # the calibration's orientation reused
    rc = main(["align", str(run["controller"]), "--acc", str(run["sensors"]["acc_tool"]),
               "--orientation", str(js), "-o", str(tmp_path / "again.csv")])
    again = capsys.readouterr().out
    assert rc == 0 and "| acc_tool | orientation | alpha |" in again and "rotation about" not in again
    # refused, not silently handled: a calibration that does not name the sensor (else unused), a
    # matrix that is no rotation (else quietly made one), a low-pass above a sensor's Nyquist
    renamed = tmp_path / "acc2.csv"
    renamed.write_bytes(run["sensors"]["acc_tool"].read_bytes())
    bad = json.loads(js.read_text())
    for sen in bad["sensors"]:
        if sen.get("rotation") is not None:
            sen["rotation"] = [[5, 1, 0], [0, 0.1, 0], [3, 0, 1]]
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    for tail, expected in ((["--acc", str(renamed), "--orientation", str(js)], "no sensor 'acc2'"),
                           (["--acc", str(run["sensors"]["acc_tool"]), "--orientation", str(tmp_path / "bad.json")],
                            "not a 3x3 rotation"),
                           (["--kgm", str(run["sensors"]["kgm"]), "--lowpass", "550"], "Nyquist")):
        rc = main(["align", str(run["controller"]), "-o", str(tmp_path / "x.csv")] + tail)
        err = capsys.readouterr().err.strip()
        assert rc == 2 and expected in err and len(err.splitlines()) == 1, err


@pytest.mark.parametrize("argv_tail, expected", [
    (["--acc", "ACC", "bogus=1"], "unknown setting 'bogus'"),
    (["--acc", "ACC", "ACC"], "exactly one file per --acc"),
    (["--acc", "ACC", "--orientation", "CTRL"], "not valid JSON"),
    ([], "give at least one sensor"),
    (["--acc", "ACC", "--range", "0:1"], "--range does not apply"),
])
def test_cli_errors_are_one_line(short, tmp_path, capsys, argv_tail, expected):
    _, run = short
    tail = [str(run["sensors"]["acc_tool"]) if a == "ACC" else str(run["controller"]) if a == "CTRL" else a
            for a in argv_tail]
    rc = main(["align", str(run["controller"]), "-o", str(tmp_path / "o.csv")] + tail)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and expected in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "o.csv").exists()


def test_thesis_head_and_table_accelerometers(short, tmp_path):
    """Thesis Fig. 7-2: the head accelerometer moves with X only, the table one with Y only.
    Each sensor's axis direction is found (its acceleration aligned); the rotation about it is
    reported missing, one line per sensor."""
    sim, _ = short
    head = AccelerometerTruth(name="acc_head", axes=("x",), alpha_deg=-2.58, beta_deg=-0.77,
                              gamma_deg=-0.64, start_s=-3.3867, drift_ppm=40.0)
    table = AccelerometerTruth(name="acc_table", axes=("y",), alpha_deg=10.0, beta_deg=-7.0,
                               gamma_deg=0.02, start_s=-3.4257, drift_ppm=-30.0, bias=(50.0, 20.0, -80.0))
    run = write_raw_run(sim, tmp_path, accelerometers=[head, table], grid_encoders=[])
    res = align(_ctrl(run), [read_accelerometer(run["sensors"]["acc_head"], axes=("x",)),
                             read_accelerometer(run["sensors"]["acc_table"], axes=("y",))])
    rot = [m for m in res.missing if "rotation about" in m]   # (+ drift lines: short record)
    assert len(rot) == 2
    assert "acc_head" in rot[0] and "rotation about machine x" in rot[0] and "provides only" in rot[0]
    assert "acc_table" in rot[1] and "rotation about machine y" in rot[1]
    m, T = run["motion"], res.trace
    expected = AccelerometerTruth().noise * np.sqrt(res.settings["aa_cutoff_hz"] / 2500.0)
    k = T.t < T.t[-1] - 0.01  # the virtual truth stops ringing at the controller's last sample
    for ax in "xy":
        e = T.get(ax, "acc")[k] - m.acc(ax, T.t[k])
        assert np.sqrt(np.mean(e ** 2)) < 1.15 * expected, ax
    for s, tr in (("acc_head", head), ("acc_table", table)):
        assert abs(res.sensor(s).get("time_offset").value - tr.start_s) < CFG.Ts


def test_roles_already_present_are_replaced_and_said(short):
    """A trace that already has a tool channel (here the simulator's truth) gets the aligned one
    under the role; the old channel stays as an extra channel and the replacement is recorded."""
    sim, run = short
    res = align(sim, [read_grid_encoder(run["sensors"]["kgm"])])
    assert res.settings["replaced_roles"] == {"y.tool": "y_tool"}   # x is rigid: had no tool
    assert res.trace.roles["y"]["tool"] == "y_tool_mm" and "y_tool" in res.trace.channels
    e = res.trace.get("y", "tool") - res.trace.extra("y_tool")
    assert np.sqrt(np.mean(e ** 2)) < 2e-3


def test_sensors_on_one_axis_add_with_their_sign(short):
    """Head - table (thesis ch. 7.2.1): two records of one axis add with their signs; the same
    record as +1 and -1 cancels, and each alone equals the single-sensor alignment."""
    _, run = short
    p = run["sensors"]["acc_tool"]
    plus = read_accelerometer(p, axes=("x", "y"), name="plus")
    minus = read_accelerometer(p, axes=("x", "y"), name="minus", sign=-1)
    both = align(_ctrl(run), [plus, minus])
    single = align(_ctrl(run), [plus])
    assert np.max(np.abs(both.trace.get("y", "acc"))) < 1e-9
    assert np.max(np.abs(single.trace.get("y", "acc"))) > 1000.0
    assert both.sensor("minus").get("alpha").value == pytest.approx(single.sensor("plus").get("alpha").value)
