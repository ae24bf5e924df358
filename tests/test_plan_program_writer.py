"""``fdid plan``'s program reader and writers: the CSV's numbers in full precision, a
program written back in its own encoding (byte order, byte-order mark and line ends kept),
``G64 P Q`` passed over, a long ``G4 P`` noted, a non-integer ``N`` refused. Each test fails without
the code it guards."""
import codecs
import math

import numpy as np
import pytest

from fdid_fmi.cli import main
from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel, Port
from fdid_fmi.plan.ncprogram import parse_program, read_program, write_program
from cli_support import run_cli

TS = 1e-3
LIMITS = "100,2000,1e5"
# a 45-ish degree line and an arc: commands that are not round numbers
PROGRAM = "G21 G90 G17 (Tiefe \u00d8 10)\nG1 X3.1 Y2.3 F1200\nG3 X1.1 Y4.3 I-2 J0\nG1 X0 Y0\n"


@pytest.fixture(scope="module")
def model_xy(tmp_path_factory):
    """Two axes, each a second-order position loop at 1 ms (two lags 25 ms and 8 ms)."""
    p, q = math.exp(-40.0 * TS), math.exp(-125.0 * TS)
    A = np.array([[p, 0, 0, 0], [1 - q, q, 0, 0], [0, 0, p, 0], [0, 0, 1 - q, q]])
    B = np.array([[1 - p, 0], [0, 0], [0, 1 - p], [0, 0]])
    C = np.array([[0, 1.0, 0, 0], [0, 0, 0, 1.0]])
    m = DriveModel(TS, A, B, C, np.zeros((2, 2)),
                   [Port(f"{a}_cmd", "mm", "command", a) for a in "xy"],
                   [Port(f"{a}_pos", "mm", "position", a) for a in "xy"], method="two lags")
    path = tmp_path_factory.mktemp("model") / "m.json"
    m.save(path)
    return path


def _plan(capsys, *args):
    return run_cli(capsys, "plan", *args)


# --- 1: the CSV's commands reproduce its prediction ----------------------------------------------

def test_csv_commands_reproduce_the_csv_prediction_through_fdid_simulate(tmp_path, capsys, model_xy):
    """Before: 10 significant digits; fdid simulate on the CSV's commands differed from the
    CSV's predicted error by ~1e-9 mm here (0.11 um on the reviewer's programs)."""
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    csv = tmp_path / "plan.csv"
    code, out, err = _plan(capsys, nc, "--model", model_xy, "--limits", LIMITS, "--csv", csv)
    assert code == 0, err
    d = np.genfromtxt(csv, delimiter=",", names=True)
    sim = tmp_path / "sim.csv"
    code = main(["simulate", str(model_xy), str(csv), "-o", str(sim), "--at-rest",
                 "--map", "t=t_s", "x.cmd=x_cmd_mm", "y.cmd=y_cmd_mm"])
    capsys.readouterr()
    assert code == 0
    s = np.genfromtxt(sim, delimiter=",", names=True)
    assert len(s) == len(d) and np.abs(d["x_e_pred_mm"]).max() > 0.01      # a real error to match
    for a in "xy":
        # fdid simulate writes 12 digits: 1e-12 mm on errors of at most 0.1 mm
        np.testing.assert_allclose(s[f"{a}_e_pred_mm"], d[f"{a}_e_pred_mm"], rtol=0, atol=1e-12)
    # the commands read back are the interpolation's floats, bit for bit
    from fdid_fmi.plan.interpolate import AxisLimits, interpolate
    ip = interpolate(parse_program(PROGRAM), {a: AxisLimits(100, 2000, 1e5) for a in "xyz"}, TS)
    for a in "xy":
        assert np.array_equal(d[f"{a}_cmd_mm"], ip.positions[a])
    assert np.array_equal(d["t_s"], ip.t)


# --- 2: written back in the program's own encoding ----------------------------------------------

@pytest.mark.parametrize("prefix, enc, name", [
    (codecs.BOM_UTF16_LE, "utf-16-le", "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be", "utf-16-be"),
    (codecs.BOM_UTF32_LE, "utf-32-le", "utf-32-le"),
    (codecs.BOM_UTF8, "utf-8", "utf-8-sig"),
    (b"", "utf-8", "utf-8"),
    (b"", "latin-1", "latin-1"),
])
def test_program_written_back_byte_for_byte_in_its_encoding(tmp_path, prefix, enc, name):
    """Before: UTF-16 (and a UTF-8 BOM) were written back as plain UTF-8."""
    src = tmp_path / "in.nc"
    raw = prefix + PROGRAM.encode(enc)
    src.write_bytes(raw)
    prog = read_program(src)
    assert prog.encoding == name
    write_program(prog, {}, path=tmp_path / "out.nc")
    assert (tmp_path / "out.nc").read_bytes() == raw              # BOM and comment bytes included


@pytest.mark.parametrize("eol", ["\r\n", "\r"])
def test_program_keeps_its_line_ends(tmp_path, eol):
    """Before: a CR LF or CR program was written back with LF line ends."""
    src = tmp_path / "in.nc"
    raw = PROGRAM.replace("\n", eol).encode("utf-8")
    src.write_bytes(raw)
    prog = read_program(src)
    write_program(prog, {}, path=tmp_path / "out.nc")
    assert (tmp_path / "out.nc").read_bytes() == raw
    # a rewritten feed keeps them too
    write_program(prog, {0: 10.0}, path=tmp_path / "out2.nc")
    out = (tmp_path / "out2.nc").read_bytes().decode("utf-8")
    assert out.count(eol) == 4 and out.split(eol)[1] == "G1 X3.1 Y2.3 F600"


def test_fdid_plan_writes_a_utf16_program_back_as_utf16(tmp_path, capsys, model_xy):
    """The reviewer's case: ``fdid plan u16b.nc ... --optimize -o out.nc`` wrote UTF-8."""
    src = tmp_path / "u16b.nc"
    src.write_bytes(codecs.BOM_UTF16_LE + PROGRAM.encode("utf-16-le"))
    out = tmp_path / "out.nc"
    code, _, err = _plan(capsys, src, "--model", model_xy, "--limits", LIMITS, "--tol", "0.05",
                         "--optimize", "-o", out)
    assert code in (0, 1), err
    raw = out.read_bytes()
    assert raw.startswith(codecs.BOM_UTF16_LE)
    text = raw.decode("utf-16")
    assert text.startswith("(feeds optimised by fdid plan") and "(Tiefe \u00d8 10)" in text
    assert read_program(out).encoding == "utf-16-le"


# --- 3: G64 P Q passed over; G80 R's wording ----------------------------------------------------

def test_g64_tolerances_are_passed_over_with_g64():
    """Before: 'P is only read with G4 (dwell)' and "word 'Q0.01' is not supported"."""
    prog = parse_program("G64 P0.01 Q0.005\nG1 X1 F600\nG64 P0.02\n", source="g64.nc")
    assert [b.kind for b in prog.blocks] == ["line"]
    assert prog.ignored == [(1, "G64"), (1, "P0.01 (G64 tolerance)"), (1, "Q0.005 (G64 tolerance)"),
                            (3, "G64"), (3, "P0.02 (G64 tolerance)")]
    # P and Q without G64 are still refused; a P that could be G4's or G64's is asked about
    with pytest.raises(InputError, match=r"row 1: P is only read with G4"):
        parse_program("G1 X1 P0.01 F600\n", source="g.nc")
    with pytest.raises(InputError, match=r"row 2: word 'Q0.01' is not supported \(read with G64 only"):
        parse_program("G1 X1 F600\nG1 X2 Q0.01\n", source="g.nc")
    with pytest.raises(InputError, match=r"row 1: 'P1' with both G4 and G64"):
        parse_program("G4 G64 P1\n", source="g.nc")


def test_r_without_a_motion_mode_is_not_called_an_axis_word():
    with pytest.raises(InputError) as exc:
        parse_program("G80 R1\n", source="g80.nc")
    msg = str(exc.value)
    assert "g80.nc, row 1: 'R1' without a motion mode" in msg and "axis word" not in msg
    with pytest.raises(InputError, match=r"row 1: 'X1 Y2' without a motion mode"):
        parse_program("X1 Y2\n", source="g.nc")


# --- 4: a long G4 P is noted ---------------------------------------------------------------------

def test_whole_number_dwell_of_100_or_more_is_noted():
    """Before: G4 P1000 was planned as 1000 s without a word (a Fanuc program means 1 s)."""
    prog = parse_program("G1 X1 F600\nG4 P1000\nG4 P99\nG4 P100.5\nG4 P0.5\n", source="d.nc")
    assert [b.block_time for b in prog.blocks[1:]] == [1000.0, 99.0, 100.5, 0.5]   # still seconds
    assert len(prog.notes) == 1 and prog.notes[0][0] == 2
    note = prog.notes[0][1]
    assert "read as 1000 s" in note and "Fanuc" in note and "ms" in note and "X or U" in note


def test_long_dwell_note_is_printed_by_fdid_plan(tmp_path, capsys, model_xy):
    nc = tmp_path / "d.nc"
    nc.write_text("G1 X1 F600\nG4 P100\n", encoding="utf-8")
    code, out, err = _plan(capsys, nc, "--model", model_xy, "--limits", LIMITS)
    assert code == 0, err
    assert "note: row 2: G4 P100 is read as 100 s" in out


# --- 5: N must be a whole number -----------------------------------------------------------------

def test_non_integer_line_number_is_refused():
    """Before: N10.5 was read as N10."""
    with pytest.raises(InputError) as exc:
        parse_program("N10 G1 X1 F600\nN10.5 X2\n", source="n.nc")
    assert str(exc.value).startswith("n.nc, row 2: line number 'N10.5' must be a whole number")
    assert "\n" not in str(exc.value)
    assert parse_program("N10 G1 X1 F600\nN11 X2\n").blocks[1].number == 11
