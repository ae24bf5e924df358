"""Resampling a sensor record onto the controller's sample times (thesis ch. 7.2.1, Fig. 7-3).

The thesis down-sampled the KGM to the accelerometer's rate and shifted it; here every sensor
goes onto the controller's grid t_k = t_0 + k Ts through the estimated clock mapping
tau_k = (t_k - offset) / scale, so that offset and drift are undone in the same step:

1. anti-alias: when the sensor samples faster than the controller, a zero-phase Butterworth
   low-pass (``scipy.signal.butter`` + ``sosfiltfilt``, no delay) at ``cutoff_hz`` (default 0.8 x
   the controller's Nyquist frequency) on the sensor's own clock;
2. interpolation at tau_k by a cubic spline (``scipy.interpolate.CubicSpline``); a slower sensor
   (a 1 kHz KGM onto 1.67 kHz) is only interpolated.

Samples whose tau_k lies outside the sensor record are NaN (the caller crops to the overlap).
"""
from __future__ import annotations

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

__all__ = ["to_controller_grid", "lowpass"]


def lowpass(x, Ts, cutoff_hz, order=4):
    """Zero-phase Butterworth low-pass of x (n, k) along axis 0 (``sosfiltfilt``)."""
    sos = signal.butter(order, cutoff_hz, fs=1.0 / Ts, output="sos")
    x = np.asarray(x, dtype=float)
    padlen = min(x.shape[0] - 1, 3 * (2 * len(sos) + 1))
    return signal.sosfiltfilt(sos, x, axis=0, padlen=padlen)


def to_controller_grid(tau, data, mapping, t, cutoff_hz=None, order=6):
    """Values of a sensor record at controller times.

    Parameters
    ----------
    tau : (n,) s, sensor clock (the file's time column)
    data : (n,) or (n, k) sensor values (any unit)
    mapping : (offset_s, scale), controller time t = offset + scale * tau
    t : (N,) s, controller sample times
    cutoff_hz : float or None   anti-alias cut-off; applied only when it lies below 0.98 x the
                                sensor's Nyquist frequency
    order : int                 Butterworth order (the zero-phase pass doubles its slope)

    Returns
    -------
    (N,) or (N, k) array, NaN outside the record
    """
    tau = np.asarray(tau, dtype=float)
    x = np.asarray(data, dtype=float)
    one = x.ndim == 1
    x = x[:, None] if one else x
    Ts_s = float(np.median(np.diff(tau)))
    if cutoff_hz is not None and cutoff_hz < 0.98 * 0.5 / Ts_s:
        x = lowpass(x, Ts_s, cutoff_hz, order)
    a, b = mapping
    tq = (np.asarray(t, dtype=float) - a) / b
    out = np.full((tq.size, x.shape[1]), np.nan)
    inside = (tq >= tau[0]) & (tq <= tau[-1])
    if inside.any():
        out[inside] = CubicSpline(tau, x, axis=0)(tq[inside])
    return out[:, 0] if one else out
