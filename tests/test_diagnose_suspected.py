"""The ``suspected`` note (lost motion) must not fire on clean data because the axis rests.

The note's statistic (:func:`fdid_fmi.diagnose.friction.concentration`) is the residual energy
in the 40 ms after each motion start / stop over a reference outside those windows. Pooled over
every other sample (the Stribeck detector's form), that reference falls with the share of the
trace the axis rests: at rest the residual is the encoder's noise, while moving it is the model's
error. On the bundled clean example (``examples/virtual_xy_moves.csv``) the Y axis rests 83 % of
the trace; with the default path's r2c2-noI model it leaves 0.53 µm RMS in the windows, 0.138 µm
while moving and 0.066 µm at rest, and the pooled statistic would be 42.8 (a false note against
a gate of 21.2); so the note's reference is the larger of the moving and resting means: 14.8.
The gate (``REVERSAL_SUSPECT`` = 19.1) is calibrated on plant2's clean runs with that reference
(both paths, 4.72-15.95) and measured on the virtual drive (``diagnose/limits.py``); on plant2's
thesis-path fits: ``benchmarks/checks/diagnose_suspected.py``.
"""
import numpy as np
import pytest

from fdid_fmi.diagnose import friction
from fdid_fmi.diagnose.limits import REVERSAL_SUSPECT, NoteKind, data_limits
from fdid_fmi.diagnose.residuals import AxisResidual, Residuals

TS = 0.001


def _residuals(rest_s, n_moves=6, move_s=0.3, amp_mm=5.0):
    """One axis of alternating smooth moves separated by ``rest_s`` of rest, and a residual with
    the RMS the bundled example's Y axis showed per regime (default-path model): 0.75 µm in the
    windows after starts, 0.085 µm after stops, 0.138 µm elsewhere while moving, 0.066 µm at rest
    (a 123.4 Hz sine of that RMS in each, so that the energies do not depend on a random draw)."""
    k_move, k_rest = int(move_s / TS), int(rest_s / TS)
    u = np.arange(k_move) / k_move
    shape = amp_mm * (u - np.sin(2 * np.pi * u) / (2 * np.pi))        # velocity 1 - cos: smooth
    cmd, pos = [np.zeros(k_rest)], 0.0
    for i in range(n_moves):
        step = shape if i % 2 == 0 else -shape
        cmd += [pos + step, np.full(k_rest, pos + step[-1])]
        pos += step[-1]
    cmd = np.concatenate(cmd)
    v = np.abs(friction.command_velocity(cmd, TS))
    moving = v > 0.02 * v.max()
    sd = np.where(moving, 0.138e-3, 0.066e-3)
    w = int(round(friction.WINDOW_S / TS))
    for k, kind, _ in friction.motion_events(cmd, TS):
        sd[k:k + w] = 0.75e-3 if kind == "start" else 0.085e-3
    r = np.sqrt(2) * sd * np.sin(2 * np.pi * 123.4 * TS * np.arange(cmd.size))
    ar = AxisResidual(axis="y", cmd=cmd, measured=cmd + r, predicted=cmd.copy(), residual=r,
                      velocity=np.gradient(cmd, TS))
    return Residuals(trace=None, t=np.arange(cmd.size) * TS, axes={"y": ar}), 1.0 - moving.mean()


def test_the_note_statistic_does_not_grow_with_the_share_of_rest():
    short, rest_short = _residuals(rest_s=0.02)
    long_, rest_long = _residuals(rest_s=1.2)
    assert rest_short < 0.2 and 0.8 < rest_long < 0.9                 # the bundled Y axis: 83 %
    s_short = friction.concentration([short], "y", TS)
    s_long = friction.concentration([long_], "y", TS)
    # in-window energy over the moving one, (0.75^2 + 0.085^2) / 2 / 0.138^2 = 15.0, either way
    assert s_short == pytest.approx(15.0, rel=0.1) and s_long == pytest.approx(s_short, rel=0.1)
    assert s_long < REVERSAL_SUSPECT
    assert [n.kind for n in data_limits(["y"], set(), {"y": s_long}, [])] == [NoteKind.NOT_OBSERVABLE]
    # the pooled reference (the Stribeck detector's statistic) is what rises with the rest: the
    # false note of the bundled example (42.8 there against a gate of 21.2)
    p_short = friction.concentration([short], "y", TS, rest="pooled")
    p_long = friction.concentration([long_], "y", TS, rest="pooled")
    assert p_long > 2 * p_short and p_long > 21.2
    assert p_long >= s_long and p_short >= s_short                   # one trace: never above pooled
    with pytest.raises(ValueError, match="rest"):
        friction.concentration([short], "y", TS, rest="moving")

