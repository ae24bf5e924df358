"""Readers for separately recorded tool-side sensor files (thesis ch. 7.2).

A sensor file is a CSV/TXT with a header line, its own time column (the acquisition
system's clock, any start) and its own steady sample rate; the text rules of
:func:`fdid_fmi.io.text.read_text` apply (delimiter and decimal comma detected, units from
``name_unit`` suffixes or ``name [unit]`` headers, row numbers as the file shows them).

=================  =========================================  =========================
kind               columns                                     units (canonical)
=================  =========================================  =========================
accelerometer      3: sensor-frame x, y, z specific force      g, m/s^2, mm/s^2 (mm/s^2)
grid encoder       2: grid-plate x, y position (KGM)           um, mm, nm, m (mm)
=================  =========================================  =========================

Which columns: ``columns=`` names them (or 1-based numbers); without it, the file must
have exactly 3 (accelerometer) or 2 (grid encoder) columns besides time. A column whose unit
is unknown (no suffix, no bracket) needs ``unit=``. A file of several sensors (e.g. head and
table accelerometer in one LMS export) is read once per sensor with its ``columns``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..io.common import check_file
from ..io.text import read_text
from ..units import UNITS

__all__ = ["SensorRecord", "read_accelerometer", "read_grid_encoder", "read_sensor", "KINDS"]

KINDS = {"accelerometer": (3, "acceleration", "mm_s2"), "grid_encoder": (2, "position", "mm")}
MACHINE_AXES = ("x", "y", "z")


@dataclass
class SensorRecord:
    """One sensor's raw record on its own clock.

    Attributes
    ----------
    name : str                   sensor name (unique within a run)
    kind : ``accelerometer`` or ``grid_encoder``
    tau : (n,) float, s          the file's time column (sensor clock)
    data : (n, k) float          sensor-frame values, mm/s^2 (k = 3) or mm (k = 2)
    axes : tuple of str          machine axes this sensor provides to the aligned trace
    sign : float                 +1, or -1 for a sensor whose motion counts negatively
                                 (e.g. the table accelerometer in a head - table difference)
    columns : tuple of str       file columns used
    source : str                 file path
    meta : dict                  sha256, units as read
    """

    name: str
    kind: str
    tau: np.ndarray
    data: np.ndarray
    axes: tuple = ("x", "y")
    sign: float = 1.0
    columns: tuple = ()
    source: str = "<memory>"
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise InputError(f"sensor kind '{self.kind}' not in {sorted(KINDS)}", source=self.source,
                             column="kind")
        k = KINDS[self.kind][0]
        tau = np.array(self.tau, dtype=float)
        data = np.array(self.data, dtype=float)
        if data.ndim != 2 or data.shape[1] != k or data.shape[0] != tau.size:
            raise InputError(f"{self.kind} data must have shape (n, {k}) with n = {tau.size} time "
                             f"samples, got {data.shape}", source=self.source)
        if tau.size < 16:
            raise InputError(f"a sensor record needs at least 16 samples, got {tau.size}",
                             source=self.source, column="time")
        bad = ~np.isfinite(data)
        if bad.any():
            r = int(np.argmax(bad.any(axis=1)))
            raise InputError("contains NaN or inf", source=self.source,
                             column=(self.columns[int(np.argmax(bad[r]))] if self.columns else None),
                             row=r + 1)
        dt = np.diff(tau)
        if not np.all(np.isfinite(tau)) or (dt <= 0).any():
            r = int(np.argmax(~(dt > 0))) if dt.size else 0
            raise InputError("sensor time is not strictly increasing", source=self.source,
                             column="time", row=r + 2)
        self.axes = tuple(self.axes)
        if not self.axes:
            raise InputError("a sensor must provide at least one machine axis", source=self.source,
                             column="axes")
        bad_ax = [a for a in self.axes if a not in MACHINE_AXES]
        if bad_ax:
            what = "an accelerometer provides" if self.kind == "accelerometer" else "a grid encoder measures"
            raise InputError(f"{what} machine axes among {MACHINE_AXES}, got {bad_ax}",
                             source=self.source, column="axes")
        if self.kind == "grid_encoder" and len(self.axes) != 2:
            raise InputError(f"a grid encoder measures two machine axes (plate x, y); got "
                             f"{list(self.axes)}", source=self.source, column="axes")
        if len(set(self.axes)) != len(self.axes):
            raise InputError(f"axes listed twice: {list(self.axes)}", source=self.source, column="axes")
        if self.sign not in (1, -1, 1.0, -1.0):
            raise InputError(f"sign must be +1 or -1, got {self.sign!r}", source=self.source,
                             column="sign")
        tau.setflags(write=False)
        data.setflags(write=False)
        self.tau, self.data = tau, data

    @property
    def rate_hz(self) -> float:
        """Nominal sample rate (1 / median step of the file's time column), Hz."""
        return float(1.0 / np.median(np.diff(self.tau)))


def _a(word):
    """``word`` with its indefinite article (an accelerometer, a grid encoder, an acceleration)."""
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def read_sensor(path, kind, columns=None, time=None, unit=None, axes=("x", "y"), name=None,
                sign=1.0, jitter_tol=0.05) -> SensorRecord:
    """Read one sensor's columns from a CSV/TXT file.

    Parameters
    ----------
    path : str or Path
    kind : ``accelerometer`` | ``grid_encoder``
    columns : sequence of str or int, optional
        The sensor's x, y(, z) columns in that order (names or 1-based numbers).
    time : str or int, optional    the time column (default: found by name, ``t_s``, ``time``...)
    unit : str, optional           unit of every sensor column (``g``, ``m_s2``, ``um``...)
    axes : sequence of str         machine axes the sensor provides (see :class:`SensorRecord`)
    name : str, optional           default: the file stem
    sign : +1 or -1
    jitter_tol : float             largest relative deviation of a time step from the median

    Returns
    -------
    SensorRecord in canonical units (mm/s^2 or mm), the file untouched.
    """
    if kind not in KINDS:
        raise InputError(f"sensor kind '{kind}' not in {sorted(KINDS)}", source=str(path), column="kind")
    p = check_file(path)
    src = str(p)
    need, quantity, _ = KINDS[kind]
    mapping = {"t": str(time)} if time is not None else None
    tr = read_text(p, mapping=mapping, layout="columns", jitter_tol=jitter_tol)
    file_cols = [c for c in tr.meta.get("units_in_file", {}) if c != tr.meta.get("time_column")]
    if columns is None:
        if len(file_cols) != need:
            raise InputError(f"expected {need} {kind.replace('_', ' ')} columns besides time, found "
                             f"{len(file_cols)} {file_cols}; name them (columns / cols=...)", source=src)
        cols = file_cols
    else:
        cols = []
        for c in columns:
            c = str(c).strip()
            if c in file_cols:
                cols.append(c)
            elif c.isdigit() and 1 <= int(c) <= len(file_cols) + 1:
                allc = list(tr.meta.get("units_in_file", {}))
                cols.append(allc[int(c) - 1])
            else:
                low = [f for f in file_cols if f.lower() == c.lower()]
                if len(low) != 1:
                    raise InputError(f"no column '{c}' in the file; its columns are {file_cols}",
                                     source=src, column=c)
                cols.append(low[0])
        if len(cols) != need:
            raise InputError(f"a {kind.replace('_', ' ')} needs {need} columns (x, y{', z' if need == 3 else ''}),"
                             f" got {len(cols)}: {cols}", source=src, column="columns")
        twice = sorted({c for c in cols if cols.count(c) > 1})
        if twice:       # one signal as two sensor axes: align() blamed the time overlap
            raise InputError(f"column(s) {twice} given for two sensor axes; the {need} columns must differ",
                             source=src, column=twice[0])
    data = []
    for c in cols:
        if c == tr.meta.get("time_column"):
            raise InputError("is the time column, not a sensor column", source=src, column=c)
        ch = tr.channels[c]
        u = ch.unit
        vals = ch.data
        if unit is not None:
            stated = tr.meta.get("units_in_file", {}).get(c)
            if stated not in (None, "1"):
                # the name already says a unit (of any quantity): it must agree with the one given
                if stated != unit:
                    raise InputError(f"the column name says unit '{stated}' but unit={unit} was given",
                                     source=src, column=c)
            else:
                from ..units import to_canonical
                vals, u = to_canonical(ch.data, unit, source=src, column=c)
        q = UNITS.get(u, (None,))[0]
        if q != quantity:
            what = "no unit" if u == "1" else f"unit '{u}' ({q})"
            raise InputError(f"has {what}; {_a(kind.replace('_', ' '))} column needs {_a(quantity)} unit: "
                             f"name it like {c}_{'g' if quantity == 'acceleration' else 'um'} or give "
                             f"unit=...", source=src, column=c)
        data.append(np.asarray(vals, dtype=float))
    return SensorRecord(name=name or p.stem, kind=kind, tau=tr.t, data=np.column_stack(data),
                        axes=tuple(axes), sign=float(sign), columns=tuple(cols), source=src,
                        meta={"sha256": tr.meta.get("sha256"), "units_in_file":
                              {c: tr.meta.get("units_in_file", {}).get(c) for c in cols}})


def read_accelerometer(path, columns=None, time=None, unit=None, axes=("x", "y"), name=None,
                       sign=1.0) -> SensorRecord:
    """A 3-axis accelerometer file (see :func:`read_sensor`); values in mm/s^2."""
    return read_sensor(path, "accelerometer", columns, time, unit, axes, name, sign)


def read_grid_encoder(path, columns=None, time=None, unit=None, axes=("x", "y"), name=None) -> SensorRecord:
    """A 2-D grid encoder (KGM) file (see :func:`read_sensor`); values in mm."""
    return read_sensor(path, "grid_encoder", columns, time, unit, axes, name, 1.0)
