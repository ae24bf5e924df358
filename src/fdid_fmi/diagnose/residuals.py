"""Residuals of a model's free run against measured traces, and the RMS/MAX error table.

Residual = measured - free-run prediction (:func:`fdid_fmi.simulate.simulate`, the semantics the
FMU implements), in mm, per axis:

``position``  measured ``act`` minus the model's ``position`` output (= minus the residual of
              the tracking error e = x_r - x, the same RMS);
``tool``      measured ``tool`` channel (when the trace has one) minus the model's
              ``tool_position`` output, or minus its ``position`` output when the model has no
              tool side (a rigid model predicts the tool where the motor is).

Arrays in, arrays out; the traces are not modified.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..metrics import rms_max_um
from ..simulate import simulate
from ..trace import Channel, Trace


@dataclass
class AxisResidual:
    """Measured, predicted and residual signals of one axis (mm, mm/s).

    Attributes
    ----------
    axis : str
    cmd : commanded position x_r
    measured, predicted, residual : motor-side position and residual = measured - predicted
    velocity : predicted velocity of the free run (mm/s)
    tool_measured, tool_predicted, tool_residual : tool side (None without a ``tool`` channel)
    """

    axis: str
    cmd: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    residual: np.ndarray
    velocity: np.ndarray
    tool_measured: np.ndarray | None = None
    tool_predicted: np.ndarray | None = None
    tool_residual: np.ndarray | None = None


@dataclass
class Residuals:
    """Free-run residuals of a model on one trace."""

    trace: Trace
    t: np.ndarray
    axes: dict = field(default_factory=dict)     # axis -> AxisResidual

    def channels(self):
        """Scored channels: ``{"x": residual, "x.tool": tool residual, ...}`` (mm)."""
        out = {}
        for a, r in self.axes.items():
            out[a] = r.residual
            if r.tool_residual is not None:
                out[f"{a}.tool"] = r.tool_residual
        return out

    def table(self):
        """``{channel: {"rms_um", "max_um"}}`` of the residuals."""
        return {k: rms_max_um(v) for k, v in self.channels().items()}


def residuals(model, trace: Trace) -> Residuals:
    """Free-run residuals of ``model`` on ``trace`` (see module docstring).

    Raises
    ------
    InputError
        The trace lacks the ``act`` channel of a model axis.
    """
    for a in model.axes:
        if not trace.has(a, "act"):
            raise InputError(f"needs the measured position ('act') of axis '{a}' to compute a residual",
                             source=trace.source, column=f"{a}.act")
    sim = simulate(model, trace)
    out = Residuals(trace=trace, t=np.asarray(trace.t))
    for a in model.axes:
        d = sim.axes[a]
        meas = np.asarray(trace.act(a), float)
        ar = AxisResidual(axis=a, cmd=np.asarray(trace.cmd(a), float), measured=meas,
                          predicted=d["position"], residual=meas - d["position"], velocity=d["velocity"])
        if trace.has(a, "tool"):
            tm = np.asarray(trace.get(a, "tool"), float)
            tp = d.get("tool_position", d["position"])
            ar.tool_measured, ar.tool_predicted, ar.tool_residual = tm, tp, tm - tp
        out.axes[a] = ar
    return out


def error_table(model, traces: dict) -> dict:
    """``{trace label: {channel: {"rms_um", "max_um"}}}`` of the model's free-run residuals."""
    return {name: residuals(model, tr).table() for name, tr in traces.items()}


# ----------------------------------------------------------------------- trace helpers
def with_channels(trace: Trace, data: dict, source_suffix="") -> Trace:
    """A copy of ``trace`` with some channels' data replaced (``{channel name: array}``)."""
    chans = dict(trace.channels)
    for name, arr in data.items():
        unit = chans[name].unit if name in chans else "1"
        chans[name] = Channel(name, unit, np.asarray(arr, float))
    return Trace(t=trace.t, channels=chans, roles={a: dict(r) for a, r in trace.roles.items()},
                 source=trace.source + source_suffix, meta=dict(trace.meta), jitter_tol=trace.jitter_tol)


def delayed(x, d):
    """x delayed by d samples (x[k - d]); the first d samples continue the starting ramp."""
    x = np.asarray(x, float)
    d = int(d)
    if d <= 0:
        return x.copy()
    out = np.empty_like(x)
    dx = x[1] - x[0] if x.size > 1 else 0.0
    out[:d] = x[0] - dx * np.arange(d, 0, -1)
    out[d:] = x[:-d]
    return out


MIN_PAUSE_S = 0.05      # a standstill: every commanded position still for at least this long
STILL = 1e-4            # still: a step below this fraction of the axis's largest step


def split_at_standstill(trace: Trace, min_part=2):
    """Fitted part, held-out part and a sentence saying where the trace was split, for a held-out
    check when no validation trace is given.

    The split is at the end of the standstill (every axis's commanded position still for at least
    ``MIN_PAUSE_S``) nearest the middle, within the middle half of the record: the held-out part
    opens with the standstill's last two samples, so it starts at rest as the model's free run
    then does (its start velocity is the first step). Split while an axis moves, the free run
    starts in the steady state of a ramp the drive may not have reached: on a two-axis trace split
    with x at 97 mm/s, 5 ms after its acceleration, 16.6 um RMS (243 um MAX) held out against
    0.49 um over the whole record.
    Without a standstill ending there (EMPS's reference never stops) the split is at the middle. A
    standstill is taken only where both parts keep at least ``min_part`` samples.

    Returns
    -------
    (Trace, Trace, str)
    """
    t, n = trace.t, trace.n
    moving = np.zeros(n - 1, bool)
    for a in trace.axes:
        if trace.has(a, "cmd"):
            d = np.abs(np.diff(trace.cmd(a)))
            moving |= d > STILL * d.max()           # an axis that never moves adds nothing
    runs = np.flatnonzero(np.diff(np.r_[0, ~moving, 0])).reshape(-1, 2)     # still steps [a, b)
    ends = [b for a, b in runs if t[b] - t[a] >= MIN_PAUSE_S
            and max(n // 4, min_part + 1) <= b <= min(3 * n // 4, n - min_part)]
    if ends:    # the held-out part opens with the run's last two still samples: a start at rest
        k = min(ends, key=lambda b: abs(b - n // 2)) - 1
        how = f"split at the standstill ending at t = {t[k + 1]:g} s"
    else:
        k = (n + 1) // 2
        how = (f"split at its middle, t = {t[k]:g} s (no standstill of {MIN_PAUSE_S:g} s ends in the "
               "middle half of the record)")
    return (trace.slice(None, t[k - 1]), trace.slice(t[k], None),
            f"no held-out trace given: first part fitted, second held out, {how}")
