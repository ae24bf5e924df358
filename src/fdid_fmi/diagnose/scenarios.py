"""Virtual-drive test data with ONE undeclared effect at a time (and clean references), for the
diagnosis tests, the threshold calibration and the examples.

Every scenario is a seeded, reproducible pair (training, held-out) of traces from the virtual
feed drive (:mod:`fdid_fmi.virtual`): the same P-PI axis (Kp 60 1/s, Kv 100 N/(mm/s), Ti 10 ms,
100 kg, Coulomb 30 N, viscous 0.5 N/(mm/s), encoder 0.1 µm, noise 0.2 µm) following jerk-limited
back-and-forth moves (``linear_moves``, different seeds for the two traces). Only measured
channels are kept (the simulator's truth channels ``*_true``, ``*_force``, ``*_friction`` are
dropped: a real trace does not have them); ``meta["truth"]`` keeps the configuration.

=================  ===========================================================================
scenario           undeclared effect
=================  ===========================================================================
``clean``          none (gentle moves: 2000 mm/s^2, 1e5 mm/s^3)
``clean_fast``     none (fast moves: 2e4 mm/s^2, 1e7 mm/s^3)
``clean_soft``     none (softer velocity loop Kv 40, Ti 20 ms; fast moves)
``stribeck``       breakaway 40 N above Coulomb, Stribeck velocity 2 mm/s
``backlash``       20 µm lost motion between motor and tool side (tool channel recorded)
``periodic``       40 N sin(2 pi x / 5 mm) on the motor side (ball-screw pitch)
``delay``          3-sample delay of the recorded position (Kv 40, Ti 20 ms; fast moves)
``mode``           two-mass axis (70 + 30 kg), 55 Hz tool-side mode, zeta 0.02 (fast moves;
                   motor-side channels only)
``coupling``       two axes; force on x = 0.02 kg x (commanded moves of y), i.e. 0.02 N per mm/s^2
``clean_xy``       the same two axes without the coupling
``asymmetric``     P position loop without integral action (Ti = inf), Coulomb 20 N in the
                   positive and 40 N in the negative direction (fit with integral_action=False)
``clean_p``        the same P loop with symmetric Coulomb friction
=================  ===========================================================================

With integral action in the loop an asymmetric Coulomb level is a constant force while moving
that the integrator rejects: it leaves nothing in the position to diagnose, hence the P loop.
"""
from __future__ import annotations

from dataclasses import replace

from ..errors import InputError
from ..trace import Trace

BASE = dict(coulomb=30.0, viscous=0.5, resolution=1e-4, noise_std=2e-4)
FAST = dict(acc=2e4, jerk=1e7)

SCENARIOS = {
    "clean": ({}, {}),
    "clean_fast": ({}, FAST),
    "clean_soft": (dict(Kv=40.0, Ti=0.02), FAST),
    "stribeck": (dict(stribeck=40.0, stribeck_velocity=2.0), {}),
    "backlash": (dict(backlash=0.02), {}),
    "periodic": (dict(periodic_amplitude=40.0, periodic_period=5.0), {}),
    "delay": (dict(record_delay=3, Kv=40.0, Ti=0.02), FAST),
    "mode": (dict(mass=70.0, tool_mass=30.0, mode_hz=55.0, mode_zeta=0.02), FAST),
    "coupling": ("xy", 0.02),
    "clean_xy": ("xy", 0.0),
    "asymmetric": (dict(Ti=float("inf"), coulomb=20.0, coulomb_neg=40.0), {}),
    "clean_p": (dict(Ti=float("inf")), {}),
}
INTEGRAL_ACTION = {"asymmetric": False, "clean_p": False}


def _measured_only(tr, keep_roles=None):
    drop = ("_true", "_force", "_friction")
    roles = {a: {k: v for k, v in r.items() if keep_roles is None or k in keep_roles}
             for a, r in tr.roles.items()}
    used = {c for r in roles.values() for c in r.values()}
    chans = {k: c for k, c in tr.channels.items()
             if not k.endswith(drop) and (keep_roles is None or k in used or k not in
                                          {c for r in tr.roles.values() for c in r.values()})}
    return Trace(t=tr.t, channels=chans, roles=roles, source=tr.source, meta=tr.meta)


def scenario(name, n_moves=10, seeds=(1, 2)):
    """(train, val) traces of a scenario (see module docstring)."""
    from ..virtual.drive import AxisConfig, Coupling, MachineConfig
    from ..virtual.machine import simulate_drive, simulate_machine
    from ..virtual.trajectories import linear_moves
    if name not in SCENARIOS:
        raise InputError(f"unknown scenario '{name}'; choose from {sorted(SCENARIOS)}", column="scenario")
    kw, traj = SCENARIOS[name]
    out = []
    for k, s in enumerate(seeds):
        if kw == "xy":
            cfg = MachineConfig([AxisConfig(name="x", **BASE), AxisConfig(name="y", **BASE)],
                                couplings=[Coupling("y", "x", "acc", traj)] if traj else [])
            tr = simulate_machine(cfg, linear_moves(n_moves=int(1.6 * n_moves), seed=s, axes=("x", "y")),
                                  seed=k, source=f"virtual:{name}:{s}")
            out.append(_measured_only(tr))
            continue
        ax = replace(AxisConfig(**BASE), **kw)
        tr = simulate_drive(ax, linear_moves(n_moves=n_moves, seed=s, **traj), seed=k,
                            source=f"virtual:{name}:{s}")
        keep = ("cmd", "act", "vel") if name == "mode" else None
        out.append(_measured_only(tr, keep))
    return out[0], out[1]
