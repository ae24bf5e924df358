"""fdid-fmi: feed-drive digital twins from CNC servo traces, shipped as FMI FMUs.

The data path (see README): ``Trace`` -> ``identify`` -> ``DriveModel`` ->
``simulate`` / ``export`` (FMU) / ``validate`` / ``diagnose`` / ``report``.
"""
from .errors import FdidError, InputError
from .trace import Trace, Channel
from .model import DriveModel
from .simulate import simulate

__version__ = "0.1.0"
__all__ = ["FdidError", "InputError", "Trace", "Channel", "DriveModel", "simulate", "__version__"]
