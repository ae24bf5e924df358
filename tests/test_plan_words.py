"""``fdid plan`` on part programs as Fanuc, SINUMERIK (ISO mode) and LinuxCNC write them
(tests/data/nc/), with the stored two-axis twin tests/data/xy_twin_model.json and no --limits:
the words real programs carry (applied or noted once), the limits the twin recorded from its
identification traces, axes it does not model, and the refusals of what is not supported."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from cli_support import one_line, run_cli
from fdid_fmi.errors import InputError
from fdid_fmi.model import FORMAT_VERSION, load_model
from fdid_fmi.plan.interpolate import AxisLimits
from fdid_fmi.plan.lookahead import interpolate_lookahead
from fdid_fmi.plan.ncprogram import parse_program, read_program
from fdid_fmi.plan.words import VOCABULARY, Action, markdown_table

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
NC = DATA / "nc"
TWIN = DATA / "xy_twin_model.json"
LIM = {a: AxisLimits(100, 2000, 1e5) for a in "xyz"}

# program -> (words it must list as applied, as noted, whether it moves Z)
PLANNED = {
    "fanuc_pocket.nc": ({"G54", "G64", "G28", "G3"}, {"G43", "H", "G40", "G49", "G80", "M6", "T", "S", "M3", "M8"}, True),
    "sinumerik_iso_slot.mpf": ({"G61", "G9", "G64", "G4", "G54"}, {"G291", "G43", "M6", ";"}, True),
    "linuxcnc_two_fixtures.ngc": ({"G10", "G55", "G28.1", "G28", "G53", "G61.1", "/"}, {"G43", "M7", "( )"}, True),
    "arc_spiral.ngc": ({"G2", "G4"}, {"( )"}, False),
}
REFUSED = {
    "linuxcnc_cutter_comp.ngc": ("row 8", "'G41'", "cutter radius compensation"),
    "linuxcnc_subroutine.ngc": ("row 2", "'o100 sub'", "O-word"),
    "fanuc_subprogram.nc": ("row 7", "'M98'", "subprogram"),
    "fanuc_drilling.nc": ("row 7", "'G81'", "canned cycle"),
}


def _plan(capsys, *args):
    return run_cli(capsys, "plan", *args)


@pytest.mark.parametrize("name", sorted(PLANNED))
def test_real_programs_plan_to_the_end_with_the_twins_own_limits(name, tmp_path, capsys):
    applied, noted, moves_z = PLANNED[name]
    js = tmp_path / "plan.json"
    code, out, err = _plan(capsys, NC / name, "--model", TWIN, "--tol", "0.005", "--json", js)
    assert code == 0, err
    rep = json.loads(js.read_text())
    data = rep["data"]
    # the words, once each, with how they were read
    words = data["program"]["words"]
    assert applied <= set(words) and noted <= set(words), set(words)
    assert all(len(set(rows)) == len(rows) for rows in words.values())
    line = out.split("words read:")[1].splitlines()[0]
    applied_part, noted_part = line.split("; noted")
    assert all(f" {w} " in f" {applied_part} " for w in applied)
    assert all(f" {w} " in f" {noted_part} " for w in noted)
    # the limits: the model's own, said where they came from; Z (not modelled) gets the default
    lim = data["interpolation"]["limits"]
    src = data["interpolation"]["limit_sources"]
    model = load_model(TWIN)
    for a in ("x", "y"):
        assert lim[a]["v"] == pytest.approx(model.limits[a]["v_mm_s"])
        assert src[a].startswith("recorded in the model")
        assert f"limits {a}: " in out and "recorded in the model" in out
    s = data["summary"]
    if moves_z:
        assert src["z"].startswith("default for an axis the twin does not model")
        assert lim["z"]["v"] == pytest.approx(min(model.limits[a]["v_mm_s"] for a in "xy"))
        assert s["not_predicted"] == ["z"] and "z: not predicted" in out
    else:
        assert "z" not in lim and s["not_predicted"] == []
    assert s["contour_max_um"] > 0 and math.isfinite(s["cycle_time_s"])


def test_the_report_lists_words_and_limits(tmp_path, capsys):
    html = tmp_path / "plan.html"
    code, out, err = _plan(capsys, NC / "fanuc_pocket.nc", "--model", TWIN, "--tol", "0.005", "--report", html)
    assert code == 0, err
    text = html.read_text()
    assert "Axis limits: x: recorded in the model from its identification traces" in text
    assert "z: default for an axis the twin does not model" in text
    assert "tool length compensation on" in text and "not predicted" in text
    # G43 is listed once, with its row
    assert text.count("<td>G43</td>") == 1


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_unsupported_programs_are_refused_in_one_line_with_nothing_written(name, tmp_path, capsys):
    row, word, what = REFUSED[name]
    outs = [tmp_path / "r.html", tmp_path / "r.json"]
    code, out, err = _plan(capsys, NC / name, "--model", TWIN, "--tol", "0.005", "--report", outs[0],
                           "--json", outs[1])
    one_line(code, err, name, row, word, what)
    assert out == "" and not any(o.exists() for o in outs)


def test_fmu_twins_carry_the_limits(tmp_path, capsys):
    from fdid_fmi.fmu import export_fmu
    fmu = export_fmu(load_model(TWIN), tmp_path / "xy.fmu")
    js = tmp_path / "plan.json"
    code, out, err = _plan(capsys, NC / "sinumerik_iso_slot.mpf", "--fmu", fmu, "--tol", "0.005", "--json", js)
    assert code == 0, err
    data = json.loads(js.read_text())["data"]
    assert data["summary"]["engine"] == "fmu" and data["summary"]["not_predicted"] == ["z"]
    assert data["interpolation"]["limit_sources"]["x"].startswith("recorded in the model")


def test_old_model_files_plan_with_limits_and_say_what_is_missing_without(tmp_path, capsys):
    d = json.loads(TWIN.read_text())
    del d["limits"]
    d["format_version"] = 2
    old = tmp_path / "old.json"
    old.write_text(json.dumps(d))
    assert load_model(old).limits == {}
    assert load_model(DATA / "plant2_clean_rigid_default_model.json").limits == {}     # a stored old file
    prog = NC / "arc_spiral.ngc"
    code, out, err = _plan(capsys, prog, "--model", old, "--tol", "0.005")
    line = one_line(code, err, "arc_spiral.ngc", "old.json", "records none", "format version 3", "--limits")
    assert out == "" and "['x', 'y']" in line
    code, out, err = _plan(capsys, prog, "--model", old, "--tol", "0.005", "--limits", "100,2000,1e5")
    assert code == 0, err
    assert "limits x: 100 mm/s, 2000 mm/s^2, 1e+05 mm/s^3: --limits" in out
    # --limits overrides the model's own on one axis, the other keeps the model's
    code, out, err = _plan(capsys, prog, "--model", TWIN, "--limits", "x=50,1000,5e4")
    assert code == 0, err
    assert "limits x: 50 mm/s, 1000 mm/s^2, 5e+04 mm/s^3: --limits" in out
    assert "limits y: 68.55 mm/s" in out and "recorded in the model" in out


# --- the model format ----------------------------------------------------------------------------

def test_model_limits_round_trip_and_are_checked(tmp_path):
    m = load_model(TWIN)
    assert FORMAT_VERSION == 3 and set(m.limits) == {"x", "y"}
    m.save(tmp_path / "m.json")
    d = json.loads((tmp_path / "m.json").read_text())
    assert d["format_version"] == 3 and d["limits"] == m.limits
    for bad, words in (({"z": m.limits["x"]}, "axis 'z'"), ({"x": {**m.limits["x"], "j_mm_s3": -1}}, "j_mm_s3"),
                       ({"x": {**m.limits["x"], "v_mm_s": True}}, "v_mm_s"), ([1], "JSON object")):
        (tmp_path / "bad.json").write_text(json.dumps({**d, "limits": bad}))
        with pytest.raises(InputError, match=words):
            load_model(tmp_path / "bad.json")


def _scurve_trace(glitch=0.0):
    from fdid_fmi.trace import Trace
    from fdid_fmi.virtual import trajectories as tj
    cmd = tj.linear_moves(n_moves=6, axes=("x",), Ts=0.6e-3, seed=1)
    x = np.asarray(cmd["x"], float).copy()
    t = np.arange(x.size) * 0.6e-3
    if glitch:
        d = np.diff(x)
        starts = np.flatnonzero((d[:-1] == 0) & (d[1:] != 0)) + 1
        x[starts[2]] += glitch                  # one setpoint off, where the third move starts
    return Trace.from_arrays(t, {"x": {"cmd": x, "act": x}}, source="scurve")


def test_recorded_limits_are_the_interpolators_and_ignore_one_bad_setpoint():
    """linear_moves: S-curves at v <= 100 mm/s, a = 2000 mm/s^2, j = 1e5 mm/s^3."""
    from fdid_fmi.identify.limits import recorded_limits
    from fdid_fmi.plan.interpolate import limits_from_trace
    clean = recorded_limits([_scurve_trace()], ["x", "y"])
    assert set(clean) == {"x"}                        # y is not in the trace
    assert clean["x"]["a_mm_s2"] == pytest.approx(2000, rel=0.04)
    assert clean["x"]["j_mm_s3"] == pytest.approx(1e5, rel=0.06)
    bad = _scurve_trace(glitch=0.5)
    rec = recorded_limits(bad, ["x"])["x"]
    assert rec["j_mm_s3"] == pytest.approx(clean["x"]["j_mm_s3"], rel=0.03)
    assert limits_from_trace(bad)["x"].j > 1.5 * rec["j_mm_s3"]      # the maximum is not robust


def test_identification_records_the_limits_of_its_traces():
    from fdid_fmi.identify import identify_full_ls
    from fdid_fmi.identify.limits import recorded_limits
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    tr = simulate_machine(MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts),
                          tj.linear_moves(n_moves=4, axes=("x",), Ts=cfg.Ts, seed=2), seed=2)
    m = identify_full_ls(tr, "x")
    assert m.limits == recorded_limits(tr, ["x"]) and m.limits["x"]["v_mm_s"] > 10


# --- the reader ----------------------------------------------------------------------------------

def test_docs_table_is_the_vocabulary():
    text = (ROOT / "docs" / "plan-words.md").read_text()
    assert markdown_table() in text
    keys = [w.key for w in VOCABULARY]
    assert len(keys) == len(set(keys))
    for must in ("G43", "G43.1", "G49", "G40", "G80", "G54", "G59", "G61", "G61.1", "G64", "G28", "G30",
                 "M6", "M3", "M4", "M5", "M7", "M8", "M9", "S", "T", "N", "/", "( )", ";"):
        assert must in keys and [w for w in VOCABULARY if w.key == must][0].action is not Action.REFUSED


def test_work_offsets_set_by_the_program_are_applied():
    p = read_program(NC / "linuxcnc_two_fixtures.ngc")
    circles = [b for b in p.blocks if b.kind == "arc"]
    assert len(circles) == 4
    for first, second in zip(circles[:2], circles[2:]):          # the same ring, 60 mm to the right
        assert second.center - first.center == pytest.approx([60, 0, 0])
        assert second.sweep == pytest.approx(2 * math.pi)
    # G28 goes back to the position G28.1 stored (the start), G53 Z10 in machine coordinates
    assert p.blocks[-1].kind == "rapid" and p.blocks[-1].end == pytest.approx([0, 0, 0])
    assert [b.end[2] for b in p.blocks if "G53" in b.text] == [10.0]
    # an offset the program does not set is read as 0, with one note at the switch
    q = parse_program("G0 X1\nG55\nG0 X2\nG54\nG0 X3\nG55\nG0 X4\n")
    assert [b.end[0] for b in q.blocks] == [1, 2, 3, 4]
    assert [r for r, t in q.notes if "not set in the program" in t] == [2, 4]


def test_reference_return_without_a_reference_is_noted_once():
    p = parse_program("G0 X5 Y5\nG91 G28 Z0\nG90 G28 X7\nG0 Y9\n", source="r.nc")
    assert [b.end.tolist() for b in p.blocks] == [[5, 5, 0], [7, 5, 0], [7, 9, 0]]
    notes = [t for _, t in p.notes if "reference position" in t]
    assert len(notes) == 1 and "also row 3" in notes[0]
    assert p.words["G28"] == [2, 3]


def test_exact_stop_words_stop_the_look_ahead():
    """An obround slot (tangent junctions): G64 keeps the velocity through them under the
    look-ahead, G61 and G9 bring it to rest."""
    body = "G1 X30 F1800\nG3 X30 Y16 I0 J8\nG1 X0\nG3 X0 Y0 I0 J-8\n"
    vj = {}
    for mode in ("G64", "G61"):
        p = parse_program(f"G21 G90 G17 {mode}\nG0 X0 Y0\n" + body)
        ip = interpolate_lookahead(p, LIM, 1e-3, 1.0)
        vj[mode] = ip.info["junction_velocity_mm_s"]
    assert min(vj["G64"][1:4]) > 5.0 and max(vj["G61"]) == 0.0
    p = parse_program("G21 G90 G17 G64\nG0 X0 Y0\nG9 " + body)
    v9 = interpolate_lookahead(p, LIM, 1e-3, 1.0).info["junction_velocity_mm_s"]
    assert v9[1] == 0.0 and v9[2] > 5.0


def test_words_that_are_offsets_or_dwells_not_moves():
    p = parse_program("G0 X1\nG43.1 Z5\nG4 X0.5\nG04 U1.5\nG43 H1 Z3\n")
    assert [b.kind for b in p.blocks] == ["rapid", "dwell", "dwell", "rapid"]
    assert [b.block_time for b in p.blocks[1:3]] == [0.5, 1.5]
    assert p.blocks[-1].end.tolist() == [1, 0, 3]                 # G43's Z moves, G43.1's does not
    with pytest.raises(InputError, match=r"row 1: 'G10 L20' is not supported"):
        parse_program("G10 L20 P1 X0\n")
    with pytest.raises(InputError, match=r"row 2: parameter '#1'"):
        parse_program("G0 X1\n#1 = 5\n")
    with pytest.raises(InputError, match=r"row 1: expression 'X\[1\+2\]'"):
        parse_program("G0 X[1+2]\n")
    with pytest.raises(InputError, match=r"row 1: G code 'G12' is not supported \(read: G0 G1"):
        parse_program("G12 X1\n")


def test_nc_readme_names_every_program():
    text = (NC / "README.md").read_text()
    for f in NC.iterdir():
        if f.name != "README.md":
            assert f"`{f.name}`" in text, f.name
