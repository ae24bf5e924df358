"""Quasi-static identification (thesis ch. 3, Eqn 3.2-3.6).

G_er(s) = e/x_r is expanded around s = 0 (Eqn 3.2); its first three Taylor terms give the
instantaneous tracking error from the commanded velocity, acceleration and jerk (Eqn 3.4):

    e(t) ~ K_vel x_r'(t) + K_acc x_r''(t) + K_jerk x_r'''(t)

The gains come from LS (Eqn 3.5) on command derivatives filtered by a zero-phase Butterworth.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError, finite_number
from ..metrics import rms
from ..model import QuasiStaticModel
from ..signals import iter_filtered_derivatives
from .ranges import training_ranges


def default_cutoff(Ts):
    """Default Butterworth cutoff for the command derivatives: min(50 Hz, 0.2 x Nyquist)."""
    return min(50.0, 0.1 / Ts)


def identify_quasi_static(traces, axes=None, cutoff_hz=None, order=2, terms=3):
    """Quasi-static model of each axis (Eqn 3.5).

    Parameters
    ----------
    traces : Trace or list[Trace] (data ranges)
    axes : list of axis names (default: every axis with cmd and act)
    cutoff_hz, order : Butterworth filter of the command derivatives
    terms : number of Taylor terms fitted (3 = the thesis's K_vel, K_acc, K_jerk). The series of
        Eqn 3.2 converges only below the slowest closed-loop pole; a trajectory with content
        beyond it biases a 3-term fit. Extra terms (snap, ...) absorb that truncation bias, so
        the first three are estimated closer to the true Taylor coefficients; they are kept
        in ``gains[axis]["K_higher"]`` and used in prediction.

    Returns
    -------
    QuasiStaticModel
    """
    traces = training_ranges(traces)
    Ts = traces[0].Ts
    axes = axes or [a for a in traces[0].axes if traces[0].has(a, "cmd") and traces[0].has(a, "act")]
    if not axes:
        raise InputError("no axis with both commanded and measured position", source=traces[0].source)
    training_ranges(traces, axes, roles=("cmd", "act"))
    # None is the default, 0 a bad value (not silently "the default")
    cutoff_hz = default_cutoff(Ts) if cutoff_hz is None else finite_number(cutoff_hz, "cutoff_hz", positive=True)
    gains, metrics = {}, {}
    for ax in axes:
        if int(terms) != terms or terms < 3:
            raise InputError(f"terms must be an integer >= 3, got {terms!r}", column="terms")
        if max(tr.cmd(ax).max() for tr in traces) - min(tr.cmd(ax).min() for tr in traces) <= 0:
            raise InputError(f"axis '{ax}' does not move in the data range: nothing to identify",
                             source=traces[0].source, column=f"{ax}.cmd")
        # one regressor matrix, filled one derivative at a time (a long trace: no copies of it)
        Phi = np.empty((sum(tr.n for tr in traces), int(terms)))
        r0 = 0
        for tr in traces:
            for k, d in enumerate(iter_filtered_derivatives(tr.cmd(ax), Ts, cutoff_hz, order, int(terms))):
                Phi[r0:r0 + tr.n, k] = d
                d = None         # noqa: F841  (the generator may free it while making the next)
            r0 += tr.n
        Y = traces[0].error(ax) if len(traces) == 1 else np.concatenate([tr.error(ax) for tr in traces])
        check_excitation(Phi, cutoff_hz, ax, traces[0].source)
        scale = max_abs_columns(Phi)
        scale[scale == 0] = 1.0
        Phi /= scale                                       # scaled columns, in place
        theta_s = least_squares_by_blocks(Phi, Y)
        theta = theta_s / scale
        gains[ax] = {"K_vel": float(theta[0]), "K_acc": float(theta[1]), "K_jerk": float(theta[2])}
        if terms > 3:
            gains[ax]["K_higher"] = [float(v) for v in theta[3:]]
        metrics[ax] = {"fit_rms_um": rms(Y - Phi @ theta_s) * 1e3, "error_rms_um": rms(Y) * 1e3}
        del Phi, Y
    return QuasiStaticModel(Ts=Ts, gains=gains, cutoff_hz=float(cutoff_hz), order=int(order),
                            metrics=metrics,
                            provenance={"data": [{"source": tr.source, "sha256": tr.meta.get("sha256")
                                                  or tr.fingerprint()} for tr in traces]})


def max_abs_columns(A):
    """max |A[:, j]| per column without an |A| array (NaN propagates, as np.abs's max would)."""
    return np.maximum(A.max(axis=0), -A.min(axis=0))


LS_BLOCK_ROWS = 1 << 18      # rows per block of least_squares_by_blocks


def least_squares_by_blocks(A, y, block=LS_BLOCK_ROWS):
    """argmin |A x - y| for a tall ``A`` (N x k), reading it in blocks of rows.

    The triangular factor R of [A y] is built block by block (Householder QR of R stacked on
    the next block), so the work arrays hold one block, not copies of A as ``lstsq`` makes (a
    10^7-sample trace: 240 MB each); then R_11 x = r_12. A is full rank here
    (``check_excitation``); where R is numerically singular, ``np.linalg.lstsq`` decides."""
    N, k = A.shape
    R = np.zeros((0, k + 1))
    for r0 in range(0, N, block):
        blk = np.column_stack([A[r0:r0 + block], y[r0:r0 + block]])
        R = np.linalg.qr(np.vstack([R, blk]), mode="r")
    R11 = R[:k, :k]
    d = np.abs(np.diag(R11))
    if R.shape[0] < k or d.min() <= 1e-12 * d.max():
        return np.linalg.lstsq(A, y, rcond=None)[0]
    return np.linalg.solve(R11, R[:k, k])


MIN_SAMPLES_PER_GAIN = 20     # as the pole search: 20 samples per estimated parameter
UNEXCITED = 1e-6              # a derivative this small against the velocity is rounding noise
GAIN_NAMES = ("K_vel", "K_acc", "K_jerk")
DERIVATIVE_NAMES = ("velocity", "acceleration", "jerk")


def check_excitation(Phi, cutoff_hz, axis, source=None, gains=GAIN_NAMES):
    """Refuse command derivatives (columns of ``Phi``, velocity first) that cannot carry a gain.

    Fewer than ``MIN_SAMPLES_PER_GAIN`` samples per gain fit anything (3 samples give 3 gains
    exactly), and a range at constant velocity has an acceleration and jerk of rounding noise
    (1e-11 mm/s^2) that the column scaling of the LS blows up into gains such as K_acc = 7e7 s^2.
    Each derivative is compared with the velocity at the filter's band: max |x_r^(k)| /
    (2 pi f_c)^(k-1) against max |x_r'| (both mm/s); below ``UNEXCITED`` it is noise.
    """
    N, terms = Phi.shape
    need = MIN_SAMPLES_PER_GAIN * terms
    if N < need:
        raise InputError(f"{N} samples are too few for {terms} gains (need at least {need})",
                         source=source, column="samples")
    level = max_abs_columns(Phi) / (2 * np.pi * cutoff_hz) ** np.arange(terms)
    for k in range(1, terms):
        if not level[k] > UNEXCITED * level[0]:
            what = DERIVATIVE_NAMES[k] if k < len(DERIVATIVE_NAMES) else f"derivative of order {k + 1}"
            gain = gains[k] if k < len(gains) else f"K_higher[{k - len(gains)}]"
            raise InputError(f"the commanded {what} of axis '{axis}' is zero over the data range (a "
                             f"move at constant velocity): {gain} cannot be identified; give data with "
                             f"accelerating and decelerating moves", source=source, column=f"{axis}.cmd")


def predict_quasi_static(model, cmds, t):
    """Tracking-error prediction of a QuasiStaticModel (Eqn 3.4); returns a SimResult."""
    from ..simulate import SimResult, check_sample_time
    Ts = float(np.median(np.diff(t)))
    check_sample_time(Ts, model.Ts)
    axes, cols = {}, []
    for ax in model.axes:
        if ax not in cmds:
            raise InputError(f"no command for axis '{ax}'", column=ax)
        g = model.gains[ax]
        k = [g["K_vel"], g["K_acc"], g["K_jerk"]] + list(g.get("K_higher", []))
        e = 0
        for kk, d in zip(k, iter_filtered_derivatives(cmds[ax], Ts, model.cutoff_hz, model.order, len(k))):
            e = e + kk * d          # the order of sum(): one derivative held at a time
            d = None                # noqa: F841
        x = np.asarray(cmds[ax], float) - e
        cols += [x, e]
    # the outputs once, in y; the per-axis arrays are its columns (a long trace: no second copy)
    y = np.column_stack(cols)
    del cols
    for i, ax in enumerate(model.axes):
        x = y[:, 2 * i]
        axes[ax] = {"position": x, "error": y[:, 2 * i + 1], "velocity": np.gradient(x, Ts)}
    names = [n for ax in model.axes for n in (f"{ax}_pos", f"{ax}_err")]
    return SimResult(t=np.asarray(t), y=y, u=np.zeros((len(t), 0)), axes=axes, output_names=names)


def feed_limits(model, axis, e_max_mm, v_max=None, a_max=None, j_max=None):
    """Feed-limit check of Eqn 3.6: |K_vel v| + |K_acc a| + |K_jerk j| <= e_max.

    Give any of the limits (mm/s, mm/s^2, mm/s^3); returns the predicted worst-case error of the
    given limits, whether it is within ``e_max_mm``, and, for each limit left out, the largest value
    that keeps the error inside e_max with the others (the budget left).
    """
    if not e_max_mm > 0:
        raise InputError(f"e_max must be > 0 mm, got {e_max_mm!r}", column="e_max")
    g = model.gains.get(axis)
    if g is None:
        raise InputError(f"the model has no axis '{axis}' (axes: {model.axes})", column="axis")
    terms = {"v_max": (abs(g["K_vel"]), v_max), "a_max": (abs(g["K_acc"]), a_max),
             "j_max": (abs(g["K_jerk"]), j_max)}
    for name, (_, val) in terms.items():
        if val is not None and not val >= 0:
            raise InputError(f"{name} must be >= 0, got {val!r}", column=name)
    used = sum(k * v for k, v in terms.values() if v is not None)
    out = {"axis": axis, "e_max_mm": e_max_mm, "predicted_max_error_mm": used, "within": used <= e_max_mm,
           "allowed": {}}
    left = e_max_mm - used
    for name, (k, val) in terms.items():
        if val is None:
            out["allowed"][name] = (left / k if k > 0 else float("inf")) if left > 0 else 0.0
    return out
