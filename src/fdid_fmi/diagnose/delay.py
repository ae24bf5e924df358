"""A dead time between command and measurement: lagged cross-correlation, and the prediction
improved by a k-sample shift of the command.

Evidence 1 (reported): the lag of the peak cross-correlation between the residual and the
commanded velocity (a measurement that lags by d samples leaves r ~ -d Ts v).
Evidence 2 (the statistic): the model is refitted (pole search over the engine's default space,
the dead time moves the poles far) on the command delayed by k = 0..``MAX_DELAY`` samples; J_k is
the fit objective. k* is the SMALLEST k whose J_k is within ``TIE`` (5 %) of the best: a 3rd-order
model mimics part of a dead time with its poles, so J_k is flat near its minimum and the smallest
shift that explains the data is the estimate. Statistic: J_0 / J_k* (1 when no shift helps).

Threshold ``RATIO`` (calibration on clean virtual-drive runs, ``examples/diagnose_calibrate.py``):
clean runs give k* = 0 (statistic 1.0) or a ratio below 1.05 by construction of the tie rule.
"""
from __future__ import annotations

import numpy as np

from . import augment as ag
from .base import Candidate, command_velocity

MAX_DELAY = 8
TIE = 0.05
RATIO = 1.08


def xcorr_lag(r, v, max_lag):
    """Lag (samples) of the peak |cross-correlation| of r with v (positive: r lags v)."""
    r = np.asarray(r, float) - np.mean(r)
    v = np.asarray(v, float) - np.mean(v)
    best, lag = 0.0, 0
    nr = np.sqrt(np.sum(r * r) * np.sum(v * v))
    if nr == 0:
        return 0, 0.0
    for k in range(-max_lag, max_lag + 1):
        c = np.sum(r[k:] * v[:v.size - k]) if k >= 0 else np.sum(r[:k] * v[-k:])
        if abs(c) > abs(best):
            best, lag = c, k
    return lag, float(best / nr)


def detect(ctx):
    out = []
    kmax = int(ctx.settings.get("max_delay", MAX_DELAY))
    maxiter = int(ctx.settings.get("maxiter", 25))
    for a in ctx.model.axes:
        ar = ctx.res[0].axes[a]
        lag, rho = xcorr_lag(ar.residual, command_velocity(ar.cmd, ctx.Ts), kmax)
        J = []
        for k in range(0, kmax + 1):
            rec = ag.add_delay(ctx.recipe, a, k) if k else ctx.recipe
            m = ag.fit(rec, ctx.train, search="wide", maxiter=maxiter, refine=False)
            J.append(m.metrics["objective_scaled_rms"])
        J = np.array(J)
        ok = np.flatnonzero(J <= (1 + TIE) * J.min())
        k_star = int(ok[0])
        stat = float(J[0] / J[k_star]) if k_star else 1.0
        cand = Candidate("delay", a, stat, RATIO, params={"samples": k_star},
                         evidence={"objective_by_shift": J.tolist(), "xcorr_peak_lag": int(lag),
                                   "xcorr_peak": rho},
                         plot={"shift": np.arange(kmax + 1), "objective": J}, search="wide",
                         note="fit objective without / with the smallest good command shift")
        if cand.detected:
            cand.recipe = ag.add_delay(ctx.recipe, a, k_star)
        out.append(cand)
    return out
