"""Write an aligned trace as a CSV that :func:`fdid_fmi.io.read_trace` reads back by name.

Columns: ``t_s`` then per axis ``<a>_cmd_mm``, ``<a>_mm`` (motor encoder), ``<a>_v_mm_s``,
``<a>_cur_<unit>``, ``<a>_tool_mm``, ``<a>_acc_mm_s2`` -- whichever roles the trace has, named
by the reader's conventions so that ``fdid identify`` / ``fdid diagnose`` find the roles
without a ``--map`` -- then every channel without a role (a current, a spindle load, a status
word of the controller's trace), in the trace's order, on the same rows. Written atomically.

A channel without a role keeps its name and the unit the controller file gave it (the name's
unit suffix, or the header's ``[unit]``, else the channel's unit, stated as ``name [unit]``);
its numbers are written so that reading the file back gives bitwise the channel's values (in
a unit other than the canonical one, the decimal whose product with the unit's factor is the
channel's value). Only where that cannot hold is the channel written under another name: one
the reader would take for a role or for time (``x_cmd_mm`` kept as an extra with a
``--map``, a replaced ``y_tool``) becomes ``ctrl_<name>``, so it reads back without a role
and the role channels read back as before; each such change is one line in ``notes``.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .. import units as U
from ..errors import InputError
from ..io.columns import assemble, split_unit
from ..io.text import _parse_header, _split
from ..outputs import atomic_write
from ..trace import Trace

__all__ = ["write_trace_csv", "trace_columns"]

_SUFFIX = {"cmd": "cmd", "act": "", "tool": "tool", "vel": "v", "acc": "acc", "cur": "cur"}
_CHECK = "<aligned header>"


def _unit(u):
    """Canonical spelling of unit ``u``, or None when it is none the reader knows."""
    try:
        return U.normalise_unit(str(u).strip())
    except InputError:
        return None


def _in_unit(v, unit):
    """Numbers y with fl(y * factor(unit)) == v bitwise (what the reader computes), or None.

    Prefers the 15-digit decimal (the number a file holds), then v / factor and its
    neighbours within 4 ulps."""
    f = U.UNITS[unit][1]
    if f == 1.0:
        return v
    with np.errstate(over="ignore", invalid="ignore"):
        y0 = v / f
        cands = [np.array([float(f"{a:.15g}") for a in y0.tolist()]), y0]
        up, down = y0, y0
        for _ in range(4):
            up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
            cands += [up, down]
        y = np.full(v.shape, np.nan)
        for c in cands:
            ok = np.isnan(y) & np.isfinite(c) & (c * f == v)
            y[ok] = c[ok]
    return None if np.isnan(y).any() else y


def _reads_back(cell):
    """(name, unit, roles, error columns) the reader gives header cell ``cell`` next to ``t_s``,
    or None when it refuses it or takes it for time."""
    try:
        names, units = _parse_header(_split(f"t_s,{cell}", ","), _CHECK, 1)
        if len(names) != 2:
            return None
        tr = assemble({names[0]: np.array([0.0, 1.0]), names[1]: np.zeros(2)}, source=_CHECK,
                      file_units=units)
    except InputError:
        return None
    if tr.meta.get("time_column") != "t_s" or names[1] not in tr.channels:
        return None
    return names[1], tr.channels[names[1]].unit, tr.roles, tr.meta.get("error_channels", {})


def _extra_column(trace, name, taken):
    """Header cell and numbers of extra channel ``name``; a note when its name had to change."""
    ch = trace.channels[name]
    v, cu = U.to_canonical(ch.data, ch.unit, trace.source, name)     # what read_trace gives
    q = U.UNITS[cu][0]
    in_file = (trace.meta.get("units_in_file") or {}).get(name)
    clean = re.sub(r"[\s,\"'\[\]()]+", "_", name).strip("_") or "channel"
    base = split_unit(clean)[0]

    def options():
        for n in (name, f"ctrl_{clean}"):
            su = split_unit(n)[1]
            if su is not None:
                yield n, su
            else:
                if in_file is not None:
                    yield n, in_file
                yield n, ch.unit
        for k in range(1, 1000):       # unit suffix dropped: the channel's unit in brackets
            yield (f"ctrl_{base}" if k == 1 else f"ctrl{k}_{base}"), cu

    for n, u in options():
        u = _unit(u)
        if n in taken or u is None or U.UNITS[u][0] != q:
            continue
        su = split_unit(n)[1]
        if su is not None and _unit(su) != u:
            continue
        y = _in_unit(v, u)
        if y is None:
            continue
        cell = n if su is not None or u == "1" else f"{n} [{u}]"
        back = _reads_back(cell)
        if back is None or back[0] != n or back[1] != cu or back[2]:
            continue
        err_axis = next(iter(back[3]), None)       # an error column derives cmd or act
        if err_axis is not None and trace.has(err_axis, "cmd") != trace.has(err_axis, "act"):
            continue
        if n == name:
            return n, cell, y, None
        return n, cell, y, (f"controller channel '{name}' (no role) written as '{cell}': its name "
                            f"would read back as time or as a role, or cannot state its unit")
    raise InputError("no column name found that reads back without a role", source=trace.source,
                     column=name)


def trace_columns(trace: Trace):
    """Header cells, data columns and notes of the aligned CSV (see the module docstring).

    Returns
    -------
    header : list[str], cols : list[ndarray], notes : list[str]  (one line per renamed channel)
    """
    header, cols, notes = ["t_s"], [trace.t], []
    for a in trace.axes:
        for role in ("cmd", "act", "vel", "cur", "tool", "acc"):
            if not trace.has(a, role):
                continue
            ch = trace.channel(a, role)
            unit = "" if ch.unit == "1" else ch.unit
            parts = [a, _SUFFIX[role], unit]
            header.append("_".join(p for p in parts if p))
            cols.append(ch.data)
    n_roles, taken = len(header), set(header)
    for name in trace.extra_channels:
        n, cell, y, note = _extra_column(trace, name, taken)
        taken.add(n)
        header.append(cell)
        cols.append(y)
        if note:
            notes.append(note)
    _check_roles(header, n_roles)
    return header, cols, notes


def _check_roles(header, n_roles):
    """The extra columns change no role the reader finds (a safety net over ``_extra_column``)."""
    def roles_of(cells):
        names, units = _parse_header(_split(",".join(cells), ","), _CHECK, 1)
        cols = {n: np.zeros(2) for n in names}
        cols["t_s"] = np.array([0.0, 1.0])
        tr = assemble(cols, source=_CHECK, file_units=units)
        return tr.roles, tr.meta.get("derived", {})
    if n_roles == len(header):
        return
    try:
        before = roles_of(header[:n_roles])
    except InputError:      # role names the reader does not take back (not the extras' doing)
        return
    if roles_of(header) != before:
        raise InputError(f"the columns without a role {header[n_roles:]} would change the roles read "
                         f"back", source=_CHECK)


def write_trace_csv(trace: Trace, path, notes=None) -> Path:
    """Write ``trace`` (role channels, then every channel without a role) to ``path``.

    Parameters
    ----------
    trace : Trace
    path : str or Path
    notes : list, optional
        Receives one line per channel without a role written under another name.

    Returns
    -------
    Path
    """
    header, cols, extra_notes = trace_columns(trace)
    if notes is not None:
        notes.extend(extra_notes)
    data = np.column_stack(cols)
    lines = [",".join(header)]
    # shortest round-trip text of every double: 9 digits made t = 123456.001 and 123456.0012 equal
    lines += [",".join(repr(v) for v in r) for r in data.tolist()]
    atomic_write(path, "\n".join(lines) + "\n")
    return Path(path)
