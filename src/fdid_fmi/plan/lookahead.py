"""Look-ahead interpolation: no stop at tangent junctions (opt-in, ``corner_angle_deg``).

Imitated behaviour: a CNC that keeps the path velocity through a junction whose tangent
directions differ by at most ``corner_angle_deg`` (a tangent line-arc transition, a chain of
short collinear blocks) and stops exactly at every other corner (and at the end of every block the program
puts in exact stop: G61 / G61.1 in force, or G9 in the block); the path itself is never
blended (every sample lies on the programmed geometry). Per block the path velocity rises from
the junction velocity v_s to a peak and falls to v_e through jerk-limited symmetric transitions
(the tangential acceleration is zero at every block end, so it is continuous), with

* the junction velocity limited by both blocks' feeds and limits, by the velocity kink
  (a direction change theta in one sample: axis acceleration v theta / Ts and jerk
  v theta / Ts^2 within half the limits) and by the curvature jump |Delta kappa| (acceleration
  step v^2 |Delta kappa|, jerk v^2 |Delta kappa| / Ts within half the limits), and by what the
  blocks' lengths allow (a backward and a forward pass, as a look-ahead does);
* on arcs conservative analytic path limits that keep every axis within its limits whatever the
  tangential motion: V <= sqrt(a R / 2), V <= (j R^2 / 3)^(1/3), tangential acceleration
  <= min(a / 2, j R / (9 V)), tangential jerk <= j / 3 (axis acceleration <= a_t + v^2/R,
  axis jerk <= j_t + 3 v a_t / R + v^3 / R^2).

These caps do not count the tangential jerk a block still has at a junction (up to the axis
limit) on top of the kink and curvature-jump terms, nor that an arc's tangent peaks are measured
on chords. So the sampled commands are then measured (n-th finite differences, n = 1, 2, 3) and,
where an axis exceeds its v, a or j limit, the junction velocity there is lowered (down to an
exact stop) or, away from a junction, the block is slowed uniformly, until every sample is
within every limit (as :mod:`fdid_fmi.plan.interpolate` promises). A kinked junction (theta > 0)
then mostly ends in an exact stop; tangent junctions keep most of their velocity.

The timeline is continuous and sampled at k Ts (block ends need not fall on samples). After
every rapid (G0) the in-position wait of :class:`~fdid_fmi.plan.interpolate.InPosition` is kept
as in the exact-stop interpolation (the next block starts at the first sample, after the rapid's
end, at which every modelled axis is within the window); cutting blocks never wait.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .interpolate import AXES, Interpolation, _tangent_peaks, _wait_entry, in_position_info

_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


def _t_change(dv, A, J):
    """Duration of a symmetric jerk-limited velocity change by dv >= 0 (s)."""
    if dv <= 0:
        return 0.0
    return dv / A + A / J if dv >= A * A / J else 2.0 * math.sqrt(dv / J)


def _d_change(v1, v2, A, J):
    """Distance covered by that change from v1 to v2 (mm): the mean velocity times its time."""
    return 0.5 * (v1 + v2) * _t_change(abs(v2 - v1), A, J)


def _reach(v0, L, A, J, vcap):
    """Largest velocity <= vcap whose change from v0 fits in the distance L (a velocity below v0
    is returned as it is: slowing down is the other pass's concern)."""
    if vcap <= v0 or _d_change(v0, vcap, A, J) <= L:
        return vcap
    lo, hi = v0, vcap
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _d_change(v0, mid, A, J) <= L else (lo, mid)
    return lo


def _segments(v1, v2, A, J):
    """(duration, jerk) segments of the change v1 -> v2."""
    dv = v2 - v1
    if dv == 0:
        return []
    s = 1.0 if dv > 0 else -1.0
    dv = abs(dv)
    if dv >= A * A / J:
        tj, ta = A / J, dv / A - A / J
        return [(tj, s * J), (ta, 0.0), (tj, -s * J)]
    tj = math.sqrt(dv / J)
    return [(tj, s * J), (tj, -s * J)]


class _Profile:
    """Path parameter s(t) of one block: v_s -> v_peak -> v_e with a cruise."""

    def __init__(self, L, vs, ve, V, A, J):
        lo, hi = max(vs, ve), max(V, vs, ve)
        if _d_change(vs, hi, A, J) + _d_change(hi, ve, A, J) > L:
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if _d_change(vs, mid, A, J) + _d_change(mid, ve, A, J) <= L:
                    lo = mid
                else:
                    hi = mid
            vp = lo
        else:
            vp = hi
        d = _d_change(vs, vp, A, J) + _d_change(vp, ve, A, J)
        cruise = (L - d) / vp if vp > 0 else 0.0
        self.segs = _segments(vs, vp, A, J) + [(max(cruise, 0.0), 0.0)] + _segments(vp, ve, A, J)
        self.segs = [(t, j) for t, j in self.segs if t > 0]
        self.L, self.v0, self.v_peak = L, vs, vp
        self.duration = float(sum(t for t, _ in self.segs))
        n = len(self.segs)
        self.edges = np.concatenate(([0.0], np.cumsum([t for t, _ in self.segs])))
        self.s0, self.vv, self.a0 = np.zeros(n + 1), np.zeros(n + 1), np.zeros(n + 1)
        self.vv[0] = vs
        for i, (t, j) in enumerate(self.segs):
            self.a0[i + 1] = self.a0[i] + j * t
            self.vv[i + 1] = self.vv[i] + self.a0[i] * t + j * t * t / 2
            self.s0[i + 1] = self.s0[i] + self.vv[i] * t + self.a0[i] * t * t / 2 + j * t ** 3 / 6
        self.jj = np.array([j for _, j in self.segs] + [0.0])

    def s(self, tau):
        tau = np.clip(np.asarray(tau, float), 0.0, self.duration)
        if not self.segs:
            return np.zeros_like(tau)
        k = np.clip(np.searchsorted(self.edges, tau, side="right") - 1, 0, len(self.segs) - 1)
        x = tau - self.edges[k]
        s = self.s0[k] + self.vv[k] * x + self.a0[k] * x * x / 2 + self.jj[k] * x ** 3 / 6
        return np.clip(s, 0.0, self.L)


def _block_limits(b, limits, override):
    """Path (V, A, J) of a block (see module docstring)."""
    u = _tangent_peaks(b)
    V, A, J = b.feed * override, math.inf, math.inf
    for i, ax in enumerate(AXES):
        if u[i] > 1e-12:
            lim = limits.get(ax)
            if lim is None:
                raise InputError(f"line {b.line} moves axis {ax.upper()} but no limits are given for it",
                                 column="--limits")
            V, A, J = min(V, lim.v / u[i]), min(A, lim.a / u[i]), min(J, lim.j / u[i])
    if b.kind == "arc":
        i, j, _ = _PLANES[b.plane]
        amin = min(limits[AXES[i]].a, limits[AXES[j]].a)
        jmin = min(limits[AXES[i]].j, limits[AXES[j]].j)
        R = min(b.r0, b.r1)
        V = min(V, math.sqrt(amin * R / 2), (jmin * R * R / 3) ** (1 / 3))
        A = min(A, amin / 2, jmin * R / (9 * V))
        J = min(J, jmin / 3)
    return V, A, J


def _ends(b):
    """Unit tangents (3,) at the start and end and curvature vectors (3,) there."""
    if b.kind == "line":
        u = (b.end - b.start) / b.length
        return u, u, np.zeros(3), np.zeros(3)
    eps = 1e-4 * b.length
    p = b.point(np.array([0.0, eps, 2 * eps, b.length - 2 * eps, b.length - eps, b.length]))
    t0 = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    t1 = (p[5] - p[4]) / np.linalg.norm(p[5] - p[4])
    i, j, _ = _PLANES[b.plane]
    R = 0.5 * (b.r0 + b.r1)
    k0, k1 = np.zeros(3), np.zeros(3)
    for kv, q in ((k0, p[0]), (k1, p[5])):
        d = b.center - q
        d[_PLANES[b.plane][2]] = 0.0
        kv[:] = d / np.linalg.norm(d) / R
    return t0, t1, k0, k1


_MAX_REPAIRS = 200


def _passes(caps, lim, blocks):
    """Junction velocities: the caps, lowered by what each block's length allows (a backward and
    a forward pass, as a look-ahead does)."""
    vj = np.array(caps, float)
    n = len(blocks)
    for k in range(n - 1, 0, -1):
        if lim[k] is not None:
            V, A, J = lim[k]
            vj[k - 1] = min(vj[k - 1], _reach(vj[k], blocks[k].length, A, J, vj[k - 1]))
    v_in = 0.0
    for k in range(n):
        if lim[k] is not None:
            V, A, J = lim[k]
            vj[k] = min(vj[k], _reach(v_in, blocks[k].length, A, J, vj[k]))
            v_in = vj[k]
        else:
            vj[k] = 0.0
            v_in = 0.0
    return vj


def _sample(blocks, items, N, Ts, k_from=0):
    """Positions (N - k_from, 3), owners and spans of the timeline's items at k Ts,
    k_from <= k < N (``k_from`` > 0: ``items`` need only start with the one holding k_from)."""
    t = np.arange(k_from, N) * Ts
    P = np.repeat(blocks[0].start[None, :], N - k_from, axis=0)
    owner = np.full(N - k_from, -1, int)
    spans = []
    for ts, dur, prof, b in items:
        k0 = int(math.floor(ts / Ts + 1e-9))
        k1 = int(math.floor((ts + dur) / Ts + 1e-9))
        sel = slice(max(k0 + 1, k_from) - k_from, max(min(k1, N - 1) + 1 - k_from, 0))
        if prof is not None and k1 > k0:
            P[sel] = b.point(prof.s(t[sel] - ts))      # tau beyond the profile: its end point
        elif k1 > k0:
            P[sel] = b.end
        owner[sel] = b.index
        spans.append((k0, k1))
    return t, P, owner, spans


def _timeline(blocks, lim, vj, Ts, lead_in, settle, in_position=None, waits=None, notes=None):
    """Sampled positions of the continuous timeline: (t, P, owner, spans, items). With
    ``in_position``, the next block after a rapid starts at the first sample after the rapid's
    end at which every axis is within the window (``waits``, ``notes``: filled)."""
    t0 = lead_in
    items = []
    v_in = 0.0
    settling = in_position.tracker(Ts) if in_position is not None else None
    i_from = 0
    for k, b in enumerate(blocks):
        if b.kind == "dwell":
            items.append((t0, b.block_time, None, b))
            t0 += b.block_time
            v_in = 0.0
            continue
        if lim[k] is None:
            items.append((t0, 0.0, None, b))
        else:
            V, A, J = lim[k]
            prof = _Profile(b.length, v_in, vj[k], V, A, J)
            items.append((t0, prof.duration, prof, b))
            t0 += prof.duration
            v_in = vj[k]
        if in_position is not None and b.kind == "rapid" and k < len(blocks) - 1:
            # the end point is first commanded at the sample after the rapid's end (k_e): the
            # commands up to k_e, then held until every axis is within the window
            k_e = int(math.floor(t0 / Ts + 1e-9)) + 1
            # the samples since the last wait only, from the item holding them (the tracker has
            # stepped the earlier ones)
            _, P0, _, _ = _sample(blocks, items[i_from:], k_e + 1, Ts, k_from=settling.k)
            P0[-1] = b.end
            w, residual = settling.wait(P0, start=settling.k)
            i_from = len(items) - 1
            ts, t_end = items[-1][0], t0
            t0 = max(t0, (k_e + w) * Ts)
            items[-1] = (ts, t0 - ts) + items[-1][2:]
            v_in = 0.0
            waits.append(dict(_wait_entry(b, w, residual, Ts), wait_s=t0 - t_end))
            note = in_position.describe(b, w, residual, Ts)
            if note:
                notes.append(note)
    t_end = t0
    N = int(math.floor((t_end + settle) / Ts)) + 1
    t, P, owner, spans = _sample(blocks, items, N, Ts)
    owner[spans[-1][1] + 1:] = blocks[-1].index
    P[spans[-1][1] + 1:] = blocks[-1].end
    return t, P, owner, spans, items


def _over_limits(P, limits, Ts):
    """Where the sampled commands exceed an axis limit: (order n, first sample m, |d|/limit) of
    every n-th finite difference (n = 1, 2, 3: v, a, j) above its limit by more than the
    rounding of an n-th difference of these positions."""
    out = []
    scale = float(np.abs(P).max()) if P.size else 0.0
    for i, ax in enumerate(AXES):
        lim = limits.get(ax)
        if lim is None:
            continue
        for order, bound in ((1, lim.v), (2, lim.a), (3, lim.j)):
            d = np.abs(np.diff(P[:, i], n=order)) / Ts ** order
            rounding = 2 ** order * np.finfo(float).eps * scale / Ts ** order
            for m in np.flatnonzero(d > bound + rounding):
                out.append((order, int(m), float(d[m] / bound)))
    return out


def interpolate_lookahead(program, limits, Ts, corner_angle_deg, overrides=None, lead_in=0.05, settle=0.5,
                          in_position=None):
    """Commanded positions with no stop at junctions within ``corner_angle_deg`` (module docstring;
    ``in_position``: the wait after every rapid, as :func:`~fdid_fmi.plan.interpolate.interpolate`).

    Returns
    -------
    Interpolation (same fields as :func:`~fdid_fmi.plan.interpolate.interpolate`)
    """
    if not (corner_angle_deg >= 0):
        raise InputError(f"corner angle must be >= 0 deg, got {corner_angle_deg!r}", column="--corner-angle")
    overrides = overrides or {}
    blocks = program.blocks
    n = len(blocks)
    lim = [None] * n
    for k, b in enumerate(blocks):
        if b.kind in ("line", "arc", "rapid") and b.length > 0:
            lim[k] = _block_limits(b, limits, float(overrides.get(b.index, 1.0)))
    used = [a for a in program.axes_used if a in limits] or list(limits)
    amin = min(limits[a].a for a in used)
    jmin = min(limits[a].j for a in used)
    # junction caps: vj[k] is the velocity at the end of block k
    vj = np.zeros(n)
    for k in range(n - 1):
        b, c = blocks[k], blocks[k + 1]
        if (lim[k] is None or lim[k + 1] is None or b.kind == "rapid" or c.kind == "rapid"
                or b.exact_stop):       # G61 / G61.1 in force, or G9: the block ends at rest
            continue
        _, t1, _, k1 = _ends(b)
        t0, _, k0, _ = _ends(c)
        theta = math.acos(max(-1.0, min(1.0, float(t1 @ t0))))
        if math.degrees(theta) > corner_angle_deg:
            continue
        cap = min(lim[k][0], lim[k + 1][0])
        dk = float(np.linalg.norm(k1 - k0))
        if theta > 1e-12:
            cap = min(cap, 0.5 * amin * Ts / theta, 0.5 * jmin * Ts * Ts / theta)
        if dk > 1e-12:
            cap = min(cap, math.sqrt(0.5 * jmin * Ts / dk), math.sqrt(0.5 * amin / dk))
        vj[k] = cap
    # build, then measure: where the sampled axis v/a/j exceed a limit (the tangential jerk of
    # the blocks adds to a junction's kink or curvature-jump terms; an arc's tangent peaks are
    # measured on chords), lower that junction's velocity (to an exact stop at worst) or, away
    # from a junction, slow the block down uniformly; repeat until every limit holds
    caps = vj.copy()
    caps0 = vj.copy()
    for _ in range(_MAX_REPAIRS):
        vj = _passes(caps, lim, blocks)
        waits, notes = [], []
        t, P, owner, spans, items = _timeline(blocks, lim, vj, Ts, lead_in, settle, in_position, waits, notes)
        over = _over_limits(P, limits, Ts)
        if not over:
            break
        ends = np.array([ts + dur for ts, dur, _, _ in items[:-1]])    # junction times, sorted
        junctions, slow = {}, {}
        for order, m, ratio in over:
            k_lo, k_hi = np.searchsorted(ends, [(m - 1) * Ts, (m + order + 1) * Ts], side="left")
            near = [k for k in range(k_lo, min(k_hi + 1, n - 1)) if caps[k] > 0
                    and (m - 1) * Ts <= ends[k] <= (m + order + 1) * Ts]
            if near:
                for k in near:
                    junctions[k] = max(junctions.get(k, 0.0), ratio)
                continue
            for k in set(owner[m:m + order + 1].tolist()) - {-1}:
                if lim[k] is not None:
                    slow[k] = min(slow.get(k, 1.0), 0.999 * ratio ** (-1.0 / order))
        for k, ratio in junctions.items():
            caps[k] = (0.8 if ratio < 1.1 else 0.5) * caps[k] if caps[k] > 0.02 * caps0[k] else 0.0
        for k, f in slow.items():
            V, A, J = lim[k]
            lim[k] = (V * f, A * f * f, J * f ** 3)
    else:
        raise InputError("the look-ahead interpolation cannot keep the axis limits; interpolate "
                         "with an exact stop at every block end (no corner angle)", column="--corner-angle")
    N = P.shape[0]
    path_s = np.zeros(N)
    s0 = 0.0
    for b, (k0, k1) in zip(blocks, spans):
        if k1 > k0 and b.kind != "dwell" and b.length > 0:
            seg = np.linalg.norm(np.diff(P[k0:k1 + 1], axis=0), axis=1)
            cs = np.cumsum(seg)
            path_s[k0 + 1:k1 + 1] = s0 + (b.length * cs / cs[-1] if cs[-1] > 0 else 0.0)
            s0 += b.length
        else:
            path_s[k0 + 1:k1 + 1] = s0
    path_s[spans[-1][1] + 1:] = s0
    first = next((k0 for k0, k1 in spans if k1 > k0), spans[0][0])
    return Interpolation(t=t, positions={a: P[:, i].copy() for i, a in enumerate(AXES)}, Ts=Ts,
                         block_of_sample=owner, spans=spans, path_s=path_s,
                         cycle_time=(spans[-1][1] - first) * Ts,
                         info={"corner_rule": f"no stop at junctions within {corner_angle_deg:g} deg "
                                              f"(tangent), exact stop at sharper corners, no blending",
                               "limits": {a: vars(l) for a, l in limits.items()},
                               "junction_velocity_mm_s": vj.tolist(), "lead_in_s": lead_in,
                               "settle_s": settle, **in_position_info(in_position, waits, notes)})
