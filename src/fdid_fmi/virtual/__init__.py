"""The virtual feed drive: traces with KNOWN truth for tests, examples and benchmarks.

* :mod:`.trajectories` - jerk-limited commanded paths (linear moves, diamond, circle, spiral,
  figure-eight), seeded and sampled at Ts.
* :mod:`.drive` - configuration (:class:`AxisConfig`, :class:`Coupling`, :class:`MachineConfig`),
  the exactly discretised plant and the linearised closed-loop truth (:func:`linear_truth`).
* :mod:`.machine` - the time simulation (:func:`simulate_machine`, :func:`simulate_drive`)
  returning a :class:`~fdid_fmi.trace.Trace` with ``meta["truth"]``.
* :mod:`.presets` - ready-made machines (deckel_maho_like, with_feedforward, flexible_y,
  coupled_xy, emps_like).

Example
-------
>>> from fdid_fmi.virtual import presets, trajectories, simulate_machine
>>> cfg = presets.deckel_maho_like()
>>> path = trajectories.circle(radius=20, v=100, acc=2000, jerk=1e5, Ts=cfg.Ts)
>>> trace = simulate_machine(cfg, path, seed=1)
>>> trace.meta["truth"]["linear"]["continuous"]["K"]["x"]["x"]["K_vel"]   # = 1/Kp  # doctest: +SKIP
0.0125
"""
from . import presets, trajectories
from .drive import AxisConfig, Coupling, MachineConfig, build_plant, linear_truth, sampled_closed_loop
from .machine import simulate_drive, simulate_machine
from .presets import PRESETS, coupled_xy, deckel_maho_like, emps_like, flexible_y, with_feedforward
from .trajectories import (Trajectory, circle, diamond, figure_eight, follow_curve, linear_moves,
                           point_to_point, scurve, sequence, spiral)

__all__ = ["AxisConfig", "Coupling", "MachineConfig", "build_plant", "linear_truth",
           "sampled_closed_loop", "simulate_drive", "simulate_machine", "PRESETS", "presets",
           "trajectories", "deckel_maho_like", "with_feedforward", "flexible_y", "coupled_xy",
           "emps_like", "Trajectory", "scurve", "point_to_point", "linear_moves", "sequence",
           "diamond", "circle", "spiral", "figure_eight", "follow_curve"]
