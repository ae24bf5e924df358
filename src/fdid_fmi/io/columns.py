"""Build a ``Trace`` from named columns: time column, axis roles, units.

Shared by the text and MATLAB readers, so both find roles and units the same way.

Roles are taken either from an explicit *mapping* or from column-name conventions
(the mapping wins: when it names any role, only the columns it names get roles and
every other column is kept as an extra channel; the time column is still found by name
when the mapping does not name it, and a mapping naming only ``t`` leaves the roles to
the name rules). Axis names in a mapping are used as written.

Name conventions (case-insensitive, tokens separated by ``_``; the unit suffix is
removed first, see ``fdid_fmi.units.unit_from_suffix``):

==========================================  ==================================
column name                                 meaning
==========================================  ==================================
``t_s``, ``time``, ``t_ms``, ``zeit``       time (no unit given: s; see below)
``x_cmd_mm``, ``x_ref_mm``, ``x_set_mm``    axis x, commanded position (cmd)
``x_mm``, ``x_act_mm``, ``x_motor_mm``      axis x, measured position (act)
``x_tool_mm``, ``x_table_mm``, ``x_kgm_mm`` axis x, tool-side position (tool)
``x_v_mm_s``, ``x_vel_...``, ``x_speed_...``  measured velocity (vel)
``x_acc_mm_s2``, ``x_a_g``                  acceleration (acc)
``x_cur_A``, ``x_current_A``, ``x_iq_A``    current / controller output (cur)
``x_e_mm``, ``x_err_mm``                    tracking error e = x_cmd - x (err)
==========================================  ==================================

The first (or else the last: ``pos_x``, ``cmd_y``) token must be an axis name:
``x y z a b c u v w`` optionally followed by digits (``a1``, ``x2``), or ``axis1``; axis
names found this way are lower case. A commanded velocity/acceleration (``x_v_cmd``)
is not a role and stays an extra channel. The unit must fit the role (a position unit
for cmd/act/tool/err, a velocity unit for vel, ...); a column whose name says one thing
and whose unit says another is refused with a clear message.

A time column with no unit is read in s, but one of 16 or more samples stepping by 0.1 s or
more is refused (:func:`check_time_unit`): servo traces step by 0.1-10 ms, so it is in ms (1 kHz read as
Ts = 1 s) or us; ``t_ms``, ``t [ms]`` or ``--unit t=ms`` states the unit. A stated time unit is
read as stated, with a note (``meta["notes"]``, printed by the CLI) when it steps that slowly
or faster than 10 us (:func:`time_step_note`); so are role columns whose names state no unit
(read in the role's default unit, mm for positions).

The tracking-error pseudo-role ``err`` is not a ``Trace`` role: the column is kept as an
extra channel, and when an axis has ``err`` and ``act`` but no ``cmd`` (the thesis GUI
files), ``cmd = act + err`` is derived as channel ``<axis>_cmd`` (and ``act = cmd - err``
the other way round). ``trace.meta["derived"]`` records what was derived.
"""
from __future__ import annotations

import re

import numpy as np

from .. import units as U
from ..errors import InputError
from ..trace import ROLES, Channel, Trace, time_grid_fault

MAP_ROLES = ROLES + ("err",)
TIME_KEYS = ("t", "time")
TIME_NAMES = {"t", "time", "zeit", "timestamp", "times"}
AXIS_RE = re.compile(r"^(?:[xyzabcuvw]\d*|axis\d+)$")
AXIS_NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")   # any axis name (it becomes C/FMI names)
MAX_UNSTATED_STEP_S = 0.1   # s: a time column with no unit stepping this slowly is not in s
MIN_CHECKED_SAMPLES = 16    # ... checked from this many samples on (a trace tool's record has 1000s)
# s: a stated time unit stepping faster than this is noted: the fastest drive trace tools sample
# the current loop every 31.25-62.5 us; s under a ms name (t_ms) steps by 1 us at 1 kHz
MIN_STATED_STEP_S = 10e-6

# role keywords (the first token after the axis that is a keyword decides; see _role_from_tokens)
ROLE_WORDS = {
    "cmd": {"cmd", "command", "commanded", "ref", "reference", "set", "setpoint", "soll", "des",
            "desired", "target", "r"},
    "act": {"act", "actual", "meas", "measured", "motor", "enc", "encoder", "ist", "mot"},
    "tool": {"tool", "table", "load", "kgm", "grid", "scale", "lin", "linear", "tcp"},
    "vel": {"v", "vel", "velocity", "speed", "dx", "xd"},
    "acc": {"acc", "accel", "acceleration", "ddx", "xdd"},
    "cur": {"cur", "current", "i", "iq", "amp", "u", "volt", "voltage", "torque", "force"},
    "err": {"e", "err", "error", "following", "lag", "ferr", "fe"},
}
NEUTRAL_WORDS = {"pos", "position", "p"}  # "x_pos_mm" is just a position

# which unit quantities fit a role
ROLE_QUANTITIES = {
    "cmd": {"position", "angle"}, "act": {"position", "angle"}, "tool": {"position", "angle"},
    "err": {"position", "angle"},
    "vel": {"velocity", "angular_velocity"}, "acc": {"acceleration"},
    "cur": {"current", "voltage", "force", "torque", "dimensionless"},
}
ROLE_DEFAULT_UNIT = {"cmd": "mm", "act": "mm", "tool": "mm", "err": "mm", "vel": "mm_s",
                     "acc": "mm_s2", "cur": "1"}
QUANTITY_ROLE = {"velocity": "vel", "angular_velocity": "vel", "acceleration": "acc",
                 "current": "cur", "voltage": "cur", "force": "cur", "torque": "cur"}


def split_unit(name):
    """Split a column name into (base name, unit suffix or None), e.g. ``x_v_mm_s`` -> (``x_v``, ``mm_s``)."""
    u = U.unit_from_suffix(name)
    if u is None:
        return name, None
    return name[: -(len(u) + 1)], u


def parse_key(key, source=None):
    """Parse a mapping key: ``"t"``/``"time"`` -> ("t", None); ``"x.cmd"`` -> ("x", "cmd")."""
    k = str(key).strip()
    if k.lower() in TIME_KEYS:
        return "t", None
    if "." not in k:
        raise InputError(f"mapping key '{k}' is neither 't' (time) nor AXIS.ROLE such as 'x.cmd'; "
                         f"roles are {', '.join(MAP_ROLES)}", source=source, column=k)
    axis, role = k.rsplit(".", 1)
    axis, role = axis.strip(), role.strip().lower()
    if not axis:
        raise InputError(f"mapping key '{k}' has no axis name before the '.'", source=source, column=k)
    if not AXIS_NAME_RE.fullmatch(axis) or len(axis) > 64:
        raise InputError(f"mapping key '{k}': axis name '{axis}' is not a name; expected letters, "
                         f"digits and '_' (not starting with a digit), e.g. x or axis1",
                         source=source, column=k)
    if role not in MAP_ROLES:
        raise InputError(f"mapping key '{k}': unknown role '{role}'; expected one of "
                         f"{', '.join(MAP_ROLES)}", source=source, column=k)
    return axis, role


def _resolve_column(value, names, source, key):
    """Find the column a mapping value names: exact name, unique case-insensitive name, or 1-based index."""
    v = str(value).strip()
    if v in names:
        return v
    low = [n for n in names if n.lower() == v.lower()]
    if len(low) == 1:
        return low[0]
    if v.isdigit() and 1 <= int(v) <= len(names):
        return names[int(v) - 1]
    raise InputError(f"mapping {key}={v} names a column that is not in the file; its columns are "
                     f"{names}", source=source, column=v)


def _role_from_tokens(tokens):
    """Role suggested by the name tokens after the axis, or None when the name is not a role."""
    kinds = []
    unknown = False
    for tok in tokens:
        hit = [r for r, words in ROLE_WORDS.items() if tok in words]
        if hit:
            kinds.append(hit[0])
        elif tok not in NEUTRAL_WORDS and not tok.isdigit():
            unknown = True
    if unknown:
        return None
    if not kinds:
        return "act"  # "x_mm", "x_pos_mm": plain measured position
    ks = set(kinds)
    if "cmd" in ks and ks & {"vel", "acc", "cur"}:
        return None  # commanded velocity etc.: not a role
    for r in ("vel", "acc", "cur", "err", "tool", "cmd", "act"):
        if r in ks:
            return r
    return None


def _reconcile(role, quantity):
    """Reconcile a name-derived role with the unit's quantity (name conventions only).

    Returns (role or None, problem or None): None role = not a role (extra channel).
    """
    if quantity is None or quantity in ROLE_QUANTITIES[role]:
        return role, None
    if quantity == "time":
        return None, None
    implied = QUANTITY_ROLE.get(quantity)
    if implied is not None and role in ("act", "tool"):
        return implied, None  # "x_motor_mm_s": motor velocity
    if role in ("cmd", "err") and implied in ("vel", "acc"):
        return None, None  # commanded velocity / error rate: extra channel
    return role, f"a {quantity} unit"


def _is_time_name(base):
    return base.lower() in TIME_NAMES


def assemble(columns, *, source, mapping=None, units=None, file_units=None, rows=None,
             meta=None, jitter_tol=0.05, owned=False):
    """Turn named columns into a ``Trace``.

    Parameters
    ----------
    columns : dict[str, ndarray]
        Column name -> values as found in the file (any unit), in file order.
    source : str
        File path for error messages.
    mapping : dict, optional
        ``{"t": col, "<axis>.<role>": col}``; roles cmd/act/tool/vel/acc/cur and err.
    units : dict, optional
        ``{col: unit}`` given by the user; overrides every other unit source.
    file_units : dict, optional
        ``{col: unit}`` the file itself states (bracket header, known layout).
    rows : array of int, optional
        Row number to report for each sample (1-based, as the file shows it); default
        sample index + 1.
    meta : dict, optional
        Extra facts for ``trace.meta``.
    jitter_tol : float
        Largest relative deviation of a time step from the median step.
    owned : bool
        The columns are the caller's own fresh float64 arrays, handed over: the channels use
        them without a copy (a reader's parsed file).

    Returns
    -------
    Trace
        Channels named as the columns, converted to canonical units (mm, mm/s, s, ...).
    """
    names = list(columns)
    meta = dict(meta or {})
    user_units = dict(units or {})
    file_units = dict(file_units or {})
    def row_of(i):
        return int(rows[i]) if rows is not None else int(i) + 1

    if not names:
        raise InputError("no data columns found", source=source)

    for col in user_units:
        if col not in columns:
            raise InputError(f"a unit is given for column '{col}', which is not in the file; its "
                             f"columns are {names}", source=source, column=col)

    # ---- units as stated (user > file > name suffix); None when nothing says
    stated = {}
    for col in names:
        in_name = split_unit(col)[1]
        u = user_units.get(col) or file_units.get(col)
        if u is None:
            u = in_name
        stated[col] = None if u is None else U.normalise_unit(str(u).strip(), source=source, column=col)
        if col not in user_units and col in file_units and in_name is not None and \
                U.normalise_unit(in_name, source=source, column=col) != stated[col]:
            # two statements of the unit disagree: only the user may settle it (COL=UNIT)
            raise InputError(f"the name says '{in_name}' but the file says '{file_units[col]}'; give "
                             f"the unit (--unit {col}=UNIT)", source=source, column=col)

    # ---- lengths
    n = None
    for col in names:
        arr = np.asarray(columns[col])
        if arr.ndim != 1:
            raise InputError(f"expected a 1-D column, got shape {arr.shape}", source=source, column=col)
        if n is None:
            n = arr.size
        elif arr.size != n:
            raise InputError(f"has {arr.size} samples but column '{names[0]}' has {n}",
                             source=source, column=col)

    # ---- time column
    tcol = None
    if mapping:
        mapping = dict(mapping)
        for key in list(mapping):
            if parse_key(key, source) == ("t", None):
                tcol = _resolve_column(mapping.pop(key), names, source, key)
    if tcol is None:
        cands = [c for c in names if _is_time_name(split_unit(c)[0])
                 and (stated[c] is None or U.UNITS[stated[c]][0] == "time")]
        if not cands:
            raise InputError(f"no time column found among {names}; name it 't_s' or 'time' "
                             f"(or 't_ms', ...), or map it: t=COLUMN", source=source)
        if len(cands) > 1:
            raise InputError(f"columns {cands} all look like time; say which one: --map t=COLUMN",
                             source=source)
        tcol = cands[0]
    tunit = stated[tcol] or "s"
    if U.UNITS[tunit][0] != "time":
        raise InputError(f"the time column has unit '{tunit}', which is not a time unit",
                         source=source, column=tcol)
    assumed = {}
    if stated[tcol] is None:
        assumed[tcol] = "s"

    # ---- roles
    roles = {}  # axis -> role -> column
    errs = {}   # axis -> column (tracking error)
    if mapping:
        used = {}
        for key, value in mapping.items():
            axis, role = parse_key(key, source)
            col = _resolve_column(value, names, source, key)
            if col == tcol:
                raise InputError(f"mapping {key}={value} names the time column", source=source, column=col)
            if col in used:         # one column as two signals would make e.g. cmd = act
                raise InputError(f"mapping names column '{col}' for both {used[col]} and {key}",
                                 source=source, column=col)
            used[col] = key
            target = errs if role == "err" else roles.setdefault(axis, {})
            if role == "err":
                if axis in errs:
                    raise InputError(f"mapping gives {axis}.err twice", source=source, column=col)
                errs[axis] = col
            else:
                if role in target:
                    raise InputError(f"mapping gives {axis}.{role} twice", source=source, column=col)
                target[role] = col
    else:
        claims = {}
        for col in names:
            if col == tcol:
                continue
            base = split_unit(col)[0]
            tokens = [t for t in re.split(r"[_\s.\-]+", base.lower()) if t]
            role = None
            if tokens and AXIS_RE.match(tokens[0]):
                axis, rest = tokens[0], tokens[1:]
                role = _role_from_tokens(rest)
            if role is None and len(tokens) > 1 and AXIS_RE.match(tokens[-1]):
                axis, rest = tokens[-1], tokens[:-1]     # "pos_x", "cmd_x", "v_y"
                role = _role_from_tokens(rest)
            if role is None:
                continue
            q = U.UNITS[stated[col]][0] if stated[col] else None
            role, problem = _reconcile(role, q)
            if role is None:
                continue
            if problem:
                raise InputError(f"the name says {role} of axis '{axis}' but the unit "
                                 f"'{stated[col]}' is {problem}; rename the column, give its unit "
                                 f"(COL=UNIT) or map it explicitly", source=source, column=col)
            claims.setdefault((axis, role), []).append(col)
        for (axis, role), cols in claims.items():
            if len(cols) > 1:
                raise InputError(f"columns {cols} all look like {axis}.{role}; say which one with a "
                                 f"mapping, e.g. {axis}.{role}={cols[0]}", source=source, column=cols[1])
            if role == "err":
                errs[axis] = cols[0]
            else:
                roles.setdefault(axis, {})[role] = cols[0]

    # check units of mapped columns fit their roles; default units where nothing is stated
    role_of = {c: (a, r) for a, rm in roles.items() for r, c in rm.items()}
    role_of.update({c: (a, "err") for a, c in errs.items()})
    unit_of = {}
    for col in names:
        if col == tcol:
            continue
        if col in role_of:
            axis, role = role_of[col]
            u = stated[col]
            if u is None:
                u = ROLE_DEFAULT_UNIT[role]
                assumed[col] = u
            q = U.UNITS[u][0]
            if q not in ROLE_QUANTITIES[role]:
                raise InputError(f"is used as {axis}.{role} but its unit '{u}' is a {q} unit; "
                                 f"expected a {' or '.join(sorted(ROLE_QUANTITIES[role]))} unit",
                                 source=source, column=col)
            unit_of[col] = u
        else:
            unit_of[col] = stated[col] or "1"

    # ---- values: finite, converted
    def values(col):
        arr = np.asarray(columns[col], dtype=float)
        bad = ~np.isfinite(arr)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(f"value {float(arr[i])!r} is not a finite number (NaN or inf)",
                             source=source, column=col, row=row_of(i))
        return arr

    t = U.to_canonical(values(tcol), tunit, source, tcol, in_place=owned)[0]
    check_time(t, source=source, column=tcol, row_of=row_of, jitter_tol=jitter_tol)
    notes = []
    if stated[tcol] is None:
        check_time_unit(t, source=source, column=tcol)
    else:
        notes += time_step_note(t, column=tcol, unit=stated[tcol])

    channels = {}
    for col in names:
        if col == tcol:
            continue
        data, cu = U.to_canonical(values(col), unit_of[col], source, col, in_place=owned)
        channels[col] = Channel.adopt(col, cu, data) if owned else Channel(col, cu, data)

    # ---- derived positions from the tracking error (thesis GUI files)
    derived = {}
    for axis, ecol in errs.items():
        rm = roles.setdefault(axis, {})
        e = channels[ecol]
        if "act" in rm and "cmd" not in rm:
            a = channels[rm["act"]]
            _same_unit(a, e, source)
            name = _free_name(f"{axis}_cmd", channels)
            channels[name] = Channel(name, a.unit, a.data + e.data)
            rm["cmd"] = name
            derived[name] = f"{rm['act']} + {ecol}"
        elif "cmd" in rm and "act" not in rm:
            c = channels[rm["cmd"]]
            _same_unit(c, e, source)
            name = _free_name(f"{axis}_act", channels)
            channels[name] = Channel(name, c.unit, c.data - e.data)
            rm["act"] = name
            derived[name] = f"{rm['cmd']} - {ecol}"
    roles = {a: rm for a, rm in roles.items() if rm}

    meta.setdefault("time_column", tcol)
    meta["units_in_file"] = {c: (stated[c] or assumed.get(c) or unit_of.get(c)) for c in names}
    if assumed:
        meta["assumed_units"] = assumed
        read_as = {c: u for c, u in assumed.items() if c != tcol}
        if read_as:     # said: a position in um or inch read as mm is a model 1000x off
            notes.append("columns " + ", ".join(f"{c} ({u})" for c, u in read_as.items())
                         + " state no unit and are read in these units; if one is in another, name "
                           "it like x_um or give --unit COLUMN=UNIT")
    if notes:
        meta["notes"] = notes
    if errs:
        meta["error_channels"] = dict(errs)
    if derived:
        meta["derived"] = derived
    return Trace(t=t, channels=channels, roles=roles, source=source, meta=meta, jitter_tol=jitter_tol)


def _same_unit(a, b, source):
    if a.unit != b.unit:
        raise InputError(f"tracking error '{b.name}' is in {b.unit} but position '{a.name}' is in "
                         f"{a.unit}; they must be the same quantity", source=source, column=b.name)


def _free_name(name, taken):
    k, out = 1, name
    while out in taken:
        k += 1
        out = f"{name}{k}"
    return out


def check_time_unit(t, *, source, column):
    """Refuse a time column read as seconds for want of a unit whose step says it is not.

    A column with no unit (``time``, ``t``, a mapped ``col1``) is read in s. Controller trace
    tools sample servo signals every 0.1-10 ms; a median step of ``MAX_UNSTATED_STEP_S``
    (0.1 s) or more is a time column in ms (1 kHz -> steps of 1 "s") or us, or a sample
    counter, and would make every filter, pole bound and Ts of the model 1000x off. A record
    that really is that slow passes once its unit is stated (``t_s``, ``--unit t=s``).
    Checked from ``MIN_CHECKED_SAMPLES`` (16) samples on: a trace tool's record has thousands,
    and hand-written examples of a few rows (``time`` 0, 1, 2) stay readable.

    Parameters
    ----------
    t : ndarray, s (as read with no unit, checked by :func:`check_time`)
    """
    ts = _slow_step(t)
    if ts is not None:
        base = split_unit(column)[0] if _is_time_name(split_unit(column)[0]) else "t"
        raise InputError(
            f"the time column has no unit and steps by {ts:.6g} (median), which as seconds would "
            f"be {1.0 / ts:.4g} Hz; servo traces step by 0.1-10 ms, so this looks like ms (or us, "
            f"or a sample count). State the unit: name the column like {base}_ms (or write "
            f"'{base} [ms]' in a header), or give --unit {column}=ms (Python: units={{'{column}': "
            f"'ms'}}); if it really is seconds, --unit {column}=s", source=source, column=column)


def time_step_note(t, *, column, unit):
    """``[note]`` when a time column with a stated unit steps by ``MAX_UNSTATED_STEP_S`` (0.1 s)
    or more, or by less than ``MIN_STATED_STEP_S`` (10 us), else ``[]``: the unit was stated, so
    it is read as stated (a slow record may be real), but servo traces step by 0.1-10 ms, and a ms
    column under an s name (``t_s``) makes every pole bound and Ts of the model 1000x off without
    an error (the bundled example's time in ms under ``t_s`` identifies a quasi-static
    K_vel of 12.4 s for 0.0124 s); s under a ms name makes them 1000x off the other way."""
    ts = _slow_step(t)
    if ts is not None:
        other = {"s": "ms", "ms": "us"}.get(unit)
        advice = (f"if it is in {other}, give --unit {column}={other}" if other else
                  "fdid reads no time unit below us: convert the column")
    elif t.size >= MIN_CHECKED_SAMPLES and (ts := float(np.median(np.diff(t)))) < MIN_STATED_STEP_S:
        other = {"us": "ms", "ms": "s"}.get(unit)
        advice = (f"if it is in {other}, give --unit {column}={other}" if other else
                  "fdid reads no time unit above s: convert the column")
    else:
        return []
    return [f"column '{column}' steps by {ts:.6g} s ({1.0 / ts:.4g} Hz), read in {unit} as stated; "
            f"servo traces step by 0.1-10 ms: {advice}"]


def _slow_step(t):
    """The median step of ``t`` (s) when it is ``MAX_UNSTATED_STEP_S`` or more and ``t`` has at
    least ``MIN_CHECKED_SAMPLES`` samples, else None."""
    if t.size < MIN_CHECKED_SAMPLES:
        return None
    ts = float(np.median(np.diff(t)))
    return ts if ts >= MAX_UNSTATED_STEP_S * (1 - 1e-6) else None    # 0.1 in a file differs by rounding


def check_time(t, *, source, column, row_of=None, jitter_tol=0.05):
    """Check a time vector (s) is strictly increasing with a steady step.

    The same rule as ``Trace`` (median step, relative tolerance ``jitter_tol``), but the
    error names the file's time column and the file row of the offending sample.

    Parameters
    ----------
    t : ndarray, s
    row_of : callable(sample index) -> row number to report (default index + 1)
    """
    row_of = row_of or (lambda i: int(i) + 1)
    if t.size < 2:
        raise InputError(f"a trace needs at least 2 samples, got {t.size}", source=source, column=column)
    fault = time_grid_fault(t, jitter_tol)
    if fault is None:
        return
    kind, k = fault[0], fault[1]
    if kind == "order":
        raise InputError(f"time is not strictly increasing ({float(t[k])!r} s then {float(t[k + 1])!r} s)",
                         source=source, column=column, row=row_of(k + 1))
    if kind == "jitter":
        raise InputError(f"sample time is not steady: step {fault[2]:.6g} s against the median {fault[3]:.6g} s "
                         f"(tolerance {jitter_tol:.0%}); resample the trace first",
                         source=source, column=column, row=row_of(k + 1))
    raise InputError(f"the time stamps drift from a uniform grid (more than half a sample at "
                     f"t = {float(t[k]):.6g} s): more than one sample rate; resample the trace first",
                     source=source, column=column, row=row_of(k))
