"""Time simulation of the virtual feed drive: sampled P-PI cascade on an exactly integrated plant.

Integration scheme
------------------
The linear plant of the whole machine (masses, springs, dampers, current lag, cross-axis
coupling; :func:`fdid_fmi.virtual.drive.build_plant`) is discretised *exactly* with a zero-order
hold (matrix exponential) over one controller sample Ts and over a sub-step h = Ts / n_sub.
The nonlinear forces enter as extra inputs held over a (sub-)step:

* Coulomb / Stribeck friction is *implicit*: the velocity at the end of the step is affine in
  the friction force, v = v_free + beta f, and f in -F(v) Sign(v) (set-valued at v = 0), so the
  step is solved in closed form: slide (f = -F+ or +F-) or stick (v = 0 exactly, |f| below the
  breakaway level). No regularisation, no chatter at rest. The Stribeck excess is evaluated at
  the velocity at the start of the step (at rest: the full breakaway force).
* the position-periodic force is evaluated at the predicted mid-step position (2nd order);
* backlash of a two-mass axis is a dead zone of the spring: the plant keeps the full spring and
  a correction force k clip(x_m - x_t, -b/2, b/2) is held per sub-step.

A full Ts step is used while every friction axis either slides in one direction with |v| above
the Stribeck band (then the held Coulomb force is exact) or stays stuck for the whole sample, and
no backlash gap is open; otherwise the sample is redone in n_sub sub-steps (the counts are in
``meta["truth"]["steps"]``). With all nonlinear effects off, the simulation *is* the
discrete closed loop of :func:`fdid_fmi.virtual.drive.sampled_closed_loop` (to rounding).

Controller (per axis, at t_k = k Ts): y_k = Q(x_{k-d} + noise) (delay d, quantisation Q),
e = r_k - y_k, v_m = (y_k - y_{k-1}) / Ts, eps = Kp e + vel_ff rd_k - v_m,
I += Ts eps (not while the force limit pushes the same way), u = Kv (eps + I/Ti) + acc_ff m rdd_k,
clipped to +-force_limit, held until t_{k+1}. The recorded ``act`` is y (shifted by
``record_delay``), ``vel`` is v_m, ``cur`` is the applied motor force / kt.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..trace import Trace
from .drive import AxisConfig, MachineConfig, build_plant, linear_truth, zoh
from .trajectories import Trajectory

__all__ = ["simulate_machine", "simulate_drive"]


def _commands(cfg, commands, Ts):
    names = cfg.axis_names
    if isinstance(commands, Trajectory):
        if abs(commands.Ts - Ts) > 1e-12 * Ts:
            raise InputError(f"trajectory sample time {commands.Ts} s differs from the machine's {Ts} s",
                             column="Ts")
        commands = commands.positions
    if isinstance(commands, Trace):
        commands = {a: commands.cmd(a) for a in commands.axes}
    if not isinstance(commands, dict):
        if len(names) != 1:
            raise InputError(f"pass a dict of commands for the axes {names}", column="commands")
        commands = {names[0]: commands}
    n = None
    out = {}
    for a in names:
        if a not in commands:
            raise InputError(f"no command for axis {a!r} (given: {sorted(commands)})", column=a)
        r = np.array(commands[a], dtype=float)  # private copy
        if r.ndim != 1 or r.size < 2:
            raise InputError(f"command must be a 1-D array of >= 2 samples, got shape {r.shape}", column=a)
        bad = ~np.isfinite(r)
        if bad.any():
            raise InputError("command contains NaN or inf", column=a, row=int(np.argmax(bad)) + 1)
        if n is not None and r.size != n:
            raise InputError(f"has {r.size} samples, other axes have {n}", column=a)
        n = r.size
        out[a] = r
    extra = set(commands) - set(names)
    if extra:
        raise InputError(f"commands for unknown axes {sorted(extra)} (machine axes: {names})",
                         column="commands")
    return out, n


def simulate_machine(cfg: MachineConfig, commands, seed=0, truth=True, source=None) -> Trace:
    """Simulate a virtual machine following commanded positions.

    Parameters
    ----------
    cfg : MachineConfig
    commands : Trajectory, Trace (its ``cmd`` roles), dict axis -> array (mm), or one array
        for a one-axis machine; sampled at cfg.Ts.
    seed : int      seeds the measurement noise (the only random part)
    truth : bool    compute the linearised truth into ``meta["truth"]["linear"]``
    source : str    trace source label

    Returns
    -------
    Trace with, per axis, roles ``cmd``, ``act`` (measured motor position, mm), ``vel`` (mm/s),
    ``cur`` (A), and for two-mass / backlash axes ``tool`` (mm) and (two-mass) ``acc`` (tool-side
    acceleration, mm/s^2). Extra channels ``<axis>_act_true`` (motor position, mm),
    ``<axis>_vel_true`` (mm/s), ``<axis>_force`` (applied motor force, N) and
    ``<axis>_friction`` (friction force, N). ``meta["truth"]`` holds the configuration, the
    effects switched on and (``truth=True``) the linearised closed-loop truth.
    """
    cfg.validate()
    Ts = float(cfg.Ts)
    R, N = _commands(cfg, commands, Ts)
    plant = build_plant(cfg)
    axes = cfg.axes
    na, nd, nz = len(axes), plant.n_dof, plant.nz
    n_sub = int(cfg.n_sub)
    h = Ts / n_sub
    Bfull = np.hstack([plant.Bu, plant.Bw])
    PhiT, GT = zoh(plant.A, Bfull, Ts)
    Phih, Gh = zoh(plant.A, Bfull, h)
    GuT, GwT = GT[:, :na], GT[:, na:]
    Guh, Gwh = Gh[:, :na], Gh[:, na:]

    rng = np.random.default_rng(seed)
    noise = [rng.normal(0.0, a.noise_std, N) if a.noise_std > 0 else None for a in axes]

    # ------------------------------------------------------------------ per-axis constants
    mi = [plant.motor[a.name] for a in axes]
    ti = [plant.tool[a.name] for a in axes]
    xm_i = [plant.pos(m) for m in mi]
    vm_i = [plant.vel(m) for m in mi]
    fric_dof = [(ti[i] if (a.two_mass and a.friction_side == "tool") else mi[i]) for i, a in enumerate(axes)]
    fric_v = [plant.vel(d) for d in fric_dof]
    fric_axes = [i for i, a in enumerate(axes) if a.has_friction]
    per_axes = [i for i, a in enumerate(axes) if a.periodic_amplitude]
    bl2_axes = [i for i, a in enumerate(axes) if a.backlash > 0 and a.two_mass]
    Fpos = [a.coulomb for a in axes]
    Fneg = [a.coulomb if a.coulomb_neg is None else a.coulomb_neg for a in axes]
    Fs = [a.stribeck for a in axes]
    vs = [a.stribeck_velocity for a in axes]
    v_safe = [3.0 * a.stribeck_velocity if a.stribeck > 0 else 0.0 for a in axes]
    beta_h = [Gwh[fric_v[i], fric_dof[i]] for i in range(na)]
    beta_T = [GwT[fric_v[i], fric_dof[i]] for i in range(na)]
    stuck = [True] * na  # at rest at the start
    # a stuck axis keeps |v| ~ 0 up to cross-coupling terms of the other axes' friction
    v_stuck = [max(1e-6, 1e-3 * a.stribeck_velocity) for a in axes]
    n_full = n_split = 0
    gcol_h = [Gwh[:, fric_dof[i]].copy() for i in range(na)]
    gcol_T = [GwT[:, fric_dof[i]].copy() for i in range(na)]
    off_axes = [i for i, a in enumerate(axes) if a.force_offset]
    nonlinear = bool(fric_axes or per_axes or bl2_axes or off_axes)

    ctrl = []
    for a in axes:
        mff = a.total_mass if a.ff_mass is None else a.ff_mass
        ctrl.append((a.Kp, a.Kv, a.Ti, a.vel_ff, a.acc_ff * mff / 1000.0, a.force_limit))
    res = [a.resolution for a in axes]
    dly = [int(a.delay) for a in axes]

    # ------------------------------------------------------------------ state
    z = np.zeros(nz)
    for i, a in enumerate(axes):
        z[plant.pos(mi[i])] = R[a.name][0]
        if ti[i] is not None:
            z[plant.pos(ti[i])] = R[a.name][0]
    Z = np.empty((N, nz))
    Uu = np.empty((N, na))
    Wrec = np.zeros((N, nd))
    meas = np.empty((N, na))   # measurement before the in-loop delay
    Y = np.empty((N, na))      # what the controller sees (delayed)
    Vm = np.empty((N, na))
    Ff = np.zeros((N, na))
    Rp = [np.concatenate((R[a.name], R[a.name][-1:])) for a in axes]  # look-ahead pad
    integ = [0.0] * na
    yprev = [None] * na
    u = np.zeros(na)

    def meas_of(i, x, k):
        if noise[i] is not None:
            x = x + noise[i][k]
        if res[i] > 0:
            x = res[i] * math.floor(x / res[i] + 0.5)
        return x

    def explicit_w(zz, dt):
        w = np.zeros(nd)
        for i in per_axes:
            a = axes[i]
            xmid = zz[xm_i[i]] + 0.5 * dt * zz[vm_i[i]]
            w[mi[i]] += a.periodic_amplitude * math.sin(2 * math.pi * xmid / a.periodic_period
                                                        + a.periodic_phase)
        for i in off_axes:
            w[mi[i]] += axes[i].force_offset
        for i in bl2_axes:
            k_s = plant.spring[axes[i].name][0]
            half = 0.5 * axes[i].backlash
            d = zz[plant.pos(mi[i])] - zz[plant.pos(ti[i])]
            corr = k_s * min(max(d, -half), half)
            w[mi[i]] += corr
            w[ti[i]] -= corr
        return w

    def fmag(i, v_start, direction):
        base = Fpos[i] if direction > 0 else Fneg[i]
        if Fs[i] > 0:
            base += Fs[i] * math.exp(-(v_start / vs[i]) ** 2)
        return base

    for k in range(N):
        # ---------------------------------------------------------- measure + control
        Z[k] = z
        for i in range(na):
            meas[k, i] = meas_of(i, z[xm_i[i]], k)
        for i in range(na):
            y = meas[k - dly[i], i] if k >= dly[i] else meas[0, i]
            Y[k, i] = y
            if yprev[i] is None:
                yprev[i] = y
            Kp, Kv, Ti, kvff, kaff, flim = ctrl[i]
            r = Rp[i]
            rk = r[k]
            rkm = r[k - 1] if k > 0 else r[0]
            rkp = r[k + 1]
            vmeas = (y - yprev[i]) / Ts
            yprev[i] = y
            eps = Kp * (rk - y) + kvff * (rkp - rkm) / (2 * Ts) - vmeas
            I_new = integ[i] + Ts * eps
            uu = Kv * (eps + I_new / Ti) + kaff * (rkp - 2 * rk + rkm) / (Ts * Ts)
            if abs(uu) > flim:
                # conditional integration: no further integration into the limit
                if eps * uu > 0:
                    I_new = integ[i]
                    uu = Kv * (eps + I_new / Ti) + kaff * (rkp - 2 * rk + rkm) / (Ts * Ts)
                uu = min(max(uu, -flim), flim)
            integ[i] = I_new
            Vm[k, i] = vmeas
            u[i] = uu
        Uu[k] = u
        if k == N - 1:
            break
        # ---------------------------------------------------------- plant over [t_k, t_k+1]
        if not nonlinear:
            z = PhiT @ z + GuT @ u
            continue
        w = explicit_w(z, Ts)
        zf = PhiT @ z + GuT @ u + GwT @ w
        ok = cfg.adaptive and all(abs(z[plant.pos(mi[i])] - z[plant.pos(ti[i])]) >= 0.5 * axes[i].backlash
                                  for i in bl2_axes)
        fvals = {}
        if ok:
            for i in fric_axes:
                v0 = z[fric_v[i]]
                if stuck[i] and abs(v0) <= v_stuck[i]:
                    # stays stuck for the whole sample if the breakaway force holds it
                    vfree = zf[fric_v[i]]
                    lim = fmag(i, 0.0, 1) if vfree > 0 else fmag(i, 0.0, -1)
                    if abs(vfree) > beta_T[i] * lim:
                        ok = False
                        break
                    f = -vfree / beta_T[i]
                elif abs(v0) > v_safe[i]:
                    f = -fmag(i, abs(v0), 1) if v0 > 0 else fmag(i, abs(v0), -1)
                else:
                    ok = False
                    break
                fvals[i] = f
                zf += gcol_T[i] * f
            if ok:
                for i in fric_axes:
                    if stuck[i] and abs(z[fric_v[i]]) <= v_stuck[i]:
                        continue
                    v0, v1 = z[fric_v[i]], zf[fric_v[i]]
                    if v0 * v1 <= 0 or abs(v1) <= v_safe[i]:
                        ok = False
                        break
            if ok and bl2_axes:
                ok = all(abs(zf[plant.pos(mi[i])] - zf[plant.pos(ti[i])]) >= 0.5 * axes[i].backlash
                         and (zf[plant.pos(mi[i])] - zf[plant.pos(ti[i])])
                         * (z[plant.pos(mi[i])] - z[plant.pos(ti[i])]) > 0 for i in bl2_axes)
        if ok:
            Wrec[k] = w
            for i in fric_axes:
                Wrec[k, fric_dof[i]] += fvals[i]
                Ff[k, i] = fvals[i]
                stuck[i] = stuck[i] and abs(z[fric_v[i]]) <= v_stuck[i]
            z = zf
            n_full += 1
            continue
        n_split += 1
        cu = Guh @ u
        for s in range(n_sub):
            w = explicit_w(z, h)
            zf = Phih @ z + cu + Gwh @ w
            if s == 0:
                Wrec[k] = w
            for i in fric_axes:
                vstart = abs(z[fric_v[i]])
                vfree = zf[fric_v[i]]
                b = beta_h[i]
                fp = fmag(i, vstart, 1)
                fn = fmag(i, vstart, -1)
                if vfree > b * fp:
                    f = -fp
                    stuck[i] = False
                elif vfree < -b * fn:
                    f = fn
                    stuck[i] = False
                else:
                    f = -vfree / b  # stick: v = 0 at the end of the sub-step
                    stuck[i] = True
                zf += gcol_h[i] * f
                if s == 0:
                    Wrec[k, fric_dof[i]] += f
                    Ff[k, i] = f
            z = zf

    if N > 1:
        Ff[N - 1] = Ff[N - 2]
        Wrec[N - 1] = Wrec[N - 2]

    # ------------------------------------------------------------------ outputs
    Aq, Bqu, Bqw = plant.force_rows()
    t = Ts * np.arange(N)
    axes_out, extra, units = {}, {}, {}
    for i, a in enumerate(axes):
        dr = int(a.record_delay)
        act = _shift(Y[:, i], dr)
        vel = _shift(Vm[:, i], dr)
        if plant.lag[a.name] is not None:
            force = Z[:, plant.lag[a.name]]
        else:
            force = Uu[:, i]
        roles = {"cmd": R[a.name], "act": act, "vel": vel, "cur": force / a.kt}
        if a.two_mass:
            tdof = ti[i]
            roles["tool"] = Z[:, plant.pos(tdof)]
            roles["acc"] = Z @ Aq[tdof] + Uu @ Bqu[tdof] + Wrec @ Bqw[tdof]
        elif a.backlash > 0:
            roles["tool"] = _play(Z[:, xm_i[i]], a.backlash, R[a.name][0])
        axes_out[a.name] = roles
        extra[f"{a.name}_act_true"] = Z[:, xm_i[i]].copy()
        extra[f"{a.name}_vel_true"] = Z[:, vm_i[i]].copy()
        extra[f"{a.name}_force"] = force.copy()
        extra[f"{a.name}_friction"] = Ff[:, i].copy()
        units.update({f"{a.name}_act_true": "mm", f"{a.name}_vel_true": "mm_s",
                      f"{a.name}_force": "N", f"{a.name}_friction": "N"})
    meta_truth = {"machine": cfg.to_dict(), "effects": {a.name: a.effects() for a in axes},
                  "seed": seed,
                  "steps": {"full": n_full, "split_into_sub_steps": n_split},
                  "integration": (f"exact ZOH of the linear plant over Ts={Ts:g} s; {n_sub} sub-steps "
                                  "per sample near friction sticking/reversal or backlash gap; implicit "
                                  "Coulomb/Stribeck friction, mid-step periodic force"),
                  "channels": {"act": "measured motor position y (noise, quantisation, in-loop "
                                      "delay, then record delay)",
                               "vel": "controller velocity feedback (y_k - y_{k-1}) / Ts",
                               "cur": "applied motor force / kt (A)",
                               "tool": "tool-side position (two-mass) or motor position through "
                                       "the backlash play (rigid)",
                               "acc": "tool-side acceleration (two-mass)"}}
    if truth:
        meta_truth["linear"] = linear_truth(cfg)
    src = source or f"virtual:{cfg.name}"
    return Trace.from_arrays(t, axes_out, extra=extra, units=units, source=src,
                             meta={"truth": meta_truth, "virtual": True})


def _shift(x, d):
    """x delayed by d samples, the first d samples held at x[0]."""
    if d == 0:
        return x.copy()
    out = np.empty_like(x)
    out[:d] = x[0]
    out[d:] = x[:-d]
    return out


def _play(x, b, x0):
    """Kinematic backlash (play operator) of width b: the output moves only when pushed."""
    half = 0.5 * b
    out = np.empty_like(x)
    p = float(x0)
    for k, xk in enumerate(x.tolist()):
        if xk - p > half:
            p = xk - half
        elif p - xk > half:
            p = xk + half
        out[k] = p
    return out


def simulate_drive(axis: AxisConfig, command, Ts=1e-3, seed=0, n_sub=8, truth=True, source=None) -> Trace:
    """Simulate one axis (a one-axis machine). ``command``: array (mm) or Trajectory."""
    if isinstance(command, Trajectory):
        Ts = command.Ts
        if len(command.axes) != 1:
            raise InputError(f"a single-axis simulation needs a one-axis trajectory, got {command.axes}",
                             column="command")
        command = {axis.name: command.positions[command.axes[0]]}
    cfg = MachineConfig([axis], Ts=Ts, n_sub=n_sub, name=axis.name)
    return simulate_machine(cfg, command, seed=seed, truth=truth, source=source)
