"""CSV / TXT trace reader, including the thesis GUI .txt layouts.

Two kinds of file:

* **With a header line** (``layout="columns"``): comma, semicolon, tab or whitespace
  delimited (detected from the first line, or ``delimiter=``). Column names give roles
  and units by convention, or a mapping names them (see ``fdid_fmi.io.columns``).
  A unit may also be written in the header as ``x_cmd [mm]`` or ``x_cmd (mm)``
  (comma, semicolon or tab files only, since a space splits whitespace files).
  With ``;`` or tab as delimiter and no ``.`` in the first data row, a decimal comma
  (``1,25``) is accepted.
* **Headerless thesis GUI files** (all numeric):

  - ``layout="siso-gui"`` (thesis sec. 4.5.1): 3 columns
    ``time [s], measured position [mm], tracking error [mm]`` -> axis ``axes[0]`` with
    act = x and cmd = x + e (tracking error e = x_cmd - x);
  - ``layout="verify-gui"`` (thesis sec. 4.5.2): 5 columns
    ``time, A1 position, A1 tracking error, A2 position, A2 tracking error`` -> axes
    ``("x", "y")`` by default.

  ``layout="auto"`` (default) picks ``columns`` when the first line has a non-numeric
  cell, else the GUI layout that fits 3 or 5 columns. The GUI columns are named
  ``t``, ``<axis>_act``, ``<axis>_err`` (units s, mm, mm unless ``units=`` says otherwise);
  the derived command is ``<axis>_cmd``.

Lines that are blank or start with ``#`` or ``%`` are skipped. Row numbers in error
messages are **line numbers of the file, 1-based**, so with the header on the first
line the first data row is row 2 -- the row number a spreadsheet shows. The file is only
read, never written.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .. import units as U
from ..errors import InputError
from ..trace import Trace
from .columns import AXIS_RE, assemble, split_unit
from .common import file_sha256, read_text_file, text_lines

LAYOUTS = ("auto", "columns", "siso-gui", "verify-gui")
MAX_COLUMNS = 10000       # columns of a trace file (bounded work; servo traces have tens)
GUI_COLUMNS = {"siso-gui": 3, "verify-gui": 5}
GUI_TEXT = {
    "siso-gui": "time [s], measured position [mm], tracking error [mm]",
    "verify-gui": "time [s], A1 measured position [mm], A1 tracking error [mm], "
                  "A2 measured position [mm], A2 tracking error [mm]",
}
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab", None: "whitespace"}
_BRACKET = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]$")
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d*(?:[eE][+-]?\d+)?$")


def read_text(path, mapping=None, units=None, *, layout="auto", axes=None, delimiter=None,
              jitter_tol=0.05) -> Trace:
    """Read a CSV/TXT trace.

    Parameters
    ----------
    path : str or Path
    mapping : dict, optional
        ``{"t": "t_s", "x.cmd": "x_cmd_mm", "x.act": "x_motor_mm", ...}``; roles
        cmd/act/tool/vel/acc/cur and ``err`` (tracking error). Values are column names
        or 1-based column numbers. Without it, roles come from the column names.
    units : dict, optional
        ``{column: unit}`` overriding units from names / header, e.g. ``{"x_pos": "um"}``.
    layout : {"auto", "columns", "siso-gui", "verify-gui"}
    axes : sequence of str, optional
        Axis names for the GUI layouts (default ``("x",)`` / ``("x", "y")``): one / two
        distinct names ``x y z a b c u v w`` (optionally with digits, ``x1``) or ``axis1``...;
        a string is a comma list. Refused with the columns layout, whose axes come from the
        column names or the mapping (see :func:`gui_axes`).
    delimiter : str, optional
        ``","``, ``";"``, ``"\\t"`` or ``"whitespace"``; detected when omitted.
    jitter_tol : float
        Largest relative deviation of a time step from the median step.

    Returns
    -------
    Trace
        Positions in mm, velocities in mm/s, time in s. ``meta`` holds ``sha256``,
        ``layout``, ``delimiter``, ``units_in_file`` and any ``assumed_units``/``derived``.
    """
    src = str(path)
    if layout is None:
        layout = "auto"
    if layout not in LAYOUTS:
        raise InputError(f"unknown layout '{layout}'; expected one of {', '.join(LAYOUTS)}",
                         source=src, column="layout")
    text = read_text_file(path)
    # the first lines decide the layout; the data body is parsed in one pass (_parse_body)
    entries, offsets = _head_entries(text)
    if not entries:
        raise InputError("file is empty (no header and no data rows)", source=src)

    delim = _pick_delimiter(entries[0][1], delimiter, src)
    first = _split(entries[0][1], delim)
    trailing = delim is not None and len(first) > 1 and first[-1] == ""  # "a,b,c," lines
    if trailing:
        first = first[:-1]
    if len(first) > MAX_COLUMNS:
        raise InputError(f"the first line has {len(first)} columns; at most {MAX_COLUMNS} are read "
                         f"(is the delimiter right? detected: {DELIMITERS[delim]})",
                         source=src, row=entries[0][0])
    comma_ok = delim != ","
    has_header = not all(_is_number(c) or (comma_ok and _DECIMAL_COMMA.match(c)) for c in first)
    # decimal comma: some cell of the first data rows looks like "1,25" and none has a "."
    probe = [_split(ln, delim) for _, ln in entries[int(has_header):200]]
    probe = [c for r in probe if not (has_header and _is_units_row(r, len(first), True)) for c in r]
    decimal_comma = (comma_ok and any("," in c and _DECIMAL_COMMA.match(c) for c in probe)
                     and not any("." in c for c in probe))

    ncol = len(first)
    if layout == "auto":
        if has_header:
            layout = "columns"
        elif ncol in (3, 5) and not mapping:
            layout = "siso-gui" if ncol == 3 else "verify-gui"
        else:
            layout = "columns"

    file_units = {}
    units_row = False
    if layout in GUI_COLUMNS:
        need = GUI_COLUMNS[layout]
        k0 = int(has_header) if len(entries) > int(has_header) else 0
        row0 = _split(entries[k0][1], delim)
        if trailing and row0 and row0[-1] == "":
            row0 = row0[:-1]
        if len(row0) != need:
            raise InputError(f"layout '{layout}' expects {need} columns ({GUI_TEXT[layout]}) but "
                             f"the first data line has {len(row0)}", source=src, row=entries[k0][0])
        ax = gui_axes(axes, layout, src)
        names = ["t"] + [f"{a}_{k}" for a in ax for k in ("act", "err")]
        # the layout says mm; its "time [s]" is the GUI's convention, not a statement of this
        # file: unless the header states it, the time unit counts as assumed (so a time column
        # in ms, steps of 1 for 1 kHz, is caught by columns.check_time_unit)
        file_units = {n: "mm" for n in names if n != "t"}
        if has_header:      # the layout fixes s and mm: a header saying otherwise is not skipped
            hnames, hunits = _parse_header(first, src, entries[0][0])
            for j, h in enumerate(hnames[:need]):
                u, want = hunits.get(h) or split_unit(h)[1], ("s" if j == 0 else "mm")
                if u is not None and U.normalise_unit(u, source=src, column=h) != want:
                    raise InputError(f"layout '{layout}' reads {GUI_TEXT[layout]}, but the header gives "
                                     f"'{u}'; use the columns layout (the header's units then hold)",
                                     source=src, column=h)
                if j == 0 and u is not None:
                    file_units["t"] = "s"
        if mapping:
            raise InputError(f"layout '{layout}' fixes the columns ({GUI_TEXT[layout]}); "
                             f"a mapping is not used with it", source=src, column="mapping")
    elif axes is not None and (isinstance(axes, str) or len(axes)):
        # the axes of a columns file come from its names or the mapping: axes= would be ignored
        raise InputError(f"axes= (--axes) names the axes of the GUI layouts ({', '.join(GUI_COLUMNS)});"
                         f" with the columns layout the axes come from the column names or the "
                         f"mapping (--map), so {_list(axes)} would be ignored", source=src, column="axes")
    elif has_header:
        names, file_units = _parse_header(first, src, entries[0][0])
        if len(entries) > 1 and _is_units_row(_split(entries[1][1], delim), len(names), comma_ok):
            urow = _split(entries[1][1], delim)[:len(names)]
            for name, u in zip(names, urow):
                u = u.strip("[]() ")
                if u and name not in file_units:
                    file_units[name] = u
            units_row = True
    else:
        names = [f"col{j + 1}" for j in range(ncol)]
        if not mapping:
            raise InputError(f"the file has no header line and {ncol} columns; give a header "
                             f"(e.g. t_s,x_cmd_mm,x_mm), a mapping such as t=col1 x.cmd=col2 "
                             f"x.act=col3, or a layout ({', '.join(GUI_COLUMNS)})", source=src)

    first_data = (1 + units_row) if has_header else 0
    if len(entries) <= first_data:
        raise InputError("the file has a header line but no data rows", source=src,
                         row=entries[0][0])
    parsed = None if decimal_comma else _parse_body(text, offsets[first_data], entries[first_data][0],
                                                    len(names), delim)
    if parsed is None:
        data_entries = list(_all_entries(text))[first_data:]
        columns, rows = _parse_lines(data_entries, names, delim, trailing, has_header, decimal_comma, src)
    else:
        cols, rows = parsed
        columns = dict(zip(names, cols))
    del text, parsed            # a long file's text is as large as its numbers: free it first

    meta = {"file": src, "sha256": file_sha256(path), "layout": layout,
            "delimiter": DELIMITERS[delim], "header": has_header}
    if decimal_comma:
        meta["decimal_comma"] = True
    if layout in GUI_COLUMNS and units:
        for k in units:
            if k not in names:
                raise InputError(f"a unit is given for column '{k}'; the {layout} layout names its "
                                 f"columns {names}", source=src, column=k)
    return assemble(columns, source=src, mapping=mapping, units=units, file_units=file_units,
                    rows=rows, meta=meta, jitter_tol=jitter_tol, owned=True)


# ----------------------------------------------------------------------------- helpers
HEAD_LINES = 210          # entries the layout detection reads (header, units row, 200 data rows)
_LINE = re.compile(r"[^\r\n]*(?:\r\n|\r|\n|$)")
_BODY_CHUNK = 1 << 22     # characters parsed at a time: bounded temporaries for long traces
_NOT_PLAIN = re.compile(r"[^0-9eE+\-.,;\t \r\nnaifNAIF]")


def _is_entry(line):
    return bool(line.strip()) and not line.lstrip().startswith(("#", "%"))


def _head_entries(text):
    """The first HEAD_LINES entries (1-based line number, line) of ``text`` (blank and comment
    lines skipped), and where each starts: ``(entries, offsets)``, read lazily so that a long
    file builds no object per line here."""
    entries, offsets = [], []
    for i, m in enumerate(_LINE.finditer(text)):
        if m.start() == len(text):
            break
        line = m.group().rstrip("\r\n")
        if _is_entry(line):
            entries.append((i + 1, line))
            offsets.append(m.start())
            if len(entries) >= HEAD_LINES:
                break
    return entries, offsets


def _all_entries(text):
    return ((i + 1, ln) for i, ln in enumerate(text_lines(text)) if _is_entry(ln))


def _parse_body(text, start, lineno, width, delim):
    """The data rows from character ``start`` (line ``lineno``) on as ``width`` float columns
    with their line numbers, parsed by numpy in chunks (no Python object per cell, bounded
    temporaries); None when the body is not plain numbers and delimiters (quotes, comments or
    blank lines inside, ragged rows, empty cells, a trailing delimiter), which the line-by-line
    reader then reads and, where wrong, names by row and column. Both read decimal text to the
    nearest double."""
    end_text = len(text)
    while end_text > start and text[end_text - 1].isspace():    # trailing blank lines
        end_text -= 1
    if _NOT_PLAIN.search(text, start, end_text) is not None:
        return None
    cr = "\r" in text
    sep = "\r" if cr and "\n" not in text else "\n"
    n_est = text.count(sep, start, end_text) + 1
    cols = [np.empty(n_est) for _ in range(width)]
    n, pos = 0, start
    while pos < end_text:
        cut = min(pos + _BODY_CHUNK, end_text)
        nl = text.rfind(sep, pos, cut + 1) if cut < end_text else -1
        stop = end_text if nl < pos else nl + 1
        chunk = text[pos:stop]
        lines = (chunk.replace("\r\n", "\n").replace("\r", "\n") if cr else chunk).split("\n")
        if lines[-1] == "":
            lines.pop()
        try:
            blk = np.loadtxt(lines, delimiter=delim, dtype=float, ndmin=2, comments=None)
        except ValueError:
            return None
        if blk.shape[1] != width or blk.shape[0] != len(lines) or n + len(lines) > n_est:
            return None     # a blank line inside: the rows' line numbers would shift
        for j in range(width):
            cols[j][n:n + len(lines)] = blk[:, j]
        n += len(lines)
        pos = stop
    if n != n_est:
        return None
    return cols, lineno + np.arange(n, dtype=np.int64)


def _parse_lines(data_entries, names, delim, trailing, has_header, decimal_comma, src):
    """Columns and row numbers of the data rows, line by line (any file the body parser declines)."""
    cells = []
    rows = np.empty(len(data_entries), dtype=np.int64)
    width = len(names)
    for k, (lineno, line) in enumerate(data_entries):
        parts = _split(line, delim)
        if trailing and len(parts) == width + 1 and parts[-1] == "":
            parts = parts[:-1]
        if len(parts) != width:
            raise InputError(f"has {len(parts)} fields but the {'header' if has_header else 'first row'}"
                             f" has {width} (ragged row; delimiter: {DELIMITERS[delim]})",
                             source=src, row=lineno)
        cells.append(parts)
        rows[k] = lineno
    columns = {}
    for j, name in enumerate(names):
        columns[name] = _to_floats([r[j] for r in cells], decimal_comma, src, name, rows)
    return columns, rows


def _list(axes):
    return [axes] if isinstance(axes, str) else [str(a) for a in axes]


def gui_axes(axes, layout, src):
    """The axis names of a GUI layout, checked: ``siso-gui`` one, ``verify-gui`` two, distinct.

    An axis name is one the name conventions of ``fdid_fmi.io.columns`` read back from the
    column ``<axis>_act``: ``x y z a b c u v w``, optionally followed by digits (``x1``,
    ``a2``), or ``axis1``, ``axis2``, ... -- lower case, as the conventions return them (any
    other name gave the axis no roles, and a name given twice read both axes into one).
    A string is a comma list (``"x,y"``, as ``--axes``). ``None`` or empty: ``x`` / ``x, y``.
    """
    need = GUI_COLUMNS[layout] // 2
    if axes is None or (not isinstance(axes, str) and len(axes) == 0):
        return ("x",) if need == 1 else ("x", "y")
    ax = tuple(a.strip() for a in axes.split(",")) if isinstance(axes, str) else tuple(axes)
    if len(ax) != need:
        raise InputError(f"layout '{layout}' needs {need} axis name(s) (axes= / --axes), got "
                         f"{list(ax)}", source=src, column="axes")
    for a in ax:
        if not isinstance(a, str) or not AXIS_RE.fullmatch(a):
            hint = (f" (lower case: '{a.lower()}')" if isinstance(a, str) and AXIS_RE.fullmatch(a.lower())
                    else "")
            raise InputError(f"axes= / --axes: {a!r} is not an axis name{hint}; expected x, y, z, a, "
                             f"b, c, u, v or w, optionally followed by digits (x1, a2), or axis1, "
                             f"axis2, ...", source=src, column="axes")
    if len(set(ax)) != len(ax):
        raise InputError(f"axes= / --axes names axis '{ax[0]}' twice ({list(ax)}); the {layout} "
                         f"layout's two axes need two names", source=src, column="axes")
    return ax


def _pick_delimiter(line, delimiter, src):
    if delimiter is not None:
        d = {"whitespace": None, "space": None, "tab": "\t", "\\t": "\t", "comma": ",",
             "semicolon": ";"}.get(delimiter, delimiter)
        if d not in DELIMITERS:
            raise InputError(f"unknown delimiter {delimiter!r}; expected ',', ';', tab or whitespace",
                             source=src, column="delimiter")
        return d
    for d in ("\t", ";", ","):
        if d in line:
            return d
    return None


def _split(line, delim):
    if delim is None:
        return [c.strip().strip('"').strip("'") for c in line.split()]
    return [c.strip().strip('"').strip("'").strip() for c in line.split(delim)]


def _is_number(cell, decimal_comma=False):
    if decimal_comma:
        cell = cell.replace(",", ".")
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _is_units_row(cells, width, comma_ok):
    """A second header line holding units (``s, mm, mm/s``): no cell is a number."""
    cells = [c for c in cells if c != ""]
    return (0 < len(cells) <= width
            and not any(_is_number(c) or (comma_ok and _DECIMAL_COMMA.match(c)) for c in cells))


def _parse_header(cells, src, lineno):
    """Column names and units of a header line (linear in the number of columns)."""
    names, units, seen = [], {}, set()
    for j, cell in enumerate(cells):
        m = _BRACKET.match(cell)
        name = m.group(1).strip() if m else cell
        if not name:
            raise InputError(f"header cell {j + 1} is empty; every column needs a name",
                             source=src, row=lineno)
        if name in seen:
            raise InputError(f"header names column '{name}' twice", source=src, column=name, row=lineno)
        names.append(name)
        seen.add(name)
        if m and m.group(2).strip():
            units[name] = m.group(2).strip()
    return names, units


def _to_floats(cells, decimal_comma, src, name, rows):
    if decimal_comma:
        cells = [c.replace(",", ".") for c in cells]
    try:
        return np.array([float(c) for c in cells], dtype=float)
    except ValueError:
        pass
    for k, c in enumerate(cells):
        try:
            float(c)
        except ValueError:
            what = "an empty cell" if c == "" else f"'{c}'"
            raise InputError(f"{what} is not a number", source=src, column=name, row=int(rows[k]))
    raise AssertionError("unreachable")  # pragma: no cover


def is_text_file(path) -> bool:
    return Path(path).suffix.lower() in (".csv", ".txt", ".dat", ".tsv")
