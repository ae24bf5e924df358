"""An unmodelled lightly damped mode: a residual spectral peak coherent with the command.

The residual's response to the command, H(f) = S_ra(f) / S_aa(f) (Welch H1 estimate, the
residual r against the commanded acceleration a, 512-sample segments), is analysed between
``F_LO`` and 0.4 / Ts where the command has energy (S_aa >= 1e-4 max S_aa).

Statistic: the fraction of those frequencies where the magnitude-squared coherence of r with a
is at least ``MIN_COHERENCE`` -- a residual that follows the command through dynamics the model
lacks. (Measurement noise shaped by the loop makes the residual's own spectrum peak near the
velocity-loop bandwidth even for a perfect model; it is not coherent with the command, so the
coherence, not the residual spectrum, is the evidence.) Parameter: the frequency of the largest
ratio |H(f)| / background(f) (running median of |H| over +-``MEDIAN_HZ``) among the coherent
frequencies, parabola-refined. The augmentation searches one more complex pole pair within
+-15 % of it (damping 0.005-0.5) with the other poles in a local window, every numerator
multiplied by a quadratic (the drive train's anti-resonance, ``augment._times_quadratic``); the
fitted pair's frequency and damping are reported, and it is kept only as a resonance
(``base.MODE_MAX_DAMPING``). A dead time also leaves a command-coherent residual: the two
candidates are both refitted and the better one on training data is tried first (loop.py).

Threshold: ``thresholds.THRESHOLDS["mode"]`` (a 5 % false-alarm rate on the plant family's
clean calibration cases). Measured on thesis-path models of the two plants the project wrote:
virtual clean runs up to 0.225, its 54 Hz mode 0.39; plant2's 52 Hz mode 0.34, its 38 Hz
tool-side mode 0.29, one of its clean runs 0.42, its delay 0.28: the statistic does not separate
modes from clean runs there, and below the threshold the loop's trials and the held-out criterion
decide (:mod:`.loop`).
"""
from __future__ import annotations

from functools import partial

import numpy as np
from scipy import signal
from scipy.ndimage import median_filter

from . import augment as ag
from .base import Candidate
from .thresholds import threshold

F_LO = 8.0
MEDIAN_HZ = 15.0
MIN_COHERENCE = 0.5


def transfer_to_residual(r, cmd, Ts, nperseg=None):
    """(f, |H|, coherence) of the residual against the commanded acceleration."""
    a = np.gradient(np.gradient(np.asarray(cmd, float), Ts), Ts)
    r = np.asarray(r, float)
    n = r.size
    nperseg = nperseg or int(min(512, 2 ** np.floor(np.log2(max(64, n // 6)))))
    f, Pra = signal.csd(a, r, fs=1 / Ts, nperseg=nperseg)
    _, Paa = signal.welch(a, fs=1 / Ts, nperseg=nperseg)
    _, Prr = signal.welch(r, fs=1 / Ts, nperseg=nperseg)
    H = np.abs(Pra) / np.maximum(Paa, 1e-300)
    coh = np.abs(Pra) ** 2 / np.maximum(Paa * Prr, 1e-300)
    return f, H, coh, Paa


def _prepare(cand, recipe, a, fpk):
    cand.recipe = ag.add_mode(recipe, a, fpk)


def detect(ctx):
    out = []
    for a in ctx.model.axes:
        res = max(ctx.res, key=lambda r: r.axes[a].residual.size)
        ar = res.axes[a]
        f, H, coh, Paa = transfer_to_residual(ar.residual, ar.cmd, ctx.Ts)
        df = f[1] - f[0]
        k = max(3, int(round(MEDIAN_HZ / df)))
        logH = np.log(np.maximum(H, 1e-300))
        bg = median_filter(logH, size=2 * k + 1, mode="nearest")
        band = (f >= F_LO) & (f <= 0.4 / ctx.Ts) & (Paa >= 1e-4 * np.max(Paa)) & (Paa > 0)
        coherent = band & (coh >= MIN_COHERENCE)
        frac = float(coherent.sum() / max(band.sum(), 1))
        ratio, fpk = 0.0, float("nan")
        if coherent.any():
            rel = np.where(coherent, logH - bg, -np.inf)
            i = int(np.argmax(rel))
            ratio = float(np.exp(rel[i]))
            fpk = float(f[i])
            if 0 < i < f.size - 1:
                y0, y1, y2 = logH[i - 1], logH[i], logH[i + 1]
                d = y0 - 2 * y1 + y2
                if d < 0:
                    fpk = float(f[i] + 0.5 * (y0 - y2) / d * df)
        cand = Candidate("mode", a, frac, threshold("mode", ctx.settings), params={"peak_hz": fpk},
                         evidence={"peak_ratio": ratio, "coherent_bins": int(coherent.sum()),
                                   "analysed_bins": int(band.sum())},
                         plot={"f_hz": f, "H": H, "background": np.exp(bg), "coherence": coh},
                         note="fraction of the command band where the residual is coherent with the "
                              "commanded acceleration; peak of |residual / acceleration|")
        if not band.any():
            cand.not_checked = (f"the command has no energy between {F_LO:g} Hz and 0.4 / Ts "
                                f"({0.4 / ctx.Ts:g} Hz) at the spectral resolution of this trace "
                                f"({df:.3g} Hz)")
        if np.isfinite(fpk) and not cand.not_checked:
            cand.prepare = partial(_prepare, cand, ctx.recipe, a, fpk)
            if cand.detected:
                cand.prepare()
        out.append(cand)
    return out
