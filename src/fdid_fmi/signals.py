"""Signal conditioning used by the identifiers (thesis ch. 3-4).

Arrays in, arrays out; inputs are never modified.
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from .errors import InputError


def butter_filtfilt(x, Ts, cutoff_hz, order=2):
    """Zero-phase Butterworth low-pass (``scipy.signal.sosfiltfilt``).

    Parameters
    ----------
    x : array_like, 1-D or (..., N) along the last axis
    Ts : float, s
    cutoff_hz : float, 0 < cutoff_hz < Nyquist = 1 / (2 Ts)
    order : int >= 1
    """
    nyq = 0.5 / Ts
    if not (0 < cutoff_hz < nyq):
        raise InputError(f"Butterworth cutoff must lie in (0, {nyq:g}) Hz (Nyquist), got {cutoff_hz!r}",
                         column="cutoff_hz")
    if int(order) != order or order < 1:
        raise InputError(f"Butterworth order must be a positive integer, got {order!r}", column="order")
    sos = signal.butter(int(order), cutoff_hz, fs=1.0 / Ts, output="sos")
    x = np.asarray(x, dtype=float)
    padlen = min(x.shape[-1] - 1, 3 * (2 * len(sos) + 1))
    return signal.sosfiltfilt(sos, x, axis=-1, padlen=padlen)


def moving_average(x, n):
    """Moving average of n-th order (window of n samples, n >= 1), centred on the sample.

    An odd n is zero-phase; an even n cannot be centred on a sample and leads by half a
    sample (window k - (n-1)//2 .. k + n//2; kept so that identified models stay the same).
    The ends use the available samples only, so no zero padding bias.
    """
    if int(n) != n or n < 1:
        raise InputError(f"moving-average order must be a positive integer, got {n!r}", column="ma_order")
    x = np.asarray(x, dtype=float)
    n = int(n)
    if n == 1:
        return x.copy()
    c = np.concatenate(([0.0], np.cumsum(x)))
    N = x.size
    lo = np.clip(np.arange(N) - (n - 1) // 2, 0, N)
    hi = np.clip(np.arange(N) + n // 2 + 1, 0, N)
    return (c[hi] - c[lo]) / (hi - lo)


def derivative(x, Ts, order=1):
    """n-th numerical derivative by repeated central differences (``numpy.gradient``)."""
    y = np.asarray(x, dtype=float)
    for _ in range(int(order)):
        y = np.gradient(y, Ts)
    return y


def filtered_derivatives(x, Ts, cutoff_hz, order=2, n=3):
    """First ``n`` derivatives of x, each through the zero-phase Butterworth filter (Eqn 3.5).

    Returns
    -------
    list of arrays [x', x'', ...] (units of x per s^k)
    """
    return list(iter_filtered_derivatives(x, Ts, cutoff_hz, order, n))


def iter_filtered_derivatives(x, Ts, cutoff_hz, order=2, n=3):
    """:func:`filtered_derivatives` one at a time: a long trace holds one derivative (and the
    filter's work arrays) at once."""
    y = np.asarray(x, dtype=float)
    for _ in range(n):
        g = np.gradient(y, Ts)
        y = None                 # the previous derivative is the caller's to keep
        y = butter_filtfilt(g, Ts, cutoff_hz, order)
        del g
        yield y


def measured_velocity(x, Ts, ma_order=5, method="central"):
    """Velocity from an encoder position, then a centred moving average of ``ma_order`` samples.

    ``method="central"``: central difference (thesis section 4.3: zero phase shift, quantisation
    noise suppressed by the average). ``method="backward"``: (x[k] - x[k-1]) / Ts, the definition
    the simulator uses for the model's own velocity (first sample repeats the second).
    """
    x = np.asarray(x, dtype=float)
    if method == "central":
        v = np.gradient(x, Ts)
    elif method == "backward":
        v = np.empty_like(x)
        v[1:] = np.diff(x) / Ts
        v[0] = v[1] if x.size > 1 else 0.0
    else:
        raise InputError(f"velocity method must be 'central' or 'backward', got {method!r}",
                         column="velocity")
    return moving_average(v, ma_order)


def sat_friction(v, v_tilde):
    """Normalised Coulomb friction signal sat(v / v_tilde) in [-1, 1] (Eqn 4.12-4.13)."""
    if not (np.isfinite(v_tilde) and v_tilde > 0):
        raise InputError(f"friction transition velocity v_tilde must be > 0 mm/s, got {v_tilde!r}",
                         column="v_tilde")
    return np.clip(np.asarray(v, dtype=float) / v_tilde, -1.0, 1.0)
