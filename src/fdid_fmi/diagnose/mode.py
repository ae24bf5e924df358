"""An unmodelled lightly damped mode: a residual spectral peak coherent with the command.

The residual's response to the command, H(f) = S_ra(f) / S_aa(f) (Welch H1 estimate, the
residual r against the commanded acceleration a), is a smooth function of frequency when the
model has all the command's dynamics; an unmodelled mode adds a resonance peak. Statistic: the
largest ratio |H(f)| / background(f) (background: running median of |H| over +-``MEDIAN_HZ``)
between ``F_LO`` and 0.4 / Ts among the frequencies where the magnitude-squared coherence of r
with a is at least ``MIN_COHERENCE`` (the peak must come from the command, not from noise).
Parameter: the peak frequency (parabolic interpolation of log|H|); the augmentation searches one
more complex pole pair within +-15 % of it (damping 0.005-0.5) with the other poles in a local
window; the fitted pair's frequency and damping are reported.

Threshold ``PEAK_RATIO`` (calibration on clean virtual-drive runs, ``examples/diagnose_calibrate.py``):
clean ratios up to about 3.5.
"""
from __future__ import annotations

import numpy as np
from scipy import signal
from scipy.ndimage import median_filter

from . import augment as ag
from .base import Candidate

F_LO = 8.0
MEDIAN_HZ = 15.0
MIN_COHERENCE = 0.3
PEAK_RATIO = 6.0


def transfer_to_residual(r, cmd, Ts, nperseg=None):
    """(f, |H|, coherence) of the residual against the commanded acceleration."""
    a = np.gradient(np.gradient(np.asarray(cmd, float), Ts), Ts)
    r = np.asarray(r, float)
    n = r.size
    nperseg = nperseg or int(min(1024, 2 ** np.floor(np.log2(max(64, n // 6)))))
    f, Pra = signal.csd(a, r, fs=1 / Ts, nperseg=nperseg)
    _, Paa = signal.welch(a, fs=1 / Ts, nperseg=nperseg)
    _, Prr = signal.welch(r, fs=1 / Ts, nperseg=nperseg)
    H = np.abs(Pra) / np.maximum(Paa, 1e-300)
    coh = np.abs(Pra) ** 2 / np.maximum(Paa * Prr, 1e-300)
    return f, H, coh


def detect(ctx):
    out = []
    for a in ctx.model.axes:
        res = max(ctx.res, key=lambda r: r.axes[a].residual.size)
        ar = res.axes[a]
        f, H, coh = transfer_to_residual(ar.residual, ar.cmd, ctx.Ts)
        df = f[1] - f[0]
        k = max(3, int(round(MEDIAN_HZ / df)))
        logH = np.log(np.maximum(H, 1e-300))
        bg = median_filter(logH, size=2 * k + 1, mode="nearest")
        band = (f >= F_LO) & (f <= 0.4 / ctx.Ts) & (coh >= MIN_COHERENCE)
        ratio, fpk = 0.0, float("nan")
        if band.any():
            rel = np.where(band, logH - bg, -np.inf)
            i = int(np.argmax(rel))
            ratio = float(np.exp(rel[i]))
            fpk = float(f[i])
            if 0 < i < f.size - 1:
                y0, y1, y2 = logH[i - 1], logH[i], logH[i + 1]
                d = y0 - 2 * y1 + y2
                if d < 0:
                    fpk = float(f[i] + 0.5 * (y0 - y2) / d * df)
        cand = Candidate("mode", a, ratio, PEAK_RATIO, params={"peak_hz": fpk},
                         evidence={"coherence_at_peak": float(np.interp(fpk, f, coh)) if np.isfinite(fpk) else 0.0},
                         plot={"f_hz": f, "H": H, "background": np.exp(bg), "coherence": coh},
                         note="peak of |residual / commanded acceleration| over its running median")
        if cand.detected:
            cand.recipe = ag.add_mode(ctx.recipe, a, fpk)
        out.append(cand)
    return out
