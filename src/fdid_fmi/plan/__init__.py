"""The process planner's workflow: NC program -> commanded positions -> twin -> errors -> feeds.

* :mod:`.ncprogram` - read an ISO / RS-274 part program into motion blocks (lines, arcs in
  G17/G18/G19, G20/G21, G90/G91, G93/G94, work offsets, exact stop, reference returns); bad
  programs stop with one line naming the line.
* :mod:`.words` - the one table of the words the reader knows and what each does (applied,
  noted, refused); docs/plan-words.md carries it.
* :mod:`.interpolate` - the blocks become commanded positions at the model's Ts, as a CNC's
  interpolator makes them (jerk-limited S-curve per block, exact stop at every block end; or,
  :mod:`.lookahead`, no stop at tangent junctions).
* :mod:`.predict` - the twin (a :class:`~fdid_fmi.model.DriveModel` through
  :func:`fdid_fmi.simulate.simulate`, or an FMU through ``fmpy.simulate_fmu``) predicts the
  tracking and contour errors per block and for the whole program.
* :mod:`.optimize` - per-block feed overrides that keep the predicted contour error within a
  tolerance at the shortest cycle time (quasi-static first pass, Eqn 3.6; dynamic correction).
* :mod:`.reporting` - the planner's HTML / JSON report.
"""
from .ncprogram import Block, Program, parse_program, read_program

__all__ = ["Block", "Program", "parse_program", "read_program"]
