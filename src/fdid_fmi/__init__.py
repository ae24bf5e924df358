"""fdid-fmi: feed-drive digital twins from CNC servo traces, shipped as FMI FMUs.

The data path (:mod:`fdid_fmi.api`): :func:`read_trace` -> :func:`identify` -> ``DriveModel``
(``save`` / ``load``) -> :func:`simulate` / :func:`export_fmu` (FMU) / :func:`validate` /
:func:`diagnose` / :func:`plan`.

``fdid_fmi.identify``, ``fdid_fmi.diagnose`` and ``fdid_fmi.plan`` are these functions; the
subpackages of the same names (the methods behind them) are imported by their full names:
``from fdid_fmi.identify import identify_siso``.
"""
import sys as _sys
import types as _types

from .errors import FdidError, InputError
from .trace import Trace, Channel
from .model import DriveModel, QuasiStaticModel
from .simulate import simulate
from .api import (ExportResult, PlanResult, diagnose, export_fmu, identify, load_model, plan,
                  read_trace, validate)

__version__ = "0.1.0"
__all__ = ["read_trace", "identify", "DriveModel", "QuasiStaticModel", "load_model", "simulate",
           "export_fmu", "ExportResult", "validate", "diagnose", "plan", "PlanResult", "Trace", "Channel",
           "FdidError", "InputError", "__version__"]


class _Package(_types.ModuleType):
    """The package keeps its API functions under their names when the subpackage of the same
    name is first imported (the import system would bind the subpackage there)."""

    def __setattr__(self, name, value):
        if name in ("identify", "diagnose", "plan", "simulate") and isinstance(value, _types.ModuleType):
            return
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package
