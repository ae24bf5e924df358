"""A position-periodic disturbance (ball-screw pitch, cogging): the residual's spectrum over
POSITION, not time.

During constant-velocity motion (|a_cmd| < 2 % of its peak, |v_cmd| > 10 % of its peak, the
first ``SETTLE_S`` after each acceleration dropped) the residual is resampled onto a uniform grid
of the measured position (step = the smallest |v| Ts of the segments) and detrended per segment.
Its power over spatial frequency kappa (1/mm) is summed over segments incoherently (the loop
changes the phase with the speed): P(kappa) = sum_seg |sum_j r_j exp(-2 pi i kappa x_j)|^2 / N.
Statistic: the peak of P over its running median (wavelengths from 4 grid steps to half the
longest segment). Parameter: lambda = 1 / kappa_peak, refined by the LS objective of the refit
with sin/cos(2 pi x / lambda) inputs and the poles fixed, scanned over +-12 % of the peak in 0.2 %
steps with a parabolic refinement (the phase coherence over the whole record makes this sharp).

Threshold: ``thresholds.THRESHOLDS["periodic_position"]`` (a 5 % false-alarm rate on the plant
family's clean calibration cases). Measured on thesis-path models: virtual clean up to 6.30, its
40 N / 5 mm force 140; plant2 clean up to 6.74 (9 runs), its 40 N / 5 mm force 208.
"""
from __future__ import annotations

from functools import partial

import numpy as np
from scipy.ndimage import median_filter

from . import augment as ag
from .base import Candidate, scan_refine
from .thresholds import threshold

SETTLE_S = 0.03


def constant_velocity_segments(cmd, Ts, settle_s=SETTLE_S):
    """Index ranges (start, stop) of constant commanded velocity."""
    v = np.gradient(np.asarray(cmd, float), Ts)
    acc = np.gradient(v, Ts)
    vmax, amax = np.max(np.abs(v)), np.max(np.abs(acc))
    if vmax <= 0:
        return []
    ok = (np.abs(v) > 0.1 * vmax) & (np.abs(acc) <= 0.02 * max(amax, 1e-12))
    settle = int(round(settle_s / Ts))
    segs = []
    k, n = 0, ok.size
    while k < n:
        if ok[k]:
            j = k
            while j < n and ok[j] and np.sign(v[j]) == np.sign(v[k]):
                j += 1
            a, b = k + settle, j
            if b - a > 10:
                segs.append((a, b))
            k = j
        else:
            k += 1
    return segs


def position_spectrum(pairs, max_fft=2 ** 16):
    """(kappa 1/mm, P, dx) from [(position, residual) per segment].

    Each segment is resampled onto a uniform position grid of step dx (the smallest median step
    of the segments, enlarged if the longest segment would need more than ``max_fft / 4`` points),
    detrended, zero-padded to a common FFT length and its |FFT|^2 summed over segments.
    """
    dx = np.inf
    for x, r in pairs:
        step = np.median(np.abs(np.diff(x)))
        if step > 0:
            dx = min(dx, step)
    if not np.isfinite(dx):
        return np.array([]), np.array([]), dx
    L = max((np.ptp(x) for x, _ in pairs), default=0.0)
    dx = max(dx, 4.0 * L / max_fft)
    resampled = []
    for x, r in pairs:
        o = np.argsort(x)
        xs, rs = x[o], r[o]
        if xs[-1] - xs[0] < 10 * dx:
            continue
        g = np.arange(xs[0], xs[-1], dx)
        rg = np.interp(g, xs, rs)
        rg = rg - np.polyval(np.polyfit(g - g.mean(), rg, 1), g - g.mean())
        resampled.append(rg)
    if not resampled:
        return np.array([]), np.array([]), dx
    nmax = max(r.size for r in resampled)
    nfft = int(2 ** np.ceil(np.log2(4 * nmax)))
    P = np.zeros(nfft // 2 + 1)
    for rg in resampled:
        P += np.abs(np.fft.rfft(rg, nfft)) ** 2
    kap = np.fft.rfftfreq(nfft, dx)
    keep = (kap >= 2.0 / (nmax * dx)) & (kap <= 1.0 / (4 * dx))
    N = sum(r.size for r in resampled)
    return kap[keep], P[keep] / N, dx


def detect(ctx):
    out = []
    gate = threshold("periodic_position", ctx.settings)
    for a in ctx.model.axes:
        pairs = []
        for res in ctx.res:
            ar = res.axes[a]
            for i, j in constant_velocity_segments(ar.cmd, ctx.Ts):
                pairs.append((ar.measured[i:j], ar.residual[i:j]))
        kap, P, dx = position_spectrum(pairs)
        if kap.size < 8:
            why = "too little constant-velocity motion for a position spectrum"
            out.append(Candidate("periodic_position", a, 0.0, gate, note=why,
                                 evidence={"segments": len(pairs)}, not_checked=f"the training trace has {why}"))
            continue
        bg = median_filter(P, size=max(9, kap.size // 8) | 1, mode="nearest")
        rel = P / np.maximum(bg, 1e-300)
        i = int(np.argmax(rel))
        lam0 = float(1.0 / kap[i])
        cand = Candidate("periodic_position", a, float(rel[i]), gate,
                         params={"peak_period_mm": lam0, "segments": len(pairs)},
                         plot={"wavelength_mm": 1.0 / kap, "power": P, "background": bg},
                         note="peak of the residual's power over position-wavenumber over its median")
        cand.prepare = partial(_prepare, cand, ctx, a, lam0)
        if cand.detected:
            cand.prepare()
        out.append(cand)
    return out


def _prepare(cand, ctx, a, lam0):
    lam = _refine(ctx, a, lam0)
    cand.params["period_mm"] = lam
    cand.recipe = ag.add_periodic(ctx.recipe, a, lam)


def _refine(ctx, a, lam0):
    xs = lam0 * np.exp(np.arange(-0.12, 0.1201, 0.002))

    def J(lam):
        return ag.fit_objective(ag.add_periodic(ctx.recipe, a, lam), ctx.train, search="locked",
                                refine=False)

    best, _ = scan_refine(J, xs)
    return float(best)
