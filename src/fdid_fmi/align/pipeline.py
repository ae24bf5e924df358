"""The alignment chain: separately recorded tool-side sensors -> one Trace at the controller's Ts.

Thesis ch. 7.2.1 (Fig. 7-3, Table 7-1): the KGM and accelerometer records were brought onto the
motor encoders' time base (shift), the accelerometers rotated (Eqn 7.1) and freed of offsets,
and all resampled, before the MIMO identification of ch. 5 used them. :func:`align` does the
same, every step estimated from the data and reported with its uncertainty:

=====  =======================  ===========================================================
step   what                     how
=====  =======================  ===========================================================
1      coarse time offset       envelope cross-correlation (timing.coarse_offset)
2      gravity + bias           rest-to-rest weighted mean (orientation.static_constant)
3      orientation              single-axis segments -> axis directions -> Wahba rotation
                                (accelerometer); 2-D Procrustes (grid encoder)
4      offset + clock drift     windowed cross-correlation vs encoder signals, LS line
       (2-4 repeated ``iterations`` times, each with the latest clock mapping)
5      resampling to Ts         zero-phase anti-alias low-pass + cubic spline at the mapped
                                controller times (resample.to_controller_grid)
=====  =======================  ===========================================================

The references are the controller's motor-encoder positions (``act``), low-passed at
``lowpass_hz`` (below the first tool-side mode: there tool and motor move alike) and
differentiated; the sensor signals get the same zero-phase low-pass, so the filters add no lag.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from ..errors import InputError
from ..signals import derivative
from ..trace import Channel, Trace
from .orientation import (AXIS_INDEX, G_MM_S2, axis_directions, euler_angles, integration_drift, mirror_residual,
                          noise_std, plate_alignment, rotation_from_directions, static_constant)
from .readers import SensorRecord
from .resample import lowpass, to_controller_grid
from .result import AlignmentResult, Estimate, SensorAlignment
from .timing import MIN_DRIFT_WINDOWS, coarse_offset, fit_clock, window_lags

__all__ = ["align", "controller_references"]

MACHINE_AXES = ("x", "y", "z")
FIRST_LAG_S = 0.025     # lag searched per window in the first round (s); later rounds: 0.006


def controller_references(trace: Trace, lowpass_hz):
    """Low-passed encoder position, velocity, acceleration and jerk per machine axis.

    Returns
    -------
    dict axis -> {"p": mm, "v": mm/s, "a": mm/s^2, "j": mm/s^3}, each (N,)
    """
    Ts = trace.Ts
    out = {}
    for a in trace.axes:
        if a not in MACHINE_AXES or not trace.has(a, "act"):
            continue
        p = lowpass(trace.act(a)[:, None], Ts, lowpass_hz)[:, 0]
        v = derivative(p, Ts)
        acc = derivative(v, Ts)
        out[a] = {"p": p, "v": v, "a": acc, "j": derivative(acc, Ts)}
    return out


def _rest_mask(ref):
    """Controller samples at rest: low-passed encoder speed below max(0.5 mm/s, 1 % of its peak)."""
    speed = np.sqrt(sum(r["v"] ** 2 for r in ref.values()))
    return speed <= max(0.5, 0.01 * float(speed.max()))


def _rest_intervals(t, ref, lo, hi):
    """Controller-time ramps (first rest, last rest) inside [lo, hi]: encoder speed ~ 0."""
    speed = np.sqrt(sum(r["v"] ** 2 for r in ref.values()))
    inside = (t >= lo) & (t <= hi)
    thr = max(0.5, 0.01 * float(speed[inside].max()))
    mov = np.flatnonzero(inside & (speed > thr))
    if mov.size == 0:
        return (lo, lo), (hi, hi)
    return (lo, float(t[mov[0]])), (float(t[mov[-1]]), hi)


class _Clocked:
    """A sensor record (low-passed copy splined) evaluated at controller times."""

    def __init__(self, tau, x):
        self.tau = tau
        self.spline = CubicSpline(tau, x, axis=0)
        self.dspline = self.spline.derivative()

    def at(self, tq, mapping, deriv=False):
        a, b = mapping
        s = (np.asarray(tq, dtype=float) - a) / b
        out = np.full((s.size,) + self.spline.c.shape[2:], np.nan)
        ok = (s >= self.tau[0]) & (s <= self.tau[-1])
        if ok.any():
            out[ok] = self.dspline(s[ok]) / b if deriv else self.spline(s[ok])
        return out


def _check_sees_motion(rec, x_lp, lowpass_hz):
    """One line when a sensor saw no motion: its low-passed signal is at its noise level."""
    dyn = float(np.max(np.std(x_lp, axis=0)))
    band = float(np.max(noise_std(rec.data))) * np.sqrt(min(1.0, 2.0 * lowpass_hz / rec.rate_hz))
    if not dyn > 5.0 * band:
        raise InputError(f"{rec.kind.replace('_', ' ')} '{rec.name}': the sensor record is at rest "
                         f"throughout (below {lowpass_hz:g} Hz it holds only noise): it did not see "
                         f"the moves, so nothing can be aligned", source=rec.source, column="time")


def _timing_estimates(mapping, sigma, info, rho, what):
    a, b = mapping
    drift = 1.0 / b - 1.0
    s_drift = sigma[1] / b ** 2 if np.isfinite(sigma[1]) else None
    note = f"coarse envelope correlation {rho:.2f}; {info['n_windows']} windows, lag scatter " \
           f"{info['residual_s'] * 1e6:.1f} us" if np.isfinite(info["residual_s"]) else \
           f"coarse envelope correlation {rho:.2f}; {info['n_windows']} window(s)"
    return [Estimate("timing", "time_offset", a, sigma[0] if np.isfinite(sigma[0]) else None, "s",
                     f"envelope xcorr, then windowed xcorr of {what} vs encoder, LS line", note),
            Estimate("timing", "clock_drift", drift * 1e6, None if s_drift is None else s_drift * 1e6,
                     "ppm", "slope of the windowed lags (t = offset + tau / (1 + drift))",
                     "" if info["drift_estimated"] else "not estimable: assumed 0")]


def _drift_missing(name, info, window_s, source):
    if info["drift_estimated"]:
        return []
    if info["n_windows"] < MIN_DRIFT_WINDOWS or not np.isfinite(info.get("slope_sigma", np.nan)):
        return [f"{name} ({source}): clock drift not estimable: motion in only {info['n_windows']} "
                f"window(s) of {window_s:g} s (needs {MIN_DRIFT_WINDOWS}), assumed 0 ppm; record moves "
                f"spread over a longer time"]
    return [f"{name} ({source}): clock drift not resolved: the lags of {info['n_windows']} windows over "
            f"{info['span_s']:.1f} s give a slope within 2 sigma of 0 (sigma "
            f"{info['slope_sigma'] * 1e6:.0f} ppm), assumed 0 ppm; a longer record resolves it"]


def _given_rotation(orientation, name, source=None):
    """The rotation of accelerometer ``name`` from a calibration (None without one). A calibration
    that does not name this sensor, or whose matrix is no rotation, is refused: silently
    estimating the rotation again would lose the calibration on a single-axis run."""
    if orientation is None:
        return None, []
    if isinstance(orientation, AlignmentResult):
        try:
            s = orientation.sensor(name)
        except KeyError:
            names = [x.name for x in orientation.sensors]
            raise InputError(f"the orientation calibration has no sensor '{name}' (it has {names}); "
                             f"name the sensor as in the calibration run (name=...)", source=source,
                             column="orientation") from None
        if s.rotation is None:
            return None, []
        return _rotation(s.rotation, name, source), [e for e in s.estimates if e.step == "orientation"]
    if name not in orientation:
        raise InputError(f"the orientation calibration has no sensor '{name}' (it has "
                         f"{sorted(orientation)})", source=source, column="orientation")
    v = orientation[name]
    ests = []
    if isinstance(v, dict):
        try:
            ests = [Estimate(**e) for e in v.get("estimates", []) if e.get("step") == "orientation"]
        except (TypeError, AttributeError):
            raise InputError(f"the calibration's estimates of sensor '{name}' are not estimate entries",
                             source=source, column="orientation") from None
        v = v.get("rotation")        # (missing: "not a 3x3 rotation" below, not a KeyError)
    rot = v if isinstance(v, Rotation) else _rotation(v, name, source)
    return rot, ests


def _rotation(matrix, name, source):
    """A proper rotation from a 3x3 matrix (finite, R^T R = I to 1e-6, det +1), else InputError:
    scipy would quietly turn any matrix into some rotation."""
    try:
        R = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError):
        R = None
    if R is None or R.shape != (3, 3) or not np.all(np.isfinite(R)) or \
            not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not np.linalg.det(R) > 0:
        raise InputError(f"the calibration's matrix of sensor '{name}' is not a 3x3 rotation "
                         f"(orthonormal, determinant +1)", source=source, column="orientation")
    return Rotation.from_matrix(R)


def _align_accelerometer(rec: SensorRecord, t, ref, opts, given):
    name, src = rec.name, rec.source
    Ts_s = 1.0 / rec.rate_hz
    f = rec.data
    f_lp = lowpass(f, Ts_s, opts["lowpass_hz"])
    _check_sees_motion(rec, f_lp, opts["lowpass_hz"])
    jerk = np.gradient(f_lp, Ts_s, axis=0)
    env_s = np.linalg.norm(jerk, axis=1)
    wanted = [a for a in rec.axes if a in ref]
    if not wanted:
        raise InputError(f"accelerometer '{name}' provides axes {list(rec.axes)}, none of which is "
                         f"in the controller trace (axes {sorted(ref)})", source=src, column="axes")
    env_r = np.sqrt(sum(ref[a]["j"] ** 2 for a in wanted))
    a0, rho = coarse_offset(t, env_r, rec.tau, env_s, opts["max_offset_s"], src,
                            f"accelerometer '{name}'")
    mapping = (a0, 1.0)
    clk = _Clocked(rec.tau, f_lp)
    rot, given_est = _given_rotation(given, name, src)
    sigma, info, dirs = (np.nan, np.nan), {}, {}
    for it in range(opts["iterations"]):
        lo = max(t[0], mapping[0] + mapping[1] * rec.tau[0])
        hi = min(t[-1], mapping[0] + mapping[1] * rec.tau[-1])
        up, down = _rest_intervals(t, ref, lo, hi)
        to_tau = lambda x: (x - mapping[0]) / mapping[1]  # noqa: E731
        c, s_c = static_constant(rec.tau, f, (to_tau(up[0]), to_tau(up[1])),
                                 (to_tau(down[0]), to_tau(down[1])))
        F = clk.at(t, mapping) - c
        ok = np.all(np.isfinite(F), axis=1)
        if rot is None:
            dirs = axis_directions(F[ok], {a: ref[a]["a"][ok] for a in ref}, wanted, kappa=opts["kappa"])
            if not dirs:
                raise InputError(f"accelerometer '{name}': orientation not estimable: none of the axes "
                                 f"{wanted} accelerates during the sensor record; give the orientation "
                                 f"of a calibration run", source=src, column="orientation")
            if len(dirs) >= 2:
                rot_it, ang, s_ang = rotation_from_directions(dirs)
                proj = {a: rot_it.as_matrix()[AXIS_INDEX[a]] for a in wanted}
            else:
                rot_it = None
                proj = {a: d["d"] for a, d in dirs.items()}
        else:
            rot_it = rot
            proj = {a: rot.as_matrix()[AXIS_INDEX[a]] for a in wanted}
        tax = [a for a in proj if a in ref and np.max(np.abs(ref[a]["a"])) > 0]
        P = np.array([proj[a] for a in tax])
        Rf = np.column_stack([ref[a]["a"] for a in tax])
        lags = window_lags(t, Rf, lambda tq: (clk.at(tq, mapping) - c) @ P.T, opts["window_s"],
                           FIRST_LAG_S if it == 0 else 0.006, rest=opts["rest"])
        mapping, sigma, info = fit_clock(lags, mapping, base=(a0, 1.0))
    # final constant with the final mapping
    lo = max(t[0], mapping[0] + mapping[1] * rec.tau[0])
    hi = min(t[-1], mapping[0] + mapping[1] * rec.tau[-1])
    up, down = _rest_intervals(t, ref, lo, hi)
    to_tau = lambda x: (x - mapping[0]) / mapping[1]  # noqa: E731
    c, s_c = static_constant(rec.tau, f, (to_tau(up[0]), to_tau(up[1])), (to_tau(down[0]), to_tau(down[1])))

    sa = SensorAlignment(name, "accelerometer", src, rec.rate_hz, mapping=mapping)
    sa.estimates += _timing_estimates(mapping, sigma, info, rho, "machine-frame acceleration")
    sa.missing += _drift_missing(name, info, opts["window_s"], src)
    if rot is not None:
        ang = euler_angles(rot)
        if given_est:
            sa.estimates += [Estimate(e.step, e.name, e.value, e.uncertainty, e.unit, e.method,
                                      "from the calibration run") for e in given_est]
        else:
            sa.estimates += [Estimate("orientation", n, v, None, "deg", "given", "")
                             for n, v in zip(("alpha", "beta", "gamma"), ang)]
        rot_final = rot
    elif len(dirs) >= 2:
        rot_final, ang, s_ang = rotation_from_directions(dirs)
        for n, v, s in zip(("alpha", "beta", "gamma"), ang, s_ang):
            sa.estimates.append(Estimate("orientation", n, float(v), float(s), "deg",
                                         "Eqn 7.1 from single-axis directions (Wahba, align_vectors)",
                                         f"axes {sorted(dirs)}"))
    else:
        rot_final = None
        (a1, d1), = dirs.items()
        d = d1["d"]
        az, el = np.degrees(np.arctan2(d[1], d[0])), np.degrees(np.arcsin(np.clip(d[2], -1, 1)))
        sd = np.degrees(d1["sigma_rad"])
        sa.estimates.append(Estimate("orientation", f"{a1}_direction", [float(az), float(el)], [sd, sd],
                                     "deg", f"azimuth / elevation of machine {a1} in the sensor frame",
                                     "single-axis segments"))
        sa.direction = {a1: d.tolist()}
        if len(rec.axes) == 1:
            why = f"the sensor provides only machine {a1} (axes={a1})"
        elif len(wanted) == 1:
            why = (f"of its axes {list(rec.axes)} only {a1} is in the controller trace (and moves "
                   f"in this record)")
        else:
            why = f"of its axes {wanted} only {a1} accelerates on its own in this record"
        sa.missing.append(f"accelerometer '{name}' ({src}): rotation about machine {a1} not estimable: "
                          f"{why}; its {a1} acceleration is aligned, the full orientation needs a run "
                          f"where two of its axes move (orientation=...)")
    # below the first tool-side mode tool and motor move alike: a gain far from 1 is a wrong unit
    # (with a calibration's rotation too: the directions of the axes that move, for this check)
    gains = dirs if rot is None else axis_directions(F[ok], {a: ref[a]["a"][ok] for a in ref}, wanted,
                                                     kappa=opts["kappa"])
    for a, d in gains.items():
        if not 1 / 3 <= d["gain"] <= 3:
            raise InputError(f"accelerometer '{name}': its machine-{a} acceleration below "
                             f"{opts['lowpass_hz']:g} Hz is {d['gain']:.3g} x the encoder's (expected ~1): the "
                             f"unit of its columns is wrong (g vs m/s^2 is 9.81x, mm/s^2 vs m/s^2 1000x; "
                             f"unit=...) or it does not move with machine {a} (axes=...)", source=src,
                             column="unit")
    for a, d in dirs.items():
        sa.estimates.append(Estimate("orientation", f"gain_{a}", d["gain"], None, "1",
                                     f"sensor / encoder acceleration below {opts['lowpass_hz']:g} Hz",
                                     "check: 1 for a rigid axis, > 1 below a tool-side mode"))
    sa.constant = c.tolist()
    sa.estimates.append(Estimate("gravity_bias", "gravity_plus_bias", c.tolist(), s_c.tolist(), "mm/s^2",
                                 "rest-to-rest weighted mean (velocity change 0), sensor frame"))
    if rot_final is not None:
        sa.rotation = rot_final.as_matrix().tolist()
        gs = rot_final.inv().apply([0.0, 0.0, G_MM_S2])
        # at rest an accelerometer reads +g along machine +z (specific force); read along -z, the
        # rotation fitted to the x/y directions is that of a mirrored (left-handed) frame
        if float(c @ gs) < -0.5 * G_MM_S2 * float(np.linalg.norm(c)):
            raise InputError(f"accelerometer '{name}': its columns {list(rec.columns)} form the mirror "
                             f"image of a rotated machine frame (at rest it reads gravity along machine -z "
                             f"of the rotation fitted to its {sorted(dirs) or list(wanted)} directions): two "
                             f"columns swapped or one counting the other way; give the columns in the "
                             f"sensor's x, y, z order (cols=)", source=src, column="columns")
        ang_sigma = [e.uncertainty or 0.0 for e in sa.estimates
                     if e.step == "orientation" and e.name in ("alpha", "beta", "gamma")]
        s_rot = np.radians(max(ang_sigma, default=0.0))  # gravity leaks by g x angle error
        sa.estimates.append(Estimate("gravity_bias", "bias", (c - gs).tolist(),
                                     np.sqrt(s_c ** 2 + (G_MM_S2 * s_rot) ** 2).tolist(), "mm/s^2",
                                     "c - R^T g e_z (g = 9806.65 mm/s^2, machine z vertical)"))
        proj = {a: rot_final.as_matrix()[AXIS_INDEX[a]] for a in wanted}
    else:
        proj = {a: np.asarray(sa.direction[a]) for a in sa.direction if a in wanted}
    nz = noise_std(f)
    sa.estimates.append(Estimate("gravity_bias", "noise", nz.tolist(), None, "mm/s^2",
                                 "white-noise level from second differences"))
    # drift of the twice-integrated machine-axis acceleration over a 1 s move (1 sigma)
    drift = {a: float(integration_drift(float(np.sqrt(np.sum((p * nz) ** 2))),
                                        float(np.sqrt(np.sum((p * s_c) ** 2))), Ts_s, 1.0))
             for a, p in proj.items()}
    for a, d in drift.items():
        sa.estimates.append(Estimate("gravity_bias", f"drift_1s_{a}", d, None, "mm",
                                     "1-sigma position drift of the double integral over 1 s "
                                     "(noise random walk + residual bias), integration_drift()",
                                     "scales as T^1.5 (noise) and T^2 (bias)"))
    signals = {a: (f - c) @ p for a, p in proj.items()}
    return sa, signals


def _align_grid(rec: SensorRecord, t, ref, opts):
    name, src = rec.name, rec.source
    Ts_s = 1.0 / rec.rate_hz
    P = rec.data
    p_lp = lowpass(P, Ts_s, opts["lowpass_hz"])
    _check_sees_motion(rec, p_lp, opts["lowpass_hz"])
    env_s = np.linalg.norm(np.gradient(p_lp, Ts_s, axis=0), axis=1)
    have = [a for a in rec.axes if a in ref]
    if not have:
        raise InputError(f"grid encoder '{name}' measures axes {list(rec.axes)}, none of which is in "
                         f"the controller trace (axes {sorted(ref)})", source=src, column="axes")
    env_r = np.sqrt(sum(ref[a]["v"] ** 2 for a in have))
    a0, rho = coarse_offset(t, env_r, rec.tau, env_s, opts["max_offset_s"], src, f"grid encoder '{name}'")
    mapping = (a0, 1.0)
    clk = _Clocked(rec.tau, p_lp)
    Q = np.column_stack([ref[a]["p"] if a in ref else np.zeros(t.size) for a in rec.axes])
    sigma, info = (np.nan, np.nan), {}
    for it in range(opts["iterations"]):
        Pm = clk.at(t, mapping)
        ok = np.all(np.isfinite(Pm), axis=1)
        th, s_th, o, s_o, res = plate_alignment(Pm[ok], Q[ok], opts["kappa"])
        c_, s_ = np.cos(np.radians(th)), np.sin(np.radians(th))
        R2 = np.array([[c_, -s_], [s_, c_]])
        idx = [rec.axes.index(a) for a in have]
        Rv = np.column_stack([ref[a]["v"] for a in have])
        lags = window_lags(t, Rv, lambda tq: (clk.at(tq, mapping, deriv=True) @ R2.T)[:, idx],
                           opts["window_s"], FIRST_LAG_S if it == 0 else 0.006, rest=opts["rest"])
        mapping, sigma, info = fit_clock(lags, mapping, base=(a0, 1.0))
    Pm = clk.at(t, mapping)
    ok = np.all(np.isfinite(Pm), axis=1)
    th, s_th, o, s_o, res = plate_alignment(Pm[ok], Q[ok], opts["kappa"])
    Pk, Qk = Pm[ok], Q[ok]
    scale = float(np.sqrt(np.sum((Qk - Qk.mean(axis=0)) ** 2) / np.sum((Pk - Pk.mean(axis=0)) ** 2)))
    if not 0.5 <= scale <= 2.0:    # the plate follows the encoders below the first tool-side mode
        raise InputError(f"grid encoder '{name}': the encoders moved {scale:.4g} x as far as the plate "
                         f"(expected ~1): the unit of its columns is wrong (um vs mm is 1000x, inch 25.4x; "
                         f"unit=...) or its axes are not the machine's {list(rec.axes)} (axes=)", source=src,
                         column="unit")
    mirrored = mirror_residual(Pm[ok], Q[ok])
    if mirrored < 0.5 * res:
        raise InputError(f"grid encoder '{name}': its plate axes are the mirror image of the machine's "
                         f"{list(rec.axes)} (columns {list(rec.columns)} swapped, or one counting the "
                         f"other way): the best rotation leaves {res * 1e3:.3g} um RMS, a mirror image "
                         f"{mirrored * 1e3:.3g} um; give the columns in plate x, y order (cols=) and the "
                         f"machine axes they measure (axes=)", source=src, column="columns")
    c_, s_ = np.cos(np.radians(th)), np.sin(np.radians(th))
    R2 = np.array([[c_, -s_], [s_, c_]])
    sa = SensorAlignment(name, "grid_encoder", src, rec.rate_hz, mapping=mapping)
    sa.estimates += _timing_estimates(mapping, sigma, info, rho, "machine-frame velocity")
    sa.missing += _drift_missing(name, info, opts["window_s"], src)
    sa.estimates.append(Estimate("orientation", "angle", th, s_th, "deg",
                                 "2-D Procrustes vs encoder positions (align_vectors)",
                                 f"residual {res * 1e3:.2f} um RMS (includes tool-side deflection)"))
    sa.estimates.append(Estimate("offset", "origin", o.tolist(), s_o.tolist(), "mm",
                                 "plate origin in machine coordinates (encoder reference)"))
    sa.rotation = np.block([[R2, np.zeros((2, 1))], [np.zeros((1, 2)), np.ones((1, 1))]]).tolist()
    sa.offset_mm = o.tolist()
    pm = P @ R2.T + o
    signals = {a: pm[:, rec.axes.index(a)] for a in have}
    return sa, signals


def _check_parameters(**kw):
    """align()'s numeric parameters: real numbers in their ranges, else one InputError naming the
    parameter (iterations=0 crashed with KeyError, a NaN window with ValueError, window_s=0 ran
    windows of one sample and returned a worse offset without a word)."""
    import numbers
    for k, v in kw.items():
        if k == "max_offset_s" and v is None:
            continue
        ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(v)
        if k == "iterations":
            ok = ok and isinstance(v, numbers.Integral) and v >= 1
            want = "an integer >= 1"
        elif k == "min_overlap_s":
            ok = ok and v >= 0
            want = "a finite number >= 0"
        else:
            ok = ok and v > 0
            want = "a finite number > 0" + (" (or None)" if k == "max_offset_s" else "")
        if not ok:
            raise InputError(f"{k} must be {want}, got {v!r}", column=k)


def align(controller: Trace, sensors, orientation=None, lowpass_hz=10.0, window_s=1.0,
          max_offset_s=None, aa_fraction=0.8, iterations=3, min_overlap_s=0.5) -> AlignmentResult:
    """Bring separately recorded tool-side sensors onto the controller trace (thesis ch. 7.2.1).

    Parameters
    ----------
    controller : Trace
        The controller's trace: per axis (named x / y / z) at least ``act`` (motor encoder, mm);
        its Ts and time base are the target.
    sensors : sequence of :class:`~fdid_fmi.align.readers.SensorRecord`
        Accelerometers and grid encoders, each on its own clock (see ``read_accelerometer``,
        ``read_grid_encoder``).
    orientation : AlignmentResult or dict name -> 3x3 / Rotation / {"rotation": ...}, optional
        Accelerometer orientations from a calibration run (the thesis's diamond): used instead
        of estimating them (a run moving one axis cannot fix the rotation about it).
    lowpass_hz : float, Hz
        Zero-phase low-pass for the estimation signals; below the first tool-side mode.
    window_s : float, s         window of the lag estimates (clock drift)
    max_offset_s : float, optional  bound on the time offset searched
    aa_fraction : float         anti-alias cut-off as a fraction of the controller's Nyquist
    iterations : int            rounds of constant / orientation / timing
    min_overlap_s : float, s    shortest common record accepted

    Returns
    -------
    AlignmentResult
        ``trace``: the controller channels over the common overlap plus ``<axis>_tool_mm``
        (grid encoder, role ``tool``) and ``<axis>_acc_mm_s2`` (accelerometers, role ``acc``;
        several sensors on one axis are added with their ``sign``: head - table).
    """
    if not isinstance(controller, Trace):
        raise InputError("the controller record must be a Trace (fdid_fmi.io.read_trace)", column="controller")
    sensors = list(sensors)
    if not sensors:
        raise InputError("no sensor records given", column="sensors")
    names = [s.name for s in sensors]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"sensor names must be unique; repeated: {dup}", column="name")
    _check_parameters(lowpass_hz=lowpass_hz, window_s=window_s, max_offset_s=max_offset_s,
                      aa_fraction=aa_fraction, iterations=iterations, min_overlap_s=min_overlap_s)
    Ts = controller.Ts
    nyq = 0.5 / Ts
    if not (0 < lowpass_hz < nyq):
        raise InputError(f"lowpass_hz must lie in (0, {nyq:g}) Hz, got {lowpass_hz!r}", column="lowpass_hz")
    span = float(controller.t[-1] - controller.t[0])
    if lowpass_hz * span < 2.0:     # 1e-300 Hz crashed in the filter design, 0.01 Hz blamed the sensor
        raise InputError(f"lowpass_hz {lowpass_hz:g} Hz keeps less than two cycles of the {span:.3g} s "
                         f"controller record (at least {2.0 / span:.3g} Hz); the estimation signals need "
                         f"the moves (below the first tool-side mode, e.g. 10 Hz)", column="lowpass_hz")
    if window_s < 2 * FIRST_LAG_S:   # shorter windows returned a biased offset without a word
        raise InputError(f"window_s {window_s:g} s is shorter than the +-{FIRST_LAG_S * 1e3:g} ms lag searched "
                         f"in each window; at least {2 * FIRST_LAG_S:g} s (default 1 s)", column="window_s")
    for rec in sensors:
        if not lowpass_hz < 0.5 * rec.rate_hz:
            raise InputError(f"lowpass_hz {lowpass_hz:g} Hz is not below the Nyquist frequency "
                             f"{0.5 * rec.rate_hz:g} Hz of sensor '{rec.name}'", source=rec.source,
                             column="lowpass_hz")
    if not (0 < aa_fraction <= 1):
        raise InputError(f"aa_fraction must lie in (0, 1], got {aa_fraction!r}", column="aa_fraction")
    ref = controller_references(controller, lowpass_hz)
    if not ref:
        raise InputError(f"the controller trace has no measured position of an axis named x, y or z "
                         f"(axes {controller.axes})", source=controller.source, column="act")
    t = controller.t
    opts = dict(lowpass_hz=float(lowpass_hz), window_s=float(window_s), max_offset_s=max_offset_s,
                iterations=int(iterations), kappa=float(nyq / lowpass_hz), rest=_rest_mask(ref))
    results, signals = [], []
    for rec in sensors:
        if rec.kind == "accelerometer":
            sa, sig = _align_accelerometer(rec, t, ref, opts, orientation)
        else:
            sa, sig = _align_grid(rec, t, ref, opts)
        results.append(sa)
        signals.append((rec, sa, sig))

    # common overlap (controller time), a few sensor samples inside each record's ends
    lo, hi = float(t[0]), float(t[-1])
    for rec, sa, _ in signals:
        a, b = sa.mapping
        m = 4.0 / rec.rate_hz
        lo = max(lo, a + b * (rec.tau[0] + m))
        hi = min(hi, a + b * (rec.tau[-1] - m))
    if hi - lo < min_overlap_s:
        worst = min(signals, key=lambda s: s[1].mapping[0] + s[1].mapping[1] * s[0].tau[-1])
        raise InputError(f"the sensors and the controller trace overlap for {max(hi - lo, 0):.3g} s "
                         f"(< {min_overlap_s:g} s) on the controller's time base; e.g. '{worst[0].name}' "
                         f"covers {worst[1].mapping[0] + worst[1].mapping[1] * worst[0].tau[0]:.3f} to "
                         f"{worst[1].mapping[0] + worst[1].mapping[1] * worst[0].tau[-1]:.3f} s, the "
                         f"controller {t[0]:.3f} to {t[-1]:.3f} s", source=controller.source, column="time")
    k0 = int(np.searchsorted(t, lo - 1e-12))
    k1 = int(np.searchsorted(t, hi + 1e-12, side="right"))
    tt = t[k0:k1]
    channels = {k: Channel(c.name, c.unit, c.data[k0:k1]) for k, c in controller.channels.items()}
    roles = {a: dict(r) for a, r in controller.roles.items()}
    replaced = {}
    acc_sum, tool = {}, {}
    aa = aa_fraction * nyq
    for rec, sa, sig in signals:
        for axis, x in sig.items():
            y = to_controller_grid(rec.tau, x, sa.mapping, tt, cutoff_hz=aa)
            if rec.kind == "accelerometer":
                acc_sum[axis] = acc_sum.get(axis, 0.0) + rec.sign * y
                sa.axes_out[axis] = f"{axis}_acc_mm_s2"
            else:
                if axis in tool:
                    raise InputError(f"two grid encoders give axis '{axis}'", source=rec.source, column="axes")
                tool[axis] = y
                sa.axes_out[axis] = f"{axis}_tool_mm"
        fs = rec.rate_hz
        sa.estimates.append(Estimate("resample", "rate", [fs, 1.0 / Ts], None, "Hz",
                                     "zero-phase Butterworth anti-alias + cubic spline at mapped times",
                                     f"anti-alias cut-off {aa:.0f} Hz" if aa < 0.98 * 0.5 * fs else
                                     "interpolation only (sensor slower than the controller)"))
    for kind, unit, store in (("acc", "mm_s2", acc_sum), ("tool", "mm", tool)):
        for axis, y in store.items():
            cname = f"{axis}_{kind}_{unit}"
            while cname in channels:
                cname += "_aligned"
            channels[cname] = Channel(cname, unit, y)
            r = roles.setdefault(axis, {})
            if kind in r:
                replaced[f"{axis}.{kind}"] = r[kind]
            r[kind] = cname
    settings = {"lowpass_hz": lowpass_hz, "window_s": window_s, "aa_cutoff_hz": aa,
                "iterations": iterations, "replaced_roles": replaced}
    meta = dict(controller.meta)
    meta["aligned_sensors"] = {s.name: s.source for s in sensors}
    out = Trace(t=tt, channels=channels, roles=roles, source=controller.source + "+aligned", meta=meta,
                jitter_tol=controller.jitter_tol)
    res = AlignmentResult(out, results, (float(tt[0]), float(tt[-1])), settings)
    out.meta["alignment"] = res.to_dict()
    return res
