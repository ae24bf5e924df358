"""A virtual plant fleet with known truth: CNC axes whose traces are written night after night.

:func:`write_virtual_fleet` simulates every axis of ``n_machines`` two-axis machines with the
virtual feed drive (:mod:`fdid_fmi.virtual`), writes one CSV trace per axis and night, and a TOML
manifest that ``fdid fleet run`` reads. Machines alternate between the ``deckel_maho_like`` preset
(no feed-forward, errors of ~1 mm) and ``with_feedforward`` (errors of a few µm); both are run at
Ts = 1 ms. Each night runs a different random linear-move program (its own seed), so an unchanged
axis is re-identified from new data, as in a plant.

Changes (``changes={(machine, axis): kind}``) switch a physical effect on from the given night:

=============  =================================================================================
kind           what changes in the plant
=============  =================================================================================
friction       Coulomb friction x 2 (``coulomb``, and the Stribeck excess with it)
backlash       20 µm lost motion between motor and tool side (seen on the ``tool`` channel)
resonance      a tool-side mode: 20 % of the mass on a 30 Hz, zeta 0.02 spring (two-mass axis)
=============  =================================================================================

Every CSV has the columns ``t_s, <a>_cmd_mm, <a>_mm, <a>_tool_mm`` (the tool-side position is the
motor position on a rigid axis without backlash: a machine with a linear scale records it always).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

CHANGE_KINDS = ("friction", "backlash", "resonance")

__all__ = ["CHANGE_KINDS", "VirtualAxis", "fleet_axes", "axis_config", "axis_trace", "write_virtual_fleet",
           "default_changes"]


@dataclass(frozen=True)
class VirtualAxis:
    """One axis of the virtual fleet: ``machine`` (``m01``...), ``axis`` (``x``/``y``), ``preset``."""

    machine: str
    axis: str
    preset: str


def fleet_axes(n_machines):
    """The axes of ``n_machines`` two-axis machines; m02, m04, ... have feed-forward."""
    out = []
    for i in range(int(n_machines)):
        preset = "with_feedforward" if i % 2 else "deckel_maho_like"
        for ax in ("x", "y"):
            out.append(VirtualAxis(f"m{i + 1:02d}", ax, preset))
    return out


def default_changes(axes):
    """A plausible second night: every 5th axis (the 3rd, 8th, 13th, ...: with and without
    feed-forward, x and y) gets one change, cycling through CHANGE_KINDS.

    Returns
    -------
    dict (machine, axis) -> kind
    """
    out = {}
    k = 0
    for i, va in enumerate(axes):
        if i % 5 == 2:
            out[(va.machine, va.axis)] = CHANGE_KINDS[k % len(CHANGE_KINDS)]
            k += 1
    return out


def axis_config(va: VirtualAxis, change=None, Ts=1e-3):
    """The single-axis :class:`~fdid_fmi.virtual.MachineConfig` of ``va`` with ``change`` applied."""
    from ..virtual import MachineConfig, presets
    cfg = presets.PRESETS[va.preset]()
    ax = dataclasses.replace(cfg.axis(va.axis))
    if change == "friction":
        ax.coulomb *= 2.0
        ax.stribeck *= 2.0
    elif change == "backlash":
        ax.backlash = 0.020
    elif change == "resonance":
        ax.tool_mass = 0.2 * ax.mass
        ax.mass = 0.8 * ax.mass
        ax.mode_hz = 30.0
        ax.mode_zeta = 0.02
    elif change is not None:
        raise InputError(f"unknown change '{change}'; expected one of {CHANGE_KINDS}", column="change")
    return MachineConfig(axes=[ax], Ts=Ts, name=f"{va.machine}_{va.preset}")


def axis_trace(va: VirtualAxis, night, change=None, n_moves=6, Ts=1e-3, noise_um=0.1,
               same_program=True):
    """Simulate one night's trace of ``va``.

    The axis runs its nightly test program (random linear moves seeded by machine and axis; with
    ``same_program=False`` also by night); the measurement noise (``noise_um`` µm, before the
    0.1 µm quantisation) is seeded by the night as well. Returns a :class:`~fdid_fmi.trace.Trace`.
    """
    from ..virtual import simulate_machine
    from ..virtual import trajectories as tj
    cfg = axis_config(va, change, Ts)
    cfg.axes[0].noise_std = noise_um * 1e-3
    base = int(va.machine[1:]) * 1000 + (0 if va.axis == "x" else 500)
    path = tj.linear_moves(n_moves=n_moves, d_min=2.0, d_max=30.0, axes=(va.axis,), Ts=Ts,
                           seed=base + (0 if same_program else int(night)), dwell=0.15,
                           pause=(0.05, 0.15))
    return simulate_machine(cfg, path, seed=base + int(night), truth=False,
                            source=f"{va.machine}_{va.axis}_night{night}")


def write_trace_csv(trace, axis, path):
    """Write ``t_s, <a>_cmd_mm, <a>_mm, <a>_tool_mm`` (atomically)."""
    from ..outputs import atomic_write
    cmd, act = trace.cmd(axis), trace.act(axis)
    tool = trace.get(axis, "tool") if trace.has(axis, "tool") else act
    cols = np.column_stack([trace.t, cmd, act, tool])
    lines = [f"t_s,{axis}_cmd_mm,{axis}_mm,{axis}_tool_mm"]
    lines += [f"{r[0]:.6f},{r[1]:.9f},{r[2]:.9f},{r[3]:.9f}" for r in cols]
    atomic_write(path, "\n".join(lines) + "\n")
    return Path(path)


def write_virtual_fleet(folder, n_machines=20, nights=(1, 2), changes=None, change_night=2, n_moves=6,
                        diagnose=True, extra_options=None):
    """Write a virtual fleet's traces and one manifest per night.

    Parameters
    ----------
    folder : output folder; traces go to ``folder/night<N>/<machine>_<axis>.csv`` and manifests to
        ``folder/night<N>.toml``
    n_machines : two-axis machines (2 n_machines axes); the even-numbered ones (m02, m04, ...)
        have feed-forward (``with_feedforward``), the others not (``deckel_maho_like``)
    nights : nights to write
    changes : dict (machine, axis) -> kind (CHANGE_KINDS); default :func:`default_changes`
    change_night : the first night the changes are present
    n_moves : linear moves per trace (6 moves ~ 3 s at 1 ms)
    diagnose : the manifests' ``diagnose`` option
    extra_options : more manifest options for every entry (e.g. ``{"maxiter": 20}``)

    Returns
    -------
    dict night -> manifest Path; the truth (changes) is written to ``folder/truth.json``
    """
    import json
    import numbers
    if isinstance(n_machines, bool) or not isinstance(n_machines, numbers.Integral) or n_machines < 1:
        # 0 wrote manifests without an entry, which fdid fleet run then refused
        raise InputError(f"n_machines must be an integer >= 1, got {n_machines!r}", column="n_machines")
    folder = Path(folder)
    axes = fleet_axes(n_machines)
    changes = default_changes(axes) if changes is None else dict(changes)
    known = {(a.machine, a.axis) for a in axes}
    for k, v in changes.items():
        if k not in known:
            raise InputError(f"no axis {k} in a fleet of {n_machines} machines", column="changes")
        if v not in CHANGE_KINDS:
            raise InputError(f"unknown change '{v}'; expected one of {CHANGE_KINDS}", column="changes")
    manifests = {}
    opts = {"diagnose": bool(diagnose), **(extra_options or {})}
    for night in nights:
        nd = folder / f"night{night}"
        nd.mkdir(parents=True, exist_ok=True)
        lines = ["# virtual fleet (fdid_fmi.fleet.virtual), night %d" % night, "", "[defaults]",
                 "options = { " + ", ".join(f"{k} = {_toml(v)}" for k, v in opts.items()) + " }", ""]
        for va in axes:
            ch = changes.get((va.machine, va.axis)) if night >= change_night else None
            tr = axis_trace(va, night, ch, n_moves=n_moves)
            name = f"{va.machine}_{va.axis}.csv"
            write_trace_csv(tr, va.axis, nd / name)
            a = va.axis
            lines += ["[[entry]]", f'machine = "{va.machine}"', f'axis = "{a}"',
                      f'traces = ["night{night}/{name}"]',
                      f'map = {{ t = "t_s", "{a}.cmd" = "{a}_cmd_mm", "{a}.act" = "{a}_mm", '
                      f'"{a}.tool" = "{a}_tool_mm" }}', ""]
        from ..outputs import atomic_write
        manifests[night] = atomic_write(folder / f"night{night}.toml", "\n".join(lines))
    truth = {"change_night": change_night,
             "axes": [{"machine": a.machine, "axis": a.axis, "preset": a.preset,
                       "change": changes.get((a.machine, a.axis))} for a in axes]}
    from ..outputs import atomic_write
    atomic_write(folder / "truth.json", json.dumps(truth, indent=1))
    return manifests


def _toml(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(v)
