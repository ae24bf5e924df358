"""Errors raised for bad user input: each names the file, column/parameter and row."""
import contextlib
import math
from pathlib import Path


def one_line(text):
    """``text`` with every line break and other non-printable character escaped (``\\n``): an error
    message is one line, whatever the user's file names, columns or tokens contain."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


class FdidError(Exception):
    """Base class of the errors fdid-fmi raises on purpose."""


class InputError(FdidError, ValueError):
    """Bad input data or parameter, with the place it was found.

    Parameters
    ----------
    message : str
        What was wrong and what was expected.
    source : str, optional
        File (or object) the input came from.
    column : str, optional
        Column / channel / parameter name.
    row : int, optional
        1-based data row (as a spreadsheet would show it), when known.

    ``message`` is kept as an attribute (one line), without the place: a caller that re-raises
    the error naming another place takes it from there, not by cutting the text.
    """

    def __init__(self, message, source=None, column=None, row=None):
        self.source, self.column, self.row = source, column, row
        self.message = one_line(message)
        where = []
        if source:
            where.append(f"{source}")
        if column is not None:
            where.append(f"column '{column}'")
        if row is not None:
            where.append(f"row {row}")
        super().__init__(one_line(f"{': '.join([', '.join(where), message]) if where else message}"))


def finite_number(value, name, positive=False):
    """``value`` as a float when it is a finite number (> 0 when ``positive``), else InputError
    naming the parameter ``name`` (a string, None or NaN would otherwise reach numpy)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and (v > 0 or not positive)):
        raise InputError(f"{name} must be a finite number{' > 0' if positive else ''}, got {value!r}",
                         column=name)
    return v


@contextlib.contextmanager
def naming(source, replaces=None):
    """Inside this block, an InputError that names no file (or names ``replaces``: the path a
    reader resolved from what the user wrote) is re-raised naming ``source`` (e.g. a model
    refused by export names the model file it came from)."""
    try:
        yield
    except InputError as exc:
        named = exc.source and not (replaces is not None and Path(str(exc.source)) == Path(replaces))
        if named or source is None:
            raise
        raise InputError(exc.message, source=str(source), column=exc.column, row=exc.row) from None
