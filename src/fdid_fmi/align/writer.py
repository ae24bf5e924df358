"""Write an aligned trace as a CSV that :func:`fdid_fmi.io.read_trace` reads back by name.

Columns: ``t_s`` then per axis ``<a>_cmd_mm``, ``<a>_mm`` (motor encoder), ``<a>_v_mm_s``,
``<a>_cur_<unit>``, ``<a>_tool_mm``, ``<a>_acc_mm_s2`` -- whichever roles the trace has, named
by the reader's conventions so that ``fdid identify`` / ``fdid diagnose`` find the roles
without a ``--map``. Channels without a role are not written. Written atomically.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..outputs import atomic_write
from ..trace import Trace

__all__ = ["write_trace_csv"]

_SUFFIX = {"cmd": "cmd", "act": "", "tool": "tool", "vel": "v", "acc": "acc", "cur": "cur"}


def write_trace_csv(trace: Trace, path) -> Path:
    """Write ``trace`` (roles only) to ``path``; returns the Path."""
    header, cols = ["t_s"], [trace.t]
    for a in trace.axes:
        for role in ("cmd", "act", "vel", "cur", "tool", "acc"):
            if not trace.has(a, role):
                continue
            ch = trace.channel(a, role)
            unit = "" if ch.unit == "1" else ch.unit
            parts = [a, _SUFFIX[role], unit]
            header.append("_".join(p for p in parts if p))
            cols.append(ch.data)
    data = np.column_stack(cols)
    lines = [",".join(header)]
    # shortest round-trip text of every double: 9 digits made t = 123456.001 and 123456.0012 equal
    lines += [",".join(repr(v) for v in r) for r in data.tolist()]
    atomic_write(path, "\n".join(lines) + "\n")
    return Path(path)
