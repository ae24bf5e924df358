"""Trace readers: CSV/TXT, thesis GUI layouts, MATLAB .mat (EMPS), SINUMERIK servo-trace XML.

``read_trace(path, mapping=None, units=None, **kw)`` picks the reader from the file type:

=====================  ======================================  ==========================
extension              reader                                   keywords
=====================  ======================================  ==========================
.csv .txt .dat .tsv    ``fdid_fmi.io.text.read_text``           layout, axes, delimiter
.mat                   ``fdid_fmi.io.matlab.read_mat``          axis
.xml (any case)        ``fdid_fmi.io.sinumerik.read_sinumerik_trace``  (none)
=====================  ======================================  ==========================

Every reader returns a ``Trace`` in canonical units (s, mm, mm/s, ...), with the file's
sha256 in ``trace.meta["sha256"]``, and raises ``InputError`` naming file, column and row
for bad input. No reader writes to the user's file.
"""
from __future__ import annotations


from ..errors import InputError
from ..trace import Trace
from .common import check_file
from .matlab import read_mat
from .ranges import parse_ranges
from .sinumerik import read_sinumerik_spectra, read_sinumerik_trace, speed_loop_frf
from .text import read_text

TEXT_EXT = (".csv", ".txt", ".dat", ".tsv")

__all__ = ["read_trace", "read_text", "read_mat", "read_sinumerik_trace", "read_sinumerik_spectra",
           "speed_loop_frf", "parse_ranges"]


def read_trace(path, mapping=None, units=None, **kw) -> Trace:
    """Read a measured trace, choosing the reader from the file extension.

    Parameters
    ----------
    path : str or Path
    mapping : dict, optional
        ``{"t": col, "<axis>.<role>": col}`` (roles cmd, act, tool, vel, acc, cur, err).
    units : dict, optional
        ``{col: unit}``, e.g. ``{"x_pos": "um"}``.
    **kw
        Passed to the reader (see the table in the module docstring).

    Returns
    -------
    Trace
    """
    p = check_file(path)
    ext = p.suffix.lower()
    if ext in TEXT_EXT:
        return read_text(p, mapping=mapping, units=units, **kw)
    if ext == ".mat":
        _only(kw, ("axis", "jitter_tol"), p, "MATLAB .mat")
        return read_mat(p, mapping=mapping, units=units, **kw)
    if ext == ".xml":
        if mapping or units:
            raise InputError("a SINUMERIK XML trace has fixed channels; --map/--unit do not apply",
                             source=str(p))
        _only(kw, (), p, "SINUMERIK XML")
        return read_sinumerik_trace(p)
    raise InputError(f"unknown file type '{p.suffix or '(none)'}'; expected one of "
                     f"{', '.join(TEXT_EXT)} (text), .mat (MATLAB) or .xml (SINUMERIK trace)",
                     source=str(p))


def _only(kw, allowed, p, what):
    extra = sorted(k for k, v in kw.items() if k not in allowed and v not in (None, "auto"))
    if extra:
        raise InputError(f"option(s) {extra} do not apply to a {what} file", source=str(p))
    for k in [k for k in kw if k not in allowed]:
        kw.pop(k)
