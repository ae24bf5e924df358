"""Opening a user's FMU archive safely, before anything reads or unpacks it.

An FMU is a zip archive, and a zip archive says itself where its members go and how large they
are. :func:`check_fmu_archive` reads only the archive's directory and refuses, with one line
naming the member,

- a member path that leaves the folder it is unpacked into: absolute (``/etc/x``, ``C:x``,
  ``\\\\server\\x``), with a ``..`` component, or with backslashes (zip paths use ``/``; an
  unpacker on Windows takes ``\\`` as a separator). Python's ``zipfile`` would silently rename
  such members, other unpackers write them where they point ("zip slip");
- a member that inflates to more than ``MAX_MEMBER_BYTES`` (64 MiB; an fdid FMU's largest member,
  its shared library, is about 100 kB), all members together more than ``MAX_TOTAL_BYTES``
  (256 MiB), or more than ``MAX_MEMBERS`` members: a small archive can hold a huge member
  ("zip bomb"; a 1 MB FMU with a 1 GiB ``resources/model.json`` was inflated in full).

:func:`read_member` reads one member in blocks and stops at its limit, whatever size the archive
declares; :func:`extract_fmu` checks, then unpacks with ``fmpy.extract``. fmpy's
``simulate_fmu`` and ``read_model_description`` unpack or inflate on their own: call
:func:`check_fmu_archive` before them.
"""
from __future__ import annotations

import lzma
import re
import zipfile
import zlib
from pathlib import Path

from ..errors import InputError

MAX_MEMBER_BYTES = 64 * 2 ** 20     # inflated size of one member
MAX_TOTAL_BYTES = 256 * 2 ** 20     # inflated size of all members
MAX_MEMBERS = 10_000

_DRIVE = re.compile(r"^[A-Za-z]:")


def _mib(n):
    return f"{n / 2 ** 20:.4g} MiB"


def unsafe_member_path(name):
    """Why the member path ``name`` would leave the folder it is unpacked into, or ``None``."""
    if "\\" in name:
        return "holds a backslash (zip member paths use '/')"
    if name.startswith("/") or _DRIVE.match(name):
        return "is an absolute path"
    if ".." in name.split("/"):
        return "has a '..' component"
    if "\x00" in name:
        return "holds a NUL character"
    return None


def open_fmu_zip(path):
    """``zipfile.ZipFile`` of the FMU at ``path``, or InputError when it is not a zip archive."""
    try:
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise InputError("is not an FMU (not a zip archive)", source=str(path)) from None
    except OSError as exc:
        raise InputError(f"cannot be read ({exc.strerror or exc})", source=str(path)) from None


def check_fmu_archive(path, max_member=MAX_MEMBER_BYTES, max_total=MAX_TOTAL_BYTES):
    """Refuse an FMU archive whose member paths or inflated sizes are unsafe (module docstring).

    Only the archive's directory is read (nothing is inflated). A directory (an unpacked FMU) is
    left alone.

    Parameters
    ----------
    path : str or Path          the FMU file
    max_member, max_total : int bytes, the inflated size allowed per member and for all members

    Raises
    ------
    InputError naming the file and the member
    """
    if Path(path).is_dir():
        return
    with open_fmu_zip(path) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise InputError(f"the archive has {len(infos)} members, more than the {MAX_MEMBERS} an FMU "
                             "may have", source=str(path))
        total = 0
        for info in infos:
            why = unsafe_member_path(info.filename)
            if why:
                raise InputError(f"member '{info.filename}' {why}: an FMU member must stay inside the "
                                 "folder it is unpacked into; refused", source=str(path))
            if info.file_size > max_member:
                raise InputError(f"member '{info.filename}' inflates to {_mib(info.file_size)}, more than "
                                 f"the {_mib(max_member)} an FMU member may have; refused",
                                 source=str(path))
            total += info.file_size
        if total > max_total:
            raise InputError(f"the members inflate to {_mib(total)} together, more than the "
                             f"{_mib(max_total)} an FMU may have; refused", source=str(path))


def read_member(path, name, limit=MAX_MEMBER_BYTES):
    """Bytes of the member ``name`` of the FMU at ``path``, read in blocks and never more than
    ``limit`` bytes, whatever size the archive declares.

    Raises
    ------
    KeyError when there is no such member; InputError when it is larger than ``limit`` or
    damaged (a wrong CRC or size).
    """
    with open_fmu_zip(path) as zf:
        info = zf.getinfo(name)           # KeyError: the caller says what is missing
        out = bytearray()
        try:
            with zf.open(info) as fh:
                while block := fh.read(min(1 << 20, limit + 1 - len(out))):
                    out += block
                    if len(out) > limit:
                        raise InputError(f"member '{name}' inflates to more than {_mib(limit)}, the "
                                         "most it may have; refused", source=str(path))
        except (zipfile.BadZipFile, EOFError, OSError, NotImplementedError, RuntimeError, zlib.error,
                lzma.LZMAError) as exc:      # RuntimeError: an encrypted member
            raise InputError(f"member '{name}' cannot be inflated ({exc})", source=str(path)) from None
        return bytes(out)


def extract_fmu(path, folder):
    """Check the FMU at ``path`` (:func:`check_fmu_archive`), then unpack it into ``folder``
    with ``fmpy.extract``; returns ``folder``."""
    from fmpy import extract
    check_fmu_archive(path)
    extract(str(path), str(folder))
    return folder
