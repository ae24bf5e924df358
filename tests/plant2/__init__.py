"""A second, independently written CNC feed-drive plant, for testing identification
and diagnosis on data that shares no code and no design with ``fdid_fmi.virtual``.

See :mod:`plant2.plant` (time stepping), :mod:`plant2.params` (parameters, presets),
:mod:`plant2.trajectories` (jerk-filtered paths) and :mod:`plant2.scenarios` (train/validation
sets with one undeclared effect at a time).
"""
from .params import Axis, Coupling, Machine, flexible_y, rigid, with_feedforward
from .plant import simulate, simulate_axis
from .scenarios import CLEAN, EFFECTS, SCENARIOS, scenario
from .trajectories import Path, circle, diamond, point_to_point, random_moves, reversals

__all__ = ["Axis", "CLEAN", "Coupling", "EFFECTS", "Machine", "Path", "SCENARIOS", "circle", "diamond", "flexible_y", "point_to_point",
           "random_moves", "reversals", "rigid", "scenario", "simulate", "simulate_axis", "with_feedforward"]
