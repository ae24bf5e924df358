"""Alignment flowing into identification: the flexible Y axis's drive-train mode fitted on the
aligned tool-side acceleration of a raw sensor run (``fdid_fmi.virtual.sensors``) against the same
fit on perfectly aligned data, and its diagnosis residual on the aligned grid-encoder channel.
The runs and their alignment are those of tests/test_align_virtual.py (which checks the
alignment itself)."""
import dataclasses
import functools
import tempfile
from pathlib import Path

import numpy as np
import pytest

from checks import check
from fdid_fmi.identify import Bounds, identify_mimo, mimo_structure
from fdid_fmi.virtual import MachineConfig, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fdid_fmi.virtual.sensors import AccelerometerTruth, GridEncoderTruth, write_raw_run
from test_align_virtual import CFG, TS, _align

_FILES = tempfile.TemporaryDirectory(prefix="fdid-align-")     # the raw runs, removed at exit


@functools.lru_cache(maxsize=None)
def yrun():
    """(simulated trace, path, raw run, aligned with the calibration run's orientation, aligned
    alone) of the identification run moving Y only."""
    d = Path(_FILES.name)
    sim = simulate_machine(CFG, tj.linear_moves(n_moves=16, axes=("x", "y"), Ts=TS, seed=3), seed=2)
    calibration = _align(write_raw_run(sim, d / "calib"))
    one = MachineConfig(axes=[CFG.axis("y")], Ts=TS)
    path = tj.linear_moves(n_moves=20, axes=("y",), Ts=TS, seed=1)
    sim = simulate_machine(one, path, seed=1)
    acc = dataclasses.replace(AccelerometerTruth(), start_s=-2.613, drift_ppm=-75.0,
                              bias=(120.0, 80.0, -150.0))
    kgm = dataclasses.replace(GridEncoderTruth(), start_s=-0.731, drift_ppm=35.0)
    run = write_raw_run(sim, d / "yrun", accelerometers=[acc], grid_encoders=[kgm], seed=5)
    return sim, path, run, _align(run, orientation=calibration), _align(run)


@functools.lru_cache(maxsize=None)
def modes():
    sim, path, run, res, _ = yrun()
    nyq = 0.5 / TS
    bounds = Bounds(real_hz=[(0.02, nyq)], omega_hz=[(0.02, nyq), (20.0, 40.0)],
                    zeta=[(0.01, 4.0), (0.001, 0.5)])
    st = mimo_structure(("y",), ("acceleration",), 1, 2, integrators={"acceleration": 2},
                        dc_gain={"acceleration": (2, 1.0)})
    out = {}
    for name, tr in (("aligned", res.trace), ("perfect", sim)):
        m = identify_mimo(tr, st, bounds=bounds, seed=0, maxiter=40)
        out[name] = [p for p in m.identification["complex_hz_zeta"] if 20 <= p[0] <= 40]
        out[name + "_model"] = m
    return out, sim.meta["truth"]["linear"]["continuous"]["modes"]["y"]


@check("tests/test_align_virtual.py::test_mode_from_aligned_acceleration")
def mode_from_aligned_acceleration():
    found, truth = modes()
    assert len(found["aligned"]) == 1 and len(found["perfect"]) == 1
    (fa, za), (fp, zp) = found["aligned"][0], found["perfect"][0]
    assert fa == pytest.approx(truth["hz"], rel=0.01)       # measured 0.01 %
    assert fa == pytest.approx(fp, rel=0.002)                # as from perfectly aligned data
    assert za == pytest.approx(zp, rel=0.1)


@check("tests/test_align_virtual.py::test_aligned_trace_flows_into_diagnosis")
def aligned_trace_flows_into_diagnosis():
    """The diagnosis residual of the model fitted on the aligned acceleration, scored on the
    aligned grid-encoder (tool) channel: as small as that of the model fitted on perfectly aligned
    data scored on the true tool position, and the same as against the true tool position."""
    from fdid_fmi.diagnose.residuals import residuals
    sim, _, run, res, _ = yrun()
    found = modes()[0]
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))  # noqa: E731
    r = residuals(found["aligned_model"], res.trace).axes["y"]
    rp = residuals(found["perfect_model"], sim).axes["y"]
    e_tool = res.trace.cmd("y") - res.trace.get("y", "tool")
    assert rms(r.tool_residual) < 0.1 * rms(e_tool)                 # measured 4.5 %
    assert rms(r.tool_residual) < 1.1 * rms(rp.tool_residual)        # measured 1.03 x (4.4 %)
    truth = run["motion"].pos("y", res.trace.t) - r.tool_predicted
    assert abs(rms(r.tool_residual) - rms(truth)) < 0.05 * rms(truth)
