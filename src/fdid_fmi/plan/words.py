"""The words of a part program the planner reads: one table, what each does.

Every G and M code, letter and mark the reader (:mod:`fdid_fmi.plan.ncprogram`) knows is one
:class:`Word` of :data:`VOCABULARY`, with what the planner does with it (:class:`Action`):

* ``applied`` - it shapes the motion and the planner acts on it (a move, a plane, units, a work
  offset the program sets, an exact stop, the end of the program);
* ``noted`` - read, and it does not act on the path in the twin's plane (spindle, coolant, tool
  change and tool length compensation, cancels of modes this reader never applies): listed once
  in the report with the rows where it stands;
* ``refused`` - not supported (cutter radius compensation, canned cycles, subprograms): the
  reader stops with one line naming the row and the word.

The spellings are those of Fanuc, SINUMERIK in ISO mode (the Fanuc dialect) and LinuxCNC: the
same codes with the same meaning; where the dialects differ the entry says how it is read
(``G4 P``, ``G10 L2 P0``). Leading zeros are the same word (``G01`` is ``G1``, ``M06`` is
``M6``). The reader, the report and the documentation (docs/plan-words.md, a table checked
against this one) take their words from here and nowhere else.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Action(str, Enum):
    """What the planner does with a word."""

    APPLIED = "applied"
    NOTED = "noted"
    REFUSED = "refused"


@dataclass(frozen=True)
class Word:
    """One entry of the vocabulary.

    Attributes
    ----------
    key : str       canonical spelling: ``G43``, ``G43.1``, ``M6``, a letter (``T``) or a mark
                    (``/``, ``( )``, ``;``, ``%``)
    action : Action
    group : str     the modal group a G code belongs to (two of one group in a block are
                    refused), ``""`` for other words
    meaning : str   what the word is
    effect : str    what the planner does with it
    """

    key: str
    action: Action
    group: str
    meaning: str
    effect: str


A, N, R = Action.APPLIED, Action.NOTED, Action.REFUSED
_OFFSET_NOTE = ("offsets the program sets with G10 L2 are applied; an offset it does not set is "
                "the controller's (unknown here) and read as 0: the moves are planned as written")
_COMP = ("the tool path it makes depends on the tool's radius in the controller's table: give "
         "the CAM's tool-centre path (without G41/G42)")
_CYCLE = "expand the cycle into G0/G1 moves (most CAM post-processors can)"

VOCABULARY = (
    # motion (RS-274 group 1) and dwell
    Word("G0", A, "motion", "rapid traverse", "a straight line at the axes' rapid limits"),
    Word("G1", A, "motion", "linear interpolation at F", "a straight line"),
    Word("G2", A, "motion", "clockwise arc or helix (I J K or R)", "an arc in the selected plane"),
    Word("G3", A, "motion", "counter-clockwise arc or helix (I J K or R)", "an arc in the selected plane"),
    Word("G4", A, "dwell", "dwell: P seconds (LinuxCNC), X or U seconds (Fanuc, SINUMERIK ISO)",
         "the axes rest for that time (a whole-number P of 100 or more is noted: ms on a Fanuc)"),
    Word("G9", A, "exact stop", "exact stop at the end of this block (non-modal)",
         "the block ends at rest also under --corner-angle"),
    # non-modal (group 0)
    Word("G10", A, "non-modal", "G10 L2 P1..P9 X Y Z: set a work offset (P1 = G54 .. P6 = G59, "
         "P7..P9 = G59.1..G59.3); G10 L1/L10/L11: tool table",
         "work offsets set by L2 are applied to the moves in that system; tool table entries are "
         "noted; L20 and P0 (read differently by Fanuc and LinuxCNC) and R (rotation) are refused"),
    Word("G28", A, "non-modal", "return to the first reference position, through the point given "
         "by X Y Z", "a rapid to the intermediate point, then to the reference position when the "
         "program gives it (G28.1); otherwise that second move is noted, not planned"),
    Word("G28.1", A, "non-modal", "store the current position as the first reference position "
         "(LinuxCNC)", "later G28 moves go there"),
    Word("G30", A, "non-modal", "return to the second reference position, through X Y Z",
         "as G28, with the position G30.1 stores"),
    Word("G30.1", A, "non-modal", "store the current position as the second reference position "
         "(LinuxCNC)", "later G30 moves go there"),
    Word("G53", A, "non-modal", "move in machine coordinates (this block only)",
         "the move is planned to the given machine coordinates, read as the program's coordinates "
         "plus the offsets the program sets (the controller's own offsets are unknown here)"),
    # planes, units, distance, feed modes
    Word("G17", A, "plane", "XY plane", "arcs in XY"),
    Word("G18", A, "plane", "ZX plane", "arcs in ZX"),
    Word("G19", A, "plane", "YZ plane", "arcs in YZ"),
    Word("G20", A, "units", "inch", "coordinates and feeds x 25.4"),
    Word("G21", A, "units", "mm", "coordinates and feeds in mm"),
    Word("G90", A, "distance", "absolute coordinates", "X Y Z are positions"),
    Word("G91", A, "distance", "incremental coordinates", "X Y Z are moves"),
    Word("G90.1", A, "arc distance", "absolute arc centres (I J K)", "I J K are the centre's position"),
    Word("G91.1", A, "arc distance", "incremental arc centres (the default)",
         "I J K are offsets from the arc's start"),
    Word("G93", A, "feed mode", "inverse time: F = 1 / block time in minutes", "each block takes 1/F min"),
    Word("G94", A, "feed mode", "F in units per minute", "F is the path feed"),
    # work offsets (group 12)
    Word("G54", A, "work offset", "work offset 1 (the default)", _OFFSET_NOTE),
    Word("G55", A, "work offset", "work offset 2", _OFFSET_NOTE),
    Word("G56", A, "work offset", "work offset 3", _OFFSET_NOTE),
    Word("G57", A, "work offset", "work offset 4", _OFFSET_NOTE),
    Word("G58", A, "work offset", "work offset 5", _OFFSET_NOTE),
    Word("G59", A, "work offset", "work offset 6", _OFFSET_NOTE),
    Word("G59.1", A, "work offset", "work offset 7 (LinuxCNC)", _OFFSET_NOTE),
    Word("G59.2", A, "work offset", "work offset 8 (LinuxCNC)", _OFFSET_NOTE),
    Word("G59.3", A, "work offset", "work offset 9 (LinuxCNC)", _OFFSET_NOTE),
    # path control (group 13)
    Word("G61", A, "path mode", "exact stop mode", "every block ends at rest, also under --corner-angle"),
    Word("G61.1", A, "path mode", "exact path mode (LinuxCNC)", "as G61: every block ends at rest"),
    Word("G64", A, "path mode", "continuous path mode; P Q: blending tolerances (LinuxCNC)",
         "with --corner-angle the velocity is kept through tangent junctions (the look-ahead); "
         "without it every block ends at rest; the path is never blended, so P and Q are noted"),
    # read, not acting on the path
    Word("G40", N, "cutter compensation", "cutter radius compensation off",
         "nothing to undo: compensation is never applied (G41/G42 are refused)"),
    Word("G43", N, "tool length", "tool length compensation on (H: the offset's number)",
         "a tool length shifts Z by a constant: the path's shape and the plane's motion are "
         "unchanged; axis words in its block move as usual"),
    Word("G43.1", N, "tool length", "dynamic tool length offset (LinuxCNC): X Y Z are offsets",
         "read; its X Y Z are offsets, not a move"),
    Word("G43.2", N, "tool length", "additional tool length offset (LinuxCNC): H or X Y Z",
         "read; its X Y Z are offsets, not a move"),
    Word("G49", N, "tool length", "tool length compensation off", "as G43: the shape is unchanged"),
    Word("G80", N, "cycle", "canned cycle off", "nothing to undo: cycles are refused"),
    Word("G15", N, "polar", "polar coordinates off (Fanuc)", "nothing to undo: polar input is never applied"),
    Word("G50.1", N, "mirror", "programmable mirror image off (Fanuc)", "nothing to undo"),
    Word("G67", N, "macro", "modal macro call off (Fanuc)", "nothing to undo"),
    Word("G69", N, "rotation", "coordinate rotation off (Fanuc)", "nothing to undo: rotation is never applied"),
    Word("G96", N, "spindle mode", "constant surface speed", "the spindle's, not the axes'"),
    Word("G97", N, "spindle mode", "constant spindle speed", "the spindle's, not the axes'"),
    Word("G98", N, "cycle return", "canned cycle return to the initial level", "read with cycles only"),
    Word("G99", N, "cycle return", "canned cycle return to the R level", "read with cycles only"),
    Word("G290", N, "dialect", "SINUMERIK: Siemens mode", "read; later Siemens-only words are refused one by one"),
    Word("G291", N, "dialect", "SINUMERIK: ISO dialect mode", "read: the ISO words of this table follow"),
    # refused
    Word("G41", R, "cutter compensation", "cutter radius compensation left", _COMP),
    Word("G42", R, "cutter compensation", "cutter radius compensation right", _COMP),
    Word("G41.1", R, "cutter compensation", "dynamic cutter compensation left (LinuxCNC)", _COMP),
    Word("G42.1", R, "cutter compensation", "dynamic cutter compensation right (LinuxCNC)", _COMP),
    *(Word(f"G{n}", R, "cycle", "canned cycle", _CYCLE) for n in (73, 74, 76, 81, 82, 83, 84, 85, 86, 87, 88, 89)),
    Word("G92", R, "coordinate shift", "coordinate system shift (G92)",
         "set the work offset with G10 L2 instead, or leave the shift out"),
    # M codes
    Word("M0", N, "", "program stop", "the plan does not wait for the operator: noted"),
    Word("M1", N, "", "optional stop", "the plan does not wait for the operator: noted"),
    Word("M2", A, "", "end of program", "nothing after it is run (the lines are listed)"),
    Word("M30", A, "", "end of program and rewind", "nothing after it is run (the lines are listed)"),
    Word("M3", N, "", "spindle on, clockwise", "the spindle's, not the axes'"),
    Word("M4", N, "", "spindle on, counter-clockwise", "the spindle's, not the axes'"),
    Word("M5", N, "", "spindle off", "the spindle's, not the axes'"),
    Word("M6", N, "", "tool change (T: the tool)", "the changer's own moves are not planned: noted"),
    Word("M7", N, "", "mist coolant on", "not the axes'"),
    Word("M8", N, "", "flood coolant on", "not the axes'"),
    Word("M9", N, "", "coolant off", "not the axes'"),
    Word("M98", R, "", "subprogram call", "expand the subprogram into the program"),
    Word("M99", R, "", "subprogram return", "expand the subprogram into the program"),
    Word("M", N, "", "any other M code: a machine function", "does not move the axes: noted"),
    # letters and marks
    Word("N", A, "", "line (sequence) number", "the report names blocks by it"),
    Word("O", N, "", "program number (O1000, Fanuc and SINUMERIK ISO)",
         "noted; LinuxCNC O-word subroutines and control flow (o100 sub, call, if, while) are refused"),
    Word("F", A, "", "feed", "the path feed (G94) or 1 / block time (G93)"),
    Word("S", N, "", "spindle speed", "the spindle's, not the axes'"),
    Word("T", N, "", "tool select", "noted"),
    Word("H", N, "", "tool length offset number (with G43)", "noted"),
    Word("D", N, "", "cutter radius offset number (SINUMERIK: tool edge)", "noted"),
    Word("/", A, "", "block delete", "the block is run, as with the block-delete switch off, and noted"),
    Word("( )", N, "", "comment in parentheses", "not read"),
    Word(";", N, "", "comment to the end of the line", "not read"),
    Word("%", A, "", "tape start / end", "the lines after the closing % are not read (listed)"),
    Word("#", R, "", "parameters and variables (#1, #<name>)", "write the numbers"),
    Word("[ ]", R, "", "expressions", "write the numbers"),
)

BY_KEY = {w.key: w for w in VOCABULARY}
if len(BY_KEY) != len(VOCABULARY):       # pragma: no cover - a table edit that repeats a word
    raise RuntimeError("the vocabulary names a word twice")


def code_key(letter, value):
    """Canonical key of a G or M code: ``G01`` -> ``G1``, ``G43.10`` -> ``G43.1``."""
    v = round(float(value), 1)
    return f"{letter}{int(v)}" if v == int(v) else f"{letter}{v:g}"


def lookup(letter, value):
    """The :class:`Word` of a G or M code, or None for a G code not in the table (an M code not in
    it is the generic ``M`` entry)."""
    w = BY_KEY.get(code_key(letter, value))
    if w is None and letter == "M":
        return BY_KEY["M"]
    return w


def supported_g():
    """The G codes read (applied or noted), in table order: for error messages."""
    return [w.key for w in VOCABULARY if w.key.startswith("G") and w.action is not Action.REFUSED]


def markdown_table():
    """The vocabulary as a Markdown table (docs/plan-words.md carries it)."""
    rows = ["| word | group | what it is | read as | what the planner does |",
            "|---|---|---|---|---|"]
    for w in VOCABULARY:
        key = w.key.replace("|", "\\|")
        rows.append(f"| `{key}` | {w.group} | {w.meaning} | {w.action.value} | {w.effect} |")
    return "\n".join(rows) + "\n"
