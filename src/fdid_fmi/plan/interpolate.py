"""Interpolate a part program into commanded positions at Ts, as a CNC's interpolator does.

Imitated behaviour: **exact stop at every block end, no corner blending** - what a CNC does in
exact-stop mode (ISO ``G61`` / ``G09`` on every block, Heidenhain's M197-free default with
zero tolerance): the path velocity comes to rest at the end of each block, so the commanded
path *is* the programmed geometry (lines, arcs, helices) and corners are sharp. After a cutting
block (G1/G2/G3) the in-position wait of a real exact stop is not imitated: the next block
starts at the next sample, and the axes' lag carries into it (that is what the twin then
predicts at the corner). After a **rapid (G0)** it is (``in_position``, :class:`InPosition`):
real controls check in-position after a rapid (Fanuc's default; SINUMERIK's exact stop for G0
even in G64), so the next block starts at the first sample at which every modelled axis's
predicted tracking error |cmd - act| is within the window (the rapid's end point held until
then; rapids in sequence are settled in turn; the wait counts to the rapid's block). Without
it the lag a rapid leaves (mm) showed as the next cut's contour error. ``G64`` blending
is not imitated. With ``corner_angle_deg`` the look-ahead of :mod:`fdid_fmi.plan.lookahead`
keeps the path velocity through junctions whose tangents differ by at most that angle (still
no blending: the path stays the programmed one).

Within a block the path parameter s(t) (arc length, mm) follows the time-optimal rest-to-rest
7-segment jerk-limited S-curve of :func:`fdid_fmi.virtual.trajectories.scurve`, with

* path feed  <= the programmed feed F (G93: the block length over its programmed time; G0: no
  feed limit), and <= v_max,i / max|u_i| for every axis i (u: unit tangent);
* path acceleration and jerk <= a_max,i / max|u_i|, j_max,i / max|u_i| for every axis;
* on arcs, the per-axis velocity, acceleration and jerk *including the centripetal terms* are
  measured on a 4x finer grid and the whole block profile is time-scaled uniformly
  (v ~ lam, a ~ lam^2, j ~ lam^3, the same profile shape) until every axis is within its limits
  (as :func:`fdid_fmi.virtual.trajectories.follow_curve` does);
* each block's duration is rounded up to a whole number of samples (another uniform time
  scaling, <= 1), so block ends fall on samples and the end point is commanded exactly.

Hence every commanded sample lies on the programmed path (to rounding), and the finite
differences of the samples respect |v| <= v_max, |a| <= a_max, |j| <= j_max per axis.
A user who has the controller's own interpolated setpoints (a trace) passes them instead
(:func:`commands_from_trace`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..simulate import check_sample_time
from ..virtual.trajectories import scurve

AXES = ("x", "y", "z")


@dataclass
class AxisLimits:
    """Kinematic limits of one axis.

    Attributes
    ----------
    v : float, mm/s      (also the rapid traverse velocity)
    a : float, mm/s^2
    j : float, mm/s^3
    """

    v: float
    a: float
    j: float

    def __post_init__(self):
        for name in ("v", "a", "j"):
            val = getattr(self, name)
            try:
                ok = math.isfinite(float(val)) and float(val) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise InputError(f"axis limit {name} must be a positive number, got {val!r}",
                                 column=f"limit {name}")
            setattr(self, name, float(val))


@dataclass
class Interpolation:
    """Commanded positions of a program.

    Attributes
    ----------
    t : ndarray (N,), s
    positions : dict axis -> ndarray (N,), mm (x, y, z)
    Ts : float, s
    block_of_sample : ndarray (N,) int   index of the block each sample belongs to (-1: before
        the first block; the settling time after the last block counts to the last block)
    spans : list of (k0, k1)   block b moves from sample k0 to sample k1 (its end point; a
        rapid's span includes its in-position wait, the end point held)
    path_s : ndarray (N,), mm    programmed path length travelled at each sample
    cycle_time : float, s     time from the first block's start to the last block's end
    info : dict               limits, per-block feed used, corner rule
    """

    t: np.ndarray
    positions: dict
    Ts: float
    block_of_sample: np.ndarray
    spans: list
    path_s: np.ndarray
    cycle_time: float
    info: dict = field(default_factory=dict)

    @property
    def n(self):
        return self.t.size


#: Default in-position window, mm: SINUMERIK 840D's fine exact-stop window (MD36010
#: STOP_LIMIT_FINE, 0.01 mm) and a typical Fanuc in-position width (10 um).
IN_POSITION_MM = 0.01

#: Longest in-position wait, s: a P loop stuck by friction can rest outside the window for good;
#: then the next block starts after this wait, and a note names the line and the residual error.
IN_POSITION_CAP_S = 5.0


class InPosition:
    """The in-position wait after a rapid (G0), found from the twin itself.

    The commands up to the rapid's end sample k_e, then the end point held for ``cap_s``, are
    run through :func:`fdid_fmi.simulate.simulate`; the wait is w = k - k_e samples, k >= k_e
    the first sample at which |cmd - act| <= ``window_mm`` on every axis of the model (the run
    is causal and deterministic: the whole program's prediction shows the same errors up to the
    next block's start). Not reached within ``cap_s``: w = the cap, and :attr:`notes` gets a line
    naming the residual error.

    Parameters
    ----------
    model : DriveModel   the twin (an FMU's: :func:`fdid_fmi.plan.predict.model_from_fmu`)
    window_mm : float > 0, mm
    cap_s : float > 0, s

    Cost: the twin stepped once over the program (:meth:`tracker`) and, after each rapid, until
    the window is reached.
    """

    def __init__(self, model, window_mm=IN_POSITION_MM, cap_s=IN_POSITION_CAP_S):
        for name, val in (("in-position window", window_mm), ("in-position cap", cap_s)):
            if not (isinstance(val, (int, float, np.floating)) and math.isfinite(val) and val > 0):
                raise InputError(f"the {name} must be a finite number > 0, got {val!r}",
                                 column="--in-position")
        bad = [a for a in model.axes if a not in AXES]
        if bad:
            raise InputError(f"the model's axes {bad} are not x, y or z", column="axes")
        self.model, self.window_mm, self.cap_s = model, float(window_mm), float(cap_s)

    def tracker(self, Ts):
        """A :class:`_Settling` for one interpolation: its ``wait`` takes the commands of one
        program as they grow, and steps the twin over each new part only (the waits of a run of
        each whole prefix from rest would be quadratic in the program's length: 400 rapids 41 s
        against 3.4 s without waits)."""
        return _Settling(self, Ts)

    def describe(self, block, w, residual, Ts):
        """The note of a wait that reached its cap (None otherwise)."""
        if residual is None:
            return None
        worst = ", ".join(f"{a} {e * 1e3:.3g} um" for a, e in residual.items())
        return (f"line {block.line}: after the rapid the axes are not within the in-position window of "
                f"{self.window_mm:g} mm after {w * Ts:.3g} s (residual error: {worst}); the next block "
                f"starts then")


class _Settling:
    """The twin stepped along one program's commands (:meth:`InPosition.tracker`): the kernel's
    stepper runs each sample as :func:`fdid_fmi.simulate.simulate` runs it from rest (the same
    C core, the same doubles); after a rapid a copy of its state holds the end point until every
    axis is within the window."""

    def __init__(self, ip, Ts):
        from .. import kernel
        check_sample_time(Ts, ip.model.Ts)
        self.ip, self.Ts = ip, float(Ts)
        self.cm = kernel.CompiledModel(ip.model)
        if any(i.kind == "external" for i in ip.model.inputs):
            raise InputError("the in-position wait needs a twin driven by its commands alone (this one "
                             "has external inputs)", column="--in-position")
        lay = self.cm.layout
        self.cols = [AXES.index(a) for a in lay.axes]
        self.pos = list(lay.axis_pos)
        self.st = self._stepper()
        self.k = 0                      # samples stepped: the last call's k_e (its start at most)

    def _stepper(self):
        from .. import kernel
        st = kernel.Stepper(self.cm)
        st.set_parameters({}, self.cm.layout.axes)
        st.views["v0"][:] = 0.0         # from rest, as simulate() runs command arrays
        return st

    def _step(self, st, row, initial=False):
        """Outputs at one sample with the commands ``row`` (x y z), then the state advanced
        (``initial``: the first sample, which sets the start state from it, as fdid_run does);
        returns |cmd - position| per axis."""
        st.views["cmd"][:] = row[self.cols]
        st.touch(initial=initial)
        y = st.outputs()
        err = np.abs(st.views["cmd"] - y[self.pos])
        st.advance()
        return err

    def wait(self, P, start=0):
        """The wait after the commanded samples ``P`` (rows: samples ``start`` .. k_e, x y z mm;
        the last the rapid's end point): the class docstring of :class:`InPosition` applied to
        the whole prefix. The samples before ``start`` are those of the earlier calls (``start``
        at most the last call's k_e: only the new part is passed and stepped).

        Returns
        -------
        (w, residual) : samples to hold the end point, and None when the window is reached
        (else {axis: |error| at the end of the cap, mm})"""
        P = np.asarray(P, float)
        k_e = start + P.shape[0] - 1
        if not start <= self.k <= k_e:
            raise ValueError("in-position tracker: the commands must continue the earlier calls'")
        for k in range(self.k, k_e):
            self._step(self.st, P[k - start], initial=k == 0)
        self.k = k_e
        probe = self.st.copy()           # the state at k_e, then the end point held
        n_cap = max(1, int(math.ceil(self.ip.cap_s / self.Ts - 1e-9)))
        for w in range(n_cap + 1):
            err = self._step(probe, P[-1], initial=k_e == 0 and w == 0)
            if np.max(err) <= self.ip.window_mm:
                return w, None
        last = dict(zip(self.cm.layout.axes, err))
        return n_cap, {a: float(last[a]) for a in self.ip.model.axes}


def parse_limits(text, default=None):
    """Limits from ``v,a,j`` or ``x=v,a,j;y=...`` text (mm/s, mm/s^2, mm/s^3)."""
    out = dict(default or {})
    parts = [p for p in str(text).replace(";", " ").split() if p]
    for part in parts:
        if "=" in part:
            ax, vals = part.split("=", 1)
            axes = [ax.strip().lower()]
        else:
            axes, vals = list(AXES), part
        try:
            v, a, j = (float(x) for x in vals.split(","))
        except ValueError:
            raise InputError(f"'{part}' is not v,a,j (mm/s, mm/s^2, mm/s^3) or AXIS=v,a,j",
                             column="--limits") from None
        for ax in axes:
            if ax not in AXES:
                raise InputError(f"unknown axis '{ax}' (x, y, z)", column="--limits")
            out[ax] = AxisLimits(v, a, j)
    return out


def limits_from_trace(trace, axes=None, cutoff_hz=None):
    """Estimate each axis's v/a/j limits from a recorded trace of the same machine.

    The largest |velocity|, |acceleration| and |jerk| of the commanded position (derivatives
    through the zero-phase Butterworth of :func:`fdid_fmi.signals.filtered_derivatives`, cutoff
    min(50 Hz, 0.1/Ts)). The record shows what the interpolator used, so these are lower
    bounds of the machine's true limits (the jerk in particular is smoothed by the filter).
    """
    from ..signals import filtered_derivatives
    from ..identify.quasi_static import default_cutoff
    axes = axes or [a for a in trace.axes if trace.has(a, "cmd")]
    cutoff_hz = cutoff_hz or default_cutoff(trace.Ts)
    out = {}
    for ax in axes:
        v, a, j = filtered_derivatives(trace.cmd(ax), trace.Ts, cutoff_hz, 2, 3)
        vals = [float(np.max(np.abs(d))) for d in (v, a, j)]
        if min(vals) <= 0:
            raise InputError(f"axis '{ax}' does not move: no limits can be estimated", source=trace.source,
                             column=f"{ax}.cmd")
        out[ax] = AxisLimits(*vals)
    return out


def _tangent_peaks(block, n=513):
    """max |u_i| of the unit tangent over the block, per axis."""
    L = block.length
    if L == 0:
        return np.zeros(3)
    if block.kind != "arc":
        return np.abs(block.end - block.start) / L
    p = block.point(np.linspace(0.0, L, n))
    d = np.diff(p, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    return np.max(np.abs(d), axis=0)


def _axis_peaks(p, dt):
    d1 = np.diff(p, axis=0) / dt
    d2 = np.diff(d1, axis=0) / dt
    d3 = np.diff(d2, axis=0) / dt
    z = np.zeros(3)
    return (np.max(np.abs(d1), axis=0) if len(d1) else z, np.max(np.abs(d2), axis=0) if len(d2) else z,
            np.max(np.abs(d3), axis=0) if len(d3) else z)


def _arc_axis_peaks(block, prof, dt):
    """:func:`_axis_peaks` of the block's points at tau = 0, dt, ... (as ``np.arange(0,
    duration + dt, dt)``), CHUNK points at a time overlapping by 3 (every 4 consecutive points,
    hence every difference, lie in one chunk): the same peaks, temporaries bounded."""
    n = int(math.ceil((prof.duration + dt) / dt))       # np.arange's length
    peaks = [np.zeros(3), np.zeros(3), np.zeros(3)]
    for i0 in range(0, max(n - 3, 1), CHUNK):
        tau = np.arange(i0, min(n, i0 + CHUNK + 3)) * dt
        for acc, pk in zip(peaks, _axis_peaks(block.point(prof.evaluate(tau)[0]), dt)):
            np.maximum(acc, pk, out=acc)
    return tuple(peaks)


#: Most samples one block (or a dwell, the lead-in, the settling time) may take. Measured after
#: the contour error was computed in chunks: ``fdid plan`` of one G1 block of 1e6 samples peaks
#: at 448 MB RSS (842 MB with --report --json --csv; 160 MB at 1e5 samples), so 5e6 samples is
#: ~2 GB (~4.5 GB with every output): within an 8 GB workstation. 5e6 samples is 50 min at
#: Ts = 0.6 ms, 83 min at 1 ms, 10 min at 8 kHz: longer than a block of a real program takes;
#: more is a mistyped feed (F0.0001 over 100 mm: 6e7 s, 1e11 samples, 745 GiB for the times alone).
MAX_BLOCK_SAMPLES = 5_000_000

CHUNK = 1 << 18     # samples evaluated at a time within one block (bounded temporaries)


def _block_words(b, v, override=1.0):
    """What sets a block's duration, for an error message: its F word (or dwell time), or the
    axes' velocity limits when the path speed ``v`` (mm/s) is below the feed. (words, option)"""
    if b.kind == "dwell":
        return f"G4 P{b.block_time:g}", "P"
    if v < b.feed * override:
        kind = "the rapid" if b.kind == "rapid" else "the axes' velocity limits"
        return f"{kind} ({v:.3g} mm/s along the path) over {b.length:.6g} mm", "--limits"
    fw = f"{b.f_word:g}" if b.f_word is not None else f"{b.feed * 60:g}"
    if b.inverse_time:
        return f"G93 F{fw} (block time {b.block_time:.3g} s) over {b.length:.6g} mm", "F"
    return f"F{fw} [{'inch' if b.units == 'inch' else 'mm'}/min] over {b.length:.6g} mm", "F"


def _refuse_long(b, T, Ts, v, source, override=1.0, at_least=True):
    """InputError when a block lasting ``T`` s takes more than MAX_BLOCK_SAMPLES samples."""
    n = T / Ts
    if not n > MAX_BLOCK_SAMPLES:       # NaN cannot occur: T >= 0
        return
    what, column = _block_words(b, v, override)
    ov = f" at feed override {override:g}" if override != 1.0 else ""
    raise InputError(f"{what}{ov} makes the block last {'at least ' if at_least else ''}{T:.3g} s "
                     f"({n:.3g} samples at Ts = {Ts * 1e3:.4g} ms); at most {MAX_BLOCK_SAMPLES:.3g} "
                     f"samples per block (the planner keeps every sample in memory)",
                     source=source, column=column, row=b.line)


def check_block_lengths(program, limits, Ts, overrides=None):
    """Refuse, before any array is made, a block of more than MAX_BLOCK_SAMPLES samples.

    The duration is bounded below by the length over the largest path speed the block may
    reach: the feed (times its override; G93: the length over the block time) and
    sqrt(sum v_max,i^2) of the axes with limits (no axis is faster than its v_max); a dwell
    lasts its P time. Both corner rules (exact stop, look-ahead) take at least that long.
    """
    for b in program.blocks:
        f = float((overrides or {}).get(b.index, 1.0))
        if b.kind == "dwell":
            _refuse_long(b, b.block_time, Ts, 0.0, program.source, at_least=False)
        elif b.length > 0:
            moved = [ax for i, ax in enumerate(AXES) if b.kind == "arc" or b.end[i] != b.start[i]]
            v_axes = math.sqrt(sum(limits[ax].v ** 2 for ax in moved if ax in limits)) or math.inf
            v = min(b.feed * f, v_axes)
            _refuse_long(b, b.length / v if v > 0 else math.inf, Ts, v, program.source, f)


def block_profile(block, limits, Ts, override=1.0, source=None):
    """The S-curve of one block and its duration rounded to whole samples.

    Parameters
    ----------
    block : Block
    limits : dict axis -> AxisLimits (every axis the block moves)
    Ts : float, s
    override : float, feed override (1 = programmed feed)
    source : str, optional   the program's file, for the error of a block longer than
        MAX_BLOCK_SAMPLES samples (refused before its samples are made)

    Returns
    -------
    (prof, n_samples, c) : the SCurve, the number of sample steps the block takes and the time
    compression c <= 1 (the profile is evaluated at tau * c).
    """
    L = block.length
    if block.kind == "dwell":
        _refuse_long(block, block.block_time, Ts, 0.0, source, at_least=False)
        return None, int(math.ceil(block.block_time / Ts - 1e-9)), 1.0
    if L == 0:
        return None, 0, 1.0
    u = _tangent_peaks(block)
    v = block.feed * override
    a = j = math.inf
    for i, ax in enumerate(AXES):
        if u[i] > 1e-12:
            lim = limits.get(ax)
            if lim is None:
                raise InputError(f"line {block.line} moves axis {ax.upper()} but no limits are given "
                                 f"for it (--limits {ax}=v,a,j)", column="--limits")
            v = min(v, lim.v / u[i])
            a = min(a, lim.a / u[i])
            j = min(j, lim.j / u[i])
    prof = scurve(L, v, a, j)
    _refuse_long(block, prof.duration, Ts, v, source, override, at_least=block.kind == "arc")
    if block.kind == "arc":
        # centripetal terms: measure the axis peaks on a fine grid, scale time uniformly
        vp, ap, jp = _arc_axis_peaks(block, prof, Ts / 4)
        lam = 1.0
        for i, ax in enumerate(AXES):
            lim = limits.get(ax)
            if lim is None:
                continue
            if vp[i] > 0:
                lam = min(lam, lim.v / vp[i])
            if ap[i] > 0:
                lam = min(lam, math.sqrt(lim.a / ap[i]))
            if jp[i] > 0:
                lam = min(lam, (lim.j / jp[i]) ** (1 / 3))
        if lam < 1.0:
            lam *= 0.995
            prof = scurve(L, lam * v, lam ** 2 * a, lam ** 3 * j)
            _refuse_long(block, prof.duration, Ts, lam * v, source, override, at_least=False)
    n = max(1, int(math.ceil(prof.duration / Ts - 1e-9)))
    c = prof.duration / (n * Ts)
    return prof, n, c


def interpolate(program, limits, Ts, overrides=None, lead_in=0.05, settle=0.5, progress=False,
                corner_angle_deg=None, in_position=None):
    """Commanded positions of a program at Ts (see module docstring).

    Parameters
    ----------
    program : Program
    limits : dict axis -> AxisLimits
    Ts : float, s (the model's sample time)
    overrides : dict block index -> feed override factor (0 < f <= any), optional
    lead_in : float, s   rest at the start position before the first block
    settle : float, s    rest after the last block (the drive settles; errors there count
        to the last block)
    corner_angle_deg : float, optional   no stop at junctions whose tangents differ by at most
        this angle (:mod:`fdid_fmi.plan.lookahead`); default: exact stop at every block end
    in_position : InPosition, optional   the in-position wait after every G0 block (before the
        next block; see the module docstring); None: no wait (the rapid's lag carries into the
        next block). Cutting blocks (G1/G2/G3) never wait.

    Returns
    -------
    Interpolation (``info["in_position"]``: the window and each rapid's wait; ``info["notes"]``:
    waits that reached the cap)
    """
    if not (Ts > 0 and math.isfinite(Ts)):
        raise InputError(f"Ts must be > 0 s, got {Ts!r}", column="Ts")
    if not program.blocks:
        raise InputError("the program has no motion block", source=program.source)
    for name, val in (("lead_in", lead_in), ("settle", settle)):
        if not (math.isfinite(val) and val >= 0):
            raise InputError(f"{name} must be a finite time >= 0 s, got {val!r}", column=name)
    for b in program.blocks:            # both corner rules (the look-ahead did not check them)
        f = float((overrides or {}).get(b.index, 1.0))
        if not f > 0:
            raise InputError(f"feed override of line {b.line} must be > 0, got {f!r}", column="override")
    for name, val in (("lead_in", lead_in), ("settle", settle)):
        if val / Ts > MAX_BLOCK_SAMPLES:
            raise InputError(f"{name} of {val:g} s is {val / Ts:.3g} samples at Ts = {Ts * 1e3:.4g} ms; "
                             f"at most {MAX_BLOCK_SAMPLES:.3g}", column=name)
    check_block_lengths(program, limits, Ts, overrides)     # before any array is made
    if corner_angle_deg is not None:
        from .lookahead import interpolate_lookahead
        return interpolate_lookahead(program, limits, Ts, corner_angle_deg, overrides, lead_in, settle,
                                     in_position=in_position)
    overrides = overrides or {}
    waits, notes = [], []
    settling = in_position.tracker(Ts) if in_position is not None else None
    n0 = int(round(lead_in / Ts))
    # what the next wait is given: the lead-in, then from the last rapid's end sample on
    head, head_start, from_piece = np.repeat(program.blocks[0].start[None, :], n0 + 1, axis=0), 0, 0
    pieces, spans, feeds = [], [], []
    k = n0
    pos = np.asarray(program.blocks[0].start, float)
    it = program.blocks
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="interpolating", unit="block", leave=False, disable=None)  # None: off without a terminal
    for b in it:
        f = float(overrides.get(b.index, 1.0))
        if not f > 0:
            raise InputError(f"feed override of line {b.line} must be > 0, got {f!r}", column="override")
        prof, n, c = block_profile(b, limits, Ts, f, source=program.source)
        if prof is None:
            pieces.append(np.repeat(b.end[None, :], n, axis=0))
            spans.append((k, k + n))
            feeds.append(0.0)
        else:
            # s at tau = (1..n) Ts c, CHUNK samples at a time (evaluate's temporaries bounded)
            s = np.empty(n)
            for i0 in range(0, n, CHUNK):
                i1 = min(n, i0 + CHUNK)
                s[i0:i1] = prof.evaluate(np.arange(i0 + 1, i1 + 1) * Ts * c)[0]
            s[-1] = b.length
            pieces.append(b.point(s))
            spans.append((k, k + n))
            feeds.append(prof.v_peak * c)
        k += n
        pos = b.end
        if in_position is not None and b.kind == "rapid" and b is not program.blocks[-1]:
            # in-position wait: the end point held until every axis is within the window
            # the samples since the last wait only (the tracker has stepped the earlier ones)
            w, residual = settling.wait(np.vstack([head] + pieces[from_piece:]), start=head_start)
            head, head_start, from_piece = b.end[None, :], k, len(pieces)
            if w:
                pieces.append(np.repeat(b.end[None, :], w, axis=0))
                spans[-1] = (spans[-1][0], k + w)
                k += w
            waits.append(_wait_entry(b, w, residual, Ts))
            note = in_position.describe(b, w, residual, Ts)
            if note:
                notes.append(note)
    n_settle = int(round(settle / Ts))
    P = np.vstack([np.repeat(program.blocks[0].start[None, :], n0 + 1, axis=0)] + pieces
                  + [np.repeat(pos[None, :], n_settle, axis=0)])
    N = P.shape[0]
    owner = np.full(N, -1, int)
    path_s = np.zeros(N)
    s0 = 0.0
    for b, (k0, k1) in zip(program.blocks, spans):
        owner[k0 + 1:k1 + 1] = b.index
        if k1 > k0 and b.kind != "dwell" and b.length > 0:
            seg = np.linalg.norm(np.diff(P[k0:k1 + 1], axis=0), axis=1)
            # the programmed length, distributed like the samples (chords sum to ~length)
            cs = np.cumsum(seg)
            path_s[k0 + 1:k1 + 1] = s0 + b.length * cs / cs[-1] if cs[-1] > 0 else s0
            s0 += b.length
        else:
            path_s[k0 + 1:k1 + 1] = s0
    last = program.blocks[-1].index
    owner[spans[-1][1] + 1:] = last
    path_s[spans[-1][1] + 1:] = s0
    t = np.arange(N) * Ts
    return Interpolation(t=t, positions={a: P[:, i].copy() for i, a in enumerate(AXES)}, Ts=Ts,
                         block_of_sample=owner, spans=spans, path_s=path_s,
                         cycle_time=(spans[-1][1] - spans[0][0]) * Ts,
                         info={"corner_rule": "exact stop at every block end, no blending",
                               "limits": {a: vars(l) for a, l in limits.items()},
                               "feed_used_mm_s": feeds, "lead_in_s": n0 * Ts,
                               "settle_s": n_settle * Ts,
                               **in_position_info(in_position, waits, notes)})


def _wait_entry(b, w, residual, Ts):
    return {"block": b.index + 1, "line": b.line, "wait_s": w * Ts, "reached": residual is None,
            "residual_um": None if residual is None else {a: e * 1e3 for a, e in residual.items()}}


def in_position_info(in_position, waits, notes):
    """The ``in_position`` and ``notes`` entries of :attr:`Interpolation.info`."""
    if in_position is None:
        return {"in_position": {"window_mm": 0.0, "waits": []}, "notes": notes}
    return {"in_position": {"window_mm": in_position.window_mm, "cap_s": in_position.cap_s, "waits": waits},
            "notes": notes}


#: How far a controller's setpoint may lie from the programmed path (mm), on top of the program's
#: own arc end-point tolerance (:func:`~fdid_fmi.plan.ncprogram.radius_tolerance` of its largest
#: arc, by which a controller's arc may differ from this reader's): a controller that blends
#: corners leaves the path by its path tolerance, typically 0.01 .. 0.1 mm (Siemens G642 /
#: CYCLE832, Heidenhain cycle 32); exact-stop setpoints lie on the path to rounding (< 1 um for
#: examples/virtual_circle.csv on circle.nc). A trace of another program lies mm away (20 mm
#: for virtual_circle.csv on pocket_corner.nc).
TRACE_PATH_TOL = 0.1


def _polyline_distance(V, i, p):
    """Distance (mm) from point ``p`` to the polyline ``V`` on the segments next to vertex i."""
    best = float(np.linalg.norm(V[i] - p))
    for a, b in ((i - 1, i), (i, i + 1)):
        if 0 <= a and b < len(V):
            ab = V[b] - V[a]
            L2 = float(ab @ ab)
            t = min(1.0, max(0.0, float((p - V[a]) @ ab) / L2)) if L2 > 0 else 0.0
            best = min(best, float(np.linalg.norm(V[a] + t * ab - p)))
    return best


def commands_from_trace(program, trace, axes, Ts=None):
    """Use a controller's own interpolated setpoints (the ``cmd`` channels of a trace) instead
    of :func:`interpolate`; samples are attributed to blocks by the nearest point of the
    programmed path (monotone along the program).

    Parameters
    ----------
    program : Program
    trace : Trace   its ``cmd`` channels of ``axes``
    axes : list[str]   the twin's axes
    Ts : float, optional   the twin's sample time, s: a trace sampled otherwise is refused (as
        :func:`fdid_fmi.simulate.simulate` refuses it), not resampled

    Setpoints farther than TRACE_PATH_TOL + the program's arc end-point tolerance from the
    programmed path (in ``axes``) are refused: a trace of another program, another ``--start``,
    or motion outside the program (cut it with ``--range``).

    Returns
    -------
    Interpolation (cycle_time: from the first to the last moving sample)
    """
    if Ts is not None:
        check_sample_time(trace.Ts, Ts, "the setpoints", source=trace.source)
    Ts = trace.Ts
    P = np.zeros((trace.n, 3))
    for i, a in enumerate(AXES):
        if a in axes:
            if not trace.has(a, "cmd"):
                raise InputError(f"the trace has no commanded position of axis '{a}'", source=trace.source)
            P[:, i] = trace.cmd(a)
    # dense programmed path, each vertex tagged with its block, path length and tangent
    verts, tags, sv, tans = [], [], [], []
    s0 = 0.0
    for b in program.blocks:
        if b.kind == "dwell" or b.length == 0:
            continue
        m = max(3, int(math.ceil(b.length / 0.02)) + 1)
        s = np.linspace(0.0, b.length, m)
        pts = b.point(s)
        tg = np.gradient(pts, axis=0)
        verts.append(pts)
        tans.append(tg / np.maximum(np.linalg.norm(tg, axis=1, keepdims=True), 1e-300))
        tags.append(np.full(m, b.index))
        sv.append(s0 + s)
        s0 += b.length
    if not verts:
        raise InputError("the program has no move of non-zero length: the trace's setpoints cannot "
                         "be attributed to its blocks", source=program.source)
    V, T, S, TG = np.vstack(verts), np.concatenate(tags), np.concatenate(sv), np.vstack(tans)
    dims = [i for i, a in enumerate(AXES) if a in axes]
    from .ncprogram import radius_tolerance
    tol = TRACE_PATH_TOL + max([radius_tolerance(max(b.r0, b.r1)) for b in program.blocks if b.kind == "arc"],
                               default=0.0)
    owner = np.empty(trace.n, int)
    path_s = np.empty(trace.n)
    motion = np.vstack([np.diff(P, axis=0), np.zeros((1, 3))])
    moved = np.flatnonzero(np.any(motion[:, dims] != 0, axis=1))
    first_move = int(moved[0]) if moved.size else trace.n
    j = 0
    win = 4000
    for k in range(trace.n):
        hi = min(len(V), j + win)
        d = np.sum((V[j:hi][:, dims] - P[k, dims]) ** 2, axis=1)
        dmin = float(d.min())
        if not dmin <= tol * tol:     # the nearest vertex; the path itself may be nearer
            i = j + int(np.argmin(d))
            dist = _polyline_distance(V[:, dims], i, P[k, dims])
            if not dist <= tol:
                chans = [trace.roles[AXES[c]]["cmd"] for c in dims]
                at = ", ".join(f"{AXES[c]} {P[k, c]:.6g}" for c in dims)
                raise InputError(
                    f"the setpoint at t = {trace.t[k]:.6g} s ({at} mm) is {dist:.4g} mm from the path "
                    f"of {program.source or 'the program'} (nearest: line {program.blocks[T[i]].line}); setpoints must "
                    f"lie within {tol:.3g} mm of it (a controller's corner blending, up to "
                    f"{TRACE_PATH_TOL:g} mm, and the program's arc end-point tolerance): a trace of "
                    f"another program or another --start? Cut motion outside the program with --range",
                    source=trace.source, column="/".join(chans))
        # a corner is in two blocks: of the nearest vertices, take the one the motion follows
        cand = np.flatnonzero(d <= (math.sqrt(dmin) + 2e-3) ** 2)
        score = TG[j + cand][:, dims] @ motion[k, dims]
        if np.any(score != 0):
            jj = j + int(cand[np.argmax(score)])
        elif dmin < 1e-12:
            # at rest on a vertex: before the first motion, the program's start (a closed contour
            # ends there too); later (a junction, the end), the vertex furthest along
            jj = j + int(cand[0] if k < first_move else cand[-1])
        else:
            jj = j + int(cand[np.argmin(d[cand])])
        j = min(jj, j + int(np.argmin(d)))
        owner[k], path_s[k] = T[jj], S[jj]
    moving = np.flatnonzero(np.any(np.abs(np.diff(P, axis=0)) > 0, axis=1))
    cyc = (moving[-1] - moving[0] + 1) * Ts if moving.size else 0.0
    spans = []
    is_moving = np.zeros(trace.n, bool)
    is_moving[moving + 1] = True
    for b in program.blocks:
        ks = np.flatnonzero((owner == b.index) & is_moving)
        spans.append((int(ks[0]) - 1, int(ks[-1])) if ks.size else (0, 0))
    return Interpolation(t=trace.t - trace.t[0], positions={a: P[:, i].copy() for i, a in enumerate(AXES)},
                         Ts=Ts, block_of_sample=owner, spans=spans, path_s=path_s, cycle_time=cyc,
                         info={"corner_rule": "the controller's own setpoints (trace)",
                               "source": trace.source})
