"""``fdid plan``'s prediction and interpolation: bounded memory of the contour error
(in chunks of samples, the same numbers), per-block figures without a blocks x samples mask,
setpoints from another program or at another sample time refused, a block too long to sample
refused before any array is made."""
import tracemalloc

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program
from fdid_fmi.plan.predict import Prediction, block_table, signed_contour_error

LIMITS = {a: AxisLimits(100, 2000, 1e5) for a in "xyz"}
Ts = 1e-3

# lines, an arc, a retrace and dwells longer than the search window below (samples at rest far
# from any motion go to the brute-force search, in groups spread over the program)
PROGRAM = """G21 G90 G17
G1 X5 F600
G4 P0.3
G1 Y5
G3 X0 Y10 I-5 J0
G4 P0.2
G1 X5 Y5
G1 X0 Y0
G1 X5 Y5
G4 P0.4
G1 X-3
"""


def _lagged(ip, lag=15, offset=(0.004, -0.003)):
    """A tool that follows the command ``lag`` samples late and off by ``offset`` mm."""
    cmd = np.column_stack([ip.positions["x"], ip.positions["y"]])
    act = np.vstack([np.repeat(cmd[:1], lag, axis=0), cmd[:-lag]]) + np.asarray(offset)
    return cmd, act


@pytest.fixture(scope="module")
def planned():
    prog = parse_program(PROGRAM, source="program.nc", start=[0, 0, 0])
    return prog, interpolate(prog, LIMITS, Ts)


def test_contour_error_in_chunks_equals_the_whole_program_at_once(planned):
    _, ip = planned
    cmd, act = _lagged(ip)
    whole = signed_contour_error(cmd, act, window=60, feet=True, chunk=cmd.shape[0])
    for chunk in (1, 37, 1000):
        part = signed_contour_error(cmd, act, window=60, feet=True, chunk=chunk)
        for w, p in zip(whole, part):
            assert np.array_equal(w, p), chunk       # bit for bit: samples are independent
    # the dwells did reach the brute-force search: a sample at rest mid-dwell, 4 um off
    k = ip.spans[1][0] + 150
    assert abs(whole[0][k]) == pytest.approx(np.hypot(0.004, 0.003), rel=1e-9)


def test_contour_error_memory_does_not_grow_with_the_program():
    """Before: ~2.5 kB per sample (N x 13 x 2 candidate arrays at once, 2.7 GB for 1e6 samples);
    in chunks the working memory is a constant (~10 MB at the default chunk) plus N x d."""
    n = 100_000
    s = np.linspace(0.0, 60.0, n)
    cmd = np.column_stack([20 * np.cos(s / 3), 20 * np.sin(s / 3)])
    act = np.vstack([np.repeat(cmd[:1], 40, axis=0), cmd[:-40]])
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        signed_contour_error(cmd, act, window=400)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert peak < 400 * n, f"{peak / n:.0f} bytes per sample"


def test_contour_error_chunk_must_be_a_positive_whole_number():
    cmd = np.column_stack([np.arange(5.0), np.zeros(5)])
    for bad in (0, -3, 2.5, True):
        with pytest.raises(InputError, match="chunk"):
            signed_contour_error(cmd, cmd, chunk=bad)


def test_block_table_matches_a_mask_per_block(planned):
    """The per-block figures from one stable sort equal those of a mask per block (the mask was
    blocks x samples work: 18 s for 20000 blocks over 1e6 samples)."""
    prog, ip = planned
    cmd, act = _lagged(ip)
    c = signed_contour_error(cmd, act, window=60)
    err = {"x": cmd[:, 0] - act[:, 0], "y": cmd[:, 1] - act[:, 1]}
    pr = Prediction(interp=ip, axes=["x", "y"], position={"x": act[:, 0], "y": act[:, 1]},
                    error=err, contour=c)
    rows = block_table(pr, prog, tol_mm=0.004)
    assert len(rows) == len(prog.blocks)
    for b, row in zip(prog.blocks, rows):
        sel = ip.block_of_sample == b.index
        assert row["contour_max_um"] == float(np.max(np.abs(c[sel]))) * 1e3
        assert row["contour_rms_um"] == pytest.approx(np.sqrt(np.mean(c[sel] ** 2)) * 1e3, rel=1e-12)
        assert row["x_max_err_um"] == float(np.max(np.abs(err["x"][sel]))) * 1e3
        # a dwell's settling error counts against the cutting block before it
        after = [r["contour_max_um"] for bb, r in zip(prog.blocks, rows) if bb.kind == "dwell"
                 and bb.index == b.index + 1]
        assert row["contour_max_with_dwell_um"] == max([row["contour_max_um"]] + after)
        assert row["flag"] == (b.kind in ("line", "arc") and row["contour_max_with_dwell_um"] > 4.0)


# --- a block too long to sample: refused before any array is made ---------------------------

def _refused(text, Ts=6e-4, **kw):
    prog = parse_program(text, source="long.nc", start=[0, 0, 0])
    tracemalloc.start()
    try:
        with pytest.raises(InputError) as ei:
            interpolate(prog, LIMITS, Ts, **kw)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5e6                     # refused up front (it tried 745 GiB of sample times)
    return str(ei.value)


def test_tiny_feed_refused_naming_line_feed_duration_and_samples():
    msg = _refused("G21 G90 G17\nG1 X100 F0.0001\nM30\n")
    assert msg.startswith("long.nc, column 'F', row 2: F0.0001 [mm/min] over 100 mm")
    assert "at least 6e+07 s (1e+11 samples at Ts = 0.6 ms); at most 5e+06 samples" in msg
    # the look-ahead corner rule takes at least as long: refused the same way
    assert _refused("G21 G90 G17\nG1 X100 F0.0001\nM30\n", corner_angle_deg=5.0) == msg


def test_long_dwell_rapid_inch_arc_and_g93_refused():
    assert "column 'P', row 3: G4 P4000 makes the block last 4e+03 s (6.67e+06 samples" in \
        _refused("G21 G90\nG1 X1 F100\nG4 P4000\n")
    assert "row 2: F0.0001 [inch/min] over 39.8982 mm" in _refused("G20 G90\nG2 X1 Y0 I0.5 J0 F0.0001\n")
    assert "row 2: G93 F1e-06 (block time 6e+07 s) over 10 mm" in _refused("G21 G93\nG1 X10 F0.000001\n")
    prog = parse_program("G21\nG0 X100\n", source="r.nc", start=[0, 0, 0])
    with pytest.raises(InputError, match=r"column '--limits', row 2: the rapid \(1e-05 mm/s along the path\)"):
        interpolate(prog, {"x": AxisLimits(1e-5, 2000, 1e5)}, 6e-4)
    # a feed override that slows a block past the limit names it
    prog = parse_program("G21\nG1 X100 F10\n", source="o.nc", start=[0, 0, 0])
    with pytest.raises(InputError, match="F10 \\[mm/min\\] over 100 mm at feed override 0.01"):
        interpolate(prog, LIMITS, 6e-4, overrides={0: 0.01})


def test_block_just_within_the_limit_is_not_refused():
    from fdid_fmi.plan.interpolate import MAX_BLOCK_SAMPLES, check_block_lengths
    Ts_ = 6e-4
    feed = 100.0 / (0.99 * MAX_BLOCK_SAMPLES * Ts_) * 60       # mm/min: 0.99 x the limit
    prog = parse_program(f"G21\nG1 X100 F{feed:.6f}\nG4 P{0.99 * MAX_BLOCK_SAMPLES * Ts_:.3f}\n",
                         source="ok.nc", start=[0, 0, 0])
    check_block_lengths(prog, LIMITS, Ts_)                     # no error


def test_arc_peaks_and_samples_in_chunks_equal_the_whole_block(monkeypatch):
    """The arc's fine-grid peaks and the block's samples, CHUNK at a time, are those of the
    whole block at once (the same numbers: the interpolation is unchanged)."""
    from fdid_fmi.plan import interpolate as I
    from fdid_fmi.virtual.trajectories import scurve
    prog = parse_program("G21 G90 G17\nG1 X10 F3000\nG3 X0 Y10 I-10 J0\nG2 X-5 Y5 R5 Z1\n",
                         source="arc.nc", start=[0, 0, 0])
    arc = prog.blocks[1]
    prof = scurve(arc.length, 40.0, 2000.0, 1e5)
    dt = Ts / 4
    whole = I._axis_peaks(arc.point(prof.evaluate(np.arange(0.0, prof.duration + dt, dt))[0]), dt)
    ref = interpolate(prog, LIMITS, Ts)
    for chunk in (1, 5, 1000):
        monkeypatch.setattr(I, "CHUNK", chunk)
        for w, p in zip(whole, I._arc_axis_peaks(arc, prof, dt)):
            assert np.array_equal(w, p), chunk
        ip = interpolate(prog, LIMITS, Ts)
        assert ip.spans == ref.spans
        for a in "xyz":
            assert np.array_equal(ip.positions[a], ref.positions[a]), chunk


# --- --commands: setpoints of another program, or at another sample time -----------------------

def _setpoints(text, Ts_=1e-3, dy=0.0, source="s.csv"):
    from fdid_fmi.trace import Trace
    ip = interpolate(parse_program(text, source="a.nc", start=[0, 0, 0]), LIMITS, Ts_)
    return Trace.from_arrays(ip.t + 2.0, {"x": {"cmd": ip.positions["x"]}, "y": {"cmd": ip.positions["y"] + dy}},
                             source=source)


SQUARE = "G21 G90 G17\nG1 X10 F3000\nG1 Y10\nG1 X0\nG1 Y0\n"


def test_setpoints_of_another_program_are_refused():
    """Before: each sample went to the nearest block however far (pocket_corner.nc with
    virtual_circle.csv: exit 0 and figures of the wrong program)."""
    from fdid_fmi.plan.interpolate import commands_from_trace
    circle = _setpoints("G21 G90 G17\nG0 X5 Y-8\nG2 X5 Y-8 I0 J8 F3000\n")
    with pytest.raises(InputError) as ei:
        commands_from_trace(parse_program(SQUARE, source="square.nc", start=[0, 0, 0]), circle, ["x", "y"])
    msg = str(ei.value)
    assert msg.startswith("s.csv, column 'x_cmd/y_cmd': the setpoint at t = 2.0")   # the file's own time
    assert "mm from the path of square.nc (nearest: line " in msg and "within 0.1 mm" in msg
    dist = float(msg.split(" mm) is ")[1].split(" mm")[0])
    assert dist > 0.1                   # the first setpoint that leaves the square's path


def test_setpoints_off_the_path_by_more_than_the_tolerance_are_refused():
    """A controller's blending tolerance (0.1 mm, TRACE_PATH_TOL) is accepted; more is not."""
    from fdid_fmi.plan.interpolate import TRACE_PATH_TOL, commands_from_trace
    prog = parse_program("G21 G90 G17\nG1 X10 F3000\nG1 X20 Y5\n", source="line.nc", start=[0, 0, 0])
    ic = commands_from_trace(prog, _setpoints("G21 G90 G17\nG1 X10 F3000\nG1 X20 Y5\n",
                                              dy=0.09), ["x", "y"])
    assert ic.block_of_sample.max() == 1
    with pytest.raises(InputError, match=r"t = 2 s \(x 0, y 0.13 mm\) is 0.13 mm from the path of line.nc "
                                         r"\(nearest: line 2\); setpoints must lie within 0.1 mm"):
        commands_from_trace(prog, _setpoints("G21 G90 G17\nG1 X10 F3000\nG1 X20 Y5\n", dy=0.13), ["x", "y"])
    assert TRACE_PATH_TOL == 0.1


def test_setpoints_at_another_sample_time_than_the_model_are_refused():
    """Before: a 0.6 ms trace with a 1 ms model was accepted (simulate, validate and diagnose
    refuse it)."""
    from fdid_fmi.plan.interpolate import commands_from_trace
    prog = parse_program(SQUARE, source="square.nc", start=[0, 0, 0])
    tr = _setpoints(SQUARE, Ts_=6e-4)
    with pytest.raises(InputError, match=r"^s.csv, column 'Ts': the setpoints are sampled at 0.0006 s but "
                                         r"the model at 0.001 s; resample the trace$"):
        commands_from_trace(prog, tr, ["x", "y"], Ts=1e-3)
    assert commands_from_trace(prog, tr, ["x", "y"], Ts=6e-4).Ts == tr.Ts
