"""Does a trace's measured position follow its command? Notes (not refusals) for traces read in a
way that may be wrong: ``fdid identify`` prints them, the fleet keeps them with an entry's notes."""
from __future__ import annotations

import numpy as np

# the tracking error of a servo is a small part of its motion: RMS(cmd - act) / RMS(cmd - mean)
# is at most 0.07 on the virtual drive's diagnosis scenarios, 0.22 on plant2's (training and
# held-out traces), 0.007 on EMPS; a command in m beside a position in mm reads 0.999 and
# would otherwise be identified without a word. A rule, with room on both plants: a note, not a refusal.
MAX_FOLLOW_RATIO = 0.5
# a servo's position lags its command: the tracking error correlates positively with the commanded
# velocity, corr(cmd - act, d cmd/dt) >= -0.03 on the virtual drive's presets (calibration: a P loop
# 0.95-1.00, feed-forward -0.03-0.11) and >= 0.09 on plant2's 11 scenarios (measured: 0.92-1.00,
# feed-forward 0.09-0.24), 0.99-1.00 on EMPS. Swapped command and position columns negate it: -0.92
# and below without feed-forward; with feed-forward the swap stays within the servos' own range
# and is not noticed.
MIN_LEAD_CORRELATION = -0.5


def lead_correlation(trace, axis):
    """corr(cmd - act, d cmd/dt) of one axis (dimensionless, -1..1; 0 without motion)."""
    c = np.asarray(trace.cmd(axis), float)
    e = c - np.asarray(trace.act(axis), float)
    e = e - e.mean()
    v = np.gradient(c, trace.Ts)
    d = float(np.sqrt(np.sum(e * e) * np.sum(v * v)))
    return float(np.sum(e * v)) / d if d > 0 else 0.0


def follow_notes(trace, axes=None):
    """Notes for the axes whose measured position does not follow the command: the tracking
    error's RMS is more than ``MAX_FOLLOW_RATIO`` of the commanded motion's (columns swapped for
    another axis, or in different units), or the position leads the command
    (:func:`lead_correlation` below ``MIN_LEAD_CORRELATION``: command and position swapped)."""
    out = []
    for ax in axes or trace.axes:
        if not (trace.has(ax, "cmd") and trace.has(ax, "act")):
            continue
        c = trace.cmd(ax)
        cmd, act = trace.roles[ax]["cmd"], trace.roles[ax]["act"]
        motion = float(np.sqrt(np.mean((c - c.mean()) ** 2)))
        r = float(np.sqrt(np.mean((c - trace.act(ax)) ** 2))) / motion if motion > 0 else 0.0
        if r > MAX_FOLLOW_RATIO:
            out.append(f"axis {ax}: the tracking error's RMS is {r:.0%} of the commanded motion's (a servo's "
                       f"stays under 25 % on both test plants): check that {cmd} and "
                       f"{act} are this axis's positions in the units given (--unit)")
        rho = lead_correlation(trace, ax)
        if rho < MIN_LEAD_CORRELATION:
            out.append(f"axis {ax}: {act} runs ahead of {cmd} (the tracking error correlates {rho:+.2f} with "
                       f"the commanded velocity; a servo lags its command: -0.03 or more on both test "
                       f"plants): check that the command and the measured position are not swapped")
    return out
