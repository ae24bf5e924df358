"""Reading a measured trace with a column map, units, data ranges and a layout: one way for
:func:`fdid_fmi.api.read_trace`, every ``fdid`` command (``--map``, ``--unit``, ``--range``,
``--layout``, ``--axes``) and the fleet's manifests.

Every command that reads a measured trace calls ``add_trace_arguments(parser)`` once and
``trace_from_args(path, args)`` for each file, so all commands read traces the same way::

    fdid identify run.csv --map t=t_s x.cmd=x_cmd_mm x.act=x_motor_mm --unit x_motor_mm=um \\
        --range 0.5:3.2,4:6
    fdid identify gui.txt --layout siso-gui
    fdid identify DATA_EMPS.mat

``--map``/``--unit`` take several ``KEY=VALUE`` tokens and may be repeated. Put them after
the file name, or end the list with ``--``, so the file name is not read as a token.
"""
from __future__ import annotations

from ..errors import InputError
from ..io import read_trace
from ..io.columns import parse_key
from ..io.ranges import parse_ranges
from ..io.text import LAYOUTS
from ..model import check_name
from ..units import normalise_unit


def _pairs(tokens, option, example):
    out = []
    if isinstance(tokens, str):
        tokens = [tokens]
    for piece in tokens or []:
        piece = str(piece)
        if "=" not in piece:
            raise InputError(f"'{piece}' is not KEY=VALUE (e.g. {example}); if it is the file "
                             f"name, put {option} after the file or end its list with --",
                             source=option, column=piece)
        key, value = piece.split("=", 1)
        key, value = key.strip(), value.strip()
        if not key or not value:
            raise InputError(f"'{piece}' needs both a key and a value (e.g. {example})",
                             source=option, column=piece)
        out.append((key, value))
    return out


def parse_mapping(tokens) -> dict:
    """Parse ``--map`` tokens into a reader mapping.

    Parameters
    ----------
    tokens : sequence of str
        ``["t=t_s", "x.cmd=x_cmd_mm", "x.act=x_motor_mm"]``; keys are ``t`` (time) or
        ``AXIS.ROLE`` with ROLE in cmd, act, tool, vel, acc, cur, err; values are column
        (or .mat variable) names or 1-based column numbers.

    Returns
    -------
    dict
        ``{"t": "t_s", "x.cmd": "x_cmd_mm", ...}`` (keys normalised: ``time`` -> ``t``,
        role in lower case).

    Raises
    ------
    InputError
        A token without ``=``, an unknown role, a key given twice.
    """
    out = {}
    for key, value in _pairs(tokens, "--map", "x.cmd=x_cmd_mm"):
        axis, role = parse_key(key, source="--map")
        norm = "t" if role is None else f"{axis}.{role}"
        if norm in out:
            raise InputError(f"'{norm}' is mapped twice ({out[norm]} and {value})", source="--map",
                             column=norm)
        out[norm] = value
    return out


def parse_units(tokens) -> dict:
    """Parse ``--unit COL=UNIT`` tokens into ``{col: unit}``; the unit must be known."""
    out = {}
    for col, unit in _pairs(tokens, "--unit", "x_pos=um"):
        if col in out:
            raise InputError(f"unit of '{col}' given twice", source="--unit", column=col)
        normalise_unit(unit, source="--unit", column=col)
        out[col] = unit
    return out


def add_trace_arguments(parser):
    """Add the trace-reading options to an ``argparse`` (sub)parser.

    Options: ``--map KEY=COL ...``, ``--unit COL=UNIT ...``, ``--range START:STOP[,...]``
    (repeatable), ``--layout {auto,columns,siso-gui,verify-gui}``, ``--axes x,y``.
    """
    g = parser.add_argument_group("reading traces")
    g.add_argument("--map", nargs="+", action="extend", default=[], metavar="KEY=COL",
                   help="say which column is what: t=COL, AXIS.ROLE=COL with ROLE in cmd, act, "
                        "tool, vel, acc, cur, err (e.g. --map t=t_s x.cmd=x_cmd_mm x.act=x_motor_mm)")
    g.add_argument("--unit", nargs="+", action="extend", default=[], metavar="COL=UNIT",
                   help="unit of a column when its name does not say it (e.g. --unit x_pos=um); "
                        "units: s ms m mm um mm_s m_s mm_min deg rad ...")
    g.add_argument("--range", action="append", default=[], metavar="START:STOP[,START:STOP]",
                   help="data range(s) in seconds, e.g. 0.5:3.2,4:6 (an empty end = data end)")
    g.add_argument("--layout", choices=LAYOUTS, default="auto",
                   help="text file layout: columns (header line), siso-gui (time, x, e), "
                        "verify-gui (time, x1, e1, x2, e2); auto detects")
    g.add_argument("--axes", default=None, metavar="X[,Y]",
                   help="axis names for the GUI layouts (default x / x,y; distinct names x y z a b c "
                        "u v w, optionally with digits, or axis1, axis2 ...) or the .mat EMPS axis")
    return parser


def trace_from_args(path, args, notes=True):
    """Read ``path`` with the options ``add_trace_arguments`` added; ``notes``: print the
    reader's notes (``trace.meta["notes"]``: units assumed or doubtful), as every command does
    (the fleet keeps them in its results instead).

    Returns
    -------
    Trace
        The whole trace. Requested ranges are parsed, checked against the data
        (``Trace.select``) and stored in ``trace.meta["ranges"]`` as ``[(start, stop), ...]``;
        get the pieces with ``trace.select(trace.meta.get("ranges"))``.
    """
    mapping = parse_mapping(getattr(args, "map", None)) or None
    units = parse_units(getattr(args, "unit", None)) or None
    ranges = parse_ranges(getattr(args, "range", None) or [])
    layout = getattr(args, "layout", None) or "auto"
    axes = getattr(args, "axes", None)
    axes = tuple(a.strip() for a in axes.split(",") if a.strip()) if axes else None
    say = (lambda note: print(f"note: {path}: {note}")) if notes else None
    return read_with_options(path, mapping, units, ranges, layout, axes, say=say)


def read_with_options(path, mapping=None, units=None, ranges=None, layout="auto", axes=None, say=None):
    """Read ``path`` with parsed options (:func:`parse_mapping`, :func:`parse_units`,
    ``parse_ranges``); ``axes`` a tuple of names; ``say``: called with each of the reader's notes
    (units assumed or doubtful) as soon as the file is read. Returns the Trace as
    :func:`trace_from_args` does."""
    for a in axes or ():
        check_name(a, "--axes")
    suffix = str(path).lower().rsplit(".", 1)[-1]
    kw = {}
    if suffix == "mat":
        if layout != "auto":
            raise InputError("--layout applies to text files only", source=str(path))
        if axes:
            if len(axes) != 1:
                raise InputError(f"a .mat trace has one axis; --axes got {list(axes)}", source=str(path))
            kw["axis"] = axes[0]
    elif suffix == "xml":
        if layout != "auto" or axes:
            raise InputError("--layout/--axes do not apply to a SINUMERIK XML trace", source=str(path))
    else:
        kw = {"layout": layout, "axes": axes}
    trace = read_trace(path, mapping=mapping, units=units, **kw)
    for note in trace.meta.get("notes", []) if say else ():   # how it was read, where that may be wrong
        say(note)
    if axes and trace.meta.get("layout") not in ("emps", "siso-gui", "verify-gui"):
        # elsewhere the axes come from the column names or --map: --axes would be ignored
        raise InputError(f"--axes names the axes of the GUI layouts and of EMPS; this file's axes "
                         f"{trace.axes} come from its column names or --map", source=str(path))
    if ranges:
        trace.select(ranges)  # raises a clear InputError for a range outside the data
        trace.meta["ranges"] = ranges
    return trace


def single_range(trace, hint="one --range"):
    """``trace`` cut to its one requested ``--range`` (the whole trace without one).

    For commands that take one piece of a trace (``fdid plan``, ``fdid diagnose``); several
    ranges are refused with ``hint`` saying what to give instead.
    """
    ranges = trace.meta.get("ranges")
    if not ranges:
        return trace
    if len(ranges) != 1:
        raise InputError(f"give {hint}", column="--range")
    return trace.slice(*ranges[0])
