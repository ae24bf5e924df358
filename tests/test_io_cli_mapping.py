"""CLI trace options: --map / --unit / --range / --layout parsing, shared by every command."""
import argparse

import numpy as np
import pytest

from fdid_fmi.pipeline.traces import add_trace_arguments, parse_mapping, parse_units, trace_from_args
from fdid_fmi.errors import InputError


def test_parse_mapping():
    m = parse_mapping(["time=t_s", "x.cmd=x_cmd_mm", "x.ACT=x_motor_mm", "x.tool=x_table_mm"])
    assert m == {"t": "t_s", "x.cmd": "x_cmd_mm", "x.act": "x_motor_mm", "x.tool": "x_table_mm"}
    with pytest.raises(InputError, match="not KEY=VALUE"):
        parse_mapping(["trace.csv"])
    with pytest.raises(InputError, match="unknown role 'speed'"):
        parse_mapping(["x.speed=v"])
    with pytest.raises(InputError, match="mapped twice"):
        parse_mapping(["t=a", "time=b"])
    with pytest.raises(InputError, match="key and a value"):
        parse_mapping(["x.cmd="])


def test_parse_units():
    assert parse_units(["x_pos=um", "t=ms"]) == {"x_pos": "um", "t": "ms"}
    with pytest.raises(InputError, match="unknown unit 'furlong'"):
        parse_units(["x=furlong"])


def parser():
    p = argparse.ArgumentParser()
    p.add_argument("trace")
    add_trace_arguments(p)
    return p


def test_trace_from_args(tmp_path):
    f = tmp_path / "run.csv"
    rows = "\n".join(f"{k * 0.01:.2f},{k},{k - 0.5},{k + 1}" for k in range(500))
    f.write_text("time,pos_ref,pos_enc,other\n" + rows + "\n")
    args = parser().parse_args([str(f), "--map", "t=time", "x.cmd=pos_ref", "--map", "x.act=pos_enc",
                                "--unit", "pos_ref=um", "pos_enc=um", "--range", "0.5:1.2,2:3",
                                "--range", "4:4.5"])
    tr = trace_from_args(args.trace, args)
    assert tr.roles == {"x": {"cmd": "pos_ref", "act": "pos_enc"}}
    np.testing.assert_allclose(tr.error("x"), 0.0005)
    assert tr.meta["ranges"] == [(0.5, 1.2), (2.0, 3.0), (4.0, 4.5)]
    parts = tr.select(tr.meta["ranges"])
    assert [p.n for p in parts] == [71, 101, 51]
    bad = parser().parse_args([str(f), "--map", "t=time", "x.cmd=pos_ref", "x.act=pos_enc",
                               "--range", "3:9"])
    with pytest.raises(InputError, match="outside the data"):
        trace_from_args(bad.trace, bad)


def test_layout_option(tmp_path):
    f = tmp_path / "gui.txt"
    f.write_text("\n".join(f"{k * 0.001} {k * 0.1} 0.02" for k in range(10)))
    args = parser().parse_args([str(f), "--layout", "siso-gui", "--axes", "z"])
    tr = trace_from_args(args.trace, args)
    assert tr.axes == ["z"] and tr.meta["layout"] == "siso-gui"
    np.testing.assert_allclose(tr.error("z"), 0.02, atol=1e-12)
    # a file with a header takes its axes from the column names: --axes would be ignored
    h = tmp_path / "named.csv"
    h.write_text("t_s,x_cmd_mm,x_mm\n" + "\n".join(f"{k * 0.001},{k * 0.1},{k * 0.1}" for k in range(10)))
    args = parser().parse_args([str(h), "--axes", "z"])
    with pytest.raises(InputError, match="--axes.*column names"):
        trace_from_args(args.trace, args)


def test_mat_and_xml_refuse_text_options(tmp_path, shared_data):
    emps = shared_data / "emps" / "DATA_EMPS.mat"
    args = parser().parse_args([str(emps), "--layout", "siso-gui"])
    with pytest.raises(InputError, match="text files only"):
        trace_from_args(args.trace, args)
    args = parser().parse_args([str(emps), "--axes", "y", "--range", "1:2"])
    tr = trace_from_args(args.trace, args)
    assert tr.axes == ["y"] and tr.meta["ranges"] == [(1.0, 2.0)]
