"""The feed, acceleration and jerk the identification traces show, per axis (``DriveModel.limits``).

A trace's commanded positions are what the controller's interpolator made within the machine's
limits: their largest velocity, acceleration and jerk are limits the machine is known to run, and
the ones the model was identified at (beyond them the twin extrapolates). ``fdid plan`` interpolates
a program within them unless ``--limits`` says otherwise.
"""
from __future__ import annotations

import numpy as np

from ..signals import filtered_derivatives

#: Percentile of |d^k x_cmd / dt^k| taken as the limit (see :func:`recorded_limits`).
PERCENTILE = 99.5
#: A sample is "moving" when its |velocity| or |acceleration| exceeds this share of the axis's peak.
MOVING_SHARE = 0.01


def recorded_limits(traces, axes, cutoff_hz=None, order=2):
    """Per axis, the velocity, acceleration and jerk of the commanded positions in ``traces``.

    The derivatives are those of the quasi-static identification (thesis Eqn 3.5,
    :func:`fdid_fmi.signals.filtered_derivatives`): each a central difference through a
    zero-phase Butterworth low-pass of ``order`` at ``cutoff_hz`` (default min(50 Hz, 0.1 / Ts)).
    The limit is the **99.5th percentile** of |v|, |a|, |j| over the samples where the axis moves
    (|v| or |a| above 1 % of its peak), all traces together. Why a percentile and not the
    maximum: an interpolator holds its velocity and acceleration limits, and its jerk limit, for
    many samples (plateaus of the S-curve), so the percentile lies within a few percent of them
    (S-curve moves at 2000 mm/s^2 and 1e5 mm/s^3 sampled at 0.6 ms: 2047 mm/s^2 and 1.047e5
    mm/s^3; the maximum 2061 and 1.065e5, the filter's overshoot), while a disturbance of a few
    samples reaches only the top ones: one setpoint 0.5 mm off where a move starts raised the
    maximum jerk to 1.89e5 mm/s^3 (+77 %) and this percentile by 1.5 %. A step in the record (a
    jump of the command held, a restart) lasts longer than 0.5 % of the moving samples and raises
    both (0.5 mm: jerk x8 the maximum, x4 the percentile): cut such a record out of the training
    range. Restricting to moving samples keeps a trace that rests most of the time from pulling
    the percentile into its rests. These are limits the machine ran, lower bounds of what it can.

    Parameters
    ----------
    traces : Trace or list[Trace]   the identification traces (commanded position ``cmd`` per axis)
    axes : list[str]
    cutoff_hz : float, optional
    order : int

    Returns
    -------
    dict axis -> {``v_mm_s``, ``a_mm_s2``, ``j_mm_s3``, ``method``}; an axis whose command never
    moves (or that no trace commands) is left out.
    """
    from .quasi_static import default_cutoff
    traces = [traces] if not isinstance(traces, (list, tuple)) else list(traces)
    out = {}
    for ax in axes:
        pools = [[], [], []]
        used = 0
        for tr in traces:
            if not tr.has(ax, "cmd") or tr.n < 4:
                continue
            ds = filtered_derivatives(tr.cmd(ax), tr.Ts, cutoff_hz or default_cutoff(tr.Ts), order, 3)
            v, a = np.abs(ds[0]), np.abs(ds[1])
            if not (v.max() > 0 and np.all(np.isfinite(ds))):
                continue
            moving = (v > MOVING_SHARE * v.max()) | (a > MOVING_SHARE * a.max())
            for pool, d in zip(pools, ds):
                pool.append(np.abs(d[moving]))
            used += 1
        if not used:
            continue
        vals = [float(np.percentile(np.concatenate(p), PERCENTILE)) for p in pools]
        if min(vals) <= 0:
            continue
        cut = cutoff_hz or default_cutoff(traces[0].Ts)
        out[ax] = {"v_mm_s": vals[0], "a_mm_s2": vals[1], "j_mm_s3": vals[2],
                   "method": f"{PERCENTILE:g}th percentile of |v|, |a|, |j| of the commanded position over "
                             f"its moving samples ({used} trace(s); derivatives through a zero-phase "
                             f"Butterworth of order {order} at {cut:g} Hz)"}
    return out
