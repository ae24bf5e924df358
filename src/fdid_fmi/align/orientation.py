"""Orientation, gravity and bias of an accelerometer; axis orientation and offset of a grid encoder.

Accelerometer (thesis ch. 7.2.1, Eqn 7.1). The sensor reads the specific force
f = R^T (a + g e_z) + b (+ noise), R the rotation sensor -> machine, R = R_x(gamma) R_y(beta)
R_z(alpha). The thesis searched the three angles (with a gain and offset) against the KGM; here
each is estimated directly:

* **gravity + bias** c = R^T g e_z + b (:func:`static_constant`) is the weighted mean of f over
  the record between rest periods: the true acceleration integrates to the velocity change,
  which is zero from rest to rest, so the mean of f is c whatever R is. The weight ramps up over
  the first rest and down over the last, which averages out a ringing tool-side velocity there.
  From one mounting c does not separate into gravity and bias; with R known it does:
  b = c - R^T g e_z.
* **axis directions** (:func:`axis_directions`): while only machine axis i accelerates (its
  commanded / encoder acceleration is large and every other axis's small), f - c = R^T e_i a_i(t)
  is one fixed direction times a scalar, whatever the tool-side dynamics (a flexible mode) do
  to a_i. The direction d_i = R^T e_i is the LS projection of the (low-passed) sensor signal on
  the encoder acceleration over those samples.
* **rotation** (:func:`rotation_from_directions`): R from two or more directions by the Wahba /
  Kabsch solution (``scipy.spatial.transform.Rotation.align_vectors``); angles per Eqn 7.1 from
  ``as_euler("XYZ")``; their uncertainty by propagating each direction's scatter (Monte Carlo,
  seeded). One direction fixes only that axis (and is all its acceleration needs): the rotation
  about it is reported missing.

Grid encoder (KGM, thesis ch. 7.1: calibrated for angle on installation). The plate reads
p_kgm = R(theta)^T (p - o): :func:`plate_alignment` solves the 2-D Procrustes problem against the
(low-passed) motor-encoder positions, also with ``Rotation.align_vectors``.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InputError

__all__ = ["G_MM_S2", "static_constant", "integration_drift", "axis_directions", "rotation_from_directions",
           "euler_angles", "plate_alignment", "noise_std"]

G_MM_S2 = 9806.65
E = np.eye(3)
AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def noise_std(x):
    """White-noise level of each column of x (n, k) from second differences (robust MAD).

    For white noise of std s, the second difference has std s sqrt(6); a smooth signal sampled
    far above its bandwidth contributes nothing.
    """
    d2 = np.diff(np.asarray(x, dtype=float), 2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(6.0)


def static_constant(tau, f, tau_ramp_up, tau_ramp_down):
    """Gravity + bias c (sensor frame) as the ramp-weighted mean of the raw specific force.

    Parameters
    ----------
    tau : (n,) s, sensor clock;  f : (n, 3) mm/s^2 raw sensor-frame readings
    tau_ramp_up : (t0, t1) sensor-clock interval of the first rest (weight 0 -> 1)
    tau_ramp_down : (t2, t3) interval of the last rest (weight 1 -> 0)

    Returns
    -------
    c : (3,) mm/s^2
    sigma : (3,) mm/s^2, 1-sigma from the white-noise level (:func:`noise_std`) and the
            effective number of samples (sum w)^2 / sum w^2
    """
    dtau = float(np.median(np.diff(tau)))
    t0, t1 = tau_ramp_up
    t2, t3 = tau_ramp_down
    t1 = max(t1, t0 + dtau)        # no rest at the start / end: a one-sample ramp
    t2 = min(max(t2, t1 + dtau), t3 - dtau)
    w = np.interp(tau, [t0, t1, t2, t3], [0.0, 1.0, 1.0, 0.0], left=0.0, right=0.0)
    sw = w.sum()
    if sw <= 0:
        raise InputError("no sensor samples between the rest periods", column="time")
    c = (w[:, None] * f).sum(axis=0) / sw
    n_eff = sw ** 2 / float(np.sum(w ** 2))
    return c, noise_std(f) / np.sqrt(n_eff)


def integration_drift(noise, sigma_c, Ts_sensor, T):
    """1-sigma drift (mm) of a position obtained by integrating the aligned acceleration twice.

    Over T seconds from a known position and velocity, two terms add (in quadrature): the
    sensor's white noise integrated twice, variance q T^3 / 3 with q = noise^2 Ts_sensor its
    spectral level (unchanged by resampling below the noise band), and the residual constant
    error of the gravity + bias removal, sigma_c T^2 / 2 (thesis sect. 5.2.5: why a d.c.-gain
    constraint is imposed on acceleration models).

    Parameters
    ----------
    noise : float, mm/s^2 RMS per sensor sample;  sigma_c : float, mm/s^2
    Ts_sensor : float, s;  T : float or array, s

    Returns
    -------
    float or array, mm
    """
    T = np.asarray(T, dtype=float)
    return np.sqrt(noise ** 2 * Ts_sensor * T ** 3 / 3.0 + (0.5 * sigma_c * T ** 2) ** 2)


def axis_directions(F, ref, axes, kappa=1.0, solo_tol=0.02, active_tol=0.05, min_samples=100):
    """Sensor-frame direction of each machine axis from single-axis motion (see module doc).

    Parameters
    ----------
    F : (N, 3) low-passed sensor signal minus c, at the controller times, mm/s^2
    ref : dict axis -> (N,) low-passed encoder acceleration, mm/s^2 (axes not recorded absent)
    axes : axes wanted
    kappa : float     variance inflation for low-passed (correlated) residuals, ~ fs / (2 f_lp)
    solo_tol : float  other axes count as still below this fraction of their peak
    active_tol : float  an axis accelerates above this fraction of its peak

    Returns
    -------
    dict axis -> {"d": unit (3,), "gain": |d| (sensor response per encoder mm/s^2),
                  "sigma_rad": 1-sigma angle of the direction, "n": samples, "solo": bool}
    for the axes that were excited; axes absent from the result were not.
    """
    peaks = {a: float(np.max(np.abs(r))) for a, r in ref.items()}
    top = max(peaks.values()) if peaks else 0.0
    out = {}
    for a in axes:
        if a not in ref or top == 0 or peaks[a] < 0.02 * top:
            continue
        r = ref[a]
        act = np.abs(r) > active_tol * peaks[a]
        solo = act.copy()
        for b, rb in ref.items():
            if b != a and peaks[b] > 0.02 * top:
                solo &= np.abs(rb) < solo_tol * peaks[b]
        use, is_solo = (solo, True) if solo.sum() >= min_samples else (act, False)
        if use.sum() < min_samples:
            continue
        rr = r[use]
        FF = F[use]
        den = float(rr @ rr)
        d = FF.T @ rr / den
        g = float(np.linalg.norm(d))
        if g == 0:
            continue
        u = d / g
        E_ = FF - np.outer(rr, d)
        perp = E_ - np.outer(E_ @ u, u)
        s2 = float(np.sum(perp ** 2) / (2 * max(1, rr.size - 1))) * kappa
        out[a] = {"d": u, "gain": g, "sigma_rad": float(np.sqrt(s2 / den) / g), "n": int(use.sum()),
                  "solo": is_solo}
    return out


def euler_angles(rot: Rotation):
    """(alpha, beta, gamma) in deg of Eqn 7.1, R = R_x(gamma) R_y(beta) R_z(alpha)."""
    g, b, a = rot.as_euler("XYZ", degrees=True)
    return np.array([a, b, g])


def rotation_from_directions(dirs, n_mc=400, seed=0):
    """Rotation sensor -> machine from >= 2 axis directions (Wahba problem, align_vectors).

    Parameters
    ----------
    dirs : output of :func:`axis_directions` (at least two axes)
    n_mc : Monte Carlo draws for the angle uncertainty (seeded, deterministic)

    Returns
    -------
    rot : Rotation
    angles : (3,) deg, (alpha, beta, gamma) of Eqn 7.1
    sigma : (3,) deg, 1-sigma of the angles
    """
    names = sorted(dirs)
    A = np.array([E[AXIS_INDEX[a]] for a in names])
    B = np.array([dirs[a]["d"] for a in names])
    sig = np.array([max(dirs[a]["sigma_rad"], 1e-9) for a in names])
    w = 1.0 / sig ** 2
    rot, _ = Rotation.align_vectors(A, B, weights=w / w.max())
    ang = euler_angles(rot)
    rng = np.random.default_rng(seed)
    draws = np.empty((n_mc, 3))
    for k in range(n_mc):
        Bk = B + rng.normal(size=B.shape) * sig[:, None]
        Bk /= np.linalg.norm(Bk, axis=1)[:, None]
        rk, _ = Rotation.align_vectors(A, Bk, weights=w / w.max())
        draws[k] = euler_angles(rk)
    return rot, ang, draws.std(axis=0)


def mirror_residual(P, Q):
    """RMS residual (mm) of the best *mirrored* plate fit: machine p = M p_kgm + o with M
    orthogonal and det M = -1 (2-D Procrustes with a reflection).

    A grid encoder whose x, y columns are swapped, or one of whose axes counts the other way,
    is the mirror image of the machine's motion: no rotation fits it, this fit does. On a record
    moving one axis (points on a line) both fits are alike.
    """
    P0, Q0 = P - P.mean(axis=0), Q - Q.mean(axis=0)
    U, _, Vt = np.linalg.svd(P0.T @ Q0)
    D = np.diag([1.0, -1.0])
    M = (U @ D @ Vt).T if np.linalg.det(U @ Vt) > 0 else (U @ Vt).T
    return float(np.sqrt(np.mean((Q0 - P0 @ M.T) ** 2)))


def plate_alignment(P, Q, kappa=1.0):
    """Grid-plate rotation and origin: machine p = R(theta) p_kgm + o (2-D Procrustes).

    Parameters
    ----------
    P : (N, 2) plate coordinates (low-passed), mm
    Q : (N, 2) machine positions (motor encoders, low-passed), mm
    kappa : variance inflation for correlated residuals

    Returns
    -------
    theta_deg, sigma_theta_deg, o (2,) mm, sigma_o (2,) mm, rms residual (mm)
    """
    pm, qm = P.mean(axis=0), Q.mean(axis=0)
    P0, Q0 = P - pm, Q - qm
    spread = float(np.sum(P0 ** 2))
    if spread <= 0:
        raise InputError("the grid encoder did not move: its axis orientation cannot be estimated",
                         column="kgm")
    # planar points plus the plate normal (heavily weighted) pinned to machine z: the solution
    # is a rotation about z even when the points lie on one line (one axis moved)
    A = np.vstack([np.column_stack([Q0, np.zeros(len(Q0))]), [0.0, 0.0, 1.0]])
    B = np.vstack([np.column_stack([P0, np.zeros(len(P0))]), [0.0, 0.0, 1.0]])
    w = np.ones(len(A))
    w[-1] = spread
    rot, _ = Rotation.align_vectors(A, B, weights=w)
    theta = float(rot.as_rotvec()[2])
    Rm = rot.as_matrix()[:2, :2]
    o = qm - Rm @ pm
    res = Q - (P @ Rm.T + o)
    s2 = float(np.sum(res ** 2) / (2 * max(1, len(P) - 3))) * kappa
    s_theta = np.sqrt(s2 / spread)
    s_o = np.sqrt(s2 / len(P)) * np.ones(2)
    return np.degrees(theta), float(np.degrees(s_theta)), o, s_o, float(np.sqrt(np.mean(res ** 2)))
