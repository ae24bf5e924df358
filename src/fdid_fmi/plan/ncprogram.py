"""Read an ISO 6983 / RS-274 part program into motion blocks.

Why a small tokenizer and no PyPI parser: the G-code parsers on PyPI either are 3D-printer
dialects that drop what they do not understand without a word and lose the line numbers
(``gcodeparser``: one regex over the whole file, no modal motion, no parenthesis comments),
are unmaintained since 2017 (``pygcode`` 0.2.1), or interpret the Siemens dialect into a
Polars table with a Rust extension (``nc-gcode-interpreter``: no ``R`` arcs, no G20, errors
not tied to our lines). RS-274 words are regular (a letter and a number, comments in
parentheses or after ``;``), so a tokenizer of ~40 lines that knows every line number and
refuses what it does not know is the safer tool here.

What is read
------------
* motion: ``G0`` (rapid, straight line at the axes' rapid limits), ``G1``, ``G2``/``G3``
  (clockwise / counter-clockwise arcs, seen from the positive axis normal to the plane) with
  ``I J K`` centre offsets (incremental from the start point; ``G90.1`` makes them absolute) or
  ``R`` radius (``R > 0``: the arc of at most 180 deg, ``R < 0``: the longer one); an ``I J K``
  arc whose end equals its start is a full circle; a move along the plane normal during an arc
  makes a helix; ``G4 P<s>`` dwell (LinuxCNC convention: P in seconds; a whole-number P of 100
  or more gets a note: a Fanuc program means ms there, and writes seconds as ``X`` or ``U``).
* modal state: ``G17/G18/G19`` (XY / ZX / YZ plane), ``G20/G21`` (inch / mm: coordinates and
  feeds x 25.4), ``G90/G91`` (absolute / incremental), ``G93`` (inverse time: ``F`` = 1 / block
  time in minutes, needed on every feed block) and ``G94`` (``F`` in units per minute, modal).
* ``N`` line numbers (whole numbers: ``N10.5`` is refused), ``O`` program numbers, ``( ... )``
  and ``;`` comments.
* ``%`` lines: the first opens the program (tape start), the second closes it: the lines after
  the closing ``%`` are not read (a controller stops reading there), only listed.
* block delete ``/``: the block is **run**, as a controller runs it with its block-delete switch
  off (the switch's state is the operator's, not the program's), and listed in
  ``Program.notes`` so that the user knows it was planned; delete the line to plan without it.
* numbers are written in digits (``X1e9``, exponent notation, is not G-code and is refused).
* the modal and non-motion words real programs carry, from the one table of
  :mod:`fdid_fmi.plan.words` (docs/plan-words.md): work offsets ``G54``-``G59`` (``G59.1``-``.3``)
  with their offsets applied where the program sets them (``G10 L2 P<n> X Y Z``); exact stop
  ``G61``/``G61.1``/``G9`` (``Block.exact_stop``: the block ends at rest also under the
  look-ahead) and ``G64`` (its ``P``/``Q`` tolerances noted: the path is never blended);
  ``G28``/``G30`` (a rapid to the intermediate point, then to the reference position where
  ``G28.1``/``G30.1`` stored it, else noted); ``G53`` moves; ``G4 X``/``U`` seconds (Fanuc).
  Read and listed once (``Program.words``), not acting on the path in the twin's plane:
  ``G40 G43 G43.1 G43.2 G49 G80`` and the cancels ``G15 G50.1 G67 G69``, ``G96 G97 G98 G99``,
  ``S M T H D`` words (``M3``-``M9``, ``M6`` tool changes, ``M0``/``M1`` stops).
* ``M2`` / ``M30`` end the program: lines after them are listed as not run, not read (a CNC
  stops there; Fanuc-style subprograms often follow).
Refused with an :class:`~fdid_fmi.errors.InputError` naming the file, the line (``row N``: line
N of the file, the word every message and list of ``fdid plan`` uses) and the word: cutter
radius compensation ``G41``/``G42``, canned cycles ``G73``-``G89``, ``G92``, subprograms
(``M98``/``M99``, LinuxCNC O-words ``o100 sub`` / ``call`` / ``if`` / ``while``), parameters
and expressions (``#1``, ``[...]``), ``A B C U V W`` axes and any G code not in the table.

Arc checks: an ``I J K`` arc whose end point is not on its circle (|r_end - r_start| larger than
the end-point tolerance 0.002 mm + 0.1 % of the radius, :func:`radius_tolerance`) is refused, as
are ``R`` arcs whose |R| is shorter than half the chord by more than that same tolerance (within
it, the rounding of the words: a half circle on the chord, radius half the chord), arcs
with both ``R`` and ``I J K`` and arcs with an offset word outside their plane. When the two
radii differ within the tolerance the arc's radius changes linearly along it (as LinuxCNC does).
"""
from __future__ import annotations

import codecs
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.common import decode_text_file, text_lines
from .words import Action, code_key, lookup, supported_g

INCH = 25.4
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}   # (first, second, normal) axis index
_PLANE_NAMES = {17: "G17 (XY)", 18: "G18 (ZX)", 19: "G19 (YZ)"}
_OFFSET_LETTER = {0: "I", 1: "J", 2: "K"}
_WORD = re.compile(r"\s*([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
_EXPONENT = re.compile(r"[eE][+-]?\d+")
_RADIUS_ABS_TOL = 0.002        # mm
_RADIUS_REL_TOL = 1e-3


def radius_tolerance(r_mm):
    """How far an arc's end point may miss its circle (rounding of the programmed words), mm:
    0.002 mm + 0.1 % of the radius ``r_mm``. The one tolerance of both arc forms: an ``I J K``
    arc's end radius may differ from its start radius by this much, and an ``R`` arc's half chord
    may exceed |R| by this much (then read as a half circle on the chord)."""
    return _RADIUS_ABS_TOL + _RADIUS_REL_TOL * r_mm


@dataclass
class Block:
    """One motion (or dwell) block of a program, in mm and s.

    Attributes
    ----------
    index : int       0-based position among the program's motion blocks
    line : int        1-based line of the program file
    number : int or None   the ``N`` word
    text : str        the line as written
    kind : str        ``rapid``, ``line``, ``arc`` or ``dwell``
    start, end : ndarray (3,), mm   X, Y, Z at the start and end
    feed : float      programmed path feed, mm/s (``inf`` for rapids, 0 for dwells)
    inverse_time : bool   G93 block: ``feed`` is the equivalent feed length / time
    block_time : float    G93 block time, s (``nan`` otherwise); dwell time for ``dwell``
    units : str       ``mm`` or ``inch`` (the program's units, for writing it back)
    f_word : float or None   the F word in force, in program units (per min, or 1/min in G93)
    center : ndarray (3,) or None   arc centre (mm); the normal coordinate is the start's
    plane : int       17, 18 or 19
    cw : bool         G2
    sweep : float     arc angle, rad (> 0)
    r0, r1 : float    arc radius at the start and end, mm
    exact_stop : bool  the block ends at rest whatever the corner rule (G61, G61.1, G9; rapids
                      and G28 / G30 returns)
    """

    index: int
    line: int
    number: int | None
    text: str
    kind: str
    start: np.ndarray
    end: np.ndarray
    feed: float
    inverse_time: bool = False
    block_time: float = float("nan")
    units: str = "mm"
    f_word: float | None = None
    center: np.ndarray | None = None
    plane: int = 17
    cw: bool = False
    sweep: float = 0.0
    r0: float = 0.0
    r1: float = 0.0
    exact_stop: bool = False

    @property
    def length(self) -> float:
        """Path length, mm (helix: in-plane arc and normal travel combined)."""
        if self.kind == "arc":
            i, j, k = _PLANES[self.plane]
            h = self.end[k] - self.start[k]
            return float(math.hypot(0.5 * (self.r0 + self.r1) * self.sweep, h))
        return float(np.linalg.norm(self.end - self.start))

    def point(self, s):
        """Points at path parameters ``s`` (mm from the start, clipped to [0, length]).

        Returns
        -------
        (n, 3) ndarray, mm
        """
        s = np.atleast_1d(np.asarray(s, float))
        L = self.length
        u = np.clip(s / L, 0.0, 1.0) if L > 0 else np.zeros_like(s)
        if self.kind != "arc":
            return self.start + np.outer(u, self.end - self.start)
        i, j, k = _PLANES[self.plane]
        a0 = math.atan2(self.start[j] - self.center[j], self.start[i] - self.center[i])
        ang = a0 + (-1.0 if self.cw else 1.0) * self.sweep * u
        r = self.r0 + (self.r1 - self.r0) * u
        out = np.empty((u.size, 3))
        out[:, i] = self.center[i] + r * np.cos(ang)
        out[:, j] = self.center[j] + r * np.sin(ang)
        out[:, k] = self.start[k] + (self.end[k] - self.start[k]) * u
        # the end point exactly as programmed
        out[u >= 1.0] = self.end
        return out


@dataclass
class Program:
    """A parsed part program.

    Attributes
    ----------
    blocks : list[Block]      motion and dwell blocks in program order
    start : ndarray (3,), mm  position before the first block (the origin)
    ignored : list of (line, word)   words passed over (S, M, T, ...) and lines not run or read
    notes : list of (line, text)     how a block was read that the user should know (block delete)
    source : str
    lines : list[str]         the program text, line by line
    encoding : str            the file's encoding, as :func:`encode_text` writes it back (its
                              comments keep their bytes): ``utf-8``, ``utf-8-sig`` (with a BOM),
                              ``latin-1`` (a file that is not UTF-8), ``utf-16-le`` / ``-be`` or
                              ``utf-32-le`` / ``-be`` (always with their BOM: read only with it)
    newline : str             the line end of the file (its first one): ``\n``, ``\r\n`` or ``\r``
    axes_used : list[str]     axes that move (``x``, ``y``, ``z``)
    words : dict              every word read, once: canonical key (``G43``, ``M6``, ``T``, ``/``;
                              :mod:`fdid_fmi.plan.words`) -> the rows where it stands, in order of
                              first use
    """

    blocks: list
    start: np.ndarray
    ignored: list = field(default_factory=list)
    source: str = "<string>"
    lines: list = field(default_factory=list)
    encoding: str = "utf-8"
    notes: list = field(default_factory=list)
    newline: str = "\n"
    words: dict = field(default_factory=dict)

    @property
    def axes_used(self):
        moved = np.zeros(3, bool)
        for b in self.blocks:
            if b.kind != "dwell":
                moved |= np.abs(b.end - b.start) > 0
                if b.kind == "arc":
                    i, j, _ = _PLANES[b.plane]
                    moved[[i, j]] = True
        return [a for a, m in zip("xyz", moved) if m]


def read_program(path, start=(0.0, 0.0, 0.0)):
    """Read a part program file (see module docstring); the file is only read.

    Decoded as the trace readers decode (:func:`fdid_fmi.io.common.read_text_file`): UTF-16/32
    with a byte-order mark, else UTF-8, else Latin-1 (a controller's ``(Tiefe Ø 10)`` comment
    in Windows-1252 / Latin-1); a file with NUL bytes is refused. ``Program.encoding`` says
    which (byte order and byte-order mark included), so that :func:`write_program`'s output keeps
    the comments' bytes and a controller reads it as it read the program.
    """
    path = Path(path)
    text, codec = decode_text_file(path)
    prog = parse_program(text, source=str(path), start=start)
    with open(path, "rb") as fh:
        head = fh.read(4)
    prog.encoding = _file_encoding(codec, head)
    return prog


def _file_encoding(codec, head):
    """Program.encoding of a file decoded by ``codec`` whose first bytes are ``head``."""
    if codec in ("utf-16", "utf-32"):            # decoded by its BOM: keep the byte order
        little = head.startswith(codecs.BOM_UTF32_LE if codec == "utf-32" else codecs.BOM_UTF16_LE)
        return f"{codec}-{'le' if little else 'be'}"
    if codec == "utf-8-sig":
        return "utf-8-sig" if head.startswith(codecs.BOM_UTF8) else "utf-8"
    return "latin-1"


def encode_text(text, encoding):
    """``text`` as bytes in a :attr:`Program.encoding`: UTF-16/32 with their byte-order mark
    (``utf-16-le`` writes none by itself), ``utf-8-sig`` with the UTF-8 one; characters the encoding
    lacks (a header in Latin-1) as backslash escapes."""
    data = text.encode(encoding, "backslashreplace")
    if encoding in ("utf-16-le", "utf-16-be", "utf-32-le", "utf-32-be"):
        data = "\ufeff".encode(encoding) + data
    return data


def _strip_comments(raw, source, row):
    """The code part of a line (comments removed) and whether it was a '%' line."""
    out, depth, k = [], 0, 0
    while k < len(raw):
        c = raw[k]
        if c == "(":
            if depth:
                raise InputError("nested '(' in a comment", source=source, row=row)
            depth = 1
        elif c == ")":
            if not depth:
                raise InputError("')' without '('", source=source, row=row)
            depth = 0
        elif c == ";" and not depth:
            break
        elif not depth:
            out.append(c)
        k += 1
    if depth:
        raise InputError("comment '(' is not closed on its line", source=source, row=row)
    return "".join(out)


def tokenize(code, source="<string>", row=None):
    """Words of a comment-free line as (letter, value, text) tuples; letter upper case.

    Raises InputError on anything that is not a letter followed by a number.
    """
    words, pos = [], 0
    code = code.rstrip()
    while pos < len(code):
        if code[pos].isspace():
            pos += 1
            continue
        m = _WORD.match(code, pos)
        if not m:
            bad = code[pos:].split()[0] if code[pos:].split() else code[pos:]
            if "#" in bad or "[" in bad:
                what = "parameter" if "#" in bad else "expression"
                raise InputError(f"{what} '{bad[:30]}' is not supported (parameters, variables and "
                                 f"expressions are not read): write the numbers", source=source, row=row)
            raise InputError(f"cannot read '{bad}' (expected a letter followed by a number, "
                             f"e.g. G1 X10.5 F600)", source=source, row=row)
        value = float(m.group(2))
        if not math.isfinite(value):                 # 400 digits read as inf
            raise InputError(f"the number in '{m.group(0).strip()[:20]}...' is too large", source=source, row=row)
        exp = _EXPONENT.match(code, m.end())
        if exp:                                      # X1e9: not X1 and a word 'e9'
            word = f"{m.group(1)}{m.group(2)}{exp.group(0)}"
            v = float(m.group(2) + exp.group(0))
            digits = f" ({m.group(1)}{np.format_float_positional(v, trim='-')})" if math.isfinite(v) else ""
            raise InputError(f"'{word}': exponent notation is not G-code: write the number in "
                             f"digits{digits}", source=source, row=row)
        words.append((m.group(1).upper(), value, m.group(0).strip()))
        pos = m.end()
    return words


def parse_program(text, source="<string>", start=(0.0, 0.0, 0.0)):
    """Parse a part program (see module docstring).

    Parameters
    ----------
    text : str
    source : str    name used in error messages
    start : (3,) mm  machine position before the first block

    Returns
    -------
    Program
    """
    pos = np.asarray(start, float).copy()
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"start must be three finite numbers (x, y, z) in mm, got {start!r}", column="start")
    st = {"motion": None, "plane": 17, "units": "mm", "distance": 90, "arc distance": 91.1,
          "feed mode": 94, "feed": None, "f_word": None, "wcs": 1, "offsets": {}, "moved": set(),
          "switches": set(), "exact": None, "ref": {28: None, 30: None}, "ref_note": {}}
    blocks, ignored, notes, seen = [], [], [], {}
    ended = None
    percent = []                             # rows of the '%' lines read: opening, closing
    lines = text_lines(text)
    eol = re.search(r"\r\n|\r|\n", text)
    for row, raw in enumerate(lines, 1):
        line = raw.strip()
        if len(percent) == 2:                # after the closing '%': not read (end of the tape)
            if line:
                ignored.append((row, f"not read: after the closing '%' of row {percent[1]}"))
            continue
        if not line:
            continue
        if line.startswith("%"):
            percent.append(row)
            _see(seen, "%", row)
            continue
        deleted = line.startswith("/")       # block delete: run, as with the switch off
        if deleted:
            line = line[1:]
            _see(seen, "/", row)
        code = _strip_comments(line, source, row)
        if "(" in line:
            _see(seen, "( )", row)
        if ";" in line:
            _see(seen, ";", row)
        _refuse_o_word(code, source, row)
        words = tokenize(code, source, row)
        if not words:
            continue
        if ended:
            ignored.append((row, f"not run: after {ended}"))
            continue
        if deleted:
            notes.append((row, "'/' (block delete) block run, as with the block-delete switch off"))
        ms = [(round(v, 1), txt) for letter, v, txt in words if letter == "M"]
        for b in _block(words, st, pos, source, row, raw, len(blocks), ignored, notes, seen):
            blocks.append(b)
            pos = b.end.copy()
        ends = [txt for m, txt in ms if m in (2, 30)]
        if ends:
            ended = ends[0]                  # program end: a CNC runs nothing after it
    return Program(blocks=blocks, start=np.asarray(start, float), ignored=ignored, source=source,
                   lines=lines, notes=notes, newline=eol.group(0) if eol else "\n", words=seen)


_O_WORD = re.compile(r"\s*[Oo]\s*(<[^>]*>|\d+)\s*([A-Za-z]+)")


def _refuse_o_word(code, source, row):
    """LinuxCNC O-words with a keyword (``o100 sub``, ``o<name> call``, ``o101 if [...]``):
    subroutines and control flow are not read; refused with the row and the word."""
    m = _O_WORD.match(code)
    if m and (m.group(1).startswith("<") or len(m.group(2)) > 1):
        word = f"{code.strip().split()[0]} {m.group(2)}" if " " in code.strip() else m.group(0).strip()
        raise _err(f"O-word '{word}' (subroutines and control flow) is not supported: expand it "
                   f"into the program's moves", source, row)


def _err(msg, source, row):
    return InputError(msg, source=source, row=row)


#: groups of G codes that set the motion (the rest: offsets, modes and cancels that do not move the
#: axes, listed in Program.ignored as they were read)
_MOTION_GROUPS = {"motion", "dwell", "plane", "units", "distance", "arc distance", "feed mode",
                  "non-modal", "exact stop"}
_WCS = {54: 1, 55: 2, 56: 3, 57: 4, 58: 5, 59: 6, 59.1: 7, 59.2: 8, 59.3: 9}
_WCS_NAME = {n: f"G{g}" for g, n in _WCS.items()}


def _see(seen, key, row):
    """Count a word read (:attr:`Program.words`): rows per canonical key, in order of first use."""
    seen.setdefault(key, []).append(row)


def _g_number(value):
    g = round(value, 1)
    return int(g) if g == int(g) else g


def _offset(st):
    """The active work offset (mm, our frame): set by G10 L2, else 0."""
    return st["offsets"].get(st["wcs"], np.zeros(3))


def _block(words, st, pos, source, row, raw, index, ignored, notes=None, seen=None):
    """The blocks of one line (none, one, or two for a G28 / G30 return): list of Block."""
    notes = [] if notes is None else notes
    seen = {} if seen is None else seen
    number = None
    gcodes, vals, texts, g64 = [], {}, {}, None
    for k, (letter, value, txt) in enumerate(words):
        if letter == "N":
            if k != 0:
                raise _err(f"line number '{txt}' must be the first word", source, row)
            if value != int(value) or value < 0:
                raise _err(f"line number '{txt}' must be a whole number 0 or more (e.g. N10)",
                           source, row)
            number = int(value)
            _see(seen, "N", row)
        elif letter == "O":
            ignored.append((row, txt))
            _see(seen, "O", row)
        elif letter in "GM":
            w = lookup(letter, value)
            if w is None:
                raise _err(f"G code '{txt}' is not supported (read: {' '.join(supported_g())}; "
                           f"docs/plan-words.md)", source, row)
            if w.action is Action.REFUSED:
                raise _err(f"{w.meaning} '{txt}' is not supported: {w.effect}", source, row)
            _see(seen, code_key(letter, value), row)
            if letter == "M":
                ignored.append((row, txt))
                continue
            if w.group not in _MOTION_GROUPS:
                ignored.append((row, txt))
            g = _g_number(value)
            if g == 64:
                g64 = txt
            gcodes.append((g, txt, w.group))
        elif letter in "STHD":
            ignored.append((row, txt))
            _see(seen, letter, row)
        elif letter in "XYZIJKRFPQLU":
            if letter in vals:
                raise _err(f"word '{letter}' appears twice", source, row)
            vals[letter], texts[letter] = value, txt
            if letter == "F":
                _see(seen, "F", row)
        else:
            kind = "axis" if letter in "ABCVW" else "word"
            raise _err(f"{kind} '{txt}' is not supported (linear axes X Y Z, arcs I J K R, feed F)",
                       source, row)
    groups = {}
    for g, txt, grp in gcodes:
        if grp in groups:
            raise _err(f"'{groups[grp][1]}' and '{txt}' are both {grp} codes", source, row)
        groups[grp] = (g, txt)
    if "motion" in groups and "dwell" in groups:
        raise _err("G4 and a motion code in one block", source, row)
    nonmodal = groups.get("non-modal")
    if nonmodal and "dwell" in groups:
        raise _err(f"G4 and '{nonmodal[1]}' in one block", source, row)
    if "U" in vals and "dwell" not in groups:
        raise _err(f"axis '{texts['U']}' is not supported (linear axes X Y Z, arcs I J K R, feed F)",
                   source, row)
    if "L" in vals and not (nonmodal and nonmodal[0] == 10):
        raise _err(f"word '{texts['L']}' is read with G10 only", source, row)
    if g64 is not None:        # G64 P<tol> Q<tol>: blending tolerances (the path is never blended)
        if "dwell" in groups and "P" in vals:
            raise _err(f"'{texts['P']}' with both G4 and {g64}: is it the dwell or the blending "
                       "tolerance? Put them in two blocks", source, row)
        for w in "PQ":
            if w in vals:
                ignored.append((row, f"{texts[w]} ({g64} tolerance)"))
                del vals[w]
    if "Q" in vals:
        raise _err(f"word '{texts['Q']}' is not supported (read with G64 only, as its tolerance)",
                   source, row)
    # modal state first (RS-274 order of execution: feed mode, feed, plane, units, distance, motion)
    for grp in ("feed mode", "plane", "distance", "arc distance"):
        if grp in groups:
            st[grp] = groups[grp][0]
    if "units" in groups:
        st["units"] = "inch" if groups["units"][0] == 20 else "mm"
    scale = INCH if st["units"] == "inch" else 1.0
    if "F" in vals:
        if not vals["F"] > 0:
            raise _err(f"feed F must be > 0, got {vals['F']:g}", source, row)
        st["f_word"] = vals["F"]
        if st["feed mode"] == 94:
            st["feed"] = vals["F"] * scale / 60.0      # mm/s
    if "work offset" in groups:
        _select_offset(st, _WCS[groups["work offset"][0]], groups["work offset"][1], row, notes)
    if "path mode" in groups:
        st["exact"] = groups["path mode"][0] in (61, 61.1)
    exact = "exact stop" in groups or bool(st["exact"])
    tool = groups.get("tool length")
    if tool and tool[0] in (43.1, 43.2):       # X Y Z are offsets there, not a move
        for w in "XYZ":
            if w in vals:
                ignored.append((row, f"{texts[w]} ({tool[1]} offset)"))
                del vals[w]
    if "dwell" in groups:
        given = [w for w in ("P", "X", "U") if w in vals]
        if len(given) != 1 or not vals[given[0]] >= 0:
            raise _err("G4 needs one dwell time >= 0: P<seconds> (or X / U <seconds>, Fanuc)",
                       source, row)
        extra = [w for w in vals if w not in (given[0], "F")]
        if extra:
            raise _err(f"G4 takes only P (or X / U), got {extra}", source, row)
        p = float(vals[given[0]])
        if given[0] == "P" and p >= 100 and p == int(p):
            notes.append((row, f"G4 {texts['P']} is read as {p:.0f} s (P in seconds, as LinuxCNC "
                               f"reads it); a Fanuc program's P is in ms (X or U for seconds there): "
                               f"for {p / 1000:g} s write P{p / 1000:g}"))
        return [Block(index, row, number, raw, "dwell", pos.copy(), pos.copy(), 0.0,
                      block_time=p, units=st["units"])]
    if "motion" in groups:
        st["motion"] = groups["motion"][0]
    if nonmodal and nonmodal[0] == 10:
        _g10(st, vals, texts, scale, source, row, ignored, notes)
        return []
    if nonmodal and nonmodal[0] in (28.1, 30.1):
        if any(w in vals for w in "XYZIJKRP"):
            raise _err(f"{nonmodal[1]} stores where the tool is: it takes no axis words", source, row)
        st["ref"][int(nonmodal[0])] = pos.copy()
        return []
    if "P" in vals:
        raise _err("P is only read with G4 (dwell), G10 and G64", source, row)
    if nonmodal and nonmodal[0] in (28, 30):
        return _reference_return(int(nonmodal[0]), nonmodal[1], st, vals, pos, scale, source, row,
                                 raw, number, index, notes)
    machine = bool(nonmodal and nonmodal[0] == 53)
    axis_words = [w for w in "XYZ" if w in vals]
    arc_words = [w for w in "IJKR" if w in vals]
    if not axis_words and not arc_words:
        if "motion" in groups and groups["motion"][0] in (2, 3):
            raise _err(f"{groups['motion'][1]} without end point or centre", source, row)
        return []                        # modal settings only
    if st["motion"] is None:
        given = " ".join(texts[w] for w in axis_words + arc_words)
        raise _err(f"'{given}' without a motion mode (G0, G1, G2 or G3) in force: end points "
                   f"(X Y Z) and arc centres and radii (I J K R) are read only with one", source, row)
    motion = st["motion"]
    if machine and (st["distance"] == 91 or motion not in (0, 1)):
        raise _err(f"{nonmodal[1]} (machine coordinates) needs G90 and G0 or G1", source, row)
    off = np.zeros(3) if machine else _offset(st)
    end = pos.copy()
    for a, w in enumerate("XYZ"):
        if w in vals:
            v = vals[w] * scale
            end[a] = end[a] + v if st["distance"] == 91 else v + off[a]
    st["moved"].add(st["wcs"])
    units = st["units"]
    inverse = st["feed mode"] == 93 and motion != 0
    if motion == 0:
        if arc_words:
            raise _err(f"G0 takes no {'/'.join(arc_words)}", source, row)
        return [Block(index, row, number, raw, "rapid", pos.copy(), end, math.inf, units=units,
                      f_word=st["f_word"], exact_stop=exact)]
    if inverse:
        if "F" not in vals:
            raise _err("inverse-time (G93) block without F: every G1/G2/G3 needs its own F "
                       "(1/minutes)", source, row)
        block_time = 60.0 / vals["F"]
    elif st["feed"] is None:
        raise _err(f"no feed rate: G{motion} needs an F word (none programmed yet)", source, row)
    if motion == 1:
        if arc_words:
            raise _err(f"G1 takes no {'/'.join(arc_words)}", source, row)
        b = Block(index, row, number, raw, "line", pos.copy(), end, 0.0, units=units, f_word=st["f_word"])
    else:
        b = _arc(index, row, number, raw, pos.copy(), end, motion == 2, st, vals, scale, source, off)
    b.exact_stop = exact
    if inverse:
        b.inverse_time, b.block_time = True, block_time
        b.feed = b.length / block_time if b.length > 0 else math.inf
    else:
        b.feed = st["feed"]
    return [b]


def _select_offset(st, n, txt, row, notes):
    """G54..G59.3: the work offset n in force; a switch after moves, to or from an offset the
    program does not set, is noted (both read as 0: the moves are planned as written)."""
    old = st["wcs"]
    st["wcs"] = n
    if n == old or old not in st["moved"]:
        return
    unknown = [_WCS_NAME[k] for k in (old, n) if k not in st["offsets"]]
    if unknown and (old, n) not in st["switches"]:
        st["switches"].add((old, n))
        notes.append((row, f"{txt} after {_WCS_NAME[old]}: the offset of {' and '.join(unknown)} is not "
                           f"set in the program (G10 L2): read as 0, the moves are planned as written"))


def _g10(st, vals, texts, scale, source, row, ignored, notes):
    """G10 L2 P<n> X Y Z: set work offset n (the axes not given keep theirs); L1 / L10 / L11 (tool
    table) are noted; L20, P0 and R are refused (their meaning differs between dialects or they
    rotate the path)."""
    if "L" not in vals:
        raise _err("G10 needs L (G10 L2 P1..P9 X Y Z sets a work offset)", source, row)
    L = vals["L"]
    if L in (1, 10, 11):
        ignored.append((row, f"G10 {texts['L']} (tool table)"))
        return
    if L == 20:
        raise _err("'G10 L20' is not supported: LinuxCNC reads it relative to the current position, "
                   "Fanuc as an extended work offset; write the offset as G10 L2 P1..P9 X Y Z", source, row)
    if L != 2:
        raise _err(f"'G10 {texts['L']}' is not supported (G10 L2 sets a work offset)", source, row)
    if "R" in vals:
        raise _err(f"'{texts['R']}' with G10 L2 rotates the coordinate system: not supported", source, row)
    p = vals.get("P")
    if p == 0:
        raise _err("'G10 L2 P0': the active system (LinuxCNC) or the external offset (Fanuc)? "
                   "Write P1..P9 (P1 = G54)", source, row)
    if p is None or p != int(p) or not 1 <= p <= 9:
        raise _err("G10 L2 needs P1..P9 (the work offset: P1 = G54 .. P6 = G59, P7..P9 = G59.1..G59.3)",
                   source, row)
    bad = [w for w in "IJK" if w in vals]
    if bad:
        raise _err(f"G10 L2 takes X Y Z, not {'/'.join(bad)}", source, row)
    n = int(p)
    off = st["offsets"].get(n, np.zeros(3)).copy()
    for a, w in enumerate("XYZ"):
        if w in vals:
            off[a] = vals[w] * scale
    st["offsets"][n] = off
    notes.append((row, f"G10 L2 P{n}: work offset {_WCS_NAME[n]} = ({', '.join(f'{v:g}' for v in off)}) mm, "
                       f"applied to the moves in {_WCS_NAME[n]}"))


def _reference_return(which, txt, st, vals, pos, scale, source, row, raw, number, index, notes):
    """G28 / G30: a rapid to the intermediate point (the axis words, LinuxCNC and Fanuc alike),
    then to the reference position for the axes named (all when none is) when the program gave it
    (G28.1 / G30.1); otherwise that move is noted and not planned."""
    bad = [w for w in "IJKRF" if w in vals]
    if bad:
        raise _err(f"{txt} takes X Y Z (the intermediate point), not {'/'.join(bad)}", source, row)
    named = [a for a, w in enumerate("XYZ") if w in vals]
    off = _offset(st)
    blocks, p = [], pos.copy()
    mid = pos.copy()
    for a in named:
        v = vals["XYZ"[a]] * scale
        mid[a] = pos[a] + v if st["distance"] == 91 else v + off[a]
    if np.any(mid != pos):
        blocks.append(Block(index, row, number, raw, "rapid", p, mid, math.inf, units=st["units"],
                            f_word=st["f_word"], exact_stop=True))
        p = mid
    ref = st["ref"][which]
    if ref is None:         # noted once per code, with every row where it stands
        k, rows = st["ref_note"].setdefault(which, (len(notes), []))
        rows.append(row)
        also = f" (also row{'s' if len(rows) > 2 else ''} {', '.join(map(str, rows[1:]))})" if len(rows) > 1 else ""
        text = (f"G{which}{also}: the reference position is not given in the program (G{which}.1 stores it): "
                f"the move to it is not planned; the next block starts from the intermediate point (the axis "
                f"words), or where the tool is")
        if len(rows) == 1:
            notes.append((row, text))
        else:
            notes[k] = (rows[0], text)
        return blocks
    end = p.copy()
    for a in (named or [0, 1, 2]):
        end[a] = ref[a]
    if np.any(end != p):
        blocks.append(Block(index + len(blocks), row, number, raw, "rapid", p.copy(), end, math.inf,
                            units=st["units"], f_word=st["f_word"], exact_stop=True))
    return blocks


def _arc(index, row, number, raw, start, end, cw, st, vals, scale, source, off=None):
    plane = st["plane"]
    i, j, k = _PLANES[plane]
    name = f"G{2 if cw else 3}"
    has_r = "R" in vals
    offs = [w for w in "IJK" if w in vals]
    allowed = {_OFFSET_LETTER[i], _OFFSET_LETTER[j]}
    if has_r and offs:
        raise _err(f"{name} with both R and {'/'.join(offs)}: give one", source, row)
    if not has_r and not offs:
        raise _err(f"{name} needs a centre (I J K) or a radius (R)", source, row)
    bad = [w for w in offs if w not in allowed]
    if bad:
        raise _err(f"{name} in {_PLANE_NAMES[plane]} takes centre words {'/'.join(sorted(allowed))}, "
                   f"not {'/'.join(bad)}", source, row)
    p0 = np.array([start[i], start[j]])
    p1 = np.array([end[i], end[j]])
    if has_r:
        R = vals["R"] * scale
        d = float(np.linalg.norm(p1 - p0))
        if d == 0:
            raise _err(f"{name} with R needs an end point different from the start", source, row)
        short = d / 2 - abs(R)
        if short > radius_tolerance(d / 2):
            raise _err(f"arc radius |R| = {abs(R):.6g} mm is smaller than half the chord "
                       f"({d / 2:.6g} mm) by {short:.3g} mm, more than the end-point tolerance "
                       f"{radius_tolerance(d / 2):.3g} mm", source, row)
        h = math.sqrt(max(R * R - d * d / 4, 0.0))   # 0 within the tolerance: a half circle
        mid = (p0 + p1) / 2
        perp = np.array([-(p1 - p0)[1], (p1 - p0)[0]]) / d        # left of the chord
        # the centre of the shorter arc lies right of the chord for a clockwise arc
        side = -1.0 if cw else 1.0
        if R < 0:
            side = -side
        c = mid + side * h * perp
    else:
        off_ij = np.array([vals.get(_OFFSET_LETTER[i], 0.0), vals.get(_OFFSET_LETTER[j], 0.0)]) * scale
        shift = np.zeros(2) if off is None else np.array([off[i], off[j]])
        c = off_ij + shift if st["arc distance"] == 90.1 else p0 + off_ij
    r0 = float(np.linalg.norm(p0 - c))
    r1 = float(np.linalg.norm(p1 - c))
    if r0 == 0:
        raise _err(f"{name}: the start point is the centre (radius 0)", source, row)
    tol = radius_tolerance(max(r0, r1))
    if abs(r1 - r0) > tol:
        raise _err(f"{name}: the end point is not on the arc: radius {r0:.6g} mm at the start, "
                   f"{r1:.6g} mm at the end (difference {abs(r1 - r0):.3g} mm > {tol:.3g} mm)",
                   source, row)
    a0 = math.atan2(p0[1] - c[1], p0[0] - c[0])
    a1 = math.atan2(p1[1] - c[1], p1[0] - c[0])
    sweep = (a0 - a1) if cw else (a1 - a0)
    sweep %= 2 * math.pi
    if sweep < 1e-12 and not has_r:
        sweep = 2 * math.pi                  # full circle
    centre = start.copy()
    centre[i], centre[j] = c
    return Block(index, row, number, raw, "arc", start, end, 0.0, units=st["units"],
                 f_word=st["f_word"], center=centre, plane=plane, cw=cw, sweep=float(sweep),
                 r0=r0, r1=r1)


def write_program(program, feeds_mm_s, path=None, header=None):
    """The program with new feeds: every feed block gets an explicit F (program units).

    Parameters
    ----------
    program : Program
    feeds_mm_s : dict block index -> new path feed, mm/s (blocks left out keep theirs: after a
        rewritten F, a G94 block left out that relied on the modal F gets its own F written)
    path : optional file to write (atomically: complete or not at all; never the program's own
        source file)
    header : str, optional   a comment line put first

    Returns
    -------
    str, the new program text. G93 blocks get F scaled by the feed ratio (inverse time is
    proportional to the feed); G94 blocks get F in units/min.
    """
    by_line, kept = {}, {}
    for b in program.blocks:
        if b.kind in ("line", "arc"):
            if b.index in feeds_mm_s:
                by_line[b.line] = b
            elif not b.inverse_time:
                kept[b.line] = b
    modal_changed = False        # a rewritten F is modal: later blocks left out get their own F
    out = []
    lines = list(program.lines)
    head = f"({_safe_comment(header)})" if header else None
    if head and not (lines and lines[0].strip().startswith("%")):
        out.append(head)
        head = None
    for row, raw in enumerate(lines, 1):
        b = by_line.get(row)
        if b is None and modal_changed and row in kept and not _has_f(raw):
            k = kept[row]
            out.append(_replace_f(raw, k.feed * 60.0 / (INCH if k.units == "inch" else 1.0)))
            continue
        if b is None:
            out.append(raw)
            if head and row == 1:            # after the leading '%'
                out.append(head)
            continue
        new = float(feeds_mm_s[b.index])
        if not (math.isfinite(new) and math.isfinite(b.feed)):     # a zero-length G93 block:
            out.append(raw)                                         # no feed to scale, as written
            continue
        if b.inverse_time:
            fword = 60.0 / b.block_time * new / b.feed
        else:
            fword = new * 60.0 / (INCH if b.units == "inch" else 1.0)
            modal_changed = True
        out.append(_replace_f(raw, fword))
    text = program.newline.join(out) + program.newline
    if path is not None:
        from ..outputs import atomic_write, check_output
        src = Path(program.source)
        check_output(path, inputs=[src] if src.is_file() else [], what="NC program")
        atomic_write(path, encode_text(text, program.encoding))
    return text


def _has_f(raw):
    """Whether a (readable) program line carries an F word outside its comments."""
    line = raw.strip()
    if line.startswith("/"):
        line = line[1:]
    return any(w[0] == "F" for w in tokenize(_strip_comments(line, "<line>", None)))


def _safe_comment(s):
    """A header text as one comment the reader reads back: no parentheses, no line breaks (CR,
    LF and every other non-printable character escaped, as errors.one_line does)."""
    from ..errors import one_line
    return one_line(str(s).replace("\n", " ")).replace("(", "[").replace(")", "]")


def _replace_f(raw, fword):
    """Replace (or add) the F word of a line: F goes after the last word, before any trailing
    comment; comments are left as written. F is written positionally (6 significant digits):
    a controller does not read 5.4e+06."""
    code, tail = _split_trailing_comment(raw)
    pieces, k, depth = [], 0, 0
    while k < len(code):
        c = code[k]
        if c == "(":
            depth = 1
        if depth == 0 and c in "Ff":
            w = _WORD.match(code, k)
            if w:
                k = w.end()
                continue
        if c == ")":
            depth = 0
        pieces.append(c)
        k += 1
    f = np.format_float_positional(fword, precision=6, unique=False, fractional=False, trim="-")
    return f"{''.join(pieces).rstrip()} F{f}{tail}"


def _split_trailing_comment(raw):
    """(code, trailing comments) of a line: a ';' comment starts only outside parentheses (as
    :func:`_strip_comments` reads it), and parenthesised comments after the last word go with it."""
    depth, cut = 0, len(raw)
    for k, c in enumerate(raw):
        if c == "(":
            depth = 1
        elif c == ")":
            depth = 0
        elif c == ";" and not depth:
            cut = k
            break
    head = raw[:cut]
    m = _TRAILING_PARENS.search(head)
    return head[:m.start()], head[m.start():] + raw[cut:]


_TRAILING_PARENS = re.compile(r"(\s*\([^()]*\))*\s*$")
