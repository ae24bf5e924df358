"""Review of the identification engine with degenerate but plausible traces: each case gives a
finite, sane model or one InputError line naming what is wrong (never a traceback, never a NaN
model, never a silently wrong one).

Traces are small (<= 2000 samples) and the searches pinned (rigid / hold / few iterations) so the
file stays fast.
"""
import json
import warnings

import numpy as np
import pytest

from fdid_fmi import identify as idf
from fdid_fmi.cli import main
from fdid_fmi.errors import InputError
from fdid_fmi.identify.structure import Bounds
from fdid_fmi.trace import Channel, Trace

TS = 1e-3


def drive_trace(n=1500, offset=0.0, source="<review>"):
    """Back-and-forth moves through a third-order closed loop (one real pole, one complex pair,
    exactly discretised): a drive with known, stable dynamics and a tracking error of ~0.5 mm."""
    from scipy import signal
    t = np.arange(n) * TS
    cmd = 10.0 * (1 - np.cos(2 * np.pi * t / (n * TS / 2))) + 2.0 * np.sin(2 * np.pi * 7 * t)
    p, wn, z = 2 * np.pi * 40, 2 * np.pi * 12, 0.8
    den = np.polymul([1, p], [1, 2 * z * wn, wn * wn])
    sys_d = signal.cont2discrete(([den[-1]], den), TS, method="zoh")
    act = signal.lfilter(np.ravel(sys_d[0]), sys_d[1], cmd - cmd[0], zi=None) + cmd[0]
    return Trace.from_arrays(t, {"x": {"cmd": cmd + offset, "act": act + offset}}, source=source)


def write_csv(path, tr, extra=None):
    cols = {"t_s": tr.t, "x_cmd_mm": tr.cmd("x"), "x_mm": tr.act("x"), **(extra or {})}
    rows = [",".join(cols)] + [",".join(repr(float(c[i])) for c in cols.values()) for i in range(tr.n)]
    path.write_text("\n".join(rows) + "\n")
    return path


def run(capsys, *args):
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(code, err, *words):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, (code, err)
    assert len(lines) == 1 and "Traceback" not in err and "internal error" not in err, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def trace():
    return drive_trace()


# ----------------------------------------------------------------------------- search bounds
def test_bounds_no_filter_can_represent_are_one_line_not_an_internal_error(capsys, tmp_path, trace):
    # --zeta 0.1:1e308 made every candidate's polynomial overflow; the LS projection then returned
    # a bare Fit where the caller unpacked (fit, residuals): "internal error: TypeError", after
    # an overflow RuntimeWarning (a second stderr line; turned into an error here)
    csv = write_csv(tmp_path / "run.csv", trace)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        code, _, err = run(capsys, "identify", csv, "--structure", "rigid", "--same-sample", "hold",
                           "--maxiter", "3", "--zeta", "0.1:1e308", "-o", tmp_path / "m.json")
    one_line(code, err, "run.csv", "no usable model", "narrow the bounds")
    assert not (tmp_path / "m.json").exists()


def test_huge_zeta_bound_warns_nothing(trace):
    # a zeta of ~1e9 rounds the slow root of the pair to 0: the canonical mirror took log10(0)
    # and printed a RuntimeWarning among the results
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        b = Bounds([(0.1, 450.0)], [(0.5, 450.0)], [(0.1, 1e10)])
        m = idf.identify_siso(trace, bounds=b, maxiter=3, same_sample="hold", refine=False)
    assert np.all(np.isfinite(m.A)) and np.all(np.isfinite(m.C))
