"""Scenario sets on the second plant: clean references and ONE undeclared effect at a time.

Each scenario returns ``(train, validation, truth)``:

* ``train``: list with one trace of random jerk-limited point-to-point moves on X and Y
  (:func:`~plant2.trajectories.random_moves`, ~12-15 s);
* ``validation``: list of three traces the model has not seen -- a circle, a diamond and a
  different move set (:func:`~plant2.trajectories.reversals`, back-and-forth strokes, ~10 s);
  each has ``meta["name"]`` (``circle``, ``diamond``, ``reversals``);
* ``truth``: the scenario name, the axis of interest, the effect present (named as
  ``fdid diagnose`` names effects: ``stribeck``, ``backlash``, ``periodic_position``, ``delay``,
  ``coupling``, ``mode``, or None) with its parameters, and every plant parameter.

Traces carry only what a controller trace would: per axis ``cmd``, ``act`` (motor encoder),
``vel`` (the drive's velocity estimate) and, where declared, ``tool``.

=================  ======  ====================================================================
scenario           Ts      what is different from the clean rigid plant (axis of interest)
=================  ======  ====================================================================
``clean_rigid``    1 ms    nothing (X, no feed-forward)
``clean_rigid_2ms`` 2 ms   nothing, slower controller clock
``clean_ff``       0.5 ms  full velocity and 90 % acceleration feed-forward
``flexible_y``     1 ms    Y two-mass, 38 Hz locked-motor mode (tool side recorded)
``stribeck``       1 ms    X breakaway 90 N over Coulomb 40 N, v_s 2.5 mm/s
``backlash_tool``  2 ms    X two-mass drive train (80 + 70 kg, 140 Hz, zeta 0.15, velocity gain
                           45 N/(mm/s)) with 15 um backlash, tool side recorded
``backlash_motor`` 2 ms    the same, motor encoder only
``periodic``       0.5 ms  X 40 N sin(2 pi x / 5 mm) on the motor
``delay``          1 ms    X recorded 3 samples late (fast moves)
``coupling``       1 ms    force on X = -25 kg x (Y table acceleration)
``mode``           0.5 ms  X two-mass, light tool side (25 kg) on 110 kg, 52 Hz locked / 57.6 Hz
                           free-free, zeta 0.02, motor side recorded only (fast moves)
=================  ======  ====================================================================
"""
from __future__ import annotations

from dataclasses import replace

from fdid_fmi.trace import Trace

from .params import Coupling, flexible_y, rigid, with_feedforward
from .plant import simulate
from .trajectories import circle, diamond, random_moves, reversals

FAST = dict(acc=1.5e4, jerk=5e6)
GENTLE = dict(acc=3000.0, jerk=2e5)
# drive train with lost motion; the velocity loop must stay stable on the motor body alone (in the
# gap): 45 N/(mm/s) on 80 kg (a 40 kg motor side limit-cycles at 30-40 um with this loop)
BACKLASH = dict(two_mass=True, motor_mass=80.0, table_mass=70.0, kp_vel=45.0, lock_hz=140.0, mode_zeta=0.15,
                backlash=0.015, table_share=0.7)

# name: (machine factory, axis, effect kind or None, trajectory limits, tool channels recorded)
SCENARIOS = {
    "clean_rigid": (lambda: rigid(0.001), "x", None, GENTLE, ()),
    "clean_rigid_2ms": (lambda: rigid(0.002), "x", None, GENTLE, ()),
    "clean_ff": (lambda: with_feedforward(0.0005), "x", None, GENTLE, ()),
    "flexible_y": (lambda: flexible_y(0.001), "y", "mode", GENTLE, ("y",)),
    "stribeck": (lambda: rigid(0.001).with_axis("x", static=90.0, stribeck_velocity=2.5), "x", "stribeck",
                 GENTLE, ()),
    "backlash_tool": (lambda: rigid(0.002).with_axis("x", **BACKLASH),
                      "x", "backlash", GENTLE, ("x",)),
    "backlash_motor": (lambda: rigid(0.002).with_axis("x", **BACKLASH),
                       "x", "backlash", GENTLE, ()),
    "periodic": (lambda: rigid(0.0005).with_axis("x", periodic_amplitude=40.0, periodic_period=5.0), "x",
                 "periodic_position", GENTLE, ()),
    "delay": (lambda: rigid(0.001).with_axis("x", record_delay=3), "x", "delay", FAST, ()),
    "coupling": (lambda: replace(rigid(0.001), couplings=(Coupling("y", "x", 25.0),)), "x", "coupling",
                 GENTLE, ()),
    "mode": (lambda: rigid(0.0005).with_axis("x", two_mass=True, motor_mass=110.0, table_mass=25.0, lock_hz=52.0,
                                            mode_zeta=0.02, table_share=0.3),
             "x", "mode", FAST, ()),
}
CLEAN = [k for k, v in SCENARIOS.items() if v[2] is None]
EFFECTS = [k for k, v in SCENARIOS.items() if v[2] is not None]


def _effect_params(effect, machine, axis):
    """The true parameters of the effect present (plant units)."""
    a = machine.axis(axis)
    d = a.derived()
    if effect == "mode":
        return {"lock_hz": a.lock_hz, "free_free_hz": d["free_free_mode_hz"], "zeta": a.mode_zeta}
    if effect == "stribeck":
        return {"static_N": a.static, "coulomb_N": a.coulomb, "v_s_mm_s": a.stribeck_velocity}
    if effect == "backlash":
        return {"backlash_mm": a.backlash}
    if effect == "periodic_position":
        return {"amplitude_N": a.periodic_amplitude, "period_mm": a.periodic_period}
    if effect == "delay":
        return {"samples": a.record_delay}
    if effect == "coupling":
        c = next(c for c in machine.couplings if c.target == axis)
        return {"source": c.source, "gain_kg": c.gain_kg, "channel": f"{c.source}_cmd"}
    return {}


def _named(tr: Trace, name, source):
    return Trace(t=tr.t, channels=tr.channels, roles=tr.roles, source=source,
                 meta={**tr.meta, "name": name})


def scenario(name, seed=0, n_moves=14):
    """Train / validation traces and the truth of one scenario (module docstring).

    Parameters
    ----------
    name : key of :data:`SCENARIOS`
    seed : int, varies the training and validation move sets and the encoder noise
    n_moves : int, moves in the training trace

    Returns
    -------
    (list[Trace], list[Trace], dict)
    """
    if name not in SCENARIOS:
        raise KeyError(f"unknown scenario {name!r}; choose from {sorted(SCENARIOS)}")
    make, axis, effect, lim, tool = SCENARIOS[name]
    m = make()
    Ts = m.Ts
    train_path = random_moves(Ts, n_moves=n_moves, seed=100 + 2 * seed, **lim)
    paths = {"circle": circle(Ts, radius=20.0, feed=150.0 if lim is FAST else 100.0, **lim),
             "diamond": diamond(Ts, half_diagonal=20.0, feed=150.0 if lim is FAST else 120.0, **lim),
             "reversals": reversals(Ts, seed=101 + 2 * seed, **lim)}
    train = [_named(simulate(m, train_path, seed=10 * seed + 1, tool=tool), "moves",
                    f"plant2:{name}:train:{seed}")]
    val = [_named(simulate(m, p, seed=10 * seed + 2 + k, tool=tool), key, f"plant2:{name}:{key}:{seed}")
           for k, (key, p) in enumerate(paths.items())]
    truth = {"scenario": name, "axis": axis, "effect": effect, "effect_params": _effect_params(effect, m, axis),
             "tool_recorded": list(tool), "Ts": Ts, "machine": m.truth()}
    return train, val, truth
