"""Coupling to another axis's motion or to an available but unused channel (e.g. EMPS ``pulses_N``).

Candidates: the commanded position of every other axis of the trace (kind ``coupling``) and every
extra channel the model does not use (kind ``extra_input``), minus ``settings["exclude"]``.

Exogeneity: a channel that follows this axis's own command (a controller output, a motor current,
a derived velocity) is a loop signal, not an input: using it would feed the measurement back into
the model. A channel is skipped when the command's regressors (x_r, v, a, j) explain more than
``MAX_FOLLOW`` of its variance (R^2), and the report says so.

Statistic: R^2 of the residual on the candidate's regressors phi_l = s^(n-l)/P(s) c (the same
Tustin filters, with the model's own denominator P, that the refit uses; for another axis's
position all terms but the d.c. one), i.e. the multiple correlation of the residual with the
candidate signal as the model would carry it.

Threshold: ``thresholds.THRESHOLDS["channel"]`` (both kinds; calibrated on the plant family's
clean calibration cases that have such a channel). Measured on thesis-path models: virtual clean
up to 0.001, its 0.02 kg coupling 0.27; plant2 clean up to 0.018 (9 runs), its 25 kg coupling
0.195; EMPS ``pulses_N`` 0.999. On the family's clean cases another axis's command, moved with
this one's, explains up to half of the residual; a coupling that reads less is tried below the
threshold when the held-out residual is structured (:mod:`.loop`).
"""
from __future__ import annotations

from functools import partial

import numpy as np

from ..identify import regressors as rg
from . import augment as ag
from .base import Candidate
from .thresholds import threshold

MAX_FOLLOW = 0.9


def _fit_r2(y, X):
    X = np.column_stack([X, np.ones(len(y))])
    scale = np.maximum(np.max(np.abs(X), axis=0), 1e-300)
    Xs = X / scale
    th, *_ = np.linalg.lstsq(Xs, y, rcond=None)
    e = y - Xs @ th
    yc = y - np.mean(y)
    return 1.0 - float(e @ e) / max(float(yc @ yc), 1e-300)


def _regressors(c, a_poly, Ts, ls):
    den, F = rg.tustin_basis(np.asarray(a_poly, float), Ts)
    n = len(a_poly) - 1
    W = np.asarray(c, float)[None, :]
    R = rg.allpole_filter(den, W - W[:, :1], np.zeros(1), np.zeros(1))
    return rg.regressors(R, F[list(ls)], n)[0].T


def _follows_command(c, cmd, Ts):
    v = np.gradient(cmd, Ts)
    acc = np.gradient(v, Ts)
    jerk = np.gradient(acc, Ts)
    return _fit_r2(np.asarray(c, float), np.column_stack([cmd, v, acc, jerk, np.sign(v)]))


def candidates(trace, model, exclude=()):
    """[(channel, kind, source axis or None)] not used by the model."""
    used = {p.params.get("channel") for p in model.inputs if p.kind == "external"}
    out = []
    for b in trace.axes:
        if b in model.axes or not trace.has(b, "cmd"):
            continue
        ch = trace.roles[b]["cmd"]
        if ch not in used and ch not in exclude:
            out.append((ch, "coupling", b))
    for ch in trace.extra_channels:
        if ch in used or ch in exclude or ch.endswith("_vel_model"):
            continue
        out.append((ch, "extra_input", None))
    return out


def _prepare(cand, recipe, a, ch, kind, extra, powers):
    cand.recipe = ag.add_external(recipe, a, ch, kind, extra, powers=powers)


def detect(ctx):
    out = []
    a_poly = ctx.model.identification.get("denominator")
    if a_poly is None:
        return out
    n = len(a_poly) - 1
    exclude = set(ctx.settings.get("exclude", ()))
    tr0 = ctx.res[0].trace
    for a in ctx.model.axes:
        for ch, kind, src in candidates(tr0, ctx.model, exclude):
            ys, Xs, follow = [], [], []
            ls = list(range(0, n)) if kind == "coupling" else list(range(0, n + 1))
            for res in ctx.res:
                c = res.trace.extra(ch) if ch in res.trace.channels else None
                if c is None:
                    break
                if np.ptp(c) <= 0:
                    break
                ar = res.axes[a]
                follow.append(_follows_command(c, ar.cmd, ctx.Ts))
                ys.append(ar.residual - np.mean(ar.residual))
                Xs.append(_regressors(c, a_poly, ctx.Ts, ls))
            if not ys:
                continue
            f = float(max(follow))
            r2 = _fit_r2(np.concatenate(ys), np.concatenate(Xs))
            params = {"channel": ch}
            if src:
                params["source_axis"] = src
            cand = Candidate(kind, a, r2, threshold(kind, ctx.settings), params=params, evidence={"follows_command_r2": f},
                             note=f"R^2 of the residual on the filtered channel '{ch}'")
            if f > MAX_FOLLOW:
                cand.threshold = float("inf")
                cand.note += (f"; skipped: the axis command explains {f:.0%} of it (a loop signal, "
                              f"not an independent input)")
            if np.isfinite(cand.threshold):     # a loop signal is never tried
                extra = {"source_axis": src} if src else {}
                cand.prepare = partial(_prepare, cand, ctx.recipe, a, ch, kind, extra, [n - l for l in ls])
            if cand.detected:
                cand.prepare()
            out.append(cand)
    return out
