"""Error metrics: RMS/MAX of tracking error and of prediction discrepancy, and contour error.

All positions in mm; the reporting helpers return µm (the thesis's tables).
"""
from __future__ import annotations

import numpy as np

from .errors import InputError


def rms(x):
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def rms_max_um(x):
    """{"rms_um", "max_um"} of a signal in mm."""
    x = np.asarray(x, float)
    return {"rms_um": rms(x) * 1e3, "max_um": float(np.max(np.abs(x))) * 1e3 if x.size else float("nan")}


def measured_position(trace, axis, side="motor"):
    """The measured position a model's position output is compared with: the motor encoder
    (``act``) or, for ``side="tool"``, the tool-side channel."""
    return trace.get(axis, "tool") if side == "tool" else trace.act(axis)


def contour_error(cmd_xy, act_xy, window=None):
    """Contour error: minimum normal distance from each actual point to the commanded polyline.

    Parameters
    ----------
    cmd_xy, act_xy : (N, 2) arrays, mm
    window : int, optional
        Only polyline segments within +-window samples of the same index are searched (the actual
        point lags the command by about the tracking error). Default: all segments for N <= 2000,
        else 500.

    Returns
    -------
    (N,) contour error in mm (>= 0)
    """
    P = np.asarray(cmd_xy, float)
    Q = np.asarray(act_xy, float)
    if P.shape != Q.shape or P.ndim != 2 or P.shape[1] != 2:
        raise ValueError(f"contour_error needs two (N, 2) arrays, got {P.shape} and {Q.shape}")
    N = len(P)
    if N < 2:
        return np.linalg.norm(Q - P, axis=1)
    A, B = P[:-1], P[1:]
    AB = B - A
    L2 = np.einsum("ij,ij->i", AB, AB)
    L2[L2 == 0] = 1.0
    if window is None:
        window = N if N <= 2000 else 500
    if not window >= 0:
        raise ValueError(f"contour_error window must be >= 0 samples, got {window!r}")
    out = np.empty(N)
    for k0 in range(0, N, 1024):
        ks = np.arange(k0, min(N, k0 + 1024))
        lo = max(0, min(k0, N - 2) - window)
        hi = min(N - 1, ks[-1] + window + 1)
        seg = slice(lo, hi)
        AQ = Q[ks, None, :] - A[None, seg, :]
        t = np.clip(np.einsum("ksj,sj->ks", AQ, AB[seg]) / L2[None, seg], 0.0, 1.0)
        d = AQ - t[..., None] * AB[None, seg, :]
        dist = np.sqrt(np.einsum("ksj,ksj->ks", d, d))
        # restrict each point to its own window
        idx = np.arange(lo, hi)[None, :]
        # the last point's own segment is the one ending there (segment N - 2)
        dist = np.where(np.abs(idx - np.minimum(ks, N - 2)[:, None]) <= window, dist, np.inf)
        out[ks] = dist.min(axis=1)
    return out


def prediction_table(measured_error, predicted_error):
    """Thesis-style table row: actual / predicted tracking error and the prediction error (µm)."""
    e = np.asarray(measured_error, float)
    p = np.asarray(predicted_error, float)
    if e.shape != p.shape:      # numpy would broadcast (N,) against (N, 1) or (1,) to a figure
        raise InputError(f"measured error of shape {e.shape} and prediction of shape {p.shape}: "
                         "expected one predicted value per measured sample", column="predicted_error")
    return {"actual": rms_max_um(e), "predicted": rms_max_um(p), "discrepancy": rms_max_um(e - p),
            "discrepancy_pct_of_rms": 100.0 * rms(e - p) / rms(e) if rms(e) > 0 else float("nan")}
