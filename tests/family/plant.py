"""Closed-loop simulation of one family plant: a sampled cascade controller around continuous
mechanics, written for this family alone (it imports neither ``fdid_fmi.virtual`` nor
``tests/plant2``).

Units: mm, mm/s, mm/s^2, N, kg, s. Force balance: acceleration [mm/s^2] = 1000 F [N] / m [kg].

Controller, once per sample k (period Ts):

1. motor encoder e_k = q round((x1(t_k) + n_k) / q), n_k ~ N(0, noise^2), q the resolution;
2. velocity estimate v_f <- v_f + Ts / (Ts + tau_vf) ((e_k - e_{k-1}) / Ts - v_f);
3. ``p-pi``: v_ref = kv (r_k - e_k) + vff (r_k - r_{k-1}) / Ts;
   F = kp_vel (v_ref - v_f) + I + aff m_est a_r / 1000, I += kp_vel Ts / ti_vel (v_ref - v_f);
   ``pid``: F = kp_pid (r_k - e_k) + kd_pid (vff (r_k - r_{k-1}) / Ts - v_f) + I + the same
   acceleration feed-forward, I += ki_pid Ts (r_k - e_k);
   a_r = (r_k - 2 r_{k-1} + r_{k-2}) / Ts^2; F saturated at +-f_max, the integrator frozen while
   the output is saturated in the direction it would push further (conditional integration);
4. F reaches the current loop ``compute_delay`` samples later and is held over the sample.

Continuous part over [t_k, t_k+1]: the current loop is a first-order lag of the held reference,
F(t) = F_r + (F(t_k) - F_r) exp(-(t - t_k) / tau_c), evaluated exactly at the stage times; the
mechanics (motor body x1, v1; tool body x2, v2 when the drive train is two-mass) advance by
``n_sub`` classical RK4 steps. Friction is a bristle (LuGre) model per body: over one RK4 step the
bristle deflection z is advanced exactly at the step's initial velocity,
z(h) = z_ss + (z - z_ss) exp(-sigma_0 |v| h / g(v)), z_ss = sign(v) g(v) / sigma_0,
g(v) = F_c + (F_s - F_c) exp(-(v / v_s)^2), and the force sigma_0 z(h) + sigma_1(v) (z(h) - z) / h
is held over the step (a body under a force below breakaway is held by the bristle spring).
Viscous friction, the position-periodic force, the drive-train spring with its dead zone (it can
only push) and the external force act inside the RK4 stages.
"""
from __future__ import annotations

import math

import numpy as np


def substeps(ax, Ts):
    """RK4 steps per controller sample: at least 2, and omega h <= 0.5 for the fastest
    oscillation of the mechanics (drive-train spring, bristle spring on either body)."""
    w = 0.0
    m1, m2 = ax.motor_mass, ax.table_mass
    if ax.two_mass:
        k = ax.spring_N_mm()
        w = max(w, math.sqrt(1000.0 * k * (1 / m1 + 1 / m2)))
    for share, m in ((1 - ax.table_share, m1 if ax.two_mass else m1 + m2),
                     (ax.table_share, m2 if ax.two_mass else m1 + m2)):
        if share > 0 and ax.coulomb > 0:
            s0 = share * max(ax.coulomb, ax.static) / ax.bristle_mm
            w = max(w, math.sqrt(1000.0 * s0 / m))
    return max(2, int(math.ceil(Ts * w / 0.5)))


def simulate_axis(ax, Ts, cmd, rng, f_ext=None):
    """Closed-loop run of one axis along a commanded position.

    Parameters
    ----------
    ax : family.params.AxisPlant
    Ts : float, s, controller sample time
    cmd : (N,) ndarray, mm, commanded position per sample
    rng : numpy.random.Generator, encoder noise
    f_ext : (N,) ndarray or None, N, force on the tool-side body (on the single body of a rigid
        drive train), held over each sample

    Returns
    -------
    dict of (N,) ndarrays at t_k: ``enc``, ``tool_enc`` (encoder readings, mm), ``x1``, ``x2``
    (true motor-side and tool-side positions, mm), ``vel`` (the controller's velocity estimate,
    mm/s), ``force_cmd`` (saturated controller output, N), ``force`` (motor force, N),
    ``table_acc`` (mean tool-side acceleration over [t_k, t_k+1], mm/s^2), ``n_sub`` (int)
    """
    cmd = np.asarray(cmd, float)
    N = cmd.size
    n_sub = substeps(ax, Ts)
    h = Ts / n_sub
    two = bool(ax.two_mass)
    m1 = ax.motor_mass if two else ax.motor_mass + ax.table_mass
    m2 = ax.table_mass
    r1, r2 = 1000.0 / m1, 1000.0 / m2
    sh = ax.table_share
    # friction of each body (rigid: all on the one body)
    Fc1, Fs1 = (1 - sh) * ax.coulomb, (1 - sh) * ax.static
    Fc2, Fs2 = sh * ax.coulomb, sh * ax.static
    if not two:
        Fc1, Fs1, Fc2, Fs2 = ax.coulomb, ax.static, 0.0, 0.0
    cv1 = ax.viscous * ((1 - sh) if two else 1.0)
    cv2 = ax.viscous * sh if two else 0.0
    s01 = max(Fc1, Fs1) / ax.bristle_mm if Fc1 > 0 else 0.0
    s02 = max(Fc2, Fs2) / ax.bristle_mm if Fc2 > 0 else 0.0
    s11 = 2 * ax.bristle_zeta * math.sqrt(s01 * m1 / 1000.0)
    s12 = 2 * ax.bristle_zeta * math.sqrt(s02 * m2 / 1000.0) if two else 0.0
    vs, fade = ax.stribeck_velocity, ax.bristle_fade
    k_sp = ax.spring_N_mm() if two else 0.0
    c_sp = 2 * ax.mode_zeta * math.sqrt(k_sp * m2 / 1000.0) if two else 0.0
    half = 0.5 * ax.backlash_mm
    Ap, kap, php = ax.periodic_amplitude, 2 * math.pi / ax.periodic_period, ax.periodic_phase
    tau_c = 1.0 / (2 * math.pi * ax.current_hz)
    # exact current-lag factors at the RK4 stage times (0, h/2, h) of every step of a sample
    E0 = np.exp(-np.arange(n_sub) * h / tau_c)
    Eh = np.exp(-(np.arange(n_sub) + 0.5) * h / tau_c)
    E1 = np.exp(-(np.arange(n_sub) + 1.0) * h / tau_c)
    E0, Eh, E1 = E0.tolist(), Eh.tolist(), E1.tolist()
    e_sample = math.exp(-Ts / tau_c)
    fext = np.zeros(N) if f_ext is None else np.asarray(f_ext, float)
    noise_m = (rng.standard_normal(N) * ax.noise_mm).tolist()
    noise_t = (rng.standard_normal(N) * ax.noise_mm).tolist()
    q = ax.resolution_mm

    def g_of(v, Fc, Fs):
        return Fc + (Fs - Fc) * math.exp(-(v / vs) ** 2) if Fs != Fc else Fc

    def bristle(z, v, Fc, Fs, s0, s1):
        av = abs(v)
        if av > 0.0:
            g = g_of(v, Fc, Fs)
            ah = s0 * av * h / g
            zss = g / s0 if v > 0 else -g / s0
            zn = zss + (z - zss) * math.exp(-ah)
        else:
            zn = z
        s1v = s1 * math.exp(-(v / fade) ** 2) if s1 else 0.0
        return zn, s0 * zn + s1v * (zn - z) / h

    def acc(x1, v1, x2, v2, F, Ff1, Ff2, Fe):
        f1 = F - Ff1 - cv1 * v1
        if Ap:
            f1 += Ap * math.sin(kap * x1 + php)
        if not two:
            a = r1 * (f1 + Fe)
            return a, a
        d = x1 - x2
        if d > half:
            Fk = k_sp * (d - half) + c_sp * (v1 - v2)
            if Fk < 0.0:
                Fk = 0.0
        elif d < -half:
            Fk = k_sp * (d + half) + c_sp * (v1 - v2)
            if Fk > 0.0:
                Fk = 0.0
        else:
            Fk = 0.0
        return r1 * (f1 - Fk), r2 * (Fk - Ff2 - cv2 * v2 + Fe)

    keys = ("enc", "tool_enc", "x1", "x2", "vel", "force_cmd", "force", "table_acc")
    out = {k: np.empty(N) for k in keys}
    o_enc, o_tool, o_x1, o_x2, o_vel, o_fc, o_f, o_acc = (out[k] for k in keys)
    x1 = x2 = float(cmd[0])
    if two:                     # tool side resting against the gap's middle
        x2 = x1
    v1 = v2 = 0.0
    z1 = z2 = 0.0
    F = 0.0
    I = 0.0
    vf = 0.0
    e_prev = q * round(x1 / q)
    r_prev = r_prev2 = float(cmd[0])
    alpha = Ts / (Ts + ax.tau_vf)
    pid = ax.controller == "pid"
    kv, kp, vff = ax.kv, ax.kp_vel, ax.vff
    ki = kp * Ts / ax.ti_vel if (not pid and math.isfinite(ax.ti_vel)) else 0.0
    kpp, kip, kdp = ax.kp_pid, ax.ki_pid * Ts, ax.kd_pid
    aff = ax.aff * ax.m_est / 1000.0
    fmax = ax.f_max
    pending = [0.0] * ax.compute_delay
    cmd_l = cmd.tolist()
    fext_l = fext.tolist()
    for k in range(N):
        # 1-3. controller at t_k
        enc = q * round((x1 + noise_m[k]) / q)
        o_enc[k] = enc
        o_tool[k] = q * round(((x2 if two else x1) + noise_t[k]) / q)
        o_x1[k], o_x2[k] = x1, (x2 if two else x1)
        vf += alpha * ((enc - e_prev) / Ts - vf)
        e_prev = enc
        o_vel[k] = vf
        r = cmd_l[k]
        vc = (r - r_prev) / Ts
        ac = (r - 2 * r_prev + r_prev2) / (Ts * Ts)
        r_prev2, r_prev = r_prev, r
        ep = r - enc
        if pid:
            err_i = ep
            u = kpp * ep + kdp * (vff * vc - vf) + I + aff * ac
            gi = kip
        else:
            err_i = kv * ep + vff * vc - vf
            u = kp * err_i + I + aff * ac
            gi = ki
        if u > fmax:
            u = fmax
            if err_i < 0:
                I += gi * err_i
        elif u < -fmax:
            u = -fmax
            if err_i > 0:
                I += gi * err_i
        else:
            I += gi * err_i
        o_fc[k] = u
        pending.append(u)
        Fr = pending.pop(0)
        o_f[k] = F
        Fe = fext_l[k]
        v2s = v2 if two else v1
        # 4. continuous part over the sample
        dF = F - Fr
        for j in range(n_sub):
            if s01:
                z1, Ff1 = bristle(z1, v1, Fc1, Fs1, s01, s11)
            else:
                Ff1 = 0.0
            if two and s02:
                z2, Ff2 = bristle(z2, v2, Fc2, Fs2, s02, s12)
            else:
                Ff2 = 0.0
            Fa, Fb, Fd = Fr + dF * E0[j], Fr + dF * Eh[j], Fr + dF * E1[j]
            hh = 0.5 * h
            a1, b1 = acc(x1, v1, x2, v2, Fa, Ff1, Ff2, Fe)
            a2, b2 = acc(x1 + hh * v1, v1 + hh * a1, x2 + hh * v2, v2 + hh * b1, Fb, Ff1, Ff2, Fe)
            a3, b3 = acc(x1 + hh * (v1 + hh * a1), v1 + hh * a2, x2 + hh * (v2 + hh * b1), v2 + hh * b2,
                         Fb, Ff1, Ff2, Fe)
            a4, b4 = acc(x1 + h * (v1 + hh * a2), v1 + h * a3, x2 + h * (v2 + hh * b2), v2 + h * b3,
                         Fd, Ff1, Ff2, Fe)
            # classical RK4 on (x, v): the stage positions use the stage velocities above
            x1 += h * (v1 + h * (a1 + a2 + a3) / 6.0)
            v1 += h * (a1 + 2 * a2 + 2 * a3 + a4) / 6.0
            if two:
                x2 += h * (v2 + h * (b1 + b2 + b3) / 6.0)
                v2 += h * (b1 + 2 * b2 + 2 * b3 + b4) / 6.0
        F = Fr + dF * e_sample
        o_acc[k] = ((v2 if two else v1) - v2s) / Ts
    out["n_sub"] = n_sub
    return out
