"""fdid_fmi.plan against hand-derived truths: the geometry the parser reads, the v/a/j
limits, end points and cycle time of the interpolation, and the contour error of a circle traced
by drives whose response is known in closed form."""
import math

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel, Port
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program
from fdid_fmi.plan.predict import predict

EPS = np.finfo(float).eps


def _within_limits(P, limits, Ts):
    """Largest |n-th finite difference| / Ts^n over its limit, per axis and n = 1, 2, 3, after
    subtracting the rounding of an n-th difference of these positions (2^n eps max|P| / Ts^n:
    each of the 2^n-weighted terms carries one rounding of size eps max|P|)."""
    worst = 0.0
    for i, a in enumerate("xyz"):
        lim = limits[a]
        for n, bound in ((1, lim.v), (2, lim.a), (3, lim.j)):
            d = np.abs(np.diff(P[:, i], n=n)).max() / Ts ** n
            rounding = 2 ** n * EPS * np.abs(P).max() / Ts ** n
            worst = max(worst, (d - rounding) / bound)
    return worst


def _P(ip):
    return np.column_stack([ip.positions[a] for a in "xyz"])


def _tangent_line_arc(phi_deg, R=10.0, L=20.0, F=6000):
    """A line at phi, a tangent counter-clockwise quarter arc and a tangent line (G-code)."""
    phi = math.radians(phi_deg)
    u = np.array([math.cos(phi), math.sin(phi)])
    nrm = np.array([-u[1], u[0]])
    p1 = L * u
    c = p1 + R * nrm
    a1 = math.atan2(-nrm[1], -nrm[0]) + math.pi / 2
    p2 = c + R * np.array([math.cos(a1), math.sin(a1)])
    p3 = p2 + L * np.array([-math.sin(a1), math.cos(a1)])
    return (f"G1 X{p1[0]:.6f} Y{p1[1]:.6f} F{F}\nG3 X{p2[0]:.6f} Y{p2[1]:.6f} I{R * nrm[0]:.6f} "
            f"J{R * nrm[1]:.6f}\nG1 X{p3[0]:.6f} Y{p3[1]:.6f}\n")


LIM = {a: AxisLimits(100.0, 2000.0, 5e4) for a in "xyz"}


@pytest.mark.parametrize("text, corner, Ts", [
    ("G1 X10 F6000\nX20 Y0.524\nX30 Y1.5\n", 10.0, 1e-3),                   # 3 deg kinks
    ("G1 F6000 X10\n" + "\n".join(f"X{10 * math.cos(2 * math.pi * k / 90):.4f} "
                                  f"Y{10 * math.sin(2 * math.pi * k / 90):.4f}" for k in range(1, 46)),
     10.0, 1e-3),                                                              # a polygon "circle"
    (_tangent_line_arc(45.0), 1.0, 5e-4),                                      # diagonal tangents
])
def test_lookahead_keeps_every_axis_limit(text, corner, Ts):
    """With --corner-angle the sampled commands stay within v/a/j of every axis as without it.
    (Before: the kink and curvature-jump terms were capped at half the limits but added to a
    tangential jerk of up to the whole limit: the 3 deg kinks had 1.04 j, the polygon 1.3 j,
    the 45 deg line-arc tangent 1.05 j.)"""
    p = parse_program(text)
    ip = interpolate(p, LIM, Ts, corner_angle_deg=corner)
    assert _within_limits(_P(ip), LIM, Ts) <= 1.0
    assert np.abs(_P(ip)[-1] - p.blocks[-1].end).max() < 1e-12


def test_lookahead_still_carries_velocity_through_diagonal_tangents():
    p = parse_program(_tangent_line_arc(45.0))
    Ts = 5e-4
    ip = interpolate(p, LIM, Ts, corner_angle_deg=1.0)
    vj = ip.info["junction_velocity_mm_s"]
    assert vj[0] > 1.0 and vj[1] > 1.0                 # no exact stop at the tangent junctions
    P = _P(ip)
    for k in (0, 1):                                   # the sampled path speed there is not zero
        k1 = ip.spans[k][1]
        v = np.linalg.norm(np.diff(P[k1 - 1:k1 + 2], axis=0), axis=1) / Ts
        assert v.min() > 0.5 * vj[k]


# ----------------------------------------------------------------- contour error, closed form
TS_C = 1e-3
LIM_C = {a: AxisLimits(200.0, 5000.0, 2e5) for a in "xyz"}


def _two_axis_model(A1, B1, C1, axes, method, Ts=TS_C):
    """The same single-axis discrete state space (A1, B1, C1) on each of two axes."""
    n = A1.shape[0]
    A = np.zeros((2 * n, 2 * n))
    B = np.zeros((2 * n, 2))
    C = np.zeros((2, 2 * n))
    for m in range(2):
        A[m * n:(m + 1) * n, m * n:(m + 1) * n] = A1
        B[m * n:(m + 1) * n, m] = B1
        C[m, m * n:(m + 1) * n] = C1
    return DriveModel(Ts, A, B, C, np.zeros((2, 2)), [Port(f"{a}_cmd", "mm", "command", a) for a in axes],
                      [Port(f"{a}_pos", "mm", "position", a) for a in axes], method=method)


def _lag(p, axes=("x", "y"), Ts=TS_C):
    """x[k+1] = p x[k] + (1 - p) r[k]: a proportional position loop sampled at Ts."""
    return _two_axis_model(np.array([[p]]), np.array([1.0 - p]), np.array([1.0]), axes, "lag", Ts)


def _delay(d, axes=("x", "y")):
    """x[k] = r[k - d]: a shift register of d states."""
    A1 = np.diag(np.ones(d - 1), -1)
    B1 = np.zeros(d)
    B1[0] = 1.0
    C1 = np.zeros(d)
    C1[-1] = 1.0
    return _two_axis_model(A1, B1, C1, axes, "delay")


def _circle(plane, g, R=10.0, F=3000):
    """A full circle of radius R about the origin of the plane, started at +R on its first axis."""
    first, second, centre = {"G17": ("X", "Y", "I"), "G18": ("Z", "X", "K"), "G19": ("Y", "Z", "J")}[plane]
    return parse_program(f"{plane} G0 {first}{R}\n{g} {first}{R} {second}0 {centre}{-R} F{F}")


def _cruise(ip, plane, R, Ts=TS_C):
    """Samples of the circle block at constant angular step, and that step's rate w (rad/s)."""
    i, j = {"G17": ("x", "y"), "G18": ("z", "x"), "G19": ("y", "z")}[plane]
    ang = np.unwrap(np.arctan2(ip.positions[j], ip.positions[i]))
    w = np.diff(ang) / Ts
    wm = np.abs(w).max()
    k = np.flatnonzero(np.abs(np.abs(w) - wm) < 1e-9 * wm)
    assert k.size > 1000 and np.all(np.diff(k) == 1)          # one stretch at constant speed
    return k, wm


@pytest.mark.parametrize("plane, axes", [("G17", ("x", "y")), ("G17", ("y", "x")), ("G18", ("x", "z")),
                                         ("G18", ("z", "x")), ("G19", ("z", "y"))])
@pytest.mark.parametrize("g", ["G3", "G2"])
def test_contour_error_of_a_lagging_drive_on_a_circle(plane, axes, g):
    """Each axis x[k+1] = p x[k] + (1 - p) r[k]. On a circle r[k] = R e^{i w k Ts} the steady
    response is x[k] = H r[k], H = (1 - p) / (e^{i w Ts} - p): a circle of radius R |H| about the
    same centre. Its shortest distance to the commanded polyline (chords of the circle) is
    R (1 - |H|) less between 0 and the chord sag R (1 - cos(w Ts / 2)); inside the circle, so
    positive on a G3 (counter-clockwise) arc and negative on a G2 one, whatever the order in
    which the model lists its axes."""
    R, Kv = 10.0, 30.0
    p = math.exp(-Kv * TS_C)
    ip = interpolate(_circle(plane, g, R), LIM_C, TS_C)
    k, w = _cruise(ip, plane, R)
    assert w * R == pytest.approx(50.0, rel=0.01)             # F 3000 mm/min (time-scaled <= 1 %)
    steady = k[k > k[0] + int(20 / Kv / TS_C)]                # transient e^-20 of the entry error
    pr = predict(ip, model=_lag(p, axes))
    H = abs((1 - p) / (np.exp(1j * w * TS_C) - p))
    sag = R * (1 - math.cos(w * TS_C / 2))
    expected = R * (1 - H)                                    # 0.1339 mm
    c = pr.contour[steady] * (1 if g == "G3" else -1)
    assert c.max() <= expected + 1e-9
    assert c.min() >= expected - sag - 1e-9


@pytest.mark.parametrize("d", [5, 20])
def test_contour_error_of_a_pure_delay_is_zero(d):
    """x[k] = r[k - d] puts the tool on a commanded sample: no contour error, while the tracking
    error is the chord over d samples, 2 R sin(w d Ts / 2). (The normal component of that chord
    at the commanded point, R (1 - cos(w d Ts)), is not the contour error: the tool is on the
    path.)"""
    R = 10.0
    ip = interpolate(_circle("G17", "G3", R), LIM_C, TS_C)
    k, w = _cruise(ip, "G17", R)
    steady = k[k > k[0] + d]
    pr = predict(ip, model=_delay(d))
    assert np.abs(pr.contour[steady]).max() < 1e-12
    track = np.hypot(pr.error["x"][steady], pr.error["y"][steady])
    np.testing.assert_allclose(track, 2 * R * math.sin(w * d * TS_C / 2), rtol=1e-9)


def test_contour_error_when_the_lag_is_many_samples():
    """Kv = 16.7 1/s (1 m/min per mm) sampled at 8 kHz: the tool lags 1 / (Kv Ts) = 479 samples
    behind its command; the contour error is still R (1 - |H|) (it was measured to a later path
    point, 0.577 mm instead of 0.414 mm, when the search window was a fixed 400 samples)."""
    R, Kv, Ts = 10.0, 16.7, 1.25e-4
    p = math.exp(-Kv * Ts)
    ip = interpolate(_circle("G17", "G3", R), LIM_C, Ts)
    k, w = _cruise(ip, "G17", R, Ts)
    steady = k[k > k[0] + int(20 / Kv / Ts)]
    pr = predict(ip, model=_lag(p, Ts=Ts))
    expected = R * (1 - abs((1 - p) / (np.exp(1j * w * Ts) - p)))         # 0.4141 mm
    sag = R * (1 - math.cos(w * Ts / 2))
    c = pr.contour[steady]
    assert c.max() <= expected + 1e-9 and c.min() >= expected - sag - 1e-9


# ----------------------------------------------------------------- the program writer
def test_write_program_is_atomic_and_never_overwrites_its_source(tmp_path):
    from fdid_fmi.plan.ncprogram import read_program, write_program
    src = tmp_path / "part.nc"
    src.write_text("G1 X10 F600\nG1 Y10\n")
    p = read_program(src)
    with pytest.raises(InputError, match="overwrite the input"):
        write_program(p, {0: 5.0}, path=src)
    assert src.read_text() == "G1 X10 F600\nG1 Y10\n"
    with pytest.raises(InputError, match="directory"):              # was IsADirectoryError
        write_program(p, {0: 5.0}, path=tmp_path)
    out = tmp_path / "opt.nc"
    out.write_text("old\n")
    link = tmp_path / "old_link.nc"
    link.hardlink_to(out)                     # the old file: replaced, not rewritten in place
    text = write_program(p, {0: 5.0}, path=out)
    assert out.read_text() == text and "F300" in text
    assert link.read_text() == "old\n"
    assert [f.name for f in tmp_path.iterdir() if f.name.endswith(".part")] == []


# ----------------------------------------------------------------- parser: hand-derived geometry
def _one(text):
    blocks = parse_program(text).blocks
    return blocks[-1]


def test_arcs_by_centre_and_by_radius():
    # R > 0: the shorter arc; chord 10 along +X, R 10: centre at (5, -/+ sqrt(100 - 25))
    h = math.sqrt(75.0)
    b = _one("G2 X10 Y0 R10 F600")
    assert b.center[:2] == pytest.approx([5.0, -h]) and b.sweep == pytest.approx(math.pi / 3)
    b = _one("G3 X10 Y0 R10 F600")
    assert b.center[:2] == pytest.approx([5.0, h]) and b.sweep == pytest.approx(math.pi / 3)
    # R < 0: the longer arc (300 deg) about the other centre
    b = _one("G2 X10 Y0 R-10 F600")
    assert b.center[:2] == pytest.approx([5.0, h]) and b.sweep == pytest.approx(5 * math.pi / 3)
    assert b.length == pytest.approx(10 * 5 * math.pi / 3)
    # a full circle: I J with the end on the start
    b = _one("G3 X0 Y0 I5 J0 F600")
    assert b.sweep == pytest.approx(2 * math.pi) and b.length == pytest.approx(10 * math.pi)
    # helix: one turn of radius 5 rising 3 mm
    b = _one("G3 X0 Y0 Z3 I5 F600")
    assert b.length == pytest.approx(math.hypot(10 * math.pi, 3.0))
    # end off its circle by more than 0.002 mm + 0.1 % of r: refused; within: accepted
    with pytest.raises(InputError, match="row 1.*not on the arc"):
        parse_program("G2 X10.02 Y0 I5 F600")                    # r 5 -> 5.02: 0.02 > 0.007
    assert _one("G2 X10.005 Y0 I5 F600").r1 == pytest.approx(5.005)
    with pytest.raises(InputError, match="half the chord"):
        parse_program("G2 X10 Y0 R4.9 F600")


@pytest.mark.parametrize("plane, text, normal", [
    ("G17", "G17 G3 X0 Y0 I5 F600", 2), ("G18", "G18 G3 Z0 X0 K5 F600", 1),
    ("G19", "G19 G3 Y0 Z0 J5 F600", 0)])
def test_g3_turns_counter_clockwise_about_the_plane_normal(plane, text, normal):
    """(p - c) x dp/ds has a positive component along the plane's positive normal (Z, Y, X)."""
    b = _one(text)
    s = np.linspace(0, b.length, 200)
    p = b.point(s)
    r = p[:-1] - b.center
    cross = np.cross(r, np.diff(p, axis=0))
    assert np.all(cross[:, normal] > 0)
    assert np.allclose(np.linalg.norm(r, axis=1), 5.0)


def test_modes_units_words_and_comments():
    p = parse_program("%\nO12 (part)\nN10 G21 G90 G94 F600 ; mm/min\n/N20 G1 X10 (to x10) Y5\n"
                      "N30 G91 X1 Y1\nN40 G20 G90 X1 F10\nN50 G93 G1 Y0 F2\nN60 G94 G0 Z1\n%\n")
    b = p.blocks
    assert [x.number for x in b] == [20, 30, 40, 50, 60]
    assert b[0].end.tolist() == [10, 5, 0] and b[0].feed == pytest.approx(10.0)      # 600 mm/min
    assert b[1].end.tolist() == [11, 6, 0]                                            # incremental
    assert b[2].end.tolist() == pytest.approx([25.4, 6, 0])                           # 1 inch
    assert b[2].feed == pytest.approx(10 * 25.4 / 60)                                 # 10 in/min
    assert b[3].inverse_time and b[3].block_time == pytest.approx(30.0)               # 1 / (2/min)
    assert b[4].kind == "rapid" and b[4].end[2] == pytest.approx(25.4) and math.isinf(b[4].feed)
    for bad, what in (("G95 G1 X1 F1", "G95"), ("G1 X1 F0", "F must be > 0"), ("G1 X1 F-5", "F must be > 0"),
                      ("G1 X1", "no feed rate"), ("G93 G1 X1", "without F")):
        with pytest.raises(InputError, match=what):
            parse_program(bad)


# ----------------------------------------------------------------- interpolation
LIM_I = {"x": AxisLimits(150.0, 3000.0, 8e4), "y": AxisLimits(80.0, 1000.0, 2e4), "z": AxisLimits(50.0, 800.0, 1e4)}
PROG_I = ("G1 X30 Y10 F4000\nG1 X30 Y10\nG2 X50 Y10 R10\nG3 X30 Y10 R-12\nG3 X30 Y10 Z-4 I5 J0\n"
          "G0 X0 Y0 Z0\nG93 G1 X20 F30\nG94 G18 G2 X30 Z0 R6 F3000\nG19 G3 Y20 Z0 J10\n")


@pytest.mark.parametrize("Ts", [2.5e-4, 1e-3, 4e-3])
def test_interpolation_limits_end_points_and_cycle_time(Ts):
    p = parse_program(PROG_I)
    ip = interpolate(p, LIM_I, Ts)
    P = _P(ip)
    assert _within_limits(P, LIM_I, Ts) <= 1.0
    bound = 0.0
    for b, (k0, k1) in zip(p.blocks, ip.spans):
        assert np.array_equal(P[k1], b.end)                         # the end point on a sample
        if b.kind == "rapid":
            bound += max(abs(b.end[i] - b.start[i]) / LIM_I[a].v for i, a in enumerate("xyz"))
        else:
            bound += b.length / b.feed
        if b.inverse_time:                                          # G93 F30: 2 s, not faster
            assert (k1 - k0) * Ts >= 2.0 - 1e-12
        if b.length == 0:                                           # the zero-length move
            assert k1 == k0
    assert ip.cycle_time >= bound
    assert np.array_equal(P[-1], p.blocks[-1].end)


def test_a_long_line_reaches_its_feed_and_no_more():
    p = parse_program("G1 X100 Y50 F4000")
    Ts = 1e-3
    ip = interpolate(p, LIM_I, Ts)
    v = np.linalg.norm(np.diff(_P(ip), axis=0), axis=1) / Ts
    # F 66.7 mm/s along (2, 1)/sqrt(5): the y axis allows 80 / (1/sqrt 5) = 179 mm/s: F limits
    assert v.max() <= 4000 / 60 * (1 + 1e-12)
    assert v.max() == pytest.approx(4000 / 60, rel=2e-3)
    assert ip.cycle_time >= math.hypot(100, 50) / (4000 / 60)


def test_bad_overrides_and_times_are_refused_with_either_corner_rule():
    """The look-ahead took a NaN override (the block then jumped in one sample) and a 0 or
    negative one (an array of 1e9..1e12 samples: MemoryError or the OOM killer); a negative
    settle time or a NaN lead-in escaped as numpy errors."""
    p = parse_program("G1 X10 F600\nG1 X20")
    for corner in (None, 5.0):
        with pytest.raises(InputError, match="override of line 1 must be > 0"):
            interpolate(p, LIM, 1e-3, overrides={0: float("nan")}, corner_angle_deg=corner)
    with pytest.raises(InputError, match="settle"):
        interpolate(p, LIM, 1e-3, settle=-1.0)
    with pytest.raises(InputError, match="lead_in"):
        interpolate(p, LIM, 1e-3, lead_in=float("nan"), corner_angle_deg=5.0)


def test_blocks_left_out_of_the_rewrite_keep_their_feed():
    """F is modal: rewriting block 1's F to 300 made the next blocks, which relied on F600 of
    line 1, run at 300 too ("blocks left out keep theirs", write_program's docstring)."""
    from fdid_fmi.plan.ncprogram import write_program
    p = parse_program("G1 X10 F600\nG1 X20\nG2 X30 Y10 R10 (arc)\nG20 G1 X2 F10\nX3\n")
    text = write_program(p, {0: 5.0, 3: 10 * 25.4 / 60 / 2})
    q = parse_program(text)
    assert [b.feed * 60 for b in q.blocks] == pytest.approx([300, 600, 600, 127, 254])
    assert text.splitlines()[2] == "G2 X30 Y10 R10 F600 (arc)"


def test_controller_setpoints_at_rest_before_a_closed_contour_belong_to_its_start():
    """A trace starts at rest on the start point of a closed contour (the square ends there too):
    those samples were given to the last block at path length 40 mm (its end)."""
    from fdid_fmi.plan.interpolate import commands_from_trace
    from fdid_fmi.trace import Trace
    p = parse_program("G1 X10 F3000\nY10\nX0\nY0\n")
    ip = interpolate(p, LIM, 1e-3)
    tr = Trace.from_arrays(ip.t, {a: {"cmd": ip.positions[a]} for a in ("x", "y")}, source="setpoints")
    ic = commands_from_trace(p, tr, ["x", "y"])
    rest = slice(0, ip.spans[0][0] + 1)                        # the lead-in, at (0, 0)
    assert np.all(ic.block_of_sample[rest] == 0)
    assert np.all(ic.path_s[rest] == 0.0)
    assert np.all(ic.block_of_sample[-10:] == 3) and ic.path_s[-1] == pytest.approx(40.0)


def test_program_end_and_subprogram_calls():
    """M30 ends the program (a Fanuc subprogram after it was read as motion); M98 / M99 were
    passed over like any M word, silently dropping the subprogram's motion."""
    p = parse_program("G1 X10 F600\nM30\nO1000\nG1 X100 Y100\nM99\n")
    assert len(p.blocks) == 1 and p.blocks[-1].end.tolist() == [10, 0, 0]
    assert (4, "not run: after M30") in p.ignored
    for text in ("G1 X10 F600\nM98 P1000\n", "G1 X10 F600\nM99\n"):
        with pytest.raises(InputError, match="row 2.*subprogram"):
            parse_program(text)


def test_optimiser_settings_are_checked():
    """rel_tol = 0 never ended its bisections (the run hung), min_override = 0 divided by zero."""
    import signal
    from fdid_fmi.plan.optimize import optimize_feeds

    def hung(*_):
        raise TimeoutError("optimize_feeds did not return")

    prog = parse_program("G1 X10 F3000\nG3 X10 Y0 I-10\n")
    model = _lag(math.exp(-30.0 * TS_C))
    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(20)
    try:
        with pytest.raises(InputError, match="rel_tol"):
            optimize_feeds(prog, LIM_C, TS_C, 0.05, model=model, rel_tol=0.0)
        with pytest.raises(InputError, match="min_override"):
            optimize_feeds(prog, LIM_C, TS_C, 0.05, model=model, min_override=0.0)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def test_contour_sign_on_a_path_that_retraces_itself():
    """Out along a diagonal and back on the same line, x with Kv 30 and y with Kv 60 1/s. At
    constant speed v along u the axis errors are e_i = v u_i K_vel,i, K_vel,i = Ts / (1 - p_i);
    the tool is off the line by -n.e (n the left normal), the same value and side on both
    passes (u, n and e all change sign). On the way back the nearest segments of the way out
    (same distance) lay within the search window and gave their side: -407 um for +416 um."""
    px, py = math.exp(-30.0 * TS_C), math.exp(-60.0 * TS_C)
    model = DriveModel(TS_C, np.diag([px, py]), np.diag([1 - px, 1 - py]), np.eye(2), np.zeros((2, 2)),
                       [Port(f"{a}_cmd", "mm", "command", a) for a in "xy"],
                       [Port(f"{a}_pos", "mm", "position", a) for a in "xy"], method="two gains")
    ip = interpolate(parse_program("G1 X20 Y20 F3000\nG1 X0 Y0\n"), LIM_C, TS_C)
    pr = predict(ip, model=model)
    P = np.column_stack([ip.positions["x"], ip.positions["y"]])
    v = np.linalg.norm(np.diff(P, axis=0), axis=1) / TS_C
    u = np.array([1.0, 1.0]) / math.sqrt(2)
    for b in (0, 1):
        k = np.arange(*ip.spans[b])
        vm = v[k].max()
        cruise = k[np.abs(v[k] - vm) < 1e-9 * vm]
        cruise = cruise[cruise > cruise[0] + 150]                 # 150 ms: past the transient
        e = vm * u * np.array([TS_C / (1 - px), TS_C / (1 - py)])
        expected = -np.array([-u[1], u[0]]) @ e                   # 0.4166 mm, left of travel
        c = pr.contour[cruise]
        assert np.all(c > 0.9 * expected)
        assert c[-1] == pytest.approx(expected, rel=5e-3)


def test_a_header_with_a_carriage_return_stays_one_comment():
    """'\\r' in the header broke the comment over two lines: the written program was unreadable."""
    from fdid_fmi.plan.ncprogram import write_program
    p = parse_program("G1 X10 F600\n")
    text = write_program(p, {0: 5.0}, header="tol 0.02\rmm (x)")
    q = parse_program(text)
    assert len(q.blocks) == 1 and q.blocks[0].feed == pytest.approx(5.0)
    assert text.splitlines()[0].startswith("(tol 0.02") and "[x]" in text


def test_controller_setpoints_for_a_program_without_moves():
    """A program of dwells / zero-length moves gave numpy's 'need at least one array to
    concatenate'."""
    from fdid_fmi.plan.interpolate import commands_from_trace
    from fdid_fmi.trace import Trace
    t = np.arange(100) * 1e-3
    tr = Trace.from_arrays(t, {a: {"cmd": np.linspace(0, 1, 100)} for a in ("x", "y")}, source="s.csv")
    for text in ("G4 P1\n", "G1 X0 F600\n"):
        with pytest.raises(InputError, match="no move of non-zero length"):
            commands_from_trace(parse_program(text), tr, ["x", "y"])


def test_start_position_must_be_finite():
    """fdid plan --start nan,0,0 was read: every position of the program became NaN."""
    for bad in ((float("nan"), 0, 0), (0, float("inf"), 0)):
        with pytest.raises(InputError, match="start must be three finite numbers"):
            parse_program("G1 X10 F600\n", start=bad)


def test_numbers_too_large_for_a_float_are_refused():
    """X or F with 400 digits was read as inf: an infinite end point or an infinite feed."""
    big = "9" * 400
    for text in (f"G1 X{big} F600\n", f"G1 X10 F{big}\n"):
        with pytest.raises(InputError, match="row 1.*too large"):
            parse_program(text)
