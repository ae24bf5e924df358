"""fdid_fmi.plan against the virtual drive: predicted contour error per block (model and FMU),
feed optimisation within the tolerance, the planner's HTML report and the CLI."""
import json
import re
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pytest

from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program
from fdid_fmi.plan.predict import predict, signed_contour_error

PROGRAM = """G21 G90 G17 G94
N10 G1 X12 F3000
N20 G3 X24 Y0 R6
N30 G1 X12 Y8 F4800
"""
LIMITS = {a: AxisLimits(100, 2000, 1e5) for a in "xyz"}


@pytest.fixture(scope="module")
def machine():
    """The virtual Deckel-Maho-like machine and the twin identified from its traces (six moves per
    axis, the SISO pole search with seed 0, combined: stored by tests/data/make_xy_twin_model.py)."""
    from pathlib import Path
    from fdid_fmi.model import load_model
    from fdid_fmi.virtual import presets
    return presets.deckel_maho_like(), load_model(Path(__file__).parent / "data" / "xy_twin_model.json")


@pytest.fixture(scope="module")
def planned(machine):
    cfg, model = machine
    prog = parse_program(PROGRAM, source="t.nc")
    ip = interpolate(prog, LIMITS, model.Ts)
    return prog, ip


def _virtual_contour(cfg, ip):
    from fdid_fmi.virtual import simulate_machine
    tr = simulate_machine(cfg, {a: ip.positions[a] for a in ("x", "y")}, seed=1)
    cmd = np.column_stack([ip.positions["x"], ip.positions["y"]])
    return signed_contour_error(cmd, np.column_stack([tr.act("x"), tr.act("y")]))


def _per_block(ip, c):
    out = []
    for b in range(len(ip.spans)):
        sel = ip.block_of_sample == b
        out.append((np.sqrt(np.mean(c[sel] ** 2)), np.abs(c[sel]).max()))
    return np.array(out)


def test_signed_contour_error_sign():
    t = np.linspace(0, 1, 200)
    cmd = np.column_stack([10 * t, 0 * t])              # along +x
    left = cmd + [0, 0.01]
    assert np.allclose(signed_contour_error(cmd, left), 0.01)
    assert np.allclose(signed_contour_error(cmd, cmd - [0, 0.01]), -0.01)
    # the distance to the path, not the same-sample error: on a counter-clockwise circle
    # (R = 5 mm) a point lagging 0.1 rad behind, 10 um inside (left) or outside, is +-10 um off
    # (the same-sample error's normal part would be 35 um; the chords sag 0.006 um)
    th = 2 * np.pi * np.arange(2000) / 2000
    circ = 5.0 * np.column_stack([np.cos(th), np.sin(th)])
    for r, c in ((4.99, 0.01), (5.01, -0.01)):
        lag = r * np.column_stack([np.cos(th - 0.1), np.sin(th - 0.1)])
        assert np.allclose(signed_contour_error(circ, lag)[100:], c, rtol=0, atol=1e-5)


def test_prediction_matches_the_virtual_drive(machine, planned):
    cfg, model = machine
    prog, ip = planned
    pr = predict(ip, model=model, tol_mm=0.02, program=prog)
    truth = _per_block(ip, _virtual_contour(cfg, ip))
    pred = _per_block(ip, pr.contour)
    moving = truth[:, 1] > 5e-3                          # blocks with > 5 um contour error
    assert moving.sum() >= 2
    assert np.all(np.abs(pred[moving] - truth[moving]) <= 0.10 * truth[moving])
    assert pr.blocks[1]["flag"] and pr.summary["flagged_blocks"]
    assert pr.summary["cycle_time_s"] == pytest.approx(ip.cycle_time)


def test_prediction_through_the_fmu(machine, planned, tmp_path):
    from fdid_fmi.fmu import export_fmu
    cfg, model = machine
    prog, ip = planned
    fmu = export_fmu(model, tmp_path / "drive.fmu")
    pf = predict(ip, fmu=fmu, program=prog)
    assert pf.engine == "fmu"
    pm = predict(ip, model=model, program=prog)
    for a in ("x", "y"):       # causal model: the row at t_k + h after doStep is simulate()'s sample
        assert np.array_equal(pf.position[a], pm.position[a])
    truth = _per_block(ip, _virtual_contour(cfg, ip))
    pred = _per_block(ip, pf.contour)
    moving = truth[:, 1] > 5e-3
    assert np.all(np.abs(pred[moving] - truth[moving]) <= 0.10 * truth[moving])


def test_feed_optimisation_within_tol_and_faster_than_uniform(machine, planned):
    from fdid_fmi.plan.optimize import optimize_feeds
    cfg, model = machine
    prog, ip = planned
    tol = 0.025
    fp = optimize_feeds(prog, LIMITS, model.Ts, tol, model=model)
    assert fp.reachable
    assert fp.before.summary["contour_max_um"] > tol * 1e3          # the programmed feeds are too fast
    for r in fp.rows:
        assert r["contour_max_after_um"] <= tol * 1e3
    # checked independently on the virtual drive itself (the feeds aim 2 % below tol)
    ip2 = interpolate(prog, LIMITS, model.Ts, overrides=fp.overrides)
    assert np.abs(_virtual_contour(cfg, ip2)).max() <= tol
    assert fp.after.interp.cycle_time < fp.uniform_cycle_time_s
    assert fp.uniform_override < 1.0


class _Collect(HTMLParser):
    def __init__(self):
        super().__init__()
        self.figures, self.tables, self._json, self.data = [], [], False, ""

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "figure":
            self.figures.append(a.get("id"))
        if tag == "table":
            self.tables.append(a.get("id"))
        if tag == "script" and a.get("id") == "report-data":
            self._json = True

    def handle_endtag(self, tag):
        if tag == "script":
            self._json = False

    def handle_data(self, d):
        if self._json:
            self.data += d


def test_cli_plan_report(machine, tmp_path):
    cfg, model = machine
    model.save(tmp_path / "m.json")
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM + "M30\n")
    before = nc.read_bytes()
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--model", str(tmp_path / "m.json"),
                        "--limits", "100,2000,1e5", "--tol", "0.02", "--report", str(tmp_path / "r.html"),
                        "--json", str(tmp_path / "r.json")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "OVER" in r.stdout and nc.read_bytes() == before
    h = _Collect()
    h.feed((tmp_path / "r.html").read_text())
    for fig in ("figure-path", "figure-errors_time", "figure-errors_path", "figure-model_bode", "figure-model_pzmap"):
        assert fig in h.figures
    for tab in ("table-blocks", "table-model_poles", "table-model_friction"):
        assert tab in h.tables
    data = json.loads(h.data.replace("<\\/", "</"))
    unit = re.compile(r"\[.+\]")
    for name, fig in data["figures"].items():
        axes = fig["axes"]
        assert axes, name
        assert all(unit.search(a["ylabel"]) for a in axes), name
        assert any(unit.search(a["xlabel"]) for a in axes), name
    assert data == json.loads((tmp_path / "r.json").read_text())
    # a bad program: one line naming the line, no traceback
    nc.write_text("G1 X1 F100\nG2 X10 Y0 I1 J0\n")
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--model", str(tmp_path / "m.json"),
                        "--limits", "100,2000,1e5"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "row 2" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    # an axis the twin does not model: planned, with a warning that it is not predicted
    nc.write_text("G21 G90 G17 G94\nN10 G1 X12 F3000\nN20 G1 Z-2 F600\nM30\n")
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--model", str(tmp_path / "m.json"),
                        "--limits", "100,2000,1e5"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "warning: the program moves ['z']" in r.stdout
    # --range cuts the --limits-from trace (it was ignored): x moves only before 0.1 s
    t = np.arange(1000) * 1e-3
    xs = np.clip(t, 0, 0.1) ** 2 * 100
    np.savetxt(tmp_path / "lim.csv", np.column_stack([t, xs, xs, xs, xs]), delimiter=",", comments="",
               header="t_s,x_cmd_mm,x_mm,y_cmd_mm,y_mm")
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--model", str(tmp_path / "m.json"),
                        "--limits-from", str(tmp_path / "lim.csv"), "--range", "0.2:0.9"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "does not move" in r.stderr, r.stderr[-2000:]


def test_cli_optimise_through_the_fmu(machine, tmp_path):
    from fdid_fmi.fmu import export_fmu
    from fdid_fmi.plan.ncprogram import read_program
    cfg, model = machine
    fmu = export_fmu(model, tmp_path / "drive.fmu")
    nc = tmp_path / "p.nc"
    nc.write_text("G21 G90 G17 G94\nG0 X2 Y0 M3\nG1 X12 F3000\nG3 X24 Y0 R6\nM30\n")
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--fmu", str(fmu),
                        "--limits", "100,2000,1e5", "--tol", "0.03", "--optimize", "-o", str(tmp_path / "opt.nc"),
                        "--json", str(tmp_path / "r.json"), "--start", "2,0,0"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "words read" in r.stdout and "M3" in r.stdout
    opt = read_program(tmp_path / "opt.nc")
    orig = read_program(nc)
    assert [b.kind for b in opt.blocks] == [b.kind for b in orig.blocks]
    assert opt.blocks[2].feed < orig.blocks[2].feed                 # the arc is slowed down
    assert opt.blocks[0].feed == orig.blocks[0].feed                # the rapid is not touched
    fp = json.loads((tmp_path / "r.json").read_text())["data"]["feed_plan"]
    assert fp["reachable"] and fp["cycle_time_after_s"] < fp["uniform_cycle_time_s"]
    tables = json.loads((tmp_path / "r.json").read_text())["tables"]
    names = [row[0] for row in tables["fmu_variables"]["rows"]]
    assert {"x_x_cmd", "y_x_cmd", "x_x", "y_x"} <= set(names)          # the FMU's variables are shown
    rows = tables["feeds"]
    after = rows["columns"].index("contour_max_after_um")
    assert max(row[after] for row in rows["rows"]) <= 30.0


def test_cli_plan_into_a_closed_pipe_stops_quietly(machine, tmp_path):
    # `fdid plan ... | head -1`: the reader goes away; before, "fdid plan: error: Broken pipe", exit 2
    cfg, model = machine
    model.save(tmp_path / "m.json")
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM + "M30\n")
    p = subprocess.Popen([sys.executable, "-m", "fdid_fmi.cli", "plan", str(nc), "--model", str(tmp_path / "m.json"),
                          "--limits", "100,2000,1e5"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    p.stdout.close()            # gone before the first line: every write meets a closed pipe
    err = p.stderr.read()
    assert p.wait(timeout=600) == 141 and err == "", err
