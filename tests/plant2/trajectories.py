"""Commanded paths for the second plant, written from scratch: a CNC-style FIR jerk filter.

Every path is built the way many CNC interpolators do it: the programmed blocks become a
piecewise-constant *vector velocity* (each block's displacement spread over an integer number of
samples at its feed), which is then smoothed by two moving averages (boxcar FIR filters of
lengths n_a and n_j samples). One boxcar limits the acceleration to |dv| / (n_a Ts), the second
the jerk to a / (n_j Ts); both have unit area, so the filtered velocity integrates to exactly the
programmed displacement: every move lands on its target (up to rounding, < 1e-9 mm).

A path is a :class:`Path`: sample times and a commanded position per axis (mm).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Path:
    """Commanded positions.

    Attributes
    ----------
    Ts : float, s
    cmd : dict axis -> ndarray, mm (all the same length)
    info : dict, how the path was made (limits, seed, kind)
    """

    Ts: float
    cmd: dict
    info: dict = field(default_factory=dict)

    @property
    def n(self):
        return len(next(iter(self.cmd.values())))

    @property
    def t(self):
        return self.Ts * np.arange(self.n)


def _boxcar(v, n):
    """Moving average of length n (samples) along axis 0, output longer by n - 1 samples."""
    if n <= 1:
        return v
    z = np.zeros((n - 1, v.shape[1]))
    c = np.cumsum(np.vstack([np.zeros((1, v.shape[1])), z, v, z]), axis=0)
    return (c[n:] - c[:-n]) / n


def jerk_filtered(blocks, Ts, acc, jerk, start, settle_s=0.3, max_dv=None):
    """Positions from a list of velocity blocks through the two-boxcar jerk filter.

    Parameters
    ----------
    blocks : list of (displacement ndarray (n_axes,) mm, feed mm/s) or (None, dwell s)
    Ts : float, s
    acc, jerk : float, mm/s^2 and mm/s^3 -- per-axis limits that the result respects
    start : ndarray (n_axes,), mm
    settle_s : float, s of standstill appended after the filter tail
    max_dv : float, mm/s, largest per-axis velocity step between blocks (default: the largest
        block feed component, i.e. blocks separated by standstill)

    Returns
    -------
    ndarray (N, n_axes), mm
    """
    start = np.asarray(start, float)
    rows = []
    for d, f in blocks:
        if d is None:
            rows.append(np.zeros((max(1, int(round(f / Ts))), start.size)))
            continue
        d = np.asarray(d, float)
        L = float(np.linalg.norm(d))
        n = max(1, int(math.ceil(L / (f * Ts))))
        rows.append(np.tile(d / (n * Ts), (n, 1)))
    v = np.vstack(rows)
    vmax_axis = np.max(np.abs(v)) if max_dv is None else max_dv
    n_a = max(1, int(math.ceil(vmax_axis / (acc * Ts))))
    n_j = max(1, int(math.ceil(acc / (jerk * Ts))))
    v = _boxcar(_boxcar(v, n_a), n_j)
    v = np.vstack([np.zeros((1, start.size)), v, np.zeros((int(round(settle_s / Ts)), start.size))])
    return start + Ts * np.cumsum(v, axis=0)


def point_to_point(Ts, targets, feeds, dwells, acc, jerk, axes=("x",), start=None, settle_s=0.3):
    """Jerk-limited point-to-point moves, each from standstill to standstill.

    Parameters
    ----------
    targets : sequence of ndarray (n_axes,), absolute target positions, mm
    feeds : sequence of float, path feed of each move, mm/s
    dwells : sequence of float, standstill after each move, s (at least the filter length is
        added so that consecutive moves never overlap)
    acc, jerk : per-axis limits, mm/s^2, mm/s^3
    """
    start = np.zeros(len(axes)) if start is None else np.asarray(start, float)
    vmax = max(feeds)
    T_filter = (math.ceil(vmax / (acc * Ts)) + math.ceil(acc / (jerk * Ts))) * Ts
    blocks, pos = [], start.copy()
    for tgt, f, dw in zip(targets, feeds, dwells):
        tgt = np.asarray(tgt, float)
        if np.linalg.norm(tgt - pos) > 0:
            blocks.append((tgt - pos, f))
        blocks.append((None, dw + T_filter))
        pos = tgt
    X = jerk_filtered(blocks, Ts, acc, jerk, start, settle_s, max_dv=vmax)
    return Path(Ts, {a: X[:, i] for i, a in enumerate(axes)},
                {"kind": "point_to_point", "acc": acc, "jerk": jerk, "targets": [list(map(float, t)) for t in targets]})


def random_moves(Ts, n_moves=12, axes=("x", "y"), seed=0, travel=(-60.0, 60.0), feed=(5.0, 250.0),
                 acc=3000.0, jerk=2e5, small_fraction=0.3, dwell=(0.05, 0.4), single_axis_fraction=0.6,
                 max_move_s=1.2):
    """Training-style moves: random targets, feeds and dwells; some moves tiny (friction), some
    on one axis only, the rest on all axes together.

    Parameters
    ----------
    travel : (lo, hi) mm of each axis
    feed : (lo, hi) mm/s, drawn log-uniformly (raised where a move would last over ``max_move_s``)
    small_fraction : share of moves shorter than 0.5 mm
    """
    rng = np.random.default_rng(seed)
    na = len(axes)
    pos = np.zeros(na)
    targets, feeds, dwells = [], [], []
    for _ in range(n_moves):
        tgt = pos.copy()
        which = [int(rng.integers(na))] if (na == 1 or rng.random() < single_axis_fraction) else range(na)
        for i in which:
            if rng.random() < small_fraction:
                step = rng.choice([-1, 1]) * rng.uniform(0.02, 0.5)
            else:
                step = rng.choice([-1, 1]) * rng.uniform(2.0, 0.6 * (travel[1] - travel[0]))
            tgt[i] = np.clip(pos[i] + step, travel[0], travel[1])
            if abs(tgt[i] - pos[i]) < 0.01:
                tgt[i] = pos[i] - step
        targets.append(tgt)
        f = float(np.exp(rng.uniform(np.log(feed[0]), np.log(feed[1]))))
        feeds.append(min(feed[1], max(f, float(np.linalg.norm(tgt - pos)) / max_move_s)))
        dwells.append(float(rng.uniform(*dwell)))
        pos = tgt
    p = point_to_point(Ts, targets, feeds, dwells, acc, jerk, axes)
    p.info.update({"kind": "random_moves", "seed": seed, "n_moves": n_moves})
    return p


def reversals(Ts, axes=("x", "y"), seed=0, amplitudes=(0.05, 0.3, 2.0, 10.0, 25.0), feeds=(2.0, 20.0, 120.0),
              acc=4000.0, jerk=4e5, dwell=0.08, max_stroke_s=0.6):
    """A validation move set unlike the training moves: back-and-forth strokes (amplitudes in mm)
    at a few feeds (mm/s), every amplitude/feed pair whose stroke lasts at most ``max_stroke_s``
    seconds at feed, on each axis in turn, in a seeded random order (many reversals)."""
    rng = np.random.default_rng(seed)
    pos = np.zeros(len(axes))
    targets, fs, dws = [], [], []
    combos = [(a, f, i) for a in amplitudes for f in feeds for i in range(len(axes)) if a / f <= max_stroke_s]
    for k in rng.permutation(len(combos)):
        amp, f, i = combos[k]
        for sgn in (1.0, -1.0):
            tgt = pos.copy()
            tgt[i] = pos[i] + sgn * amp
            targets.append(tgt)
            fs.append(f)
            dws.append(dwell)
            pos = tgt
    p = point_to_point(Ts, targets, fs, dws, acc, jerk, axes)
    p.info.update({"kind": "reversals", "seed": seed})
    return p


def circle(Ts, radius=20.0, feed=100.0, turns=1.0, acc=3000.0, jerk=2e5, axes=("x", "y"), settle_s=0.3):
    """A circle starting and ending at rest at (0, 0) (centre at (-radius, 0)), counter-clockwise.

    The arc length follows the jerk filter on one rectangle of speed ``feed`` (reduced so the
    centripetal acceleration feed^2 / radius stays below ``acc``).
    """
    feed = min(feed, 0.9 * math.sqrt(acc * radius))
    L = 2 * math.pi * radius * turns
    s = jerk_filtered([(np.array([L]), feed)], Ts, acc, jerk, np.zeros(1), settle_s)[:, 0]
    th = s / radius
    x = -radius + radius * np.cos(th)
    y = radius * np.sin(th)
    return Path(Ts, {axes[0]: x, axes[1]: y},
                {"kind": "circle", "radius": radius, "feed": feed, "acc": acc, "jerk": jerk})


def diamond(Ts, half_diagonal=20.0, feed=120.0, acc=3000.0, jerk=2e5, axes=("x", "y"), settle_s=0.3):
    """A diamond (square rotated 45 deg) through (0,0) -> (-h,h) -> (-2h,0) -> (-h,-h) -> (0,0),
    corners blended by the jerk filter (per-axis acceleration and jerk within the limits)."""
    h = half_diagonal
    edges = [np.array(e, float) for e in ((-h, h), (-h, -h), (h, -h), (h, h))]
    blocks = [(e, feed) for e in edges]
    dv = feed * math.sqrt(2.0)                   # one axis component reverses at a corner
    X = jerk_filtered(blocks, Ts, acc, jerk, np.zeros(2), settle_s, max_dv=dv)
    return Path(Ts, {axes[0]: X[:, 0], axes[1]: X[:, 1]},
                {"kind": "diamond", "half_diagonal": h, "feed": feed, "acc": acc, "jerk": jerk})
