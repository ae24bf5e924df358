"""Residual whiteness and input cross-correlation tests, with confidence bands, for whatever is
left after augmentation (reported, not augmented: they say THAT something is left, not what).

Autocorrelation rho_rr(k), k = 1..M, and cross-correlation rho_ru(k), k = -M..M, of the residual
with the commanded velocity u; the 99 % band of an uncorrelated pair is +-2.58 / sqrt(N) (the
Box-Jenkins test MATLAB's ``resid`` draws). The summary is the fraction of lags outside the band
(about 1 % for white noise) and the largest |rho|. A free-run residual is rarely white (sensor
noise is, but slow model errors are not), so these numbers describe rather than decide.
"""
from __future__ import annotations

import numpy as np

Z99 = 2.58


def correlation_tests(r, u, max_lag=50):
    r = np.asarray(r, float) - np.mean(r)
    u = np.asarray(u, float) - np.mean(u)
    N = r.size
    max_lag = max(0, min(int(max_lag), N - 1))      # no lag beyond the record
    band = Z99 / np.sqrt(N)
    rr = float(r @ r)
    uu = float(u @ u)
    lags = np.arange(1, max_lag + 1)
    acf = np.array([float(r[k:] @ r[:-k]) / rr if rr > 0 else 0.0 for k in lags])
    xl = np.arange(-max_lag, max_lag + 1)
    den = np.sqrt(rr * uu) if rr > 0 and uu > 0 else 1.0
    xcf = np.array([float(r[k:] @ u[:N - k]) / den if k >= 0 else float(r[:k] @ u[-k:]) / den for k in xl])
    return {
        "band": band,
        "acf_lags": lags, "acf": acf, "acf_outside": float(np.mean(np.abs(acf) > band)) if acf.size else 0.0,
        "acf_max": float(np.max(np.abs(acf))) if acf.size else 0.0,
        "xcf_lags": xl, "xcf": xcf, "xcf_outside": float(np.mean(np.abs(xcf) > band)),
        "xcf_max": float(np.max(np.abs(xcf))) if xcf.size else 0.0,
    }


def summary(tests):
    return {k: tests[k] for k in ("band", "acf_outside", "acf_max", "xcf_outside", "xcf_max")}


def structured_share(r):
    """Share of a residual's variance that is not white: ``1 - w / var(r)``, with
    ``w = mean(diff(r)^2) / 2`` the variance of its white part (for white noise
    E[(r_k - r_{k-1})^2] = 2 var; a slow model error hardly changes from one sample to the next,
    so the difference leaves it out). 0 for a white residual (noise the model cannot explain), near
    1 for one a better model could follow; clipped to [0, 1]. The loop reads it on the held-out
    trace (:data:`.loop.UNEXPLAINED_SHARE`).
    """
    r = np.asarray(r, float)
    if r.size < 3:
        return 0.0
    var = float(np.var(r))
    if var <= 0:
        return 0.0
    w = 0.5 * float(np.mean(np.diff(r) ** 2))
    return float(min(1.0, max(0.0, 1.0 - w / var)))
