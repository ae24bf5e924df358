"""Small helpers shared by the readers: reading a user's file safely, hashing it."""
from __future__ import annotations

import hashlib
from pathlib import Path

from ..errors import InputError


def check_file(path) -> Path:
    """Return ``Path(path)`` after checking it is an existing, non-empty regular file."""
    p = Path(path)
    if not p.exists():
        raise InputError("file not found", source=str(p))
    if not p.is_file():
        raise InputError("is not a regular file (a directory?)", source=str(p))
    if p.stat().st_size == 0:
        raise InputError("file is empty (0 bytes)", source=str(p))
    return p


def read_text_file(path) -> str:
    """Text of a user's file: UTF-8 (with or without BOM), else Latin-1. Read only."""
    raw = check_file(path).read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def file_sha256(path) -> str:
    """sha256 (hex) of a file's bytes, for provenance."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
