"""Seeded cases of the plant family: a plant, zero to two undeclared effects, training and
validation traces. Nothing is stored: ``case(seed)`` builds the same case, bit for bit, every time.

Drawing order (every draw is made whatever is chosen, so that a case rebuilt ``without`` some of
its effects differs from it in those effects alone, with the same noise and paths):

1. sample time Ts in {0.5, 1, 1.5, 2} ms, one axis (60 %) or two; path limits: top feed 1-20 m/min,
   acceleration 0.5-8 m/s^2 (lower for heavy axes), jerk time 5-40 ms or a trapezoidal profile
   (30 %), stroke 150-800 mm;
2. each axis (:func:`family.params.draw_axis`);
3. the parameters of every effect kind (below), then how many effects the case has (none 30 %,
   one 45 %, two 25 %) and which (distinct kinds; ``coupling`` only on two axes, where it is
   three times as likely as each other kind, so that over the family every kind is about as
   frequent);
4. the paths and the noise seeds.

Effects act on the first axis (``x``; the source of a coupling is ``y``). Magnitudes are drawn
log-uniform on a scale from well below the noise floor to dominant:

=====================  =====================================================================
kind                   what changes (magnitude, unit)
=====================  =====================================================================
``stribeck``           breakaway F_s = F_c + excess; excess 0.02-3 F_c (N), v_s 0.5-10 mm/s
``backlash``           a two-mass drive train (lock 250-450 Hz) with a dead zone of 0.1-50 um
                       (mm); tool-side encoder recorded in half the cases (``params["tool"]``)
``periodic_position``  force A sin(2 pi x1 / period + phase) on the motor side; A 0.01-2 F_c
                       (N), period 1-20 mm
``delay``              every measured channel recorded 1-3 samples after the command (samples)
``mode``               a tool-side body of 3-45 % of the mass on a spring: locked-motor mode
                       15-150 Hz, damping 0.01-0.08; magnitude its mass (kg)
``coupling``           force on x = -g (tool-side acceleration of y) / 1000, g = 0.001-0.3 times
                       the mass of x (kg)
``extra_input``        an external force on x (band-limited noise, 1-10 Hz, RMS 0.02-3 F_c, N),
                       recorded in the extra channel ``x_load_N``
=====================  =====================================================================

Clean cases (and cases without ``extra_input``) carry a measured channel that does not act on the
plant in a quarter of the cases (``Machine.decoy_channel``), as real traces carry channels that do
not matter.

A case's split is ``calibration`` for an even seed and ``held-out`` for an odd one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from fdid_fmi.trace import Channel, Trace

from . import paths
from .params import Effect, Machine, draw_axis, loguniform
from .plant import simulate_axis

KINDS = ("stribeck", "backlash", "periodic_position", "delay", "mode", "coupling", "extra_input")
UNITS = {"stribeck": "N", "backlash": "mm", "periodic_position": "N", "delay": "samples", "mode": "kg",
         "coupling": "kg", "extra_input": "N"}
SPLITS = ("calibration", "held-out")
COUPLING_WEIGHT = 3.0       # odds of coupling against any other kind on a two-axis plant


def split_of(seed):
    """``calibration`` for an even seed, ``held-out`` for an odd one."""
    return SPLITS[int(seed) % 2]


def seeds(split, n, start=0):
    """The first ``n`` seeds >= ``start`` of a split (``calibration``, ``held-out`` or ``all``)."""
    out, s = [], int(start)
    while len(out) < n:
        if split == "all" or split_of(s) == split:
            out.append(s)
        s += 1
    return out


@dataclass
class Case:
    """One generated case.

    seed : int; split : ``calibration`` or ``held-out``
    machine : :class:`family.params.Machine` (the plant with its effects applied)
    effects : list of :class:`family.params.Effect` (empty: a clean case)
    train, val : lists of :class:`fdid_fmi.trace.Trace` (mm, s), each with ``meta["name"]``
    limits : dict, the path limits (feed mm/s, acc mm/s^2, jerk_time s, stroke mm)
    """

    seed: int
    split: str
    machine: Machine
    effects: list
    train: list
    val: list
    limits: dict = field(default_factory=dict)

    @property
    def axis(self):
        """The axis the effects act on."""
        return self.machine.axes[0].name

    @property
    def kinds(self):
        return [e.kind for e in self.effects]

    def effect(self, kind):
        """The effect of this kind, or None."""
        return next((e for e in self.effects if e.kind == kind), None)

    def truth(self):
        """A JSON-able record of the plant, its effects and the path limits."""
        return {"seed": self.seed, "split": self.split, "axis": self.axis, "Ts": self.machine.Ts,
                "effects": [dict(kind=e.kind, magnitude=e.magnitude, unit=e.unit, axis=e.axis,
                                 relative=e.relative, params=dict(e.params)) for e in self.effects],
                "machine": self.machine.to_dict(), "limits": dict(self.limits)}


def _draw_effects(rng, x, Ts):
    """Parameters of every effect kind for axis x (all drawn, in a fixed order)."""
    Fc = x.coulomb
    out = {}
    rel = loguniform(rng, 0.02, 3.0)
    out["stribeck"] = (rel * Fc, rel, {"v_s_mm_s": loguniform(rng, 0.5, 10.0), "coulomb_N": Fc,
                                       "static_N": Fc * (1 + rel)})
    width = loguniform(rng, 1e-4, 5e-2)
    out["backlash"] = (width, width / x.noise_mm, {"tool": bool(rng.uniform() < 0.5),
                                                   "lock_hz": x.lock_hz})
    rel = loguniform(rng, 0.01, 2.0)
    out["periodic_position"] = (rel * Fc, rel, {"period_mm": loguniform(rng, 1.0, 20.0),
                                                "phase_rad": x.periodic_phase})
    d = int(rng.integers(1, 4))
    out["delay"] = (d, float(d), {"seconds": d * Ts})
    frac = loguniform(rng, 0.03, 0.45)
    out["mode"] = (frac * x.mass, frac, {"lock_hz": loguniform(rng, 15.0, 150.0),
                                         "zeta": loguniform(rng, 0.01, 0.08)})
    rel = loguniform(rng, 0.001, 0.3)
    out["coupling"] = (rel * x.mass, rel, {"source": "y", "channel": "y_cmd_mm"})
    rel = loguniform(rng, 0.02, 3.0)
    out["extra_input"] = (rel * Fc, rel, {"channel": "x_load_N", "band_hz": loguniform(rng, 1.0, 10.0)})
    return out


def _apply(machine, effects):
    """The machine with the effects' parameter changes (first axis; coupling and disturbance on
    the machine)."""
    x = machine.axes[0]
    ch = {}
    for e in effects:
        p = e.params
        if e.kind == "stribeck":
            ch.update(static=p["static_N"], stribeck_velocity=p["v_s_mm_s"])
        elif e.kind == "periodic_position":
            ch.update(periodic_amplitude=e.magnitude, periodic_period=p["period_mm"])
        elif e.kind == "delay":
            ch.update(record_delay=int(e.magnitude))
        elif e.kind == "backlash":
            ch.update(two_mass=True, backlash_mm=e.magnitude, tool_channel=p["tool"])
    mode = next((e for e in effects if e.kind == "mode"), None)
    if mode is not None:
        share = x.table_share if "backlash" in [e.kind for e in effects] else 0.0
        ch.update(two_mass=True, table_mass=mode.magnitude, motor_mass=x.mass - mode.magnitude,
                  lock_hz=mode.params["lock_hz"], mode_zeta=mode.params["zeta"], table_share=share)
    axes = (replace(x, **ch),) + tuple(machine.axes[1:])
    kw = {}
    for e in effects:
        if e.kind == "coupling":
            kw["coupling_kg"] = e.magnitude
        elif e.kind == "extra_input":
            kw["disturbance_rms"] = e.magnitude
    return replace(machine, axes=axes, **kw)


def _moves(rng, n_axes, n_moves, lim, Ts, center):
    """Point-to-point moves: short (1-20 mm) and long (20-90 % of the stroke) ones, on one axis
    or on both together along a random direction, within the stroke around ``center``."""
    half = 0.5 * lim["stroke"]
    pos = np.array(center, float)
    targets, feeds, dwells = [], [], []
    for _ in range(n_moves):
        long_ = rng.uniform() < 0.5
        f = rng.uniform(0.3, 1.0) * lim["feed"]
        # a long move cruises 0.4-2 s at most (a slow axis does not cross its whole stroke)
        L = (min(rng.uniform(0.2, 0.9) * lim["stroke"], f * rng.uniform(0.4, 2.0)) if long_
             else loguniform(rng, 1.0, 20.0))
        which = (int(rng.integers(0, 3)) if len(targets) else 2) if n_axes == 2 else 0
        # one axis, or both along a random direction (not the same on both: the second axis's
        # command would then follow the first's)
        th = rng.uniform(0.0, 2 * math.pi)
        comp = [math.cos(th), math.sin(th)] if which == 2 else [float(which == a) for a in range(n_axes)]
        d = np.zeros(n_axes)
        for a in range(n_axes):
            if comp[a]:
                step = L * comp[a]
                if abs(pos[a] + step - center[a]) > half:
                    step = -step
                d[a] = step
        tgt = pos + d
        targets.append(tgt)
        feeds.append(f)
        dwells.append(rng.uniform(0.1, 0.4))
        pos = tgt
    return paths.line_moves(center, targets, feeds, lim["acc"], Ts, lim["jerk_time"], dwells)


def _long_strokes(rng, n_axes, lim, Ts, center):
    """Back-and-forth strokes over 60-90 % of the stroke (at most 1.5 s at the top feed) at 2-3
    feeds (constant-velocity stretches), on the first axis."""
    pos = np.array(center, float)
    targets, feeds = [], []
    L = min(rng.uniform(0.6, 0.9) * lim["stroke"], 1.5 * lim["feed"])
    for f in rng.uniform(0.3, 1.0, size=int(rng.integers(2, 4))):
        for sgn in (1.0, -1.0):
            tgt = pos.copy()
            tgt[0] = center[0] + sgn * 0.5 * L
            targets.append(tgt)
            feeds.append(f * lim["feed"])
            pos = tgt
    targets.append(np.array(center, float))
    feeds.append(lim["feed"])
    return paths.line_moves(center, targets, feeds, lim["acc"], Ts, lim["jerk_time"], [0.15] * len(targets))


def _contour(rng, lim, Ts, center):
    """A circle then a diamond (two axes), each reached by a move from ``center``."""
    R = rng.uniform(10.0, 60.0)
    c = np.array(center, float)
    start = c + [R, 0.0]
    a = lim["acc"]
    parts = [paths.line_moves(c, [start], [lim["feed"]], a, Ts, lim["jerk_time"], [0.1]),
             paths.circle(c, R, lim["feed"] * rng.uniform(0.4, 1.0), a, Ts, lim["jerk_time"]),
             paths.diamond(c, R, lim["feed"] * rng.uniform(0.4, 1.0), a, Ts, lim["jerk_time"]),
             paths.line_moves(start, [c], [lim["feed"]], a, Ts, lim["jerk_time"], [0.2])]
    return np.vstack(parts)


def _loop_rate(ax):
    """The slowest rate of the position loop, 1/s (kv, or the PID's triple pole)."""
    if ax.controller == "pid":
        return ax.kd_pid * 1000.0 / ax.m_est / 3.0
    return ax.kv


def _settled(cmd, seconds, Ts):
    """The path with ``seconds`` of standstill at its last position appended."""
    return np.vstack([cmd, np.repeat(cmd[-1:], int(round(seconds / Ts)), axis=0)])


def _disturbance(rng, n, Ts, rms, band_hz):
    """Band-limited noise (two first-order low-passes at band_hz) scaled to ``rms`` N."""
    w = rng.standard_normal(n)
    a = math.exp(-2 * math.pi * band_hz * Ts)
    y = np.empty(n)
    s1 = s2 = 0.0
    for k in range(n):
        s1 = a * s1 + (1 - a) * w[k]
        s2 = a * s2 + (1 - a) * s1
        y[k] = s2
    y -= y.mean()
    sd = float(np.std(y))
    return y * (rms / sd) if sd > 0 else y


def _delayed(x, d):
    return x if d <= 0 else np.concatenate([np.full(d, x[0]), x[:-d]])


def simulate(machine, cmd, rng, name, source, dist_band_hz=3.0):
    """Simulate the machine along commanded positions and return a measured trace.

    Parameters
    ----------
    machine : Machine
    cmd : (n, n_axes) ndarray, mm, the columns in the order of ``machine.axes``
    rng : numpy.random.Generator (encoder noise, disturbance)
    name : ``meta["name"]`` of the trace; source : its source label
    dist_band_hz : Hz, band of the measured disturbance (and of the decoy channel)

    Returns
    -------
    Trace with roles per axis ``cmd``, ``act`` and, where the axis records them, ``vel``, ``cur``,
    ``tool``; the extra channel ``x_load_N`` when the plant has a measured disturbance or a decoy
    channel; ``meta["n_sub"]`` (RK4 steps per sample) and ``meta["force_N"]`` / ``meta["true"]``
    (per axis: force, true positions; for the tests, not channels)
    """
    Ts = machine.Ts
    n = cmd.shape[0]
    t = Ts * np.arange(n)
    seeds_ax = rng.integers(2 ** 32, size=len(machine.axes) + 2)
    dist = _disturbance(np.random.default_rng(seeds_ax[-1]), n, Ts, 1.0, dist_band_hz)
    chans, roles, meta = {}, {}, {"name": name, "n_sub": {}, "force_N": {}, "force_cmd_N": {}, "true": {}}
    runs = {}
    # the coupling source (second axis) first: its tool-side acceleration drives the first
    for i in reversed(range(len(machine.axes))):
        ax = machine.axes[i]
        f = np.zeros(n)
        if i == 0 and machine.coupling_kg and len(machine.axes) > 1:
            f -= machine.coupling_kg * runs[machine.axes[1].name]["table_acc"] / 1000.0
        if i == 0 and machine.disturbance_rms:
            f += machine.disturbance_rms * dist
        runs[ax.name] = simulate_axis(ax, Ts, cmd[:, i], np.random.default_rng(seeds_ax[i]), f)
    d0 = machine.axes[0].record_delay
    for ax in machine.axes:
        r, a, d = runs[ax.name], ax.name, ax.record_delay
        roles[a] = {}

        def put(role, key, unit, data):
            chans[key] = Channel(key, unit, data)
            roles[a][role] = key

        put("cmd", f"{a}_cmd_mm", "mm", cmd[:, list(machine.axes).index(ax)])
        put("act", f"{a}_act_mm", "mm", _delayed(r["enc"], d))
        if ax.vel_channel:
            put("vel", f"{a}_vel_mm_s", "mm_s", _delayed(r["vel"], d))
        if ax.cur_channel:
            put("cur", f"{a}_cur_A", "A", _delayed(r["force"] / ax.kt, d))
        if ax.tool_channel:
            put("tool", f"{a}_tool_mm", "mm", _delayed(r["tool_enc"], d))
        meta["n_sub"][a] = r["n_sub"]
        meta["force_N"][a] = r["force"]
        meta["force_cmd_N"][a] = r["force_cmd"]
        meta["true"][a] = {"x1": r["x1"], "x2": r["x2"]}
    if machine.disturbance_rms or machine.decoy_channel:
        scale = machine.disturbance_rms or 1.0
        meas = scale * (dist + 0.01 * np.random.default_rng(seeds_ax[-2]).standard_normal(n))
        chans[machine.disturbance_channel] = Channel(machine.disturbance_channel, "N", _delayed(meas, d0))
    return Trace(t=t, channels=chans, roles=roles, source=source, meta=meta)


def case(seed, without=(), scale=1.0, traces=True, validation=True):
    """Build the case of a seed (module docstring).

    Parameters
    ----------
    seed : int
    without : kinds of effects to leave out (the same case otherwise: same plant, paths, noise)
    scale : float, scales the number of moves of every trace (1: the benchmark's length, about 5-15 s
        of training data; smaller for fast tests)
    traces : bool, simulate the traces (False: the draws alone, ``train`` and ``val`` empty)
    validation : bool, simulate the validation traces too (False: ``val`` empty)

    Returns
    -------
    Case
    """
    rng = np.random.default_rng([int(seed), 20261206])
    Ts = float(rng.choice([0.0005, 0.001, 0.0015, 0.002]))
    n_axes = 1 if rng.uniform() < 0.6 else 2
    names = ("x", "y")[:n_axes]
    feed = loguniform(rng, 1000.0, 20000.0) / 60.0                 # mm/s
    jerk_time = 0.0 if rng.uniform() < 0.3 else rng.uniform(0.005, 0.04)
    stroke = loguniform(rng, 150.0, 800.0)
    acc0 = loguniform(rng, 500.0, 8000.0)
    axes = []
    for nm in names:
        ax = draw_axis(rng, nm, Ts, acc0)
        axes.append(ax)
    heavy = max(a.mass for a in axes)
    acc = min(acc0, acc0 * (150.0 / heavy) ** 0.3)
    lim = {"feed": feed, "acc": acc, "jerk_time": jerk_time, "stroke": stroke}
    machine = Machine(Ts=Ts, axes=tuple(axes), decoy_channel=bool(rng.uniform() < 0.25))
    drawn = _draw_effects(rng, axes[0], Ts)
    u = rng.uniform()
    count = 0 if u < 0.3 else (1 if u < 0.75 else 2)
    pool = [k for k in KINDS if k != "coupling" or n_axes == 2]
    # coupling exists on two-axis plants alone: weighted up there so that every kind is about
    # as frequent over the family
    w = np.array([COUPLING_WEIGHT if k == "coupling" else 1.0 for k in pool])
    chosen = [pool[i] for i in rng.choice(len(pool), size=count, replace=False, p=w / w.sum())]
    effects = [Effect(kind=k, magnitude=float(drawn[k][0]), unit=UNITS[k], axis="x", params=dict(drawn[k][2]),
                      relative=float(drawn[k][1])) for k in KINDS if k in chosen]
    band = drawn["extra_input"][2]["band_hz"]
    if "extra_input" in chosen:
        machine = replace(machine, decoy_channel=False)
    path_seed = rng.integers(2 ** 32, size=4)
    noise_seed = rng.integers(2 ** 32, size=4)
    kept = [e for e in effects if e.kind not in without]
    m = _apply(machine, kept)
    center = [0.0] * n_axes
    n_tr = max(2, int(round(10 * scale)))
    n_va = max(2, int(round(7 * scale)))
    prs = [np.random.default_rng(s) for s in path_seed]
    train_cmd = _moves(prs[0], n_axes, n_tr, lim, Ts, center)
    val_cmds = [("moves", _moves(prs[1], n_axes, n_va, lim, Ts, center))]
    if n_axes == 2:
        val_cmds.append(("contour", _contour(prs[2], lim, Ts, center)))
    else:
        val_cmds.append(("strokes", _long_strokes(prs[2], n_axes, lim, Ts, center)))
    # every trace ends at rest long enough for the slowest loop to settle
    settle = 0.3 + 6.0 / min(_loop_rate(a) for a in m.axes)
    train_cmd = _settled(train_cmd, settle, Ts)
    val_cmds = [(nm, _settled(c, settle, Ts)) for nm, c in val_cmds]
    if not traces:
        return Case(seed=int(seed), split=split_of(seed), machine=m, effects=kept, train=[], val=[], limits=lim)
    src = f"family:{seed}"
    train = [simulate(m, train_cmd, np.random.default_rng(noise_seed[0]), "moves", f"{src}:train", band)]
    val = [simulate(m, c, np.random.default_rng(noise_seed[1 + k]), nm, f"{src}:val:{nm}", band)
           for k, (nm, c) in enumerate(val_cmds)] if validation else []
    return Case(seed=int(seed), split=split_of(seed), machine=m, effects=kept, train=train, val=val, limits=lim)


def visibility(c, scale=1.0):
    """How much each effect of a case shows in its first training trace: the same case rebuilt
    without that effect (same plant, path and noise), and the difference of the recorded
    channels of the first axis.

    Parameters
    ----------
    c : Case
    scale : the ``scale`` the case was built with

    Returns
    -------
    dict kind -> {``act_rms_um``: RMS of the motor-encoder difference, um; ``tool_rms_um``: of the
    tool-side channel (None without one); ``noise_ratio``: act_rms over the encoder noise (its
    standard deviation, or the quantisation step's 1/sqrt(12) when larger)}
    """
    out = {}
    tr = c.train[0]
    ax = c.machine.axes[0]
    floor = max(ax.noise_mm, ax.resolution_mm / math.sqrt(12.0))
    for e in c.effects:
        o = case(c.seed, without=(e.kind,), scale=scale, validation=False).train[0]
        d = tr.act(c.axis) - o.act(c.axis)
        tool = None
        if tr.has(c.axis, "tool") and o.has(c.axis, "tool"):
            tool = float(np.sqrt(np.mean((tr.get(c.axis, "tool") - o.get(c.axis, "tool")) ** 2))) * 1e3
        rms = float(np.sqrt(np.mean(d ** 2)))
        out[e.kind] = {"act_rms_um": rms * 1e3, "tool_rms_um": tool, "noise_ratio": rms / floor}
    return out
