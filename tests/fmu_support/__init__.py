"""Hand-built DriveModels and command signals for the FMU tests and the FMU benchmark.

The models follow the thesis's structure (Eqn 4.10-4.17): the command x_r and the friction
signal d_nf are filtered through s^k / P(s), P(s) = (s + p)(s^2 + 2 zeta w s + w^2), and
the tracking error is e = (c0 s^3 + c1 s^2 + c2 s)/P x_r + d0 s/P d_nf; x = x_r - e.
The continuous model is discretised with Tustin, which gives the friction input a direct
feed-through into the position (and so into the backward-difference velocity): with the
values used here the friction loop gain L |beta| / v_tilde is about 40, so the exact
piecewise-linear friction solve matters. The same-sample term of inputs from outside the drive
(commands, external inputs, features of the command) then uses their extrapolation from the
samples before (:func:`causal`), as in every identified model.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import cont2discrete

from fdid_fmi.identify.pole_search import extrapolate_late_inputs
from fdid_fmi.identify.regressors import SAME_SAMPLE
from fdid_fmi.model import DriveModel, Port

TS = 1e-3


def _allpole(p, w, zeta):
    """Controllable canonical form of 1/P(s); state z = [y, y', y''] with P(s) y = u."""
    a2, a1, a0 = np.poly([-p, complex(-zeta * w, w * np.sqrt(1 - zeta ** 2)),
                          complex(-zeta * w, -w * np.sqrt(1 - zeta ** 2))]).real[1:]
    A = np.array([[0, 1, 0], [0, 0, 1], [-a0, -a1, -a2]])
    B = np.array([[0.0], [0.0], [1.0]])
    return A, B, np.array([a0, a1, a2])


def _sk(k, a):
    """(C, D) of s^k / P(s) on the state of _allpole."""
    if k < 3:
        C = np.zeros(3)
        C[k] = 1.0
        return C, 0.0
    return -a, 1.0


def axis_blocks(p=150.0, w=2 * np.pi * 40, zeta=0.7, kvel=1.2e-3, kacc=2e-6, kjerk=1e-9, d0=2.0e5):
    """Continuous (A, B, C_e, D_e) from [x_r, d_nf] to e for one axis (6 states)."""
    A1, B1, a = _allpole(p, w, zeta)
    a0 = a[0]
    c2, c1, c0 = kvel * a0, kacc * a0, kjerk * a0
    A = np.block([[A1, np.zeros((3, 3))], [np.zeros((3, 3)), A1]])
    B = np.block([[B1, np.zeros((3, 1))], [np.zeros((3, 1)), B1]])
    Ce = np.zeros(6)
    De = np.zeros(2)
    for k, c in ((3, c0), (2, c1), (1, c2)):
        Ck, Dk = _sk(k, a)
        Ce[:3] += c * Ck
        De[0] += c * Dk
    Ck, Dk = _sk(1, a)
    Ce[3:] += d0 * Ck
    De[1] += d0 * Dk
    return A, B, Ce, De


def _disc(A, B, C, D, Ts=TS):
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), Ts, method="bilinear")
    return Ad, Bd, Cd, Dd


def causal(Ts, A, B, C, D, inputs, outputs, **kw):
    """DriveModel whose outside inputs reach the outputs through their extrapolation from the
    samples before (the identified models' causal form, ``pole_search.extrapolate_late_inputs``)."""
    A, B, C, D = extrapolate_late_inputs(*(np.atleast_2d(np.asarray(x, float)) for x in (A, B, C, D)),
                                         inputs, outputs, SAME_SAMPLE["quadratic"])
    return DriveModel(Ts=Ts, A=A, B=B, C=C, D=D, inputs=inputs, outputs=outputs, **kw)


def siso_model(v_tilde=1.0, level=1.0, **kw):
    """SISO tracking-error model with position and error outputs (velocity by backward difference)."""
    A, B, Ce, De = axis_blocks(**kw)
    C = np.vstack([-Ce, Ce])
    D = np.vstack([np.array([1.0, 0.0]) - De, De])
    Ad, Bd, Cd, Dd = _disc(A, B, C, D)
    return causal(
        TS, Ad, Bd, Cd, Dd, method="hand-built",
        inputs=[Port("x_cmd", "mm", "command", "x"),
                Port("x_dnf", "1", "friction", "x", {"v_tilde": v_tilde, "level": level})],
        outputs=[Port("x_pos", "mm", "position", "x"), Port("x_err", "mm", "error", "x")])


def coupled_model(kxy=0.3, kyx=0.2, vt_y=2.2, level_y=0.9):
    """Two axes (x, y), two friction inputs, cross terms in C and (after Tustin) in D.

    The friction of each axis also drives the other axis's error through k * d0 s/P(s)
    (continuous time, before discretisation, so that the cross feed-through in D is
    consistent with the states). Axis y has a velocity output (an appended state holds
    y[k-1]); axis x uses the backward difference: both velocity sources are exercised.
    """
    Ax, Bx, Cex, Dex = axis_blocks()
    Ay, By, Cey, Dey = axis_blocks(p=120.0, w=2 * np.pi * 30, zeta=0.6, kvel=1.5e-3, d0=1.5e5)
    A = np.block([[Ax, np.zeros((6, 6))], [np.zeros((6, 6)), Ay]])
    # inputs: x_cmd, x_dnf, y_cmd, y_dnf
    B = np.zeros((12, 4))
    B[:6, :2] = Bx
    B[6:, 2:] = By
    Ce = np.zeros((2, 12))
    Ce[0, :6] = Cex
    Ce[1, 6:] = Cey
    Ce[0, 9:12] += kxy * Cey[3:6]                                 # y friction -> x error
    Ce[1, 3:6] += kyx * Cex[3:6]                                   # x friction -> y error
    De = np.zeros((2, 4))
    De[0, :2] = Dex
    De[1, 2:] = Dey
    Ad, Bd, Ced, Ded = _disc(A, B, Ce, De)
    Sel = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    Cx = -Ced
    Dx = Sel - Ded
    # appended state q[k+1] = y_pos[k]; y velocity output = (y_pos[k] - q[k]) / Ts
    n = 12
    A2 = np.zeros((n + 1, n + 1))
    A2[:n, :n] = Ad
    A2[n, :n] = Cx[1]
    B2 = np.vstack([Bd, Dx[1:2]])
    C2 = np.zeros((5, n + 1))
    D2 = np.zeros((5, 4))
    C2[0, :n], D2[0] = Cx[0], Dx[0]
    C2[1, :n], D2[1] = Ced[0], Ded[0]
    C2[2, :n], D2[2] = Cx[1], Dx[1]
    C2[3, :n], D2[3] = Ced[1], Ded[1]
    C2[4, :n], D2[4] = Cx[1] / TS, Dx[1] / TS
    C2[4, n] = -1.0 / TS
    return causal(
        TS, A2, B2, C2, D2, method="hand-built",
        inputs=[Port("x_cmd", "mm", "command", "x"),
                Port("x_dnf", "1", "friction", "x", {"v_tilde": 0.8, "level": 1.0}),
                Port("y_cmd", "mm", "command", "y"),
                Port("y_dnf", "1", "friction", "y", {"v_tilde": vt_y, "level": level_y})],
        outputs=[Port("x_pos", "mm", "position", "x"), Port("x_err", "mm", "error", "x"),
                 Port("y_pos", "mm", "position", "y"), Port("y_err", "mm", "error", "y"),
                 Port("y_vel", "mm_s", "velocity", "y")])


def flexible_model(wm=2 * np.pi * 60, zm=0.05):
    """SISO model plus a lightly damped mode between motor and tool: tool_position output."""
    A, B, Ce, De = axis_blocks()
    Cx, Dx = -Ce, np.array([1.0, 0.0]) - De
    # w'' + 2 zm wm w' + wm^2 w = wm^2 x
    Am = np.array([[0.0, 1.0], [-wm ** 2, -2 * zm * wm]])
    A2 = np.block([[A, np.zeros((6, 2))], [np.vstack([np.zeros(6), wm ** 2 * Cx]), Am]])
    B2 = np.vstack([B, np.zeros((1, 2)), wm ** 2 * Dx[None, :]])
    C = np.zeros((3, 8))
    D = np.zeros((3, 2))
    C[0, :6], D[0] = Cx, Dx
    C[1, :6], D[1] = Ce, De
    C[2, 6] = 1.0
    Ad, Bd, Cd, Dd = _disc(A2, B2, C, D)
    return causal(
        TS, Ad, Bd, Cd, Dd, method="hand-built",
        inputs=[Port("x_cmd", "mm", "command", "x"),
                Port("x_dnf", "1", "friction", "x", {"v_tilde": 1.0, "level": 1.0})],
        outputs=[Port("x_pos", "mm", "position", "x"), Port("x_err", "mm", "error", "x"),
                 Port("x_tool", "mm", "tool_position", "x")])


def feature_model():
    """SISO model with an external force input and feature inputs of every function."""
    A1, B1, a = _allpole(150.0, 2 * np.pi * 40, 0.7)
    base = siso_model()
    feats = [Port("x_sin", "1", "feature", "x", {"function": "sin_position", "period_mm": 5.0,
                                                  "source": "command"}),
             Port("x_cos", "1", "feature", "x", {"function": "cos_position", "period_mm": 3.0,
                                                  "source": "position"}),
             Port("x_stribeck", "1", "feature", "x", {"function": "stribeck", "v_tilde": 0.5,
                                                      "v_s": 4.0}),
             Port("x_abs", "1", "feature", "x", {"function": "abs_sat", "v_tilde": 2.0}),
             Port("x_sat", "1", "feature", "x", {"function": "sat", "v_tilde": 3.0}),
             Port("x_play", "1", "feature", "x", {"function": "play", "width_mm": 0.05,
                                                  "source": "position"}),
             Port("x_play_stribeck", "1", "feature", "x", {"function": "play_stribeck", "width_mm": 0.02,
                                                           "v_s": 3.0, "source": "position"})]
    ext = Port("force_N", "N", "external", None, {"channel": "force_N"}, "external force on the table")
    A, B, Ce, De = axis_blocks()
    ne = len(feats) + 1
    # each extra input enters e through g_k s/P(s) (or 1/P for the force), own filter states
    n0 = A.shape[0]
    A2 = np.zeros((n0 + 3 * ne, n0 + 3 * ne))
    A2[:n0, :n0] = A
    B2 = np.zeros((n0 + 3 * ne, 2 + ne))
    B2[:n0, :2] = B
    Ce2 = np.zeros(n0 + 3 * ne)
    Ce2[:n0] = Ce
    De2 = np.zeros(2 + ne)
    De2[:2] = De
    gains = [4e2, 3e2, 5e2, 2e2, 6e2, 3e2, 4e2, 2e2]
    for k in range(ne):
        sl = slice(n0 + 3 * k, n0 + 3 * k + 3)
        A2[sl, sl] = A1
        B2[sl, 2 + k] = B1[:, 0]
        Ck, _ = _sk(1 if k < ne - 1 else 0, a)
        Ce2[sl] = gains[k] * Ck
    C = np.vstack([-Ce2, Ce2])
    D = np.vstack([np.r_[1.0, np.zeros(1 + ne)] - De2, De2])
    Ad, Bd, Cd, Dd = _disc(A2, B2, C, D)
    return causal(
        TS, Ad, Bd, Cd, Dd, method="hand-built",
        inputs=[*base.inputs, *feats, ext],
        outputs=base.outputs)


def smooth_moves(n, rng, amplitude=20.0, vmax=80.0, start=0.0, v_start=0.0, Ts=TS):
    """Commanded position (mm) of random point-to-point moves, jerk-limited by smoothing.

    Starts at ``start`` moving at ``v_start`` mm/s (the first samples are a steady ramp).
    """
    v = np.zeros(n)
    k = 0
    while k < n:
        dur = int(rng.integers(150, 600))
        # moves or stops; no long slow crawls (stick-slip hunting at a few mm/s is chaotic)
        v[k:k + dur] = rng.choice((-1, 1)) * rng.uniform(0.25 * vmax, vmax) if rng.random() < 0.75 else 0.0
        k += dur
    for width in (60, 25):                       # acceleration then jerk limit
        v = np.convolve(v, np.ones(width) / width, mode="same")
    ramp = np.clip(np.arange(n) - 40, 0, None)
    blend = np.clip(ramp / 200.0, 0, 1)
    v = v_start * (1 - blend) + v * blend        # start in a steady ramp at v_start
    x = start + np.concatenate([[0.0], np.cumsum(v[:-1]) * Ts])
    scale = amplitude / max(1.0, np.ptp(x)) if amplitude else 1.0
    return start + (x - start) * min(1.0, scale) if v_start == 0 else x

