"""``fdid plan`` and its NC program reader: a program the twin cannot see, options
checked only after the work, R arcs without the I/J rounding tolerance, Latin-1 comments, and
the small parse messages. Each test fails without the code it guards."""
import math

import numpy as np
import pytest

from fdid_fmi.cli import main
from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel, Port
from fdid_fmi.plan.ncprogram import parse_program, read_program

TS = 1e-3
LIMITS = "100,2000,1e5"


@pytest.fixture(scope="module")
def model_xy(tmp_path_factory):
    """A two-axis (x, y) proportional position loop at 1 ms: x[k+1] = p x[k] + (1 - p) r[k]."""
    p = math.exp(-40.0 * TS)
    m = DriveModel(TS, np.diag([p, p]), np.diag([1 - p, 1 - p]), np.eye(2), np.zeros((2, 2)),
                   [Port(f"{a}_cmd", "mm", "command", a) for a in "xy"],
                   [Port(f"{a}_pos", "mm", "position", a) for a in "xy"], method="two lags")
    path = tmp_path_factory.mktemp("model") / "m.json"
    m.save(path)
    return path


def _nc(tmp_path, text, name="p.nc", encoding="utf-8"):
    f = tmp_path / name
    f.write_bytes(text.encode(encoding))
    return f


def _plan(capsys, *args):
    code = main(["plan", *[str(a) for a in args]])
    out, err = capsys.readouterr()
    return code, out, err


# --- 1: a program that moves only axes the model lacks ------------------------------------------

def test_program_moving_only_unmodelled_axes_is_refused(tmp_path, model_xy, capsys):
    """Before: exit 0, contour error 0.00 µm, and --optimize wrote an "optimised" program."""
    nc = _nc(tmp_path, "G21 G90 G17\nG1 Z10 F3000\nM30\n", "axis_z.nc")
    out_nc = tmp_path / "z_opt.nc"
    code, out, err = _plan(capsys, nc, "--model", model_xy, "--limits", LIMITS, "--tol", "0.001",
                           "--optimize", "-o", out_nc)
    assert code == 2 and out == ""
    assert "axis_z.nc" in err and "['z']" in err and "none of which the twin models" in err
    assert len(err.strip().splitlines()) == 1 and not out_nc.exists()


def test_program_moving_some_unmodelled_axes_still_warns(tmp_path, model_xy, capsys):
    nc = _nc(tmp_path, "G21 G90 G17\nG1 X5 Z2 F3000\nM30\n")
    code, out, err = _plan(capsys, nc, "--model", model_xy, "--limits", LIMITS)
    assert code == 0, err
    assert "warning: the program moves ['z']" in out


# --- 2: options checked before the work, nothing printed before an error -----------------------

@pytest.mark.parametrize("program, extra, words", [
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "-o", "{tmp}/x.nc"], ["'-o'", "--optimize"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--corner-angle", "nan"], ["'--corner-angle'", "nan"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--corner-angle", "181"], ["'--corner-angle'", "0 to 180"]),
    ("G1 X10 Y5 F3000\n", ["--limits", "0,2000,1e5"], ["'--limits'", "'0,2000,1e5'", "limit v"]),
    ("G1 X10 Y5 F3000\n", ["--limits", "x=" + LIMITS], ["p.nc", "'--limits'", "['y']"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--margin", "0.1"], ["'--margin'", "--optimize"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--range", "0:1"], ["'--range'", "--limits-from"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--start", "0,0,nan"], ["'--start'", "0,0,nan"]),
    ("G1 X10 Y5 F3000\n", ["--limits", LIMITS, "--commands", "{tmp}/tr.csv"], ["'--limits'", "--commands"]),
    ("G1 X10 Y5 F3000\n", ["--commands", "{tmp}/tr.csv", "--optimize", "--tol", "0.01"], ["'--optimize'"]),
    ("", ["--limits", LIMITS], ["p.nc", "empty (0 bytes)"]),
    ("(only a comment)\nM30\n", ["--limits", LIMITS], ["p.nc", "no motion block"]),
    ("G4 P1\nG1 X0 F100\n", ["--limits", LIMITS], ["p.nc", "moves no axis"]),
])
def test_options_and_programs_refused_before_any_output(tmp_path, model_xy, capsys, program, extra, words):
    """Before: -o without --optimize ran the whole prediction and printed its table, and a NaN
    --corner-angle, a zero limit or an empty program printed the header lines, then the error;
    the --limits errors named no file even when the program's axes were the cause."""
    nc = _nc(tmp_path, program)
    (tmp_path / "tr.csv").write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.001,1,1\n")
    code, out, err = _plan(capsys, nc, "--model", model_xy, *[a.format(tmp=tmp_path) for a in extra])
    assert code == 2 and out == "", out
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "x.nc").exists()


# --- 3: R arcs get the I/J arcs' end-point tolerance ---------------------------------------------

@pytest.mark.parametrize("text, half_chord_mm", [
    ("G21 G90 G17\nG1 X0 Y0 F3000\nG2 X20.0004 Y0 R10\n", 10.0002),
    ("G20 G90 G17\nG1 X0 Y0 F100\nG2 X1.0001 Y0 R0.5\n", 0.50005 * 25.4),
])
def test_r_arc_rounded_past_half_the_chord_is_a_half_circle(text, half_chord_mm):
    """Before: refused as '|R| = 10 mm is smaller than half the chord (10.0002 mm)', while an
    I J arc whose end radius differs by up to 0.012 mm was read."""
    arc = parse_program(text, source="r.nc").blocks[-1]
    assert arc.kind == "arc" and arc.sweep == pytest.approx(math.pi, abs=1e-12)
    assert arc.r0 == pytest.approx(half_chord_mm, rel=1e-12) and arc.r1 == pytest.approx(arc.r0, rel=1e-12)
    top = arc.point(arc.length / 2)[0]                 # clockwise from the left end: over the top
    assert top[0] == pytest.approx(half_chord_mm, rel=1e-12)
    assert top[1] == pytest.approx(half_chord_mm, rel=1e-12)
    assert np.array_equal(arc.point(arc.length)[0], arc.end)


def test_r_arc_beyond_the_tolerance_still_refused_naming_it():
    # |R| = 10 mm: the tolerance at half chord 10.0125 mm is 0.002 + 0.0100125 = 0.0120125 mm
    parse_program("G1 X0 Y0 F3000\nG2 X20.024 Y0 R10\n")                      # 0.012 over: read
    with pytest.raises(InputError, match=r"row 2: .*half the chord \(10.0125 mm\) by 0.0125 mm, "
                                         r"more than the end-point tolerance 0.012 mm"):
        parse_program("G1 X0 Y0 F3000\nG2 X20.025 Y0 R10\n", source="r.nc")


# --- 4: a Latin-1 / Windows-1252 comment ---------------------------------------------------------

LATIN1 = "G21 G90 G17\nG1 X10 F3000\nG1 Y10\nG1 X0\nG1 Y0 (Tiefe \u00d8 10)\nM30\n"


def test_latin1_comment_is_read_and_written_back_in_latin1(tmp_path):
    """Before: 'is not a text file (invalid continuation byte)', no line, the whole program
    refused for one comment."""
    from fdid_fmi.plan.ncprogram import write_program
    nc = _nc(tmp_path, LATIN1, "latin1_line5.nc", encoding="latin-1")
    prog = read_program(nc)
    assert [b.line for b in prog.blocks] == [2, 3, 4, 5] and prog.encoding == "latin-1"
    assert prog.lines[4] == "G1 Y0 (Tiefe \u00d8 10)"
    write_program(prog, {0: 10.0}, path=tmp_path / "out.nc")
    out = (tmp_path / "out.nc").read_bytes()
    assert b"(Tiefe \xd8 10)" in out and b"G1 X10 F600" in out       # the comment's byte kept
    assert read_program(tmp_path / "out.nc").blocks[0].feed == pytest.approx(10.0)


def test_latin1_character_outside_a_comment_names_its_line(tmp_path):
    nc = _nc(tmp_path, LATIN1.replace("(Tiefe \u00d8 10)", "\u00d810"), "l1.nc", encoding="latin-1")
    with pytest.raises(InputError, match=r"l1.nc, row 5: cannot read '\u00d810'"):
        read_program(nc)


# --- 5: small parse messages ---------------------------------------------------------------------

@pytest.mark.parametrize("word, digits", [("X1e9", "X1000000000"), ("Y-1.5E-3", "Y-0.0015")])
def test_exponent_notation_is_named_as_such(word, digits):
    """Before: "word 'e9' is not supported" (the number read as X1 and a word e9)."""
    with pytest.raises(InputError, match=rf"e.nc, row 2: '{word}': exponent notation is not G-code: "
                                         rf"write the number in digits \({digits}\)"):
        parse_program(f"G21 G90\nG1 {word} F100\n", source="e.nc")


def test_block_delete_is_run_and_said(tmp_path, model_xy, capsys):
    """'/' is read as a controller with its block-delete switch off reads it (module docstring):
    the block runs. Before: run with no word; now listed in Program.notes and printed."""
    prog = parse_program("G21 G90 F3000\nG1 X10\n/N60 G1 X100 Y5\nG1 X0 Y0\n")
    assert [b.line for b in prog.blocks] == [2, 3, 4] and prog.blocks[1].end[0] == 100.0
    assert prog.notes == [(3, "'/' (block delete) block run, as with the block-delete switch off")]
    nc = _nc(tmp_path, "G21 G90 F3000\nG1 X10\n/N60 G1 X12 Y5\nG1 X0 Y0\n")
    code, out, err = _plan(capsys, nc, "--model", model_xy, "--limits", LIMITS, "--json", tmp_path / "r.json")
    assert code == 0, err
    assert "note: row 3: '/' (block delete) block run" in out
    # and in the report, which had neither the notes nor (in the JSON) the passed-over lines
    import json
    said = json.loads((tmp_path / "r.json").read_text())["data"]["program"]["notes"]
    assert said == [[3, "'/' (block delete) block run, as with the block-delete switch off"]]


def test_program_ends_at_the_closing_percent(tmp_path, model_xy, capsys):
    """Before: the block after the closing '%' ran (G1 X20 here) and the passed-over list said
    'line N' while the errors say 'row N'."""
    text = "%\nG21 G90\nG1 X10 F3000 M8\n%\nG1 X20\nthis is no G-code\n"
    prog = parse_program(text)
    assert [b.line for b in prog.blocks] == [3] and prog.blocks[-1].end[0] == 10.0
    assert prog.ignored == [(3, "M8"), (5, "not read: after the closing '%' of row 4"),
                            (6, "not read: after the closing '%' of row 4")]
    code, out, err = _plan(capsys, _nc(tmp_path, text), "--model", model_xy, "--limits", LIMITS)
    assert code == 0, err
    # the words once ("words read"), the lines not run by row
    assert "passed over: row 5: not read: after the closing '%' of row 4" in out
    assert "M8" in out.split("words read:")[1].splitlines()[0]
    assert "line 3" not in out


def test_setpoints_at_another_sample_time_are_resampled_with_a_note(tmp_path, capsys):
    """fdid plan --commands resamples a 0.6 ms trace to a 1 ms twin and says so (simulate,
    validate and diagnose refuse such a trace, but a controller's interpolation cycle need not be
    the model's)."""
    import fmu_support as fs
    from pathlib import Path
    ex = Path(__file__).resolve().parents[1] / "examples"
    m = fs.coupled_model()      # two axes: a one-axis twin under the circle is refused
    assert m.Ts == 1e-3
    m.save(tmp_path / "m.json")
    assert main(["plan", str(ex / "circle.nc"), "--model", str(tmp_path / "m.json"),
                 "--commands", str(ex / "virtual_circle.csv")]) == 0
    out = capsys.readouterr().out
    assert "recorded at Ts = 0.0006 s, are resampled to the model's Ts = 0.001 s" in out
