"""Trace input: axis names of the GUI layouts, a time column in ms with no
unit, an ``--external`` channel that is the identified axis's own signal.

Each case fails without the code it guards: wrong axis names would be read without a word (two
names alike put A2's positions on A1, an unknown name leaves the axis without roles), a 1 kHz
trace with its time in ms would be read at Ts = 1 s, and ``--external x_mm`` would give a model
predicting the measured position from itself.
"""
import numpy as np
import pytest
from scipy.io import savemat

from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.io.text import read_text
from cli_support import one_line, run_cli

N = 200            # samples of the small files (the ms check starts at 16)


def run(capsys, *args):
    """``fdid ARGS`` in-process: (exit code, stderr)."""
    code, _, err = run_cli(capsys, *args)
    return code, err


def _signals(n=N, dt=1e-3):
    t = np.arange(n) * dt
    return t, np.sin(5 * t), 1e-3 * np.cos(5 * t), 2 * np.sin(3 * t), 1e-3 * np.sin(t)


@pytest.fixture
def verify_gui(tmp_path):
    """Headerless thesis verification-GUI file: time, A1 x, A1 e, A2 x, A2 e."""
    p = tmp_path / "verify.txt"
    np.savetxt(p, np.column_stack(_signals()))
    return p


@pytest.fixture
def siso_gui(tmp_path):
    p = tmp_path / "siso.txt"
    np.savetxt(p, np.column_stack(_signals()[:3]))
    return p


# ----------------------------------------------------------------------------- 1. axis names
@pytest.mark.parametrize("axes,words", [
    (("x", "x"), ["'x' twice"]),                            # was: x read A2's positions, A1 lost
    (("spindle", "y"), ["'spindle' is not an axis name"]),   # was: A1 read with no roles
    (("X", "Y"), ["'X' is not an axis name", "lower case: 'x'"]),   # was: X_act but x_cmd
    (("x", "t"), ["'t' is not an axis name"]),               # was: A2 dropped
    (("x",), ["needs 2 axis name(s)"]),
])
def test_gui_axes_are_checked(verify_gui, axes, words):
    before = verify_gui.read_bytes()
    with pytest.raises(InputError) as ei:
        read_text(verify_gui, axes=axes)
    msg = str(ei.value)
    assert ei.value.column == "axes" and str(verify_gui) in msg
    for w in words:
        assert w in msg, msg
    assert verify_gui.read_bytes() == before


def test_siso_gui_axis_name_is_checked(siso_gui):
    for bad in (("spindle",), ("t",), ("a b",)):
        with pytest.raises(InputError, match="is not an axis name"):
            read_text(siso_gui, axes=bad)


def test_valid_gui_axes_read_each_column_onto_its_axis(verify_gui):
    t, x1, e1, x2, e2 = _signals()
    tr = read_text(verify_gui, axes=("a1", "axis2"))
    assert tr.axes == ["a1", "axis2"]
    np.testing.assert_allclose(tr.act("a1"), x1)
    np.testing.assert_allclose(tr.cmd("axis2"), x2 + e2)
    # a string is a comma list, as --axes (not split into 'z', ',', 'y')
    tr = read_text(verify_gui, axes="z,y")
    np.testing.assert_allclose(tr.act("z"), x1)
    np.testing.assert_allclose(tr.act("y"), x2)


def test_axes_with_the_columns_layout_are_refused_not_ignored(tmp_path):
    p = tmp_path / "run.csv"
    p.write_text("t_s,x_cmd_mm,x_mm\n" + "\n".join(f"{k * 1e-3:.3f},{k},{k}" for k in range(20)) + "\n")
    with pytest.raises(InputError, match="axes come from the column names"):
        read_text(p, axes=("y",))
    assert read_text(p).axes == ["x"]


def test_cli_axes_twice_is_one_line(capsys, verify_gui, tmp_path):
    code, err = run(capsys, "identify", verify_gui, "--axes", "x,x", "-o", tmp_path / "m.json")
    one_line(code, err, "verify.txt", "'x' twice")
    assert not (tmp_path / "m.json").exists()


# ----------------------------------------------------------------------------- 2. time in ms
def _ms_csv(path, header="time,x_cmd_mm,x_mm", step=1.0):
    t, x, e = _signals()[:3]
    rows = [header] + [f"{k * step:g},{a + b:.9f},{a:.9f}" for k, (a, b) in enumerate(zip(x, e))]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_time_in_ms_without_unit_is_refused(tmp_path):
    p = _ms_csv(tmp_path / "servo.csv")            # 1 kHz, time in ms, header says no unit
    before = p.read_bytes()
    with pytest.raises(InputError) as ei:          # was: read with Ts = 1 s
        read_trace(p)
    msg = str(ei.value)
    assert ei.value.column == "time" and "servo.csv" in msg
    for w in ("no unit", "steps by 1 ", "time_ms", "time [ms]", "--unit time=ms", "units={'time': 'ms'}"):
        assert w in msg, (w, msg)
    assert p.read_bytes() == before


@pytest.mark.parametrize("header,units,Ts", [
    ("t_ms,x_cmd_mm,x_mm", None, 1e-3),
    ("time [ms],x_cmd_mm,x_mm", None, 1e-3),
    ("time,x_cmd_mm,x_mm", {"time": "ms"}, 1e-3),
    ("time,x_cmd_mm,x_mm", {"time": "s"}, 1.0),    # a record that really is slow, said so
    ("t_s,x_cmd_mm,x_mm", None, 1.0),
])
def test_a_stated_time_unit_is_read(tmp_path, header, units, Ts):
    tr = read_trace(_ms_csv(tmp_path / "servo.csv", header), units=units)
    assert tr.Ts == pytest.approx(Ts)


def test_a_slow_stated_time_unit_and_unitless_positions_are_said(tmp_path, capsys):
    """ms under 't_s' (the user's own word, so read as s) and positions whose names state no unit
    (read as mm) give a model 1000x off: notes say so, on the trace's meta and printed by every
    command that reads a trace; a clean file gets none."""
    slow = read_trace(_ms_csv(tmp_path / "slow.csv", "t_s,x_cmd_mm,x_mm"))
    assert slow.Ts == pytest.approx(1.0)
    assert slow.meta["notes"] == ["column 't_s' steps by 1 s (1 Hz), read in s as stated; servo "
                                  "traces step by 0.1-10 ms: if it is in ms, give --unit t_s=ms"]
    bare = read_trace(_ms_csv(tmp_path / "bare.csv", "t_ms,x_cmd,x"))
    assert bare.meta["notes"] == ["columns x_cmd (mm), x (mm) state no unit and are read in these units; if "
                                  "one is in another, name it like x_um or give --unit COLUMN=UNIT"]
    # in us there is no smaller unit to suggest (--unit t_us=ms would make it 1000x worse)
    assert read_trace(_ms_csv(tmp_path / "us.csv", "t_us,x_cmd_mm,x_mm", step=1e6)).meta["notes"][0].endswith(
        "fdid reads no time unit below us: convert the column")
    # s under a ms name: 1 kHz read as 1 MHz
    assert read_trace(_ms_csv(tmp_path / "fast.csv", "t_ms,x_cmd_mm,x_mm", step=0.001)).meta["notes"] == [
        "column 't_ms' steps by 1e-06 s (1e+06 Hz), read in ms as stated; servo traces step by 0.1-10 ms: "
        "if it is in s, give --unit t_ms=s"]
    assert "notes" not in read_trace(_ms_csv(tmp_path / "fast_ok.csv", "t_us,x_cmd_mm,x_mm", step=31.25)).meta
    assert "notes" not in read_trace(_ms_csv(tmp_path / "ok.csv", "t_ms,x_cmd_mm,x_mm")).meta
    assert "notes" not in read_trace(_ms_csv(tmp_path / "ok2.csv", "t_s,x_cmd_mm,x_mm", step=0.099)).meta
    code, out, err = run_cli(capsys, "identify", tmp_path / "slow.csv", "-o", tmp_path / "m.json",
                             "--method", "quasi-static")
    assert f"note: {tmp_path / 'slow.csv'}: column 't_s' steps by 1 s" in out, (out, err)


def test_the_limit_is_a_step_of_a_tenth_of_a_second(tmp_path):
    assert read_trace(_ms_csv(tmp_path / "a.csv", step=0.099)).Ts == pytest.approx(0.099)
    with pytest.raises(InputError, match="steps by 0.1 "):
        read_trace(_ms_csv(tmp_path / "b.csv", step=0.1))


def test_gui_layout_time_in_ms_is_refused_and_readable_with_its_unit(tmp_path):
    t, x, e = _signals()[:3]
    p = tmp_path / "gui.txt"
    np.savetxt(p, np.column_stack([t * 1e3, x, e]))
    with pytest.raises(InputError, match="column 't': the time column has no unit"):
        read_trace(p)                              # was: Ts = 1 s
    assert read_trace(p, units={"t": "ms"}).Ts == pytest.approx(1e-3)
    np.savetxt(p, np.column_stack([t, x, e]))      # the GUI's own seconds: unchanged
    assert read_trace(p).Ts == pytest.approx(1e-3)


def test_mat_time_in_ms_is_refused(tmp_path):
    t, x, e = _signals()[:3]
    p = tmp_path / "run.mat"
    savemat(p, {"t": t * 1e3, "x_cmd_mm": x + e, "x_mm": x})
    with pytest.raises(InputError, match="column 't'.*--unit t=ms"):
        read_trace(p)
    assert read_trace(p, units={"t": "ms"}).Ts == pytest.approx(1e-3)


def test_cli_time_in_ms_is_one_line(capsys, tmp_path):
    p = _ms_csv(tmp_path / "servo.csv")
    code, err = run(capsys, "identify", p, "-o", tmp_path / "m.json")
    one_line(code, err, "servo.csv", "column 'time'", "--unit time=ms")
    assert not (tmp_path / "m.json").exists()


# ----------------------------------------------------------------------------- 3. --external
@pytest.fixture
def xy_csv(tmp_path):
    """Two axes, 1 kHz; each position lags its command by 3 samples."""
    n = 1500
    t = np.arange(n) * 1e-3
    cx = 5.0 * (1 - np.cos(2 * np.pi * t / 0.75))
    cy = 3.0 * np.sin(2 * np.pi * t / 0.5)
    lag = lambda c: np.concatenate([[c[0]] * 3, c[:-3]])
    p = tmp_path / "xy.csv"
    np.savetxt(p, np.column_stack([t, cx, lag(cx), cy, lag(cy)]), delimiter=",", fmt="%.9g",
               header="t_s,x_cmd_mm,x_mm,y_cmd_mm,y_mm", comments="")
    return p


@pytest.mark.parametrize("channel,role", [("x_mm", "x.act"), ("x_cmd_mm", "x.cmd")])
def test_cli_external_own_channel_is_refused(capsys, xy_csv, tmp_path, channel, role):
    # was: identified (--external x_mm: free run 0.05 um RMS on a 370 um error) and written
    code, err = run(capsys, "identify", xy_csv, "--method", "mimo", "--axis", "x", "--maxiter", "2",
                    "--external", channel, "-o", tmp_path / "m.json")
    one_line(code, err, "xy.csv", f"column '{channel}'", f"--external {channel}", role)
    assert not (tmp_path / "m.json").exists()


def test_external_roles_of_every_identified_axis(xy_csv, siso_gui):
    from fdid_fmi.identify.ranges import check_externals
    tr = read_trace(xy_csv)
    with pytest.raises(InputError, match="y_mm.*y.act of the identified axes"):
        check_externals(tr, ["x", "y"], ["y_mm"])
    check_externals(tr, ["x"], ["y_cmd_mm"])       # an axis not identified: an outside input
    gui = read_trace(siso_gui)                     # the tracking error is the x.err pseudo-role
    with pytest.raises(InputError, match="x.err"):
        check_externals(gui, ["x"], ["x_err"])
    with pytest.raises(InputError, match="x.cmd"):
        check_externals(gui, ["x"], ["x_cmd"])     # the derived command


def test_grid_encoder_axes_are_machine_axes():
    """A grid encoder (KGM) on axes ('x', 'q') is refused for its axis name; accepted, align()
    would blame the time overlap ("no common motion")."""
    from fdid_fmi.align.readers import SensorRecord
    with pytest.raises(InputError, match="grid encoder measures machine axes"):
        SensorRecord("k", "grid_encoder", np.arange(20) * 1e-3, np.zeros((20, 2)), axes=("x", "q"))
    rec = SensorRecord("k", "grid_encoder", np.arange(20) * 1e-3, np.zeros((20, 2)), axes=("x", "y"))
    assert list(rec.axes) == ["x", "y"]


def test_api_external_own_channel_is_refused(xy_csv):
    """The same check in the identification engine (the CLI's was the only one): identify_mimo
    with an axis's own measured position as external input predicted it from itself."""
    from fdid_fmi.identify import identify_mimo, mimo_structure
    tr = read_trace(xy_csv)
    st = mimo_structure(("x",), ("error",), 1, 1, externals=[tr.roles["x"]["act"]], same_sample="hold")
    with pytest.raises(InputError, match=f"external input {tr.roles['x']['act']}: this channel is x.act"):
        identify_mimo(tr, st, maxiter=1)
