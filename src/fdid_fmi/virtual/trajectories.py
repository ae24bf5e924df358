"""Jerk-limited commanded trajectories for the virtual feed drive (mm, sampled at Ts).

Every trajectory is built from *moves* whose path parameter s(t) (arc length, mm) follows a
7-segment jerk-limited S-curve (jerk +j, 0, -j, 0, -j, 0, +j), so the commanded position is
continuous up to acceleration and the jerk is piecewise constant along straight moves. Curved
paths (circle, spiral, figure-eight) are followed at constant arc-length speed with the
tangential feed ramped up and down by the same S-curve; their feed limits are then enforced on
the *vector* (path) velocity, acceleration and jerk, centripetal terms included, by a uniform
time scaling: the profile is built with (lam v, lam^2 acc, lam^3 jerk), lam <= 1, chosen from
the peaks measured on a 4x oversampled grid. Hence every axis respects |v| <= v, |a| <= acc,
|j| <= jerk.

The thesis trajectories (ch. 4, 7): a diamond of 20 mm edge, a circle of 20 mm radius, a
varying-distance linear interpolation ("pseudo-random") move sequence executed one axis at a
time, and a spiral (ch. 5). Each starts and ends with a dwell (settling).

Arrays out, nothing global: the random sequences take a ``seed`` and are reproducible.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import InputError
from ..trace import Trace

__all__ = ["SCurve", "Trajectory", "scurve", "point_to_point", "linear_moves", "diamond",
           "circle", "spiral", "figure_eight", "follow_curve", "sequence"]


# ----------------------------------------------------------------------------- checks
def _positive(name, value):
    try:
        ok = np.isfinite(value) and value > 0
    except TypeError:
        ok = False
    if not ok:
        raise InputError(f"must be a positive finite number, got {value!r}", column=name)
    return float(value)


def _nonneg(name, value):
    try:
        ok = np.isfinite(value) and value >= 0
    except TypeError:
        ok = False
    if not ok:
        raise InputError(f"must be a finite number >= 0, got {value!r}", column=name)
    return float(value)


def _dwell_pair(dwell):
    if np.isscalar(dwell):
        d = _nonneg("dwell", dwell)
        return d, d
    if len(dwell) != 2:
        raise InputError(f"dwell must be a number or a (start, end) pair of seconds, got {dwell!r}",
                         column="dwell")
    return _nonneg("dwell[0]", dwell[0]), _nonneg("dwell[1]", dwell[1])


# ----------------------------------------------------------------------------- S-curve
@dataclass(frozen=True)
class SCurve:
    """A rest-to-rest 7-segment jerk-limited profile over a distance.

    Attributes
    ----------
    distance : float, mm (>= 0)
    v_peak, a_peak : float, mm/s, mm/s^2 reached (<= the limits)
    jerk : float, mm/s^3
    durations : tuple of 7 floats, s (jerk +j, 0, -j, cruise, -j, 0, +j)
    """

    distance: float
    v_peak: float
    a_peak: float
    jerk: float
    durations: tuple

    @property
    def duration(self) -> float:
        """Total move time (s)."""
        return float(sum(self.durations))

    def evaluate(self, tau):
        """Path position, velocity, acceleration and jerk at times ``tau`` (s) after the start.

        Vectorised; ``tau`` is clipped to [0, duration] (rest before and after).

        Returns
        -------
        s, v, a, j : ndarrays (mm, mm/s, mm/s^2, mm/s^3)
        """
        tau = np.clip(np.asarray(tau, dtype=float), 0.0, self.duration)
        jseq = np.array([1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0]) * self.jerk
        edges = np.concatenate(([0.0], np.cumsum(self.durations)))
        s0 = np.zeros(8)
        v0 = np.zeros(8)
        a0 = np.zeros(8)
        for i in range(7):
            d = self.durations[i]
            a0[i + 1] = a0[i] + jseq[i] * d
            v0[i + 1] = v0[i] + a0[i] * d + jseq[i] * d * d / 2
            s0[i + 1] = s0[i] + v0[i] * d + a0[i] * d * d / 2 + jseq[i] * d ** 3 / 6
        seg = np.clip(np.searchsorted(edges, tau, side="right") - 1, 0, 6)
        x = tau - edges[seg]
        jj = jseq[seg]
        s = s0[seg] + v0[seg] * x + a0[seg] * x * x / 2 + jj * x ** 3 / 6
        v = v0[seg] + a0[seg] * x + jj * x * x / 2
        a = a0[seg] + jj * x
        # the closed-form end point is exact up to rounding: pin it
        at_end = tau >= self.duration
        s = np.where(at_end, self.distance, np.minimum(s, self.distance))
        v = np.where(at_end, 0.0, v)
        a = np.where(at_end, 0.0, a)
        jj = np.where(at_end, 0.0, jj)
        return s, v, a, jj


def scurve(distance, v, acc, jerk) -> SCurve:
    """Time-optimal rest-to-rest jerk-limited (7-segment) profile over ``distance``.

    Parameters
    ----------
    distance : float, mm (>= 0)
    v, acc, jerk : float, mm/s, mm/s^2, mm/s^3 (limits, > 0)

    Notes
    -----
    Accelerating from rest to a speed V takes T_a(V) = V/acc + acc/jerk when the acceleration
    limit is reached (V >= acc^2/jerk), else 2 sqrt(V/jerk); the acceleration and deceleration
    together cover V * T_a(V). When that exceeds the distance, V is lowered to the root of
    V * T_a(V) = distance (closed form in each branch).
    """
    D = _nonneg("distance", distance)
    v = _positive("v", v)
    A = _positive("acc", acc)
    J = _positive("jerk", jerk)
    if D == 0.0:
        return SCurve(0.0, 0.0, 0.0, J, (0.0,) * 7)

    def t_acc(V):
        return V / A + A / J if V >= A * A / J else 2.0 * np.sqrt(V / J)

    V = v
    if V * t_acc(V) > D:
        # branch with constant-acceleration phase
        c = A / J
        V = 0.5 * A * (-c + np.sqrt(c * c + 4.0 * D / A))
        if V < A * A / J:
            V = (D * np.sqrt(J) / 2.0) ** (2.0 / 3.0)
    if V >= A * A / J:
        tj = A / J
        ta = V / A - tj
        a_pk = A
    else:
        tj = np.sqrt(V / J)
        ta = 0.0
        a_pk = J * tj
    tv = max(0.0, (D - V * (2 * tj + ta)) / V)
    return SCurve(D, float(V), float(a_pk), J, (tj, ta, tj, tv, tj, ta, tj))


# ----------------------------------------------------------------------------- result
@dataclass
class Trajectory:
    """Commanded positions of one or more axes, sampled at Ts.

    Attributes
    ----------
    t : ndarray, s (k * Ts, k = 0..N-1)
    positions : dict axis -> ndarray, mm
    Ts : float, s
    info : dict    kind, limits asked and actually used, seed, path length, ...
    """

    t: np.ndarray
    positions: dict
    Ts: float
    info: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def axes(self) -> list:
        return list(self.positions)

    def __getitem__(self, axis):
        return self.positions[axis]

    def as_trace(self) -> Trace:
        """A command-only :class:`~fdid_fmi.trace.Trace` (role ``cmd`` per axis)."""
        return Trace.from_arrays(self.t, {a: {"cmd": p} for a, p in self.positions.items()},
                                 source=f"virtual:{self.info.get('kind', 'trajectory')}",
                                 meta={"trajectory": dict(self.info)})


# ----------------------------------------------------------------------------- timeline
class _Timeline:
    """A list of moves laid end to end in continuous time, evaluated on the sample grid."""

    def __init__(self, start):
        self.start = np.asarray(start, dtype=float)
        self.pos = self.start.copy()
        self.t = 0.0
        self.items = []  # (t0, duration, evaluate(tau) -> (n, dim) positions, end point)

    def dwell(self, duration):
        self.t += _nonneg("dwell", duration)

    def line(self, target, v, acc, jerk):
        target = np.asarray(target, dtype=float)
        delta = target - self.pos
        dist = float(np.linalg.norm(delta))
        if dist == 0.0:
            return
        prof = scurve(dist, v, acc, jerk)
        p0, u = self.pos.copy(), delta / dist

        def ev(tau, prof=prof, p0=p0, u=u):
            return p0 + np.outer(prof.evaluate(tau)[0], u)

        self.items.append((self.t, prof.duration, ev, target))
        self.t += prof.duration
        self.pos = target

    def curve(self, prof, point_at_s, end):
        self.items.append((self.t, prof.duration, lambda tau: point_at_s(prof.evaluate(tau)[0]), end))
        self.t += prof.duration
        self.pos = np.asarray(end, dtype=float)

    def sample(self, Ts):
        n = int(np.floor(self.t / Ts + 1e-9)) + 1
        t = Ts * np.arange(n)
        out = np.empty((n, self.start.size))
        out[:] = self.start
        for t0, dur, ev, end in self.items:
            i0 = int(np.searchsorted(t, t0, side="left"))
            i1 = int(np.searchsorted(t, t0 + dur, side="left"))
            if i1 > i0:
                out[i0:i1] = ev(t[i0:i1] - t0)
            out[i1:] = end
        return t, out


def _axes_names(axes, dim):
    axes = tuple(axes)
    if len(axes) != dim:
        raise InputError(f"needs {dim} axis names, got {axes!r}", column="axes")
    return axes


# ----------------------------------------------------------------------------- simple moves
def point_to_point(start, stop, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.2, axis="x"):
    """One rest-to-rest jerk-limited move of one axis, with dwell before and after.

    Parameters
    ----------
    start, stop : float, mm
    v, acc, jerk : float, mm/s, mm/s^2, mm/s^3 (limits)
    Ts : float, s
    dwell : float or (start, end), s
    axis : str

    Returns
    -------
    Trajectory
    """
    Ts = _positive("Ts", Ts)
    d0, d1 = _dwell_pair(dwell)
    tl = _Timeline([float(start)])
    tl.dwell(d0)
    tl.line([float(stop)], v, acc, jerk)
    tl.dwell(d1)
    t, p = tl.sample(Ts)
    return Trajectory(t, {axis: p[:, 0]}, Ts, dict(kind="point_to_point", v=v, acc=acc, jerk=jerk,
                                                     start=float(start), stop=float(stop)))


def linear_moves(n_moves=20, d_min=1.0, d_max=40.0, stroke=100.0, v=100.0, acc=2000.0,
                 jerk=1e5, Ts=1e-3, dwell=0.3, pause=(0.02, 0.25), speed_range=(0.3, 1.0),
                 seed=0, axes=("x",)):
    """Varying-distance linear moves ("pseudo-random" back-and-forth), one axis at a time.

    Each move picks an axis (at random among ``axes``), reverses that axis's last direction
    (back and forth), draws a distance in [d_min, d_max] mm (shortened to stay inside
    +-stroke/2 around 0) and a feed factor in ``speed_range`` (times ``v``), then pauses for
    a random time in ``pause``. Thesis ch. 4/7 "varying distance linear interpolation".

    Parameters
    ----------
    n_moves : int
    d_min, d_max : float, mm
    stroke : float, mm       axis travel, centred on 0
    v, acc, jerk : float     limits (mm/s, mm/s^2, mm/s^3)
    Ts : float, s
    dwell : float or pair, s settling at the start and end
    pause : (lo, hi), s      pause between moves
    speed_range : (lo, hi)   feed factor range, 0 < lo <= hi <= 1
    seed : int
    axes : tuple of str

    Returns
    -------
    Trajectory (all axes start at 0 mm); ``info["moves"]`` lists each move's axis, start and
    end time (s), target (mm) and feed (mm/s).
    """
    Ts = _positive("Ts", Ts)
    if int(n_moves) != n_moves or n_moves < 1:
        raise InputError(f"n_moves must be a positive integer, got {n_moves!r}", column="n_moves")
    d_min, d_max = _positive("d_min", d_min), _positive("d_max", d_max)
    stroke = _positive("stroke", stroke)
    if d_min > d_max or d_max > stroke:
        raise InputError(f"need d_min <= d_max <= stroke, got {d_min}, {d_max}, {stroke}", column="d_max")
    lo, hi = speed_range
    if not (0 < lo <= hi <= 1):
        raise InputError(f"speed_range must satisfy 0 < lo <= hi <= 1, got {speed_range!r}",
                         column="speed_range")
    p_lo, p_hi = _nonneg("pause[0]", pause[0]), _nonneg("pause[1]", pause[1])
    if p_lo > p_hi:
        raise InputError(f"pause must be (lo, hi) with lo <= hi, got {pause!r}", column="pause")
    axes = tuple(axes)
    rng = np.random.default_rng(seed)
    d0, d1 = _dwell_pair(dwell)
    tl = _Timeline(np.zeros(len(axes)))
    tl.dwell(d0)
    direction = rng.choice([-1.0, 1.0], size=len(axes))
    half = stroke / 2
    moves = []
    for m in range(int(n_moves)):
        ax = int(rng.integers(len(axes)))
        direction[ax] = -direction[ax]
        dist = rng.uniform(d_min, d_max)
        cur = tl.pos[ax]
        room = half - direction[ax] * cur
        if room < d_min:  # cannot go further this way: turn round
            direction[ax] = -direction[ax]
            room = half - direction[ax] * cur
        dist = min(dist, room)
        feed = v * rng.uniform(lo, hi)
        target = tl.pos.copy()
        target[ax] = cur + direction[ax] * dist
        t_start = tl.t
        tl.line(target, feed, acc, jerk)
        moves.append({"axis": axes[ax], "t_start": t_start, "t_end": tl.t,
                      "target": float(target[ax]), "feed": float(feed)})
        if m < n_moves - 1:
            tl.dwell(rng.uniform(p_lo, p_hi))
    tl.dwell(d1)
    t, p = tl.sample(Ts)
    return Trajectory(t, {a: p[:, i] for i, a in enumerate(axes)}, Ts,
                      dict(kind="linear_moves", v=v, acc=acc, jerk=jerk, seed=seed, n_moves=n_moves,
                           d_min=d_min, d_max=d_max, stroke=stroke, moves=moves))


def sequence(points, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.3, corner_dwell=0.0,
             axes=("x", "y"), kind="sequence"):
    """Straight rest-to-rest moves through a list of points (exact stop at each corner).

    Parameters
    ----------
    points : array (m, dim), mm; the first is the start
    v, acc, jerk : float   limits on the path (hence on every axis)
    corner_dwell : float, s   wait at each intermediate point

    Returns
    -------
    Trajectory
    """
    Ts = _positive("Ts", Ts)
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if pts.shape[0] < 2 or not np.isfinite(pts).all():
        raise InputError(f"need at least 2 finite points, got shape {pts.shape}", column="points")
    axes = _axes_names(axes, pts.shape[1])
    d0, d1 = _dwell_pair(dwell)
    tl = _Timeline(pts[0])
    tl.dwell(d0)
    for i, p in enumerate(pts[1:]):
        tl.line(p, v, acc, jerk)
        if i < len(pts) - 2:
            tl.dwell(_nonneg("corner_dwell", corner_dwell))
    tl.dwell(d1)
    t, p = tl.sample(Ts)
    return Trajectory(t, {a: p[:, i] for i, a in enumerate(axes)}, Ts,
                      dict(kind=kind, v=v, acc=acc, jerk=jerk, points=pts.tolist()))


def diamond(edge=20.0, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.3, corner_dwell=0.0,
            loops=1, center=(0.0, 0.0), axes=("x", "y")):
    """Diamond (square turned 45 deg) of ``edge`` mm, both axes moving on every edge.

    Starts and ends at the left vertex; exact stop at the corners (thesis ch. 4/7: 20 mm).
    """
    edge = _positive("edge", edge)
    h = edge / np.sqrt(2.0)
    cx, cy = center
    loop = [(cx - h, cy), (cx, cy - h), (cx + h, cy), (cx, cy + h)]
    pts = [loop[0]] + (loop[1:] + [loop[0]]) * int(loops)
    tr = sequence(pts, v, acc, jerk, Ts, dwell, corner_dwell, axes, kind="diamond")
    tr.info.update(edge=edge, loops=int(loops), center=[cx, cy])
    return tr


# ----------------------------------------------------------------------------- curves
def _arc_length_map(curve, u_end, n_dense):
    """Arc length of a parametric plane curve and a smooth map s -> u (cubic spline)."""
    u = np.linspace(0.0, u_end, n_dense)
    p = np.asarray(curve(u), dtype=float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    if not (np.diff(s) > 0).all():
        raise InputError("the curve must move at every parameter value (zero-speed point found)",
                         column="curve")
    return s[-1], CubicSpline(s, u)


def _vector_peaks(p, dt):
    d1 = np.diff(p, axis=0) / dt
    d2 = np.diff(d1, axis=0) / dt
    d3 = np.diff(d2, axis=0) / dt
    return (np.linalg.norm(d1, axis=1).max(), np.linalg.norm(d2, axis=1).max(),
            np.linalg.norm(d3, axis=1).max())


def follow_curve(curve, u_end, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.3, axes=("x", "y"),
                 kind="curve", n_dense=None, approach=True):
    """Follow a smooth parametric curve at a jerk-limited tangential feed.

    The curve is re-parameterised by arc length; s(t) is one S-curve over the whole length
    (feed ramps up from rest at the start and down to rest at the end), then the whole profile
    is time-scaled so that the vector velocity, acceleration and jerk (centripetal terms
    included) stay within (v, acc, jerk).

    Parameters
    ----------
    curve : callable u -> (n, 2) points, mm (vectorised, smooth, never stationary)
    u_end : float    parameter range [0, u_end]
    v, acc, jerk : float   limits (mm/s, mm/s^2, mm/s^3)
    n_dense : int     points of the arc-length table (default 40001)

    Returns
    -------
    Trajectory, info carries ``v_used``, ``acc_used``, ``jerk_used`` (the scaled S-curve limits)
    and ``length`` (mm).
    """
    Ts = _positive("Ts", Ts)
    v, acc, jerk = _positive("v", v), _positive("acc", acc), _positive("jerk", jerk)
    axes = _axes_names(axes, 2)
    d0, d1 = _dwell_pair(dwell)
    n_dense = int(n_dense or 40001)
    length, u_of_s = _arc_length_map(curve, float(u_end), n_dense)

    def point(s):
        return np.asarray(curve(u_of_s(np.clip(s, 0.0, length))), dtype=float)

    def build(lam, step):
        prof = scurve(length, lam * v, lam ** 2 * acc, lam ** 3 * jerk)
        tl = _Timeline(point(np.array([0.0]))[0])
        tl.dwell(d0)
        tl.curve(prof, point, point(np.array([length]))[0])
        tl.dwell(d1)
        return tl.sample(step)

    # measure the vector peaks on a 4x finer grid (a finite difference never exceeds the true
    # peak of the derivative), then scale time uniformly: v ~ lam, a ~ lam^2, j ~ lam^3
    _, pf = build(1.0, Ts / 4)
    vp, ap, jp = _vector_peaks(pf, Ts / 4)
    lam = min(1.0, v / vp, np.sqrt(acc / ap), np.cbrt(jerk / jp)) * 0.995
    t, p = build(lam, Ts)
    return Trajectory(t, {a: p[:, i] for i, a in enumerate(axes)}, Ts,
                      dict(kind=kind, v=v, acc=acc, jerk=jerk, length=float(length),
                           time_scale=float(lam), v_used=lam * v, acc_used=lam ** 2 * acc,
                           jerk_used=lam ** 3 * jerk))


def circle(radius=20.0, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.3, turns=1.0,
           center=(0.0, 0.0), start_angle=-90.0, ccw=True, axes=("x", "y")):
    """Circle of ``radius`` mm (thesis: 20 mm), ``turns`` revolutions, with a jerk-limited
    tangential feed ramp-up and ramp-down. Starts on the circle at ``start_angle`` (deg)."""
    R = _positive("radius", radius)
    turns = _positive("turns", turns)
    cx, cy = center
    a0 = np.deg2rad(start_angle)
    sgn = 1.0 if ccw else -1.0

    def curve(u):
        return np.column_stack((cx + R * np.cos(a0 + sgn * u), cy + R * np.sin(a0 + sgn * u)))

    tr = follow_curve(curve, 2 * np.pi * turns, v, acc, jerk, Ts, dwell, axes, kind="circle")
    tr.info.update(radius=R, turns=turns, center=[cx, cy])
    return tr


def spiral(r_start=2.0, r_end=20.0, turns=3.0, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3,
           dwell=0.3, center=(0.0, 0.0), axes=("x", "y")):
    """Archimedean spiral from ``r_start`` to ``r_end`` mm over ``turns`` revolutions
    (thesis ch. 5 identification trajectory)."""
    r0 = _positive("r_start", r_start)
    r1 = _positive("r_end", r_end)
    turns = _positive("turns", turns)
    cx, cy = center
    U = 2 * np.pi * turns

    def curve(u):
        r = r0 + (r1 - r0) * u / U
        return np.column_stack((cx + r * np.cos(u), cy + r * np.sin(u)))

    tr = follow_curve(curve, U, v, acc, jerk, Ts, dwell, axes, kind="spiral")
    tr.info.update(r_start=r0, r_end=r1, turns=turns, center=[cx, cy])
    return tr


def figure_eight(width=40.0, height=20.0, v=100.0, acc=2000.0, jerk=1e5, Ts=1e-3, dwell=0.3,
                 loops=1, center=(0.0, 0.0), axes=("x", "y")):
    """Smooth closed figure-eight (1:2 Lissajous curve) ``width`` x ``height`` mm:
    x = W/2 sin(u), y = H/2 sin(2u); starts and ends at the centre crossing."""
    W = _positive("width", width)
    H = _positive("height", height)
    cx, cy = center

    def curve(u):
        return np.column_stack((cx + W / 2 * np.sin(u), cy + H / 2 * np.sin(2 * u)))

    tr = follow_curve(curve, 2 * np.pi * int(loops), v, acc, jerk, Ts, dwell, axes,
                      kind="figure_eight")
    tr.info.update(width=W, height=H, loops=int(loops), center=[cx, cy])
    return tr
