"""Small helpers shared by the readers: reading a user's file safely, hashing it."""
from __future__ import annotations

import codecs
import hashlib
import re
import stat
from pathlib import Path

from ..errors import InputError


def check_file(path, what="file") -> Path:
    """Return ``Path(path)`` after checking it is an existing, non-empty regular file (the one
    check of every file the user gives: a trace, a model, an FMU). ``what`` names it in the
    messages (``"model file"``)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found", source=str(p))
    if not p.is_file():
        raise InputError(f"is {_file_kind(p.stat().st_mode)}, not a regular file", source=str(p))
    if p.stat().st_size == 0:
        raise InputError(f"{what} is empty (0 bytes)", source=str(p))
    return p


def _file_kind(mode):
    """What a file that is not a regular file is, from its ``st_mode`` (a FIFO or a device would be
    read without end or block, a directory cannot be read at all)."""
    for test, kind in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "a special file"


def text_lines(text):
    """Lines of a text file, split at CR LF, CR or LF only: ``str.splitlines`` also splits at
    U+0085, U+2028, form feeds, ..., which a Latin-1 comment may hold ('…' in Windows-1252
    reads as U+0085), and would shift the row numbers the errors report."""
    lines = re.split(r"\r\n|\r|\n", text)
    return lines[:-1] if lines and lines[-1] == "" else lines


_BOMS = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"),
         (codecs.BOM_UTF16_LE, "utf-16"), (codecs.BOM_UTF16_BE, "utf-16"))


def read_text_file(path) -> str:
    """Text of a user's file (:func:`decode_text_file`'s text). Read only."""
    return decode_text_file(path)[0]


def decode_text_file(path):
    """``(text, codec)`` of a user's file. Read only.

    UTF-32 / UTF-16 with a byte-order mark, else UTF-8 (with or without BOM), else Latin-1
    (old controller exports). A file with NUL bytes and no BOM (UTF-16 without BOM, or a
    binary file) is refused with one line rather than read as garbage. ``codec``: the one that
    decoded it (``utf-8-sig`` or ``latin-1`` without a BOM)."""
    p = check_file(path)
    raw = p.read_bytes()
    for bom, enc in _BOMS:
        if raw.startswith(bom):
            try:
                return raw.decode(enc), enc
            except UnicodeDecodeError as exc:
                raise InputError(f"starts with a {enc.upper()} byte-order mark but is not valid "
                                 f"{enc.upper()} text (byte {exc.start})", source=str(p)) from None
    if b"\x00" in raw:
        k = raw.index(b"\x00")
        zeros = max(raw[0::2].count(0), raw[1::2].count(0))
        hint = (" it looks like UTF-16 text without a byte-order mark; save it as UTF-8"
                if zeros > 0.3 * len(raw) / 2 else " is it a binary file?")
        raise InputError(f"is not a text file: NUL byte at offset {k};{hint}", source=str(p))
    try:
        return raw.decode("utf-8-sig"), "utf-8-sig"
    except UnicodeDecodeError:     # a UTF-8 BOM on Latin-1 text is still a BOM, not "ï»¿"
        return raw.removeprefix(codecs.BOM_UTF8).decode("latin-1"), "latin-1"


def file_sha256(path) -> str:
    """sha256 (hex) of a file's bytes, for provenance."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
