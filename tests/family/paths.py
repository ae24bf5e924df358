"""Commanded paths of the plant family: point-to-point moves and contours, sampled at Ts.

A move of length L (mm) at feed v (mm/s) and acceleration a (mm/s^2) has the trapezoidal
velocity profile (triangular when L < v^2 / a), sampled at Ts and rescaled so that its samples
add up to L exactly. ``jerk_time`` > 0 makes it jerk-limited: the velocity is averaged over
``jerk_time`` (a moving average of unit area), which ramps the acceleration in that time (jerk
a / jerk_time) and keeps the length. Contours (circle) follow a parametric curve along such a
profile of the path length; a diamond is four straight moves with an exact stop at each corner.

Every builder returns an ``(n, n_axes)`` array of commanded positions in mm.
"""
from __future__ import annotations

import math

import numpy as np


def speed_profile(L, v, a, Ts, jerk_time=0.0):
    """Path velocity samples (mm/s) of one move from standstill to standstill.

    Parameters
    ----------
    L : float, mm, path length (> 0)
    v, a : float, mm/s and mm/s^2, feed and acceleration limits
    Ts : float, s
    jerk_time : float, s, time the acceleration takes to build up (0: trapezoidal profile)

    Returns
    -------
    ndarray, mm/s, one velocity per sample; ``Ts * sum`` equals L to rounding
    """
    v = min(v, math.sqrt(L * a))
    ta = v / a
    T = L / v + ta                      # total time of the trapezoid
    n = max(2, int(math.ceil(T / Ts)))
    t = (np.arange(n) + 0.5) * (T / n)
    prof = np.minimum(np.minimum(a * t, v), a * (T - t))
    prof *= L / (Ts * prof.sum())
    nj = int(round(jerk_time / Ts))
    if nj > 1:
        prof = np.convolve(prof, np.full(nj, 1.0 / nj))
    return prof


def _pad(v, dwell, Ts):
    return np.concatenate([v, np.zeros(max(1, int(round(dwell / Ts))))])


def line_moves(start, targets, feeds, a, Ts, jerk_time, dwells):
    """Straight moves (all axes interpolated together, as G1) from standstill to standstill.

    Parameters
    ----------
    start : (n_axes,) mm
    targets : list of (n_axes,) mm, absolute
    feeds : list of float, mm/s, path feed of each move
    a : float, mm/s^2, path acceleration
    Ts : float, s
    jerk_time : float, s
    dwells : list of float, s, standstill after each move

    Returns
    -------
    ndarray (n, n_axes), mm
    """
    pos = np.asarray(start, float).copy()
    rows = [pos[None, :].repeat(max(1, int(round(0.2 / Ts))), 0)]
    for tgt, f, dw in zip(targets, feeds, dwells):
        tgt = np.asarray(tgt, float)
        d = tgt - pos
        L = float(np.linalg.norm(d))
        if L > 1e-9:
            s = Ts * np.cumsum(_pad(speed_profile(L, f, a, Ts, jerk_time), dw, Ts))
            s *= L / s[-1]
            rows.append(pos + s[:, None] * (d / L)[None, :])
        pos = tgt
    return np.vstack(rows)


def circle(center, radius, feed, a, Ts, jerk_time, turns=1.0, start_angle=0.0, ccw=True):
    """A circle (two axes) at path feed ``feed`` from standstill to standstill, starting and
    ending at ``center + radius (cos start_angle, sin start_angle)``.

    The feed is lowered so that the centripetal acceleration feed^2 / radius stays below ``a``.

    Returns
    -------
    ndarray (n, 2), mm
    """
    feed = min(feed, math.sqrt(0.7 * a * radius))
    L = 2 * math.pi * radius * turns
    s = Ts * np.cumsum(_pad(speed_profile(L, feed, 0.7 * a, Ts, jerk_time), 0.3, Ts))
    s *= L / s[-1]
    th = start_angle + (1 if ccw else -1) * s / radius
    return np.column_stack([center[0] + radius * np.cos(th), center[1] + radius * np.sin(th)])


def diamond(center, half_diagonal, feed, a, Ts, jerk_time):
    """A diamond (square rotated by 45 degrees, two axes): four straight moves with an exact stop
    at each corner, starting and ending at its right-hand corner.

    Returns
    -------
    ndarray (n, 2), mm
    """
    c = np.asarray(center, float)
    h = half_diagonal
    corners = [c + [h, 0], c + [0, h], c + [-h, 0], c + [0, -h], c + [h, 0]]
    return line_moves(corners[0], corners[1:], [feed] * 4, a, Ts, jerk_time, [0.05] * 4)
