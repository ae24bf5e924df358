"""Trace: select / slice / resample, range errors, jitter, read-only copies."""
import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.io.ranges import parse_ranges
from fdid_fmi.trace import Channel, Trace


def make(n=101, Ts=0.01):
    t = np.arange(n) * Ts
    cmd = np.sin(t)
    act = cmd - 0.01
    return Trace.from_arrays(t, {"x": {"cmd": cmd, "act": act}}, extra={"f_N": 2 * t},
                             units={"f_N": "N"}, source="mem")


def test_slice_and_select():
    tr = make()
    s = tr.slice(0.2, 0.5)
    assert s.t[0] == pytest.approx(0.2) and s.t[-1] == pytest.approx(0.5) and s.n == 31
    np.testing.assert_allclose(s.cmd("x"), np.sin(s.t))
    assert s.roles == tr.roles and s.channels["f_N"].unit == "N"
    parts = tr.select(parse_ranges("0.1:0.3, 0.5:0.9"))
    assert [p.n for p in parts] == [21, 41]
    assert parts[1].t[0] == pytest.approx(0.5)
    assert tr.select(None) == [tr] and tr.select([]) == [tr]
    open_end = tr.select(parse_ranges("0.9:"))[0]
    assert open_end.t[-1] == pytest.approx(1.0) and open_end.n == 11


def test_range_outside_data():
    tr = make()
    with pytest.raises(InputError, match=r"outside the data") as ei:
        tr.select([(0.5, 2.0)])
    assert ei.value.column == "range"
    with pytest.raises(InputError, match="must be before"):
        tr.slice(0.5, 0.4)
    with pytest.raises(InputError, match="fewer than 2 samples"):
        tr.slice(0.501, 0.505)


def test_resample():
    tr = make()
    r = tr.resample(0.02)
    assert r.n == 51 and r.Ts == pytest.approx(0.02)
    np.testing.assert_allclose(r.cmd("x"), tr.cmd("x")[::2])
    mid = tr.resample(0.005)
    np.testing.assert_allclose(mid.act("x")[1], 0.5 * (tr.act("x")[0] + tr.act("x")[1]))
    with pytest.raises(InputError, match="positive"):
        tr.resample(0.0)


def test_jitter_and_monotonic_errors():
    t = np.arange(10) * 0.01
    t[5] += 0.002                                        # 20 % off the 10 ms step
    with pytest.raises(InputError, match="not steady") as ei:
        Trace(t=t, channels=[Channel("x", "mm", np.zeros(10))])
    assert ei.value.row == 6
    t2 = np.arange(10) * 0.01
    t2[4] = t2[3]
    with pytest.raises(InputError, match="strictly increasing"):
        Trace(t=t2, channels=[])
    ok = Trace(t=t, channels=[], jitter_tol=0.5)          # a looser tolerance lets it through
    assert ok.n == 10


def test_user_arrays_never_modified_and_channels_read_only():
    t = np.arange(5) * 0.1
    x = np.arange(5.0)
    tr = Trace.from_arrays(t, {"x": {"cmd": x, "act": x}})
    x[0] = 42.0                                          # the trace holds its own copy
    assert tr.cmd("x")[0] == 0.0
    with pytest.raises(ValueError):
        tr.cmd("x")[1] = 1.0
    with pytest.raises(ValueError):
        tr.t[0] = 1.0
    sl = tr.slice(0.1, 0.3)
    with pytest.raises(ValueError):
        sl.act("x")[0] = 5.0
    assert x[1] == 1.0 and t[0] == 0.0


def test_parse_ranges():
    assert parse_ranges("0.5:3.2,4:6") == [(0.5, 3.2), (4.0, 6.0)]
    assert parse_ranges(["0:1", "2:3"]) == [(0.0, 1.0), (2.0, 3.0)]
    assert parse_ranges(":1, 2:") == [(None, 1.0), (2.0, None)]
    assert parse_ranges("") == []
    with pytest.raises(InputError, match="START:STOP"):
        parse_ranges("0.5-3.2")
    with pytest.raises(InputError, match="'a' is not a number"):
        parse_ranges("a:3")
    with pytest.raises(InputError, match="must be before"):
        parse_ranges("3:1")
    with pytest.raises(InputError, match="overlap"):
        parse_ranges("0:2,1:3")
    with pytest.raises(InputError, match="finite"):
        parse_ranges("0:inf")
