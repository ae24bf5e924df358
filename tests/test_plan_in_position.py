"""``fdid plan``: the in-position wait after a rapid (G0), a dwell's settling error
counted against the cutting block before it, the optimiser's figures as the written program
plans them, the JSON's overrides keyed by the tables' block number, and the summary when no
uniform override meets the tolerance.

Small hand-built twins (position loops at 1 ms, no friction), so every test runs in well under
a second of CPU."""
import json
import math

import numpy as np
import pytest

from fdid_fmi.model import DriveModel, Port
from fdid_fmi.plan.interpolate import AxisLimits, InPosition, interpolate
from fdid_fmi.plan.ncprogram import parse_program, write_program
from fdid_fmi.plan.optimize import optimize_feeds
from fdid_fmi.plan.predict import predict
from cli_support import run_cli

TS = 1e-3
LIMITS = {a: AxisLimits(100, 2000, 1e5) for a in "xyz"}

#: the reviewer's program: a rapid, then a cut along X (the rapid's Y lag showed there)
RAPID_THEN_CUT = "%\nG21 G90 G17 G94\nG0 X0 Y-30\nG1 X30 F600\nG1 Y0\nM30\n%\n"


def _ploops(kx=40.0, ky=30.0, gain_x=1.0):
    """Two proportional position loops x[k+1] = p x[k] + (1 - p) g r[k] (g: d.c. gain of x)."""
    px, py = math.exp(-kx * TS), math.exp(-ky * TS)
    return DriveModel(TS, np.diag([px, py]), np.diag([(1 - px) * gain_x, 1 - py]), np.eye(2), np.zeros((2, 2)),
                      [Port(f"{a}_cmd", "mm", "command", a) for a in "xy"],
                      [Port(f"{a}_pos", "mm", "position", a) for a in "xy"], method="two lags")


def _overshooting(wn=150.0, zeta=0.7, ky=40.0):
    """x: a second-order loop (wn rad/s, damping zeta) that overshoots its end point; y: a P loop."""
    from scipy.signal import cont2discrete
    A = np.array([[0.0, 1.0], [-wn ** 2, -2 * zeta * wn]])
    Ad, Bd, Cd, _, _ = cont2discrete((A, np.array([[0.0], [wn ** 2]]), np.array([[1.0, 0.0]]),
                                      np.zeros((1, 1))), TS)
    p = math.exp(-ky * TS)
    AA, BB, CC = np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((2, 3))
    AA[:2, :2], AA[2, 2] = Ad, p
    BB[:2, 0], BB[2, 1] = Bd[:, 0], 1 - p
    CC[0, :2], CC[1, 2] = Cd[0], 1.0
    return DriveModel(TS, AA, BB, CC, np.zeros((2, 2)), [Port(f"{a}_cmd", "mm", "command", a) for a in "xy"],
                      [Port(f"{a}_pos", "mm", "position", a) for a in "xy"], method="overshoot")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("r9")
    _ploops().save(d / "m.json")
    _ploops(gain_x=0.999).save(d / "offset.json")      # x rests 0.1 % short of its command
    _ploops(300.0, 250.0).save(d / "fast.json")         # stiff loops: feeds within 10 um exist
    (d / "rc.nc").write_text("G21 G90 G17\nG0 X0 Y-30\nG1 X30 F600\nG1 X40\n")
    (d / "rtc.nc").write_text(RAPID_THEN_CUT)
    return d


def _plan(capsys, *args):
    return run_cli(capsys, "plan", *args)


def _rows(out):
    """The console's block table: {block: (kind, contour MAX um, flag text)}."""
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 8 and cells[0].isdigit():
            rows[int(cells[0])] = (cells[2], float(cells[6]), cells[7])
    return rows


# --- 1: the in-position wait after a rapid ------------------------------------------------------

@pytest.mark.parametrize("corner", [None, 1.0])
def test_rapid_lag_does_not_carry_into_the_next_cut(files, corner):
    """Before: the cut after the rapid started with the Y axis ~0.9 mm behind (mm of contour
    error on the X line); now it starts at the first sample where every axis is within 0.01 mm."""
    model = _ploops()
    prog = parse_program(RAPID_THEN_CUT)
    old = predict(interpolate(prog, LIMITS, TS, corner_angle_deg=corner), model=model, tol_mm=0.02, program=prog)
    ip = interpolate(prog, LIMITS, TS, corner_angle_deg=corner, in_position=InPosition(model, 0.01))
    new = predict(ip, model=model, tol_mm=0.02, program=prog)
    assert old.blocks[1]["contour_max_um"] > 100.0             # the rapid's lag, seen on the cut
    k_end, k_start = old.interp.spans[0][1], ip.spans[1][0]    # rapid's end; the cut's start
    err = np.maximum(np.abs(new.error["x"]), np.abs(new.error["y"]))
    assert err[k_start] <= 0.01 and np.all(err[k_end:k_start] > 0.01)     # the first sample within
    assert new.blocks[1]["contour_max_um"] <= 10.0 and not new.blocks[1]["flag"]
    w = ip.info["in_position"]["waits"]
    assert len(w) == 1 and w[0]["line"] == 3 and w[0]["reached"]
    assert w[0]["wait_s"] == pytest.approx(ip.cycle_time - old.interp.cycle_time, abs=1.5 * TS)
    assert w[0]["wait_s"] > 0.05


def test_in_position_option_and_zero_keeps_the_old_behaviour(files, capsys):
    code, out, _ = _plan(capsys, files / "rtc.nc", "--model", files / "m.json", "--limits", "100,2000,1e5",
                         "--tol", "0.02")
    assert code == 0 and _rows(out)[2][1] <= 10.0 and _rows(out)[2][2] == ""
    code, out0, _ = _plan(capsys, files / "rtc.nc", "--model", files / "m.json", "--limits", "100,2000,1e5",
                          "--tol", "0.02", "--in-position", "0")
    assert code == 0 and _rows(out0)[2][1] > 100.0 and _rows(out0)[2][2] == "OVER"
    code, out, err = _plan(capsys, files / "rtc.nc", "--model", files / "m.json", "--limits", "100,2000,1e5",
                           "--in-position", "-1")
    assert code != 0 and "--in-position" in err and out == ""


def test_in_position_not_reached_inserts_the_cap_and_says_so(files, capsys):
    """An axis resting outside the window (here x short by 0.1 % of 30 mm = 30 um) waits the cap
    (5 s) and the console names the line and the residual error, rather than failing."""
    prog = "G21 G90 G17\nG0 X30 Y0\nG1 Y10 F600\n"
    (files / "cap.nc").write_text(prog)
    code, out, _ = _plan(capsys, files / "cap.nc", "--model", files / "offset.json", "--limits", "100,2000,1e5")
    assert code == 0
    note = [ln for ln in out.splitlines() if "in-position window" in ln]
    assert len(note) == 1 and "line 2" in note[0] and "x 30" in note[0], out
    ip = interpolate(parse_program(prog), LIMITS, TS, in_position=InPosition(_ploops(gain_x=0.999)))
    w = ip.info["in_position"]["waits"][0]
    assert not w["reached"] and w["wait_s"] == pytest.approx(5.0) and w["residual_um"]["x"] == pytest.approx(30, rel=0.01)


def test_optimiser_replans_keep_the_in_position_wait(files, capsys):
    """Before: the optimiser drove the cut after the rapid to its 5 % floor for the rapid's lag
    and still failed. Also: the JSON's overrides are keyed by the tables' 1-based block number."""
    code, out, _ = _plan(capsys, files / "rc.nc", "--model", files / "m.json", "--limits", "100,2000,1e5",
                         "--tol", "0.02", "--optimize", "--json", files / "rc.json")
    assert code == 0, out
    fp = json.loads((files / "rc.json").read_text())["data"]["feed_plan"]
    assert fp["reachable"] and set(fp["overrides"]) == {"2", "3"}      # the G1 blocks: 2 and 3
    assert fp["overrides"]["2"] == 1.0                                  # the cut is not slowed
    table = json.loads((files / "rc.json").read_text())["tables"]["feeds"]
    blk = table["columns"].index("block")
    assert {str(r[blk]) for r in table["rows"] if r[table["columns"].index("kind")] != "rapid"} == set(fp["overrides"])


# --- 2: a dwell's settling error counts against the cutting block before it --------------------

DWELL = "G21 G90 G17\nG1 X20 F3000\nG4 P0.3\nG1 Y10\n"


def test_dwell_error_is_flagged_on_the_block_before_it_and_the_optimiser_slows_it():
    """An X move whose axis overshoots its end: 0 um on the line, 14 um in the dwell after it.
    Before: nothing flagged; the optimiser left the block at 100 %."""
    model = _overshooting()
    prog = parse_program(DWELL)
    pr = predict(interpolate(prog, LIMITS, TS), model=model, tol_mm=0.01, program=prog)
    line, dwell = pr.blocks[0], pr.blocks[1]
    assert line["contour_max_um"] < 1.0 and dwell["contour_max_um"] > 12.0
    assert line["flag"] and not dwell["flag"] and pr.summary["flagged_blocks"] == [1]
    assert line["contour_max_with_dwell_um"] == dwell["contour_max_um"]
    fpl = optimize_feeds(prog, LIMITS, TS, 0.01, model=model, before=pr)
    assert fpl.overrides[0] < 0.6 and fpl.reachable
    assert fpl.after.blocks[1]["contour_max_um"] <= 10.0 and fpl.after.summary["flagged_blocks"] == []


def test_dwell_after_a_rapid_is_not_flagged():
    model = _overshooting()
    prog = parse_program("G21 G90 G17\nG0 X20\nG4 P0.3\nG1 Y10 F600\n")
    pr = predict(interpolate(prog, LIMITS, TS), model=model, tol_mm=0.001, program=prog)
    assert pr.blocks[1]["contour_max_um"] > 1.0 and not pr.blocks[0]["flag"] and not pr.blocks[1]["flag"]


# --- 3: the optimiser's "after" is what the written program plans ------------------------------

def test_after_figures_are_those_of_the_written_program(files, tmp_path, capsys):
    """Before: the figures came from the unrounded feeds; F is written to 6 significant digits,
    so planning the written program gave other figures (0.22 um on the reviewer's twin)."""
    nc = tmp_path / "sq.nc"
    nc.write_text("%\nO1\nN10 G21 G90 G17 G94\nN20 G1 X20 Y0 F3000\nN30 G1 Y20\nN40 G3 X0 Y20 I-10 J0\n"
                  "N50 G4 P0.2\nN60 G1 X0 Y0 F1500\nN70 M30\n%\n")
    code, out, _ = _plan(capsys, nc, "--model", files / "fast.json", "--limits", "100,2000,1e5", "--tol", "0.01",
                         "--optimize", "-o", tmp_path / "opt.nc", "--json", tmp_path / "opt.json")
    assert code == 0, out
    rep = json.loads((tmp_path / "opt.json").read_text())
    feeds = rep["tables"]["feeds"]
    col = feeds["columns"].index("contour_max_after_um")
    reported = {r[feeds["columns"].index("block")]: r[col] for r in feeds["rows"]}
    assert any(v > 1.0 for v in reported.values())
    code, out2, _ = _plan(capsys, tmp_path / "opt.nc", "--model", files / "fast.json", "--limits", "100,2000,1e5",
                          "--tol", "0.01", "--json", tmp_path / "re.json")
    re_rows = {r[0]: r for r in json.loads((tmp_path / "re.json").read_text())["tables"]["blocks"]["rows"]}
    cols = json.loads((tmp_path / "re.json").read_text())["tables"]["blocks"]["columns"]
    for blk, v in reported.items():
        assert re_rows[blk][cols.index("contour_max_with_dwell_um")] == v, blk
    s_after = rep["data"]["feed_plan"]["cycle_time_after_s"]
    assert json.loads((tmp_path / "re.json").read_text())["data"]["summary"]["cycle_time_s"] == s_after


def test_overrides_are_those_the_written_feeds_give():
    model = _ploops(300.0, 250.0)
    prog = parse_program("G21 G90 G17\nG1 X20 Y3 F2777.77\nG2 X30 Y13 I0 J10\n")
    fpl = optimize_feeds(prog, LIMITS, TS, 0.005, model=model)
    again = parse_program(write_program(prog, fpl.new_feeds_mm_s(prog)))
    for k, ov in fpl.overrides.items():
        assert again.blocks[k].feed == pytest.approx(prog.blocks[k].feed * ov, rel=1e-12)
        assert again.blocks[k].f_word == float(f"{again.blocks[k].f_word:.6g}")       # 6 digits


# --- 5: no uniform override meets the tolerance ------------------------------------------------

def test_no_feasible_uniform_override_is_said_in_words(files, tmp_path, capsys):
    """x rests 30 um short of X30: a Y line there is 30 um off the path at any feed."""
    nc = tmp_path / "off.nc"
    nc.write_text("G21 G90 G17\nG1 X30 F3000\nG1 Y10\n")
    code, out, _ = _plan(capsys, nc, "--model", files / "offset.json", "--limits", "100,2000,1e5", "--tol", "0.01",
                         "--optimize", "--in-position", "0", "--report", tmp_path / "r.html")
    assert code == 1
    assert "no uniform override meets the tolerance" in out and "nan" not in out
    html = (tmp_path / "r.html").read_text()
    assert "no uniform feed override meets the tolerance" in html and "0.0 %" not in html


# --- a twin of one axis under a program in a plane -------------------------------------------------

def _one_axis(d):
    p = math.exp(-40.0 * TS)
    DriveModel(TS, np.array([[p]]), np.array([[1 - p]]), np.eye(1), np.zeros((1, 1)),
               [Port("x_cmd", "mm", "command", "x")], [Port("x_pos", "mm", "position", "x")],
               method="one lag").save(d / "x_only.json")
    return d / "x_only.json"


def test_a_one_axis_twin_under_a_plane_program_is_refused_before_any_line(files, capsys):
    """A twin of x alone under a program moving x and y reported contour 0.00 um and "every block
    stays inside" the tolerance; --optimize printed the whole table before refusing."""
    m = _one_axis(files)
    for extra in ([], ["--optimize"]):
        code, out, err = _plan(capsys, files / "rtc.nc", "--model", m, "--limits", "100,2000,1e5", "--tol", "0.01",
                               *extra)
        assert code == 2 and out == "" and "column 'axes'" in err and "the twin models one axis (x)" in err, err
    (files / "x.nc").write_text("G21 G90\nG1 X10 F600\nM30\n")     # a one-axis program on it: planned
    code, out, err = _plan(capsys, files / "x.nc", "--model", m, "--limits", "100,2000,1e5", "--tol", "0.01")
    assert code == 0, err
    code, out, err = _plan(capsys, files / "x.nc", "--model", m, "--limits", "100,2000,1e5", "--tol", "0.01",
                           "--optimize")
    assert code == 2 and out == "" and "feed optimisation needs a model of (at least) two axes" in err, err


# --- the in-position wait, stepped once along the program -----------------------------------------

def _reference_wait(model, P, Ts, window, cap_s):
    """The wait as first built: the whole prefix simulated from rest, then the end point held."""
    from fdid_fmi.simulate import simulate
    n_cap = max(1, int(math.ceil(cap_s / Ts - 1e-9)))
    k_e = P.shape[0] - 1
    cmds = {a: np.concatenate([P[:, "xyz".index(a)], np.full(n_cap, P[-1, "xyz".index(a)])]) for a in model.axes}
    res = simulate(model, cmds, Ts=Ts)
    worst = np.max([np.abs(cmds[a][k_e:] - res.axes[a]["position"][k_e:]) for a in model.axes], axis=0)
    inside = np.flatnonzero(worst <= window)
    return int(inside[0]) if inside.size else n_cap


class _ReferenceTracker:
    """The whole prefix kept and simulated from rest at every rapid."""

    def __init__(self, ip, Ts):
        self.ip, self.Ts, self.P, self.k = ip, Ts, np.zeros((0, 3)), 0

    def wait(self, P, start=0):
        self.P = np.concatenate([self.P[:start], np.asarray(P, float)])
        self.k = self.P.shape[0] - 1
        n = _reference_wait(self.ip.model, self.P, self.Ts, self.ip.window_mm, self.ip.cap_s)
        n_cap = max(1, int(math.ceil(self.ip.cap_s / self.Ts - 1e-9)))
        return n, (None if n < n_cap else {a: 0.0 for a in self.ip.model.axes})


@pytest.mark.parametrize("corner", [None, 1.0])
def test_the_stepped_waits_are_those_of_a_run_of_each_prefix(corner, monkeypatch):
    """A program's rapids (in sequence, incremental, after an arc) waited for by the twin stepped
    once along the program give the commands that a run of each whole prefix from rest gives,
    to the bit, on a twin with friction and cross-axis coupling."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    import fmu_support as fs
    m = fs.coupled_model()
    prog = parse_program("G21 G90 G17\nG0 X5 Y-3\nG1 X10 F900\nG0 X12 Y4\nG0 X2\nG3 X-2 Y4 R2 F600\n"
                         "G91 G0 X3 Y-2\nG1 Y-4 F1200\nG90 G0 X0 Y0\nG1 X1 F300\n")
    ip = InPosition(m, 0.002)
    it = interpolate(prog, LIMITS, m.Ts, corner_angle_deg=corner, in_position=ip)
    waits = [w["wait_s"] for w in it.info["in_position"]["waits"]]
    assert len(waits) == 5 and sum(w > 0 for w in waits) >= 3, waits
    monkeypatch.setattr(InPosition, "tracker", lambda self, Ts: _ReferenceTracker(self, Ts))
    ref = interpolate(prog, LIMITS, m.Ts, corner_angle_deg=corner, in_position=ip)
    assert [w["wait_s"] for w in ref.info["in_position"]["waits"]] == waits
    for a in "xyz":
        assert np.array_equal(it.positions[a], ref.positions[a])


def test_the_optimisation_line_judges_the_cutting_blocks_not_the_rapids(files, tmp_path, capsys):
    """A whole-program contour MAX above the tolerance was printed beside the optimised feeds when
    it came from a rapid (not judged): 21.64 um at tol 20 on a 1000-block program whose cutting
    blocks were all within it."""
    nc = tmp_path / "rapids.nc"
    nc.write_text("G21 G90 G17\nG0 X40 Y25\nG1 X41 F300\nG0 X0 Y0\nG1 Y1 F300\n")
    code, out, _ = _plan(capsys, nc, "--model", files / "fast.json", "--limits", "100,2000,1e5", "--tol", "0.02",
                         "--optimize")
    line = next(ln for ln in out.splitlines() if ln.startswith("feed optimisation ("))
    cut = float(line.split("contour MAX ")[1].split(" µm on the cutting blocks")[0])
    rapid = float(line.split("µm on the cutting blocks, ")[1].split(" µm during rapids, not judged")[0])
    assert code == 0 and cut <= 20.0 < rapid, line
