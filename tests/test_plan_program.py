"""fdid_fmi.plan: NC program reading and interpolation (geometry and v/a/j limits at every sample)."""
import math

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program, read_program, write_program

PROGRAM = """%
O1 (lines, arcs in three planes, inch, incremental, inverse time)
N10 G21 G90 G17 G94 F1800 S1000 M3
N20 G1 X10 Y0
N30 G2 X20 Y0 I5 J0
N40 G3 X20 Y0 I-5 J0 ; full circle
N50 G18 G3 X25 Z-5 R5
N60 G19 G2 Y5 Z0 R5
N70 G17 G20 G91 G1 X0.2 Y0.2 F60
N80 G21 G90 G93 G1 X10 Y10 F20
N90 G94 G2 X0 Y0 R-8 F2400
M30
"""
LIMITS = {"x": AxisLimits(100, 2000, 1e5), "y": AxisLimits(80, 1500, 8e4), "z": AxisLimits(50, 1000, 5e4)}
TS = 6e-4


def _distance_to_block(b, P):
    """Exact distance of points P (n, 3) from a block's programmed geometry, mm."""
    if b.kind == "line":
        d = b.end - b.start
        t = np.clip((P - b.start) @ d / (d @ d), 0, 1)
        return np.linalg.norm(P - b.start - np.outer(t, d), axis=1)
    i, j, k = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[b.plane]
    r = np.hypot(P[:, i] - b.center[i], P[:, j] - b.center[j])
    assert b.r0 == pytest.approx(b.r1, abs=1e-9)
    return np.hypot(r - b.r0, P[:, k] - b.start[k])      # no helix in this program


def test_parser_reads_every_mode():
    p = parse_program(PROGRAM, source="t.nc")
    kinds = [b.kind for b in p.blocks]
    assert kinds == ["line", "arc", "arc", "arc", "arc", "line", "line", "arc"]
    b = p.blocks
    assert b[0].feed == pytest.approx(30.0)                          # F1800 mm/min
    assert b[2].sweep == pytest.approx(2 * math.pi)                  # full circle
    assert b[3].plane == 18 and b[3].end == pytest.approx([25, 0, -5])
    assert b[4].plane == 19 and b[4].end == pytest.approx([25, 5, 0])
    assert b[5].end == pytest.approx([25 + 5.08, 5 + 5.08, 0])       # 0.2 inch incremental
    assert b[5].feed == pytest.approx(60 * 25.4 / 60)                # 60 inch/min
    assert b[6].inverse_time and b[6].block_time == pytest.approx(3.0)
    assert b[7].sweep > math.pi                                      # R < 0: the longer arc
    assert [w for _, w in p.ignored] == ["O1", "S1000", "M3", "M30"]
    assert [bb.line for bb in b] == [4, 5, 6, 7, 8, 9, 10, 11]


@pytest.mark.parametrize("text, words", [
    ("G1 X1 F100\nG1 X2 Q5\n", ["row 2", "'Q5'"]),
    ("G1 X1 F100\nG2 X10 Y0 I1 J0\n", ["row 2", "not on the arc"]),
    ("G21\nG1 X10\n", ["row 2", "no feed rate"]),
    ("G1 X1 F100\nG93 G1 X2\n", ["row 2", "without F"]),
    ("G1 X1 F100\nG2 X5 R1\n", ["row 2", "half the chord"]),
    ("G1 X1 F100\nG41 X2\n", ["row 2", "G41"]),
    ("G1 X1 F100 (open\n", ["row 1", "not closed"]),
    ("G1 X1 A5 F100\n", ["row 1", "'A5'"]),
])
def test_bad_programs_one_line_naming_the_line(text, words):
    with pytest.raises(InputError) as e:
        parse_program(text, source="bad.nc")
    msg = str(e.value)
    assert "\n" not in msg and "bad.nc" in msg
    for w in words:
        assert w in msg


@pytest.mark.parametrize("corner", [None, 2.0])
def test_interpolation_follows_geometry_and_limits(corner):
    p = parse_program(PROGRAM)
    ip = interpolate(p, LIMITS, TS, corner_angle_deg=corner)
    P = np.column_stack([ip.positions[a] for a in "xyz"])
    for b, (k0, k1) in zip(p.blocks, ip.spans):
        seg = P[k0 + 1:k1 + 1]
        assert _distance_to_block(b, seg).max() < 1e-4               # 0.1 um, no blending
        if corner is None:
            assert np.abs(P[k1] - b.end).max() < 1e-9               # exact end point on a sample
        assert ip.block_of_sample[k1] == b.index
    assert np.abs(P[-1] - p.blocks[-1].end).max() < 1e-9
    for i, a in enumerate("xyz"):
        lim = LIMITS[a]
        for n, bound in ((1, lim.v), (2, lim.a), (3, lim.j)):
            d = np.abs(np.diff(P[:, i], n=n)) / TS ** n
            rounding = 2 ** n * np.finfo(float).eps * np.abs(P).max() / TS ** n
            assert d.max() <= bound + rounding, (a, n, d.max(), bound)
    if corner is not None:
        return
    # the feed is reached on the long line (30 mm/s) and the G93 block takes at least its 3 s
    v = np.linalg.norm(np.diff(P, axis=0), axis=1) / TS
    k0, k1 = ip.spans[0]
    assert v[k0:k1].max() == pytest.approx(30.0, rel=2e-3)      # <= 1 sample of rounding (0.12 %)
    k0, k1 = ip.spans[6]
    assert (k1 - k0) * TS >= 3.0 - TS


def test_overrides_slow_a_block_and_rewrite_the_program(tmp_path):
    p = parse_program(PROGRAM)
    ip1 = interpolate(p, LIMITS, TS)
    ip2 = interpolate(p, LIMITS, TS, overrides={0: 0.5})
    d1, d2 = (ip.spans[0][1] - ip.spans[0][0] for ip in (ip1, ip2))
    assert d2 > 1.8 * d1
    text = write_program(p, {0: 15.0, 5: p.blocks[5].feed / 2, 6: p.blocks[6].feed / 2})
    q = parse_program(text)
    assert q.blocks[0].feed == pytest.approx(15.0)
    assert q.blocks[5].feed == pytest.approx(p.blocks[5].feed / 2)
    assert q.blocks[6].block_time == pytest.approx(6.0)                # inverse time halves
    assert [b.end.tolist() for b in q.blocks] == [b.end.tolist() for b in p.blocks]


def test_rewritten_feeds_land_outside_comments_and_stay_readable():
    """Found by a review: a ';' inside a '( )' comment took the new F into the comment (the old
    feed stayed in force); a zero-length G93 block was written as 'Fnan'; a large G93 F value in
    exponent form (5.4e+06), which neither this parser nor a controller reads."""
    p = parse_program("G1 X10 (a;b) F600\nG93 G1 X10 F10\nG1 X10.001 F5400000 ; fast\n")
    assert p.blocks[1].length == 0.0
    text = write_program(p, {0: 5.0, 1: p.blocks[1].feed, 2: 2 * p.blocks[2].feed})
    lines = text.splitlines()
    assert lines[0] == "G1 X10 (a;b) F300"
    assert lines[1] == "G93 G1 X10 F10"                  # nothing to scale: as written
    assert lines[2] == "G1 X10.001 F10800000 ; fast"       # G93 is modal: inverse time, positional
    q = parse_program(text)
    assert q.blocks[0].feed == pytest.approx(5.0) and q.blocks[2].block_time == pytest.approx(60 / 10.8e6)


def test_example_programs_read():
    from pathlib import Path
    ex = Path(__file__).resolve().parents[1] / "examples"
    for f in sorted(ex.glob("*.nc")):
        prog = read_program(f)
        ip = interpolate(prog, LIMITS, TS)
        assert ip.cycle_time > 0 and prog.blocks, f


def test_controller_setpoints_and_estimated_limits():
    from fdid_fmi.plan.interpolate import commands_from_trace, limits_from_trace
    from fdid_fmi.trace import Trace
    from fdid_fmi.virtual import trajectories as tj
    p = parse_program("G21 G17 G90 G94\nG1 X10 F3000\nG3 X20 Y0 R5\nG1 X10 Y5 F1200\n")
    ip = interpolate(p, LIMITS, TS)
    tr = Trace.from_arrays(ip.t, {a: {"cmd": ip.positions[a]} for a in ("x", "y")}, source="setpoints")
    ic = commands_from_trace(p, tr, ["x", "y"])
    moving = ip.block_of_sample >= 0
    inside = np.zeros(ip.n, bool)
    for k0, k1 in ip.spans:                 # away from the block ends (a corner sample is ambiguous)
        inside[k0 + 2:k1 - 1] = True
    assert np.array_equal(ic.block_of_sample[moving & inside], ip.block_of_sample[moving & inside])
    assert ic.positions["x"] == pytest.approx(ip.positions["x"])
    traj = tj.linear_moves(n_moves=4, axes=("x",), v=100.0, acc=2000.0, jerk=1e5, Ts=TS, seed=3,
                           speed_range=(1.0, 1.0))
    lim = limits_from_trace(traj.as_trace())["x"]
    # the zero-phase Butterworth rings a few % above the true peaks; every limit is reached (feed
    # factor 1, jerk phases of a/j = 20 ms against the 50 Hz cut-off), so each is found to 10 %
    # (measured 100.2 mm/s, 2061 mm/s^2, 1.043e5 mm/s^3; a quarter of the jerk passed before)
    assert 95.0 <= lim.v <= 102.0 and 1800.0 <= lim.a <= 2100.0 and 9e4 <= lim.j <= 1.05e5


def test_helix_stays_on_its_helix():
    p = parse_program("G21 G17 G90 G94 F1200\nG1 X10\nG3 X10 Y0 Z-3 I-5 J0\n")
    ip = interpolate(p, LIMITS, TS)
    b = p.blocks[1]
    k0, k1 = ip.spans[1]
    P = np.column_stack([ip.positions[a] for a in "xyz"])[k0:k1 + 1]
    r = np.hypot(P[:, 0] - b.center[0], P[:, 1] - b.center[1])
    assert np.abs(r - 5.0).max() < 1e-4
    ang = np.unwrap(np.arctan2(P[:, 1] - b.center[1], P[:, 0] - b.center[0]))
    frac = (ang - ang[0]) / (2 * np.pi)                       # full turn, counter-clockwise
    assert np.abs(P[:, 2] - (-3.0 * frac)).max() < 1e-4       # z linear in the swept angle
    assert b.length == pytest.approx(np.hypot(2 * np.pi * 5, 3))


def test_lookahead_passes_tangent_junctions_within_limits():
    p = parse_program("G21 G17 G90 G94 F3000\nG1 X20\nG3 X30 Y10 R10\nG1 Y30\nG2 X40 Y40 R10\n"
                      "G1 X60\nG1 X70\nG1 Y50\n")
    stop = interpolate(p, LIMITS, TS)
    ip = interpolate(p, LIMITS, TS, corner_angle_deg=1.0)
    vj = ip.info["junction_velocity_mm_s"]
    assert all(v > 5.0 for v in vj[:5])          # tangent (and collinear) junctions: no stop
    assert vj[4] == pytest.approx(50.0)          # collinear lines: the feed, 3000 mm/min
    assert vj[5] == 0.0 and vj[6] == 0.0         # 90 deg corner and program end: exact stop
    assert ip.cycle_time < stop.cycle_time
    P = np.column_stack([ip.positions[a] for a in "xyz"])
    for b, (k0, k1) in zip(p.blocks, ip.spans):
        assert _distance_to_block(b, P[k0 + 1:k1 + 1]).max() < 1e-4
    for i, a in enumerate("xyz"):
        lim = LIMITS[a]
        for n, bound in ((1, lim.v), (2, lim.a), (3, lim.j)):
            rounding = 2 ** n * np.finfo(float).eps * np.abs(P).max() / TS ** n   # of an n-th difference
            assert (np.abs(np.diff(P[:, i], n=n)) / TS ** n).max() <= bound + rounding, (a, n)
    # the path speed near the first tangent junction is the junction velocity, not zero
    k1 = ip.spans[0][1]
    v = np.linalg.norm(np.diff(P[k1 - 1:k1 + 2], axis=0), axis=1) / TS
    assert v.min() == pytest.approx(vj[0], rel=0.05)
