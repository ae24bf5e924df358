"""CSV/TXT reader: name conventions, mappings, units, GUI layouts, and every error it promises."""
import hashlib

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.io.text import read_text

HEADER = "t_s,x_cmd_mm,x_motor_mm,x_table_mm,x_v_motor_mm_s,x_cur_A,pulses_N"


def write(tmp_path, text, name="trace.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def csv_rows(n=6, ts=0.001):
    rows = []
    for k in range(n):
        t = k * ts
        rows.append(f"{t:.6f},{0.1 * k:.4f},{0.1 * k - 0.01:.4f},{0.1 * k - 0.02:.4f},"
                    f"{100.0 * k:.1f},{0.5 + k:.2f},{5 * (k % 2)}")
    return rows


def test_roles_and_units_from_column_names(tmp_path):
    p = write(tmp_path, "\n".join([HEADER] + csv_rows()) + "\n")
    tr = read_trace(p)
    assert tr.roles == {"x": {"cmd": "x_cmd_mm", "act": "x_motor_mm", "tool": "x_table_mm",
                              "vel": "x_v_motor_mm_s", "cur": "x_cur_A"}}
    assert tr.extra_channels == ["pulses_N"]
    assert tr.channels["pulses_N"].unit == "N"
    assert tr.channels["x_v_motor_mm_s"].unit == "mm_s"
    assert tr.n == 6 and tr.Ts == pytest.approx(0.001)
    np.testing.assert_allclose(tr.error("x"), 0.01, atol=1e-12)
    assert tr.meta["sha256"] == hashlib.sha256(p.read_bytes()).hexdigest()
    assert tr.meta["delimiter"] == "comma"


def test_units_converted_to_mm_and_s(tmp_path):
    text = "t_ms,x_cmd_um,x_m,x_v_m_s\n0,1000,0.001,0.1\n2,2000,0.002,0.2\n4,3000,0.003,0.3\n"
    tr = read_trace(write(tmp_path, text))
    np.testing.assert_allclose(tr.t, [0, 0.002, 0.004])
    np.testing.assert_allclose(tr.cmd("x"), [1, 2, 3])
    np.testing.assert_allclose(tr.act("x"), [1, 2, 3])
    np.testing.assert_allclose(tr.get("x", "vel"), [100, 200, 300])
    assert tr.channels["x_cmd_um"].unit == "mm"
    assert tr.meta["units_in_file"]["x_cmd_um"] == "um"


@pytest.mark.parametrize("sep,name", [(";", "semicolon"), ("\t", "tab"), (" ", "whitespace")])
def test_delimiters_detected(tmp_path, sep, name):
    lines = ["t_s x_cmd_mm x_mm".replace(" ", sep)]
    lines += [sep.join(["0.0", "1.0", "0.5"]), sep.join(["0.1", "2.0", "1.5"]),
              sep.join(["0.2", "3.0", "2.5"])]
    tr = read_trace(write(tmp_path, "\n".join(lines)))
    assert tr.meta["delimiter"] == name
    np.testing.assert_allclose(tr.cmd("x"), [1, 2, 3])
    np.testing.assert_allclose(tr.act("x"), [0.5, 1.5, 2.5])


def test_decimal_comma_with_semicolons_and_bracket_units(tmp_path):
    text = "Zeit [ms];y_cmd [um];y_act [um]\n0;1,5;1,25\n1;2,5;2,25\n2;3,5;3,25\n"
    tr = read_trace(write(tmp_path, text))
    assert tr.meta["decimal_comma"] is True
    np.testing.assert_allclose(tr.t, [0, 0.001, 0.002])
    np.testing.assert_allclose(tr.cmd("y"), [0.0015, 0.0025, 0.0035])
    np.testing.assert_allclose(tr.act("y"), [0.00125, 0.00225, 0.00325])


def test_explicit_mapping_and_units(tmp_path):
    text = "time,pos_set,pos_enc,lin_scale,spd\n0,1,0.9,0.8,10\n0.5,2,1.9,1.8,20\n1.0,3,2.9,2.8,30\n"
    mapping = {"t": "time", "x.cmd": "pos_set", "x.act": "pos_enc", "x.tool": "lin_scale",
               "x.vel": "spd"}
    tr = read_trace(write(tmp_path, text), mapping=mapping,
                    units={"pos_set": "um", "pos_enc": "um", "lin_scale": "um", "spd": "mm_min"})
    np.testing.assert_allclose(tr.cmd("x"), [0.001, 0.002, 0.003])
    np.testing.assert_allclose(tr.get("x", "tool"), [0.0008, 0.0018, 0.0028])
    np.testing.assert_allclose(tr.get("x", "vel"), np.array([10, 20, 30]) / 60)
    assert tr.roles["x"] == {"cmd": "pos_set", "act": "pos_enc", "tool": "lin_scale", "vel": "spd"}


def test_mapping_replaces_name_rules_and_keeps_other_columns_as_extras(tmp_path):
    text = "t_s,x_cmd_mm,x_mm,x_other_mm\n0,1,1,5\n1,2,2,6\n2,3,3,7\n"
    tr = read_trace(write(tmp_path, text), mapping={"x.cmd": "x_cmd_mm", "x.act": "x_other_mm"})
    assert tr.roles == {"x": {"cmd": "x_cmd_mm", "act": "x_other_mm"}}
    assert sorted(tr.extra_channels) == ["x_mm"]


def test_missing_unit_is_assumed_canonical_and_recorded(tmp_path):
    text = "time,x_cmd,x\n0,1,1\n1,2,2\n2,3,3\n"
    tr = read_trace(write(tmp_path, text))
    assert tr.meta["assumed_units"] == {"time": "s", "x_cmd": "mm", "x": "mm"}


def test_two_axes_and_error_column_derives_command(tmp_path):
    text = "t_s,x_mm,x_err_mm,y_cmd_mm,y_e_mm\n0,1,0.1,5,0.5\n1,2,0.2,6,0.5\n2,3,0.3,7,0.5\n"
    tr = read_trace(write(tmp_path, text))
    np.testing.assert_allclose(tr.cmd("x"), [1.1, 2.2, 3.3])
    np.testing.assert_allclose(tr.act("y"), [4.5, 5.5, 6.5])
    assert tr.meta["derived"] == {"x_cmd": "x_mm + x_err_mm", "y_act": "y_cmd_mm - y_e_mm"}


def test_siso_gui_layout_autodetected(tmp_path):
    x = np.array([0.0, 0.1, 0.3, 0.6])
    e = np.array([0.01, 0.02, 0.03, 0.02])
    text = "\n".join(f"{k * 0.001:.3f}\t{xi:.3f}\t{ei:.3f}" for k, (xi, ei) in enumerate(zip(x, e)))
    tr = read_trace(write(tmp_path, text, "gui.txt"))
    assert tr.meta["layout"] == "siso-gui"
    np.testing.assert_allclose(tr.act("x"), x)
    np.testing.assert_allclose(tr.cmd("x"), x + e)           # x_cmd = x + e (thesis 4.5.1)
    np.testing.assert_allclose(tr.error("x"), e, atol=1e-12)


def test_verify_gui_layout_two_axes_and_axis_names(tmp_path):
    rows = [f"{k * 0.002:.3f} {k:.1f} 0.1 {2 * k:.1f} -0.2" for k in range(5)]
    p = write(tmp_path, "\n".join(rows), "verify.txt")
    tr = read_trace(p)
    assert tr.axes == ["x", "y"]
    np.testing.assert_allclose(tr.cmd("y"), 2 * np.arange(5) - 0.2)
    tr2 = read_trace(p, layout="verify-gui", axes=("a1", "a2"))
    assert tr2.axes == ["a1", "a2"]
    np.testing.assert_allclose(tr2.error("a1"), 0.1)


def test_gui_layout_with_wrong_column_count(tmp_path):
    p = write(tmp_path, "0 1 2 3\n1 2 3 4\n", "gui.txt")
    with pytest.raises(InputError, match=r"siso-gui.*expects 3 columns"):
        read_trace(p, layout="siso-gui")
    with pytest.raises(InputError, match="no header line and 4 columns"):
        read_trace(p)


def test_headerless_with_mapping_by_column_number(tmp_path):
    p = write(tmp_path, "0,5,4\n1,6,5\n2,7,6\n3,8,7\n", "raw.dat")
    tr = read_trace(p, mapping={"t": "1", "z.cmd": "col2", "z.act": "3"}, units={"col2": "um", "col3": "um"})
    np.testing.assert_allclose(tr.cmd("z"), [0.005, 0.006, 0.007, 0.008])


def test_user_file_is_not_modified(tmp_path):
    p = write(tmp_path, "\n".join([HEADER] + csv_rows()) + "\n")
    before = p.read_bytes()
    mtime = p.stat().st_mtime_ns
    read_trace(p)
    assert p.read_bytes() == before and p.stat().st_mtime_ns == mtime


def test_channels_are_read_only(tmp_path):
    tr = read_trace(write(tmp_path, "\n".join([HEADER] + csv_rows())))
    with pytest.raises(ValueError):
        tr.cmd("x")[0] = 99.0


# --------------------------------------------------------------------------- errors
def err(tmp_path, text, name="bad.csv", **kw):
    with pytest.raises(InputError) as ei:
        read_trace(write(tmp_path, text, name), **kw)
    return ei.value


def test_missing_mapped_column(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n1,2,2\n", mapping={"x.cmd": "x_ref_mm"})
    assert e.column == "x_ref_mm" and "not in the file" in str(e) and "x_cmd_mm" in str(e)


def test_unknown_role_in_mapping(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n1,2,2\n", mapping={"x.pos": "x_mm"})
    assert "unknown role 'pos'" in str(e)


def test_non_numeric_cell_names_column_and_spreadsheet_row(tmp_path):
    text = "t_s,x_cmd_mm,x_mm\n0,1,1\n0.1,2,2\n0.2,abc,3\n0.3,4,4\n"
    e = err(tmp_path, text)
    # header = row 1, so the 3rd data line is row 4, as a spreadsheet shows it
    assert (e.column, e.row) == ("x_cmd_mm", 4)
    assert "'abc' is not a number" in str(e) and "bad.csv" in str(e) and "row 4" in str(e)


def test_comment_lines_count_as_rows(tmp_path):
    text = "# exported by the CNC\nt_s,x_cmd_mm,x_mm\n0,1,1\n0.1,,2\n"
    e = err(tmp_path, text)
    assert (e.column, e.row) == ("x_cmd_mm", 4) and "empty cell" in str(e)


def test_nan_is_refused(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n0.1,2,nan\n0.2,3,3\n")
    assert (e.column, e.row) == ("x_mm", 3) and "NaN" in str(e)


def test_non_monotonic_time(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n0.1,2,2\n0.3,3,3\n0.2,4,4\n")
    assert (e.column, e.row) == ("t_s", 5) and "not strictly increasing" in str(e)


def test_jittered_time(tmp_path):
    ts = [0.0, 0.001, 0.002, 0.0032, 0.004, 0.005]
    text = "t_s,x_cmd_mm,x_mm\n" + "\n".join(f"{t},1,1" for t in ts)
    e = err(tmp_path, text)
    assert e.column == "t_s" and e.row == 5 and "not steady" in str(e)


def test_ragged_row(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n0.1,2\n0.2,3,3\n")
    assert e.row == 3 and "2 fields but the header has 3" in str(e)


def test_unknown_unit(tmp_path):
    e = err(tmp_path, "t_s,x_cmd,x_mm\n0,1,1\n1,2,2\n", units={"x_cmd": "furlong"})
    assert e.column == "x_cmd" and "unknown unit 'furlong'" in str(e)
    e = err(tmp_path, "t [s],x_cmd [inch],x_mm\n0,1,1\n1,2,2\n")
    assert e.column == "x_cmd" and "unknown unit 'inch'" in str(e)


def test_unit_for_unknown_column(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n1,2,2\n", units={"y_mm": "um"})
    assert e.column == "y_mm" and "not in the file" in str(e)


def test_unit_that_does_not_fit_role(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm_s,x_mm\n0,1,1\n1,2,2\n", mapping={"x.cmd": "x_cmd_mm_s", "x.act": "x_mm"})
    assert e.column == "x_cmd_mm_s" and "velocity unit" in str(e)


def test_empty_file_and_header_only(tmp_path):
    e = err(tmp_path, "")
    assert "empty" in str(e)
    e = err(tmp_path, "\n# nothing here\n\n")
    assert "empty" in str(e)
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n")
    assert "header line but no data rows" in str(e)


def test_single_sample(tmp_path):
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm\n0,1,1\n")
    assert "at least 2 samples" in str(e)


def test_no_time_column(tmp_path):
    e = err(tmp_path, "x_cmd_mm,x_mm\n1,1\n2,2\n")
    assert "no time column" in str(e) and "t=COLUMN" in str(e)


def test_ambiguous_roles(tmp_path):
    e = err(tmp_path, "t_s,x_mm,x_act_mm\n0,1,1\n1,2,2\n")
    assert "x.act" in str(e) and "mapping" in str(e)


def test_duplicate_header(tmp_path):
    e = err(tmp_path, "t_s,x_mm,x_mm\n0,1,1\n1,2,2\n")
    assert e.column == "x_mm" and "twice" in str(e)


def test_missing_file_and_unknown_type(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_trace(tmp_path / "nope.csv")
    p = write(tmp_path, "t_s,x_mm\n0,1\n1,2\n", "trace.xlsx")
    with pytest.raises(InputError, match=r"unknown file type '\.xlsx'"):
        read_trace(p)


def test_unknown_layout(tmp_path):
    p = write(tmp_path, "t_s,x_mm\n0,1\n1,2\n")
    with pytest.raises(InputError, match="unknown layout"):
        read_text(p, layout="fancy")


def test_commanded_velocity_is_an_extra_and_velocity_named_position_is_refused(tmp_path):
    tr = read_trace(write(tmp_path, "t_s,x_cmd_mm,x_mm,x_cmd_mm_s\n0,1,1,0\n1,2,2,1\n"))
    assert tr.extra_channels == ["x_cmd_mm_s"] and tr.channels["x_cmd_mm_s"].unit == "mm_s"
    e = err(tmp_path, "t_s,x_cmd_mm,x_mm,x_v_mm\n0,1,1,0\n1,2,2,1\n")
    assert e.column == "x_v_mm" and "the name says vel" in str(e)


def test_units_row_under_the_header(tmp_path):
    text = "time;pos_x;x_v\ns;um;mm/min\n0;1000;60\n0,5;2000;120\n1;3000;180\n"
    tr = read_trace(write(tmp_path, text))
    np.testing.assert_allclose(tr.t, [0, 0.5, 1.0])
    np.testing.assert_allclose(tr.act("x"), [1, 2, 3])      # "pos_x": axis last is fine too
    np.testing.assert_allclose(tr.get("x", "vel"), [1, 2, 3])
    e = err(tmp_path, "t,x_cmd,x\ns,mm,furlong\n0,1,1\n1,2,2\n")
    assert e.column == "x" and "unknown unit 'furlong'" in str(e)


def test_gui_layout_skips_a_header_line(tmp_path):
    text = "Time(sec) Position(mm) Error(mm)\n0 0 0.01\n0.001 0.1 0.02\n0.002 0.2 0.03\n"
    tr = read_trace(write(tmp_path, text, "gui.txt"), layout="siso-gui")
    np.testing.assert_allclose(tr.cmd("x"), [0.01, 0.12, 0.23])
    # without the layout the header is read as column names: time found, no axis roles
    plain = read_trace(write(tmp_path, text, "gui.txt"))
    assert plain.roles == {} and plain.extra_channels == ["Position", "Error"]
    with pytest.raises(InputError, match="'cmd' channel of axis 'x'"):
        plain.cmd("x")


def test_trailing_delimiter(tmp_path):
    tr = read_trace(write(tmp_path, "t_s,x_cmd_mm,x_mm,\n0,1,1,\n1,2,2,\n"))
    np.testing.assert_allclose(tr.cmd("x"), [1, 2])
    tr = read_trace(write(tmp_path, "0;0;0,01;\n1;0,1;0,02;\n2;0,2;0,03;\n", "gui.txt"))
    assert tr.meta["layout"] == "siso-gui"
    np.testing.assert_allclose(tr.cmd("x"), [0.01, 0.12, 0.23])


def _rows(n=200, time=lambda k: f"{k * 0.001:.6f}", cols=2):
    return "\n".join(",".join([time(k)] + [f"{k * 0.01:.5f}"] * cols) for k in range(n))


@pytest.mark.parametrize("name,text,mapping,words", [
    # one column as two signals would make the tracking error 0 (cmd = act)
    ("two_roles.csv", "t_s,p1,p2\n" + _rows(), {"x.cmd": "p1", "x.act": "p1"}, ["'p1'", "x.cmd", "x.act"]),
    # the name says mm, the header's unit um: which one is right only the user knows
    ("unit_clash.csv", "t_s,x_cmd_mm [um],x_mm\n" + _rows(), None, ["x_cmd_mm", "'mm'", "'um'"]),
    # two time columns (ms and s): taking the first one silently could be the wrong one
    ("two_time.csv", "time_ms,t_s,x_cmd_mm,x_mm\n" + _rows(time=lambda k: f"{k},{k * 0.001:.6f}"), None,
     ["time_ms", "t_s", "--map t="]),
    # each step within the jitter tolerance, but two rates: the uniform grid would be 12 ms off
    ("drift.csv", "t_s,x_cmd_mm,x_mm\n" + _rows(time=lambda k: f"{k * 0.001 if k < 100 else 0.099 + (k - 99) * 0.001049:.7f}"),
     None, ["t_s", "row", "uniform grid"]),
])
def test_ambiguous_or_inconsistent_files_are_refused(tmp_path, name, text, mapping, words):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        read_trace(p, mapping=mapping)
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


def test_axis_last_names_are_recognised(tmp_path):
    """'v_y' (the README's example) is axis y's velocity, not a role of an axis 'v'."""
    p = tmp_path / "vy.csv"
    p.write_text("t_s,y_cmd_mm,y_mm,v_y_mm_s\n" + _rows(cols=3))
    assert read_trace(p).roles["y"] == {"cmd": "y_cmd_mm", "act": "y_mm", "vel": "v_y_mm_s"}


def test_latin1_comment_with_next_line_character_is_still_a_comment(tmp_path):
    """'…' in Windows-1252 is byte 0x85, which Latin-1 decodes to U+0085; str.splitlines splits
    the comment there, and its tail must not become a 'header' that refuses the file."""
    p = tmp_path / "cp1252.csv"
    p.write_bytes(b"# Messung\x85 Achse X\n" + ("t_s,x_cmd_mm,x_mm\n" + _rows()).encode("latin-1"))
    tr = read_trace(p)
    assert tr.n == 200 and tr.roles["x"] == {"cmd": "x_cmd_mm", "act": "x_mm"}


def test_gui_layout_refuses_a_header_with_other_units(tmp_path):
    """--layout siso-gui reads s and mm; a header 't_ms,x_um,e_um' is refused, not skipped
    with the data read as s and mm (Ts = 1 s, positions 1000x too large)."""
    p = tmp_path / "gui.csv"
    p.write_text("t_ms,x_um,e_um\n" + "\n".join(f"{k},{k * 10},{1}" for k in range(100)))
    with pytest.raises(InputError, match="siso-gui.*'ms'"):
        read_text(p, layout="siso-gui")
    p.write_text("t_s,x_mm,e_mm\n" + "\n".join(f"{k * 0.001},{k * 0.01},0.001" for k in range(100)))
    assert read_text(p, layout="siso-gui").Ts == pytest.approx(0.001)


def test_utf8_bom_on_latin1_text(tmp_path):
    """An editor's UTF-8 BOM in front of Latin-1 text (a 'µ' byte 0xB5 further on): the BOM is not
    read into the first column's name (it was 'ï»¿t_s', and no time column was found)."""
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf# Achse X, Aufl\xf6sung 0.1 \xb5m\n" + ("t_s,x_cmd_mm,x_mm\n" + _rows()).encode())
    tr = read_trace(p)
    assert tr.n == 200 and tr.roles["x"] == {"cmd": "x_cmd_mm", "act": "x_mm"}


def _random_numbers_file(path, n=3000, newline="\n", seed=0):
    rng = np.random.default_rng(seed)
    vals = rng.normal(0, 1, (n, 2)) * 10.0 ** rng.integers(-20, 20, (n, 2))
    cells = [[repr(float(a)), "%.9g" % b] for a, b in vals]
    cells[5] = [" 1.5", "-.5 "]                      # spaces around a number, a bare fraction
    cells[6] = ["-0.0", "5e-324"]                    # signed zero, the smallest subnormal
    path.write_bytes(("t_s,x_cmd_mm,x_mm" + newline + newline.join(
        f"{k * 0.001!r},{a},{b}" for k, (a, b) in enumerate(cells)) + newline).encode())
    return vals


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
def test_long_bodies_read_to_the_same_doubles_as_line_by_line(tmp_path, newline, monkeypatch):
    """A plain numeric body is parsed in blocks by numpy; it must give the doubles the line-by-line
    reader gives (float() of each cell), bit for bit, whatever the line ends."""
    import fdid_fmi.io.text as T
    p = tmp_path / "plain.csv"
    _random_numbers_file(p, newline=newline)
    monkeypatch.setattr(T, "_BODY_CHUNK", 4096)      # many blocks, cut inside lines
    fast = read_text(p)
    monkeypatch.setattr(T, "_parse_body", lambda *a, **k: None)
    slow = read_text(p)
    for name in ("x_cmd_mm", "x_mm"):
        a, b = fast.channels[name].data, slow.channels[name].data
        assert a.tobytes() == b.tobytes()
    assert fast.t.tobytes() == slow.t.tobytes()


def test_a_blank_line_inside_a_long_body_keeps_the_row_numbers(tmp_path):
    """The block parser declines a body with a blank line (its rows would shift); the line reader
    then names the file row of a bad value."""
    lines = ["t_s,x_cmd_mm,x_mm"] + [f"{k * 0.001!r},{k * 0.01!r},{k * 0.01!r}" for k in range(500)]
    lines.insert(200, "")
    lines[400] = f"{398 * 0.001!r},nan,1"             # file row 401
    p = tmp_path / "blank.csv"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as exc:
        read_text(p)
    assert exc.value.row == 401 and exc.value.column == "x_cmd_mm"
