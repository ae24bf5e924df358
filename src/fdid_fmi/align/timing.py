"""Time offset and clock-rate drift of a sensor against the controller (thesis ch. 7.2.1).

The thesis shifted the KGM and accelerometer records onto the encoder's time base with a
global search (Table 7-1). Here the shift is found by cross-correlation, in two stages:

1. **coarse offset** (:func:`coarse_offset`): one FFT cross-correlation
   (``scipy.signal.correlate``) of rotation- and offset-invariant envelopes -- the norm of the
   low-passed jerk (accelerometer) or velocity (grid encoder) against the same norm from the
   motor encoders -- over every possible shift; the sensor's orientation is not needed yet.
   A weak peak means there is no common motion: the records do not overlap or the sensor saw
   nothing, and that is said in one line.
2. **offset and drift** (:func:`window_lags`, :func:`fit_clock`): the machine-frame sensor
   signals against the encoder signals, in windows; each window's lag comes from the peak of
   the summed cross-correlation, refined to a fraction of a sample by a parabola through the
   three samples around it. A straight line through the lags (LS) gives the offset and the
   clock drift, with 1-sigma uncertainties from the scatter of the lags about the line.

Clock model: controller time t = offset + scale * tau, tau the sensor's own clock (its file's
time column); drift = 1 / scale - 1 (the sensor clock runs fast by ``drift``).
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from ..errors import InputError

__all__ = ["coarse_offset", "window_lags", "fit_clock", "MIN_CORRELATION", "MIN_DRIFT_WINDOWS"]

MIN_CORRELATION = 0.6  # normalised envelope correlation below which no common motion is found
MIN_DRIFT_WINDOWS = 5  # a drift (slope) needs lags from this many windows (3 degrees of freedom)


def coarse_offset(t, ref_env, tau, sens_env, max_offset_s=None, source=None, what="sensor"):
    """Offset (s) that best lines up two non-negative motion envelopes, clock rates equal.

    Parameters
    ----------
    t : (N,) s, controller time (steady step Ts);  ref_env : (N,) envelope on it
    tau : (n,) s, sensor clock;  sens_env : (n,) envelope on it
    max_offset_s : float, optional   search only |offset - (t[0] - tau[0])| <= this

    Returns
    -------
    offset : float, s   t = offset + tau
    rho : float         normalised peak correlation (1: identical envelopes)

    Raises
    ------
    InputError when the peak correlation is below ``MIN_CORRELATION`` (no common motion).
    """
    Ts = float(np.median(np.diff(t)))
    tg = np.arange(tau[0], tau[-1], Ts)
    s = np.interp(tg, tau, sens_env)
    r = np.asarray(ref_env, dtype=float)
    r0, s0 = r - r.mean(), s - s.mean()
    nr, ns = np.linalg.norm(r0), np.linalg.norm(s0)
    if nr == 0 or ns == 0:
        raise InputError(f"{what}: no motion to align on (the {'controller' if nr == 0 else 'sensor'} "
                         f"record is at rest throughout)", source=source, column="time")
    z = signal.correlate(r0, s0, mode="full", method="fft")
    lags = signal.correlation_lags(r0.size, s0.size, mode="full")
    off = t[0] + lags * Ts - tg[0]
    if max_offset_s is not None:
        ok = np.abs(off - (t[0] - tau[0])) <= max_offset_s
        if not ok.any():
            raise InputError(f"{what}: no shift within max_offset_s = {max_offset_s} s (fdid align "
                             f"--max-offset)", source=source)
        z = np.where(ok, z, -np.inf)
    k = int(np.argmax(z))
    rho = float(z[k] / (nr * ns))
    if rho < MIN_CORRELATION:
        # a bound below the true offset hides the match: say so (it read as "no overlap")
        bound = ("" if max_offset_s is None else
                 f", or the offset lies beyond the searched {max_offset_s:g} s of the records' starts "
                 f"(max_offset_s, fdid align --max-offset: give a larger bound or leave it out)")
        raise InputError(f"{what}: no common motion with the controller trace (best envelope "
                         f"correlation {rho:.2f} < {MIN_CORRELATION}): the records do not overlap in "
                         f"time, or the sensor did not see the moves{bound}", source=source, column="time")
    return float(off[k]), rho


def _windows(n, nw, L, rest):
    """Window [start, stop) indices of at least nw samples; with a rest mask, each window ends at
    the first resting sample after nw samples, so no move is cut by a window edge."""
    out, i0 = [], L
    while i0 + nw + L < n:
        i1 = i0 + nw
        if rest is not None:
            nxt = np.flatnonzero(rest[i1:min(n - L, i0 + 4 * nw)])
            if nxt.size:
                i1 = i1 + int(nxt[0])
        if i1 + L > n:
            break
        out.append((i0, i1))
        i0 = i1
    return out


def window_lags(t, ref, sens_fn, window_s=1.0, max_lag_s=0.025, min_energy=0.05, rest=None):
    """Residual lag of the sensor against the reference, window by window.

    Parameters
    ----------
    t : (N,) s controller time; ref : (N, m) reference signals (e.g. encoder accelerations)
    sens_fn : callable(t_array) -> (len, m) sensor signals at those controller times under the
        current clock mapping (NaN outside the sensor record)
    window_s : float, s        window length
    max_lag_s : float, s       largest lag searched
    min_energy : float         windows with less than this fraction of the largest window's
                               reference energy are skipped (nothing moves there)
    rest : (N,) bool, optional samples where the machine is at rest: windows then end there.
        A window that cuts a move biases the lag whenever the sensor and the reference differ by
        more than a delay and a gain (a tool-side mode below the low-pass: the tool moves a few
        percent more than the motor, more at higher frequencies); with both signals zero at the
        window edges that bias vanishes (measured: lag scatter 150 us -> 10 us on the Y axis).

    Returns
    -------
    list of dicts ``{"t": centre (s), "lag": s, "corr": normalised peak, "weight": energy of the
    reference's time derivative (the lag's variance is inversely proportional to it)}``; the
    sensor's event at mapped time t_m really happened at t_m - lag.
    """
    Ts = float(np.median(np.diff(t)))
    L = max(2, int(np.ceil(max_lag_s / Ts)))
    nw = max(1, int(round(window_s / Ts)))
    ref = np.atleast_2d(np.asarray(ref, dtype=float).T).T
    wins = _windows(t.size, nw, L, rest)
    energy = [float(np.sum(ref[i0:i1] ** 2)) / (i1 - i0) for i0, i1 in wins]
    if not energy:
        return []
    emax = max(energy)
    out = []
    for (i0, i1), e in zip(wins, energy):
        if emax == 0 or e < min_energy * emax:
            continue
        te = t[i0 - L:i1 + L]
        s = sens_fn(te)
        if not np.all(np.isfinite(s)):
            continue
        r = ref[i0:i1]
        nw = i1 - i0
        c = sum(signal.correlate(s[:, j], r[:, j], mode="valid") for j in range(r.shape[1]))
        # energy of the shifted sensor segment: J = C^2 / E_s is the LS fit of a gain times the
        # reference at each lag (a plain correlation peak is pulled by the window's edges)
        es = signal.correlate(np.sum(s ** 2, axis=1), np.ones(nw), mode="valid")
        er = float(np.sum(r ** 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            J = np.where((c > 0) & (es > 0), c ** 2 / (es * er), 0.0)
        k = int(np.argmax(J))
        if k == 0 or k == J.size - 1 or J[k] <= 0:
            continue  # peak at the search edge: no reliable lag here
        y0, y1, y2 = J[k - 1], J[k], J[k + 1]
        den = y0 - 2 * y1 + y2
        frac = 0.5 * (y0 - y2) / den if den != 0 else 0.0
        # information about the lag: energy of the reference's slope (its variance ~ 1 / that)
        info = float(np.sum(np.diff(r, axis=0) ** 2)) / Ts ** 2
        out.append({"t": float(0.5 * (t[i0] + t[i1 - 1])), "lag": float((k - L + frac) * Ts),
                    "corr": float(np.sqrt(y1)), "weight": info})
    return out


def fit_clock(lags, mapping, min_corr=0.5, min_significance=2.0, base=None):
    """Update the clock mapping from window lags by a straight-line LS fit.

    Parameters
    ----------
    lags : output of :func:`window_lags`
    mapping : (offset, scale), current t = offset + scale * tau (the lags were measured with it)
    base : (offset, scale), optional
        Mapping the returned one is fitted from (default: ``mapping``). With the coarse mapping
        as base, each round refits offset and drift as a whole, so the significance test of the
        drift sees all of it.
    min_corr : windows with a weaker normalised correlation are not used
    min_significance : the fitted drift is kept only when |drift| exceeds this many of its
        standard deviations; otherwise the clocks are taken as equal (a short record's poorly
        determined slope would shift the ends more than the drift it cannot resolve)

    Returns
    -------
    mapping : (offset, scale), updated
    sigma : (sigma_offset_s, sigma_scale) 1-sigma, NaN when not estimable
    info : dict ``n_windows``, ``drift_estimated`` (bool), ``residual_s`` (RMS of the lags about
           the line)
    """
    a, b = mapping
    use = [w for w in lags if w["corr"] >= min_corr]
    n = len(use)
    if n == 0:
        return mapping, (np.nan, np.nan), {"n_windows": 0, "drift_estimated": False, "residual_s": np.nan}
    tw = np.array([w["t"] for w in use])
    lw = np.array([w["lag"] for w in use])
    if base is not None:
        # the same events against the base mapping: true time t_w - lag, base time of that tau
        a0, b0 = base
        tb = a0 + b0 * (tw - a) / b
        lw = tb - (tw - lw)
        tw = tb
        a, b = a0, b0
    tbar = float(tw.mean())
    if n < MIN_DRIFT_WINDOWS or np.ptp(tw) == 0:
        e0, c1 = float(lw.mean()), 0.0
        s_e0 = float(lw.std(ddof=1) / np.sqrt(n)) if n > 1 else np.nan
        s_c1, res = np.nan, np.nan
        drift_ok = False
    else:
        # weighted LS line (weights ~ 1 / variance of each window's lag, scale from the scatter)
        w = np.array([u.get("weight", 1.0) for u in use], dtype=float)
        w = w / w.mean() if w.mean() > 0 else np.ones(n)
        tbar = float(np.sum(w * tw) / np.sum(w))
        X = np.column_stack([np.ones(n), tw - tbar])
        sw = np.sqrt(w)
        (e0, c1), *_ = np.linalg.lstsq(X * sw[:, None], lw * sw, rcond=None)
        r = lw - X @ np.array([e0, c1])
        dof = n - 2
        res = float(np.sqrt(np.sum(w * r ** 2) / np.sum(w)))
        if dof > 0:
            s2 = float(np.sum(w * r ** 2) / dof)
            s_e0 = np.sqrt(s2 / np.sum(w))
            s_c1 = np.sqrt(s2 / float(np.sum(w * (tw - tbar) ** 2)))
        else:
            s_e0 = s_c1 = np.nan
        drift_ok = True
        if not (np.isfinite(s_c1) and abs(c1) > min_significance * s_c1):
            e0, c1 = float(lw.mean()), 0.0
            s_e0 = float(lw.std(ddof=1) / np.sqrt(n)) if n > 1 else np.nan
            drift_ok = False
    a_new = a - e0 - c1 * (a - tbar)
    b_new = b * (1 - c1)
    s_a = float(np.sqrt(s_e0 ** 2 + (a - tbar) ** 2 * s_c1 ** 2)) if np.isfinite(s_c1) else float(s_e0)
    s_b = float(b * s_c1)
    return (float(a_new), float(b_new)), (s_a, s_b), {"n_windows": n, "drift_estimated": drift_ok,
                                                       "residual_s": res, "slope": float(c1),
                                                       "slope_sigma": float(s_c1),
                                                       "span_s": float(np.ptp(tw)) if n else 0.0}
