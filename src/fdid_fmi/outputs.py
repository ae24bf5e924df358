"""Writing output files safely: checked before the work, written atomically, never onto an input.

Every writer of fdid-fmi (model JSON, prediction CSV, JSON summaries, reports, FMUs) goes
through this module, so that

* an output path is checked **before** the work starts (:func:`check_output`): its folder
  exists and is a folder, the path is not a directory, and it is not one of the command's
  input files (``-o`` equal to the input would otherwise overwrite the user's trace or model);
* the file appears complete or not at all (:func:`atomic_write`, :func:`atomic_path`): the
  bytes go to a temporary file in the same folder (same file system), which is moved onto the
  target with ``os.replace`` only when everything was written; on any failure (disk full,
  interrupted, an exception in the writer) the temporary file is removed and an existing
  target is left as it was.

File-system failures become :class:`~fdid_fmi.errors.InputError` naming the file, so that the
command line prints one line (e.g. ``out/m.json: cannot write (No space left on device)``).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from .errors import InputError

__all__ = ["check_output", "atomic_write", "atomic_path", "same_file"]


def same_file(a, b) -> bool:
    """True when paths ``a`` and ``b`` name the same file (after resolving links; also when
    either does not exist yet but both resolve to the same absolute path)."""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(os.fspath(a)) == os.path.realpath(os.fspath(b))


def check_output(path, inputs=(), what="output file", suffix=None) -> Path:
    """Check that ``path`` can be written as an output, before any work is done.

    Parameters
    ----------
    path : str or Path
        The file to be written.
    inputs : iterable of str or Path
        The command's input files; the output must differ from all of them.
    what : str
        What the file is, for messages (``"model file"``, ``"FMU"``...).
    suffix : str, optional
        Required file extension (e.g. ``".fmu"``), case-insensitive.

    Returns
    -------
    Path

    Raises
    ------
    InputError
        Empty name, path is a directory, its folder is missing / not a folder / not
        writable, a wrong suffix, or the path is one of ``inputs``.
    """
    if path is None or str(path) == "":
        raise InputError(f"the {what} name is empty")
    p = Path(path)
    src = str(p)
    if suffix and p.name.lower() == suffix.lower():     # 'x/.fmu' has no suffix: a hidden file
        raise InputError(f"the {what} name '{p.name}' has nothing before {suffix}; give a name such "
                         f"as drive{suffix}", source=src)
    if suffix and p.suffix.lower() != suffix.lower():
        raise InputError(f"the {what} must end in {suffix}", source=src)
    for i in inputs:
        if i is not None and same_file(p, i):
            raise InputError(f"the {what} would overwrite the input file {i}; choose another name",
                             source=src)
    try:
        _check_place(p, src, what)
    except OSError as exc:          # e.g. a name longer than the file system allows
        raise InputError(f"cannot write the {what} ({exc.strerror or exc})", source=src) from None
    return p


def _check_place(p, src, what):
    if p.is_dir():
        raise InputError(f"the {what} names a directory; give a file name", source=src)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise InputError(f"cannot write the {what}: folder '{parent}' does not exist", source=src)
    if not parent.is_dir():
        raise InputError(f"cannot write the {what}: '{parent}' is not a folder", source=src)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"cannot write the {what}: folder '{parent}' is not writable", source=src)
    if p.exists() and not p.is_file():
        raise InputError(f"the {what} exists and is not a regular file", source=src)


def _umask_mode():
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_path(path):
    """Context manager giving a temporary path in the folder of ``path``; on success the
    temporary file replaces ``path`` (``os.replace``), on any exception it is removed.

    Examples
    --------
    >>> with atomic_path("drive.fmu") as tmp:          # doctest: +SKIP
    ...     write_zip(tmp)
    """
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    try:
        # the name cut short: '.<name>.<random>.part' must fit in NAME_MAX (255) as the name does
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name[:100]}.", suffix=".part", dir=parent)
    except OSError as exc:
        raise InputError(f"cannot write ({exc.strerror or exc})", source=str(p)) from None
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        try:        # an existing file keeps its permissions (a private 0600 file stays private)
            mode = os.stat(p).st_mode & 0o777
        except OSError:
            mode = _umask_mode()
        os.chmod(tmp, mode)
        os.replace(tmp, p)
    except OSError as exc:
        _unlink(tmp)
        raise InputError(f"cannot write ({exc.strerror or exc})", source=str(p)) from None
    except BaseException:
        _unlink(tmp)
        raise


def remove_orphan_temp_files(folder) -> list[Path]:
    """Remove the temporary files :func:`atomic_path` leaves in ``folder`` when its writer was killed
    (SIGKILL, power loss): ``.<name>.<random>.part``. Call only when no writer can still be running
    there. Returns the removed paths."""
    removed = []
    for tmp in Path(folder).glob(".*.part"):
        if tmp.is_file():
            _unlink(tmp)
            removed.append(tmp)
    return removed


def atomic_write(path, data) -> Path:
    """Write ``data`` (str: UTF-8, or bytes) to ``path`` atomically (see module docstring).

    Returns
    -------
    Path of the written file.
    """
    # a file name that is not UTF-8 reaches Python as lone surrogates ('\udcff'): written
    # escaped, as the command line prints it, instead of failing after the work
    raw = data.encode("utf-8", "backslashreplace") if isinstance(data, str) else bytes(data)
    p = Path(path)
    with atomic_path(p) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(raw)
            fh.flush()
            os.fsync(fh.fileno())
    return p


def _unlink(p):
    try:
        os.unlink(p)
    except OSError:
        pass
