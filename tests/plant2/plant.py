"""Time stepping of the second plant: a CNC position loop at Ts around a drive with its own
faster velocity-loop clock, a continuous current loop and continuous mechanics.

Position loop, once per controller sample k (period Ts, 0.5 to 2 ms):

1. the motor encoder is read at t_k: x_enc = q round((x + n) / q), n ~ N(0, noise^2), q the
   resolution; the position loop may see it ``feedback_delay`` samples late;
2. v_ref = kv (x_cmd - x_enc) + vff (x_cmd[k] - x_cmd[k-1]) / Ts and the force feed-forward
   aff m_est a_cmd / 1000 (a_cmd the second backward difference of x_cmd) reach the drive
   ``compute_delay`` samples later and are held for Ts.

Drive (velocity loop), every drive cycle h = Ts / n (``drive_period``, 250 us by default):

3. velocity estimate from the encoder difference through a backward-Euler first-order filter:
   v_f <- v_f + alpha ((x_enc[j] - x_enc[j-1]) / h - v_f), alpha = h / (h + tau_vel);
4. F_ref = kp_vel (v_ref - v_f) + I + F_ff, saturated at +-f_max; I <- I + kp_vel h / ti_vel
   (v_ref - v_f) unless that drives a saturated output further (conditional integration);
   F_ref is applied one drive cycle later, held, as the reference of the current loop.

Continuous part (current loop as a 1st/2nd-order lag, motor body, table body, coupling, friction)
advanced by ``integration_steps`` fixed steps per drive cycle. Each step is a Lie splitting:

* LuGre bristle states, velocity frozen at the step start: dz/dt = v - a z with
  a = sigma_0 |v| / g(v) is linear in z, so z is advanced exactly,
  z(h) = z_ss + (z - z_ss) e^{-a h}, z_ss = g(v) sign(v) / sigma_0 (stable at any speed, where an
  explicit scheme on the stiff bristle would need micro-steps). The friction force applied over the
  step is sigma_0 z_mean + sigma_1(v) (z(h) - z) / h, z_mean the exact mean of z over the step;
* motor body, table body, coupling, current loop, viscous and position-periodic forces: one
  classical RK4 step with the bristle force held.

A body that stops under a force below the breakaway level is held by the bristle spring
(presliding of a few um), so the axis sticks without any switching logic.
"""
from __future__ import annotations

import math

import numpy as np

from fdid_fmi.trace import Channel, Trace

from .params import Axis, Machine
from .trajectories import Path


def _lugre(z, v, Fc, Fs, vs, s0, s1, fade, h):
    """Exact bristle update at frozen velocity. Returns (z_new, friction force over the step, N)."""
    av = abs(v)
    if av > 0.0:
        g = Fc + (Fs - Fc) * math.exp(-(v / vs) ** 2) if Fs != Fc else Fc
        a = s0 * av / g
        ah = a * h
        if ah > 1e-12:
            zss = g / s0 if v > 0 else -g / s0
            e = math.exp(-ah)
            zn = zss + (z - zss) * e
            zm = zss + (z - zss) * (1.0 - e) / ah
        else:
            zn = z + v * h
            zm = z + 0.5 * v * h
    else:
        zn = zm = z
    s1v = s1 * math.exp(-(v / fade) ** 2) if s1 else 0.0
    return zn, s0 * zm + s1v * (zn - z) / h


def simulate_axis(ax: Axis, Ts, cmd, rng, f_ext=None, drive_period=2.5e-4, integration_steps=1):
    """Closed-loop run of one axis.

    Parameters
    ----------
    ax : Axis
    Ts : float, s
    cmd : ndarray, commanded position per sample, mm
    rng : numpy.random.Generator (encoder noise)
    f_ext : ndarray or None, external force on the table per sample, N (held over the sample)
    drive_period : float, s, clock of the velocity loop; Ts must be an integer multiple of it
    integration_steps : int, fixed integration steps per drive period

    Returns
    -------
    dict of ndarrays, one value per sample at t_k: ``motor``, ``table`` (true positions, mm),
    ``motor_v``, ``table_v`` (mm/s), ``enc``, ``tool_enc`` (encoder readings, mm), ``vel``
    (controller velocity estimate, mm/s), ``force_cmd`` (N), ``force`` (actual motor force, N),
    ``friction`` (total LuGre force, N, positive when it opposes positive motion; viscous part
    excluded), ``table_acc`` (mean table acceleration over
    [t_k, t_k+1], mm/s^2)
    """
    cmd = np.asarray(cmd, float)
    N = cmd.size
    n_sub = int(round(Ts / drive_period))
    if n_sub < 1 or abs(n_sub * drive_period - Ts) > 1e-9 * Ts:
        raise ValueError(f"Ts = {Ts} s is not an integer multiple of the drive period {drive_period} s")
    h = Ts / n_sub                       # drive cycle (velocity loop), s
    n_int = int(integration_steps)
    hi = h / n_int                       # integration step, s
    two = bool(ax.two_mass)
    m1 = ax.motor_mass if two else ax.mass
    m2 = ax.table_mass
    r1, r2 = 1000.0 / m1, 1000.0 / m2
    share = ax.table_share if two else 0.0
    Fc1, Fs1, c1v = (1 - share) * ax.coulomb, (1 - share) * ax.static, (1 - share) * ax.viscous
    Fc2, Fs2, c2v = share * ax.coulomb, share * ax.static, share * ax.viscous
    s0_1 = Fc1 / ax.bristle if Fc1 > 0 else 0.0
    s0_2 = Fc2 / ax.bristle if Fc2 > 0 else 0.0
    s1_1 = 2 * ax.bristle_zeta * math.sqrt(s0_1 * m1 / 1000.0)
    s1_2 = 2 * ax.bristle_zeta * math.sqrt(s0_2 * m2 / 1000.0)
    vs, fade = ax.stribeck_velocity, ax.bristle_fade
    k = m2 * (2 * math.pi * ax.lock_hz) ** 2 / 1000.0          # N/mm
    c = 2 * ax.mode_zeta * math.sqrt(k * m2 / 1000.0)          # N/(mm/s)
    half = 0.5 * ax.backlash
    wc = 2 * math.pi * ax.current_hz
    wc2, zw2 = wc * wc, 2 * ax.current_zeta * wc
    order2 = ax.current_order == 2
    A, lam, ph = ax.periodic_amplitude, 2 * math.pi / ax.periodic_period, ax.periodic_phase
    fext = np.zeros(N) if f_ext is None else np.asarray(f_ext, float)

    def deriv(x1, v1, x2, v2, F, Fd, Ff1, Ff2, Fe):
        f1 = F - Ff1 - c1v * v1
        if A:
            f1 += A * math.sin(lam * x1 + ph)
        if two:
            d = x1 - x2
            if d > half:
                Fk = k * (d - half) + c * (v1 - v2)
                Fk = Fk if Fk > 0.0 else 0.0
            elif d < -half:
                Fk = k * (d + half) + c * (v1 - v2)
                Fk = Fk if Fk < 0.0 else 0.0
            else:
                Fk = 0.0
            a1 = r1 * (f1 - Fk)
            a2 = r2 * (Fk - Ff2 - c2v * v2 + Fe)
        else:
            a1 = r1 * (f1 + Fe)
            a2 = a1
        if order2:
            return v1, a1, v2, a2, Fd, wc2 * (Fr - F) - zw2 * Fd
        return v1, a1, v2, a2, wc * (Fr - F), 0.0

    # encoder noise drawn up front (deterministic per seed), one value per drive cycle
    n_m = rng.standard_normal(N * n_sub) * ax.noise
    n_t = rng.standard_normal(N) * ax.noise
    q = ax.resolution
    out = {key: np.empty(N) for key in ("motor", "table", "motor_v", "table_v", "enc", "tool_enc", "vel",
                                        "vel_ref", "force_cmd", "force", "friction", "table_acc")}
    # initial state: at rest at the first command, bristles relaxed
    x1 = x2 = float(cmd[0])
    v1 = v2 = F = Fd = z1 = z2 = 0.0
    I = vf = 0.0
    alpha = h / (h + ax.tau_vel)
    kp, ki = ax.kp_vel, (ax.kp_vel * h / ax.ti_vel if math.isfinite(ax.ti_vel) else 0.0)
    m_est = ax.mass if ax.mass_estimate is None else ax.mass_estimate
    aff = ax.aff * m_est / 1000.0
    fmax, kv, vff = ax.f_max, ax.kv, ax.vff
    pos_pending = [(0.0, 0.0)] * ax.compute_delay          # (v_ref, force feed-forward) in flight
    enc_hist = [q * round(x1 / q)] * ax.feedback_delay
    e_prev = q * round(x1 / q)
    c_prev = c_prev2 = float(cmd[0])
    Ff1 = Ff2 = 0.0
    Fr = 0.0                                                # force reference held by the current loop
    j = 0
    for i in range(N):
        # 1. position loop at t_k on the (possibly late) motor encoder
        e_m = q * round((x1 + n_m[j]) / q)
        out["motor"][i], out["table"][i] = x1, (x2 if two else x1)
        out["motor_v"][i], out["table_v"][i] = v1, (v2 if two else v1)
        out["enc"][i] = e_m
        out["tool_enc"][i] = q * round(((x2 if two else x1) + n_t[i]) / q)
        out["vel"][i] = vf
        enc_hist.append(e_m)
        xe = enc_hist.pop(0)
        ci = float(cmd[i])
        vr_new = kv * (ci - xe) + vff * (ci - c_prev) / Ts
        ff_new = aff * (ci - 2 * c_prev + c_prev2) / (Ts * Ts)
        c_prev2, c_prev = c_prev, ci
        pos_pending.append((vr_new, ff_new))
        vref, fff = pos_pending.pop(0)
        out["vel_ref"][i] = vref
        out["force"][i] = F
        Fe = fext[i]
        v2_start = v2 if two else v1
        fr_sum = ff_sum = 0.0
        for sub in range(n_sub):
            # 2. drive cycle: velocity PI on the filtered encoder difference; its output is
            #    applied one drive cycle later (Fr from the previous cycle drives this step)
            e_m = q * round((x1 + n_m[j]) / q) if sub else e_m
            j += 1
            vf += alpha * ((e_m - e_prev) / h - vf)
            e_prev = e_m
            ev = vref - vf
            u = kp * ev + I + fff
            if u > fmax:
                u = fmax
                if ev < 0:
                    I += ki * ev
            elif u < -fmax:
                u = -fmax
                if ev > 0:
                    I += ki * ev
            else:
                I += ki * ev
            fr_sum += u
            # 3. continuous part over one drive cycle, n_int fixed steps
            for _ in range(n_int):
                z1, Ff1 = _lugre(z1, v1, Fc1, Fs1, vs, s0_1, s1_1, fade, hi) if s0_1 else (z1, 0.0)
                if two:
                    z2, Ff2 = _lugre(z2, v2, Fc2, Fs2, vs, s0_2, s1_2, fade, hi) if s0_2 else (z2, 0.0)
                ff_sum += Ff1 + Ff2
                k1 = deriv(x1, v1, x2, v2, F, Fd, Ff1, Ff2, Fe)
                hh = 0.5 * hi
                k2 = deriv(x1 + hh * k1[0], v1 + hh * k1[1], x2 + hh * k1[2], v2 + hh * k1[3], F + hh * k1[4],
                           Fd + hh * k1[5], Ff1, Ff2, Fe)
                k3 = deriv(x1 + hh * k2[0], v1 + hh * k2[1], x2 + hh * k2[2], v2 + hh * k2[3], F + hh * k2[4],
                           Fd + hh * k2[5], Ff1, Ff2, Fe)
                k4 = deriv(x1 + hi * k3[0], v1 + hi * k3[1], x2 + hi * k3[2], v2 + hi * k3[3], F + hi * k3[4],
                           Fd + hi * k3[5], Ff1, Ff2, Fe)
                s = hi / 6.0
                x1 += s * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
                v1 += s * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
                if two:
                    x2 += s * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
                    v2 += s * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3])
                F += s * (k1[4] + 2 * k2[4] + 2 * k3[4] + k4[4])
                Fd += s * (k1[5] + 2 * k2[5] + 2 * k3[5] + k4[5])
            Fr = u
        out["force_cmd"][i] = fr_sum / n_sub
        out["friction"][i] = ff_sum / (n_sub * n_int)
        out["table_acc"][i] = ((v2 if two else v1) - v2_start) / Ts
    return out


def _delayed(x, d):
    if d <= 0:
        return x
    return np.concatenate([np.full(d, x[0]), x[:-d]])


def _order(machine: Machine):
    """Axes in an order where every coupling source comes before its target."""
    names = [a.name for a in machine.axes]
    deps = {n: {c.source for c in machine.couplings if c.target == n} for n in names}
    done = []
    while len(done) < len(names):
        ready = [n for n in names if n not in done and deps[n] <= set(done)]
        if not ready:
            raise ValueError("cyclic axis couplings")
        done.extend(ready)
    return done


def simulate(machine: Machine, path: Path, seed=0, tool=None, current=False, truth_channels=False,
             source=None):
    """Simulate the machine along a commanded path and return a measured trace.

    Parameters
    ----------
    machine : Machine
    path : Path (its Ts must equal machine.Ts; axes of the path not in the machine are ignored,
        machine axes not in the path hold their position at 0 mm)
    seed : int, encoder noise seed
    tool : None (a ``tool`` channel for every two-mass axis), or a collection of axis names
        that get a ``tool`` channel (the tool-side encoder, mm)
    current : bool, add a ``cur`` channel (force command / kt, A)
    truth_channels : bool, add ``<axis>_motor_true``, ``<axis>_tool_true`` (mm),
        ``<axis>_force_N``, ``<axis>_friction_N`` as extra channels (a real trace lacks them)
    source : str, the trace's source label

    Returns
    -------
    fdid_fmi.trace.Trace
        roles per axis ``cmd`` (mm), ``act`` (motor encoder, mm), ``vel`` (controller velocity
        estimate, mm/s), optionally ``tool`` and ``cur``; ``meta["truth"]`` holds every parameter,
        the effects present and the path description.
    """
    if abs(path.Ts - machine.Ts) > 1e-12:
        raise ValueError(f"path sampled at {path.Ts} s, machine at {machine.Ts} s")
    N = path.n
    rng = np.random.default_rng(seed)
    names = _order(machine)
    runs = {}
    for name in names:
        ax = machine.axis(name)
        cmd = path.cmd.get(name, np.zeros(N))
        f = np.zeros(N)
        for cp in machine.couplings:
            if cp.target == name:
                f -= cp.gain_kg * runs[cp.source]["table_acc"] / 1000.0
        runs[name] = simulate_axis(ax, machine.Ts, cmd, np.random.default_rng(rng.integers(2 ** 32)), f,
                                   machine.drive_period, machine.integration_steps)
        runs[name]["cmd"] = np.asarray(cmd, float)
    chans, roles = {}, {}
    for ax in machine.axes:
        r, a, d = runs[ax.name], ax.name, ax.record_delay
        roles[a] = {}

        def put(role, key, unit, data):
            chans[key] = Channel(key, unit, data)
            roles[a][role] = key

        put("cmd", f"{a}_cmd_mm", "mm", r["cmd"])
        put("act", f"{a}_mm", "mm", _delayed(r["enc"], d))
        put("vel", f"{a}_v_mm_s", "mm_s", _delayed(r["vel"], d))
        if (tool is None and ax.two_mass) or (tool is not None and a in tool):
            put("tool", f"{a}_tool_mm", "mm", _delayed(r["tool_enc"], d))
        if current:
            put("cur", f"{a}_cur_A", "A", _delayed(r["force_cmd"] / ax.kt, d))
        if truth_channels:
            for key, unit, arr in ((f"{a}_motor_true", "mm", r["motor"]), (f"{a}_tool_true", "mm", r["table"]),
                                   (f"{a}_force_N", "N", r["force"]), (f"{a}_friction_N", "N", r["friction"])):
                chans[key] = Channel(key, unit, arr)
    truth = machine.truth()
    truth["path"] = dict(path.info)
    truth["seed"] = seed
    return Trace(t=path.t, channels=chans, roles=roles, source=source or f"plant2:{path.info.get('kind', 'path')}",
                 meta={"truth": truth})
