"""Parse data ranges such as ``"0.5:3.2,4:6"`` (seconds) for ``Trace.select``.

The thesis GUI lets the user pick up to four data ranges of a record for training;
here any number of non-overlapping ranges is allowed, in seconds of trace time.
"""
from __future__ import annotations

import math
import re

from ..errors import InputError


def parse_ranges(text, source="--range"):
    """Parse ``"START:STOP,START:STOP,..."`` into a list of (start_s, stop_s).

    Parameters
    ----------
    text : str or sequence of str
        Ranges in seconds separated by commas (or given as a list); either end may be
        left empty to mean the start/end of the data (``":3.2"``, ``"4:"``).
    source : str
        Name used in error messages (the CLI option).

    Returns
    -------
    list of tuple (float or None, float or None)
        In the order given; ``[]`` for an empty string.

    Raises
    ------
    InputError
        A piece without ``:``, a bound that is not a finite number, start >= stop,
        or two ranges that overlap.
    """
    if text is None:
        return []
    if isinstance(text, str):
        pieces = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    else:
        pieces = [p for item in text for p in re.split(r"[,\s]+", str(item).strip()) if p]
    out = []
    for piece in pieces:
        if piece.count(":") != 1:
            raise InputError(f"range '{piece}' must be START:STOP in seconds, e.g. 0.5:3.2",
                             source=source, column="range")
        a_txt, b_txt = piece.split(":")
        a = _bound(a_txt, piece, source)
        b = _bound(b_txt, piece, source)
        if a is not None and b is not None and not a < b:
            raise InputError(f"range '{piece}': start {a:g} s must be before stop {b:g} s",
                             source=source, column="range")
        out.append((a, b))
    lo = lambda r: -math.inf if r[0] is None else r[0]  # noqa: E731
    hi = lambda r: math.inf if r[1] is None else r[1]  # noqa: E731
    srt = sorted(out, key=lo)
    for r1, r2 in zip(srt, srt[1:]):
        if lo(r2) < hi(r1):
            raise InputError(f"ranges {_fmt(r1)} and {_fmt(r2)} overlap; give disjoint ranges",
                             source=source, column="range")
    return out


def _bound(txt, piece, source):
    txt = txt.strip()
    if txt == "":
        return None
    try:
        v = float(txt)
    except ValueError:
        raise InputError(f"range '{piece}': '{txt}' is not a number of seconds",
                         source=source, column="range") from None
    if not math.isfinite(v):
        raise InputError(f"range '{piece}': bound must be finite", source=source, column="range")
    return v


def _fmt(r):
    a = "" if r[0] is None else f"{r[0]:g}"
    b = "" if r[1] is None else f"{r[1]:g}"
    return f"{a}:{b}"
