"""Tool-side sensors as they come off the machine, aligned onto the controller trace (thesis ch. 7).

* :mod:`.readers` - accelerometer and grid-encoder (KGM) files with their own clocks and rates.
* :mod:`.timing` - time offset and clock drift by cross-correlation with the motor encoders.
* :mod:`.orientation` - accelerometer rotation (Eqn 7.1), gravity and bias; grid-plate angle and
  origin.
* :mod:`.resample` - anti-alias filtering and resampling onto the controller's Ts.
* :mod:`.pipeline` - :func:`align`, the whole chain, returning an :class:`AlignmentResult`
  (the aligned :class:`~fdid_fmi.trace.Trace` with ``tool`` / ``acc`` roles, and every step's
  estimate with its uncertainty).

Example
-------
>>> from fdid_fmi.io import read_trace
>>> from fdid_fmi.align import align, read_accelerometer, read_grid_encoder
>>> ctrl = read_trace("controller.csv")                                   # doctest: +SKIP
>>> res = align(ctrl, [read_accelerometer("acc_tool.csv", axes=("x", "y")),
...                    read_grid_encoder("kgm.csv")])                     # doctest: +SKIP
>>> print(res.table())                                                    # doctest: +SKIP
"""
from .pipeline import align, controller_references
from .readers import SensorRecord, read_accelerometer, read_grid_encoder, read_sensor
from .result import AlignmentResult, Estimate, SensorAlignment

__all__ = ["align", "controller_references", "SensorRecord", "read_accelerometer",
           "read_grid_encoder", "read_sensor", "AlignmentResult", "Estimate", "SensorAlignment"]
