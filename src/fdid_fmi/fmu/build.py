"""Compile the FMU's C sources into platform binaries (gcc; mingw-w64 for win64).

Flags: ``-O2 -std=c99 -Wall -Wextra -Werror -fPIC -shared -fvisibility=hidden``; only the
fmi2/fmi3 functions are exported (``FMI2_Export``/``FMI3_Export`` in the standard headers).
``-lm`` is added only when the model needs sin/cos/exp (feature inputs); models without
them give a binary with no libm dependency. The win64 DLL is linked with ``-static-libgcc``
so it needs nothing beyond the Windows C runtime (msvcrt). Binaries are stripped (``-s``);
the exported fmi* symbols stay in the dynamic symbol table.
"""
from __future__ import annotations

import errno
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..errors import FdidError, InputError


class BuildError(FdidError):
    """The C compiler failed (the message carries its output)."""


class CompilerNotFound(InputError):
    """The C compiler of a platform is not installed on this machine: a fault of the environment,
    not of the model or the options (the fleet retries an entry that met it on a worker)."""


class NoRoomError(InputError):
    """Writing the FMU or its build files failed for want of room: a full file system, an
    exhausted disk quota, or the process's file-size limit (``ulimit -f``)."""


# errno of a write that failed for want of room, and how a compiler's tools say it
ROOM_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
_ROOM_TEXTS = (("No space left on device", errno.ENOSPC), ("Disk quota exceeded", errno.EDQUOT),
               ("File size limit exceeded", errno.EFBIG), ("File too large", errno.EFBIG))


def _file_size_limit():
    """This process's file-size limit as ``ulimit -f`` shows it, in words."""
    try:
        import resource
        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    except (ImportError, OSError, ValueError):
        return "ulimit -f"
    return "ulimit -f" if soft == resource.RLIM_INFINITY else f"ulimit -f: {soft} bytes"


def no_room(code, folder, what):
    """NoRoomError for a write of ``what`` (``"the FMU's build files"``) into ``folder`` that
    failed with errno ``code`` (one of ``ROOM_ERRNOS``), saying what to do about it."""
    if code == errno.EFBIG:
        return NoRoomError(f"cannot write {what}: a file would exceed this process's file-size limit "
                           f"({_file_size_limit()}); raise the limit", source=str(folder))
    full = "its disk quota is exhausted" if code == errno.EDQUOT else "no space is left on its device"
    if Path(folder) == Path(tempfile.gettempdir()):
        where, hint = "the temporary folder", "free space there or set TMPDIR to a folder with room"
    else:
        where, hint = "this folder", "free space there or write the FMU to another folder"
    return NoRoomError(f"cannot write {what} in {where}: {full}; {hint}", source=str(folder))


def room_errno(text):
    """The errno (ENOSPC, EDQUOT, EFBIG) a compiler's output reports a failed write with, or None."""
    for words, code in _ROOM_TEXTS:
        if words in text:
            return code
    return None


@dataclass(frozen=True)
class Platform:
    name: str          # fdid name: linux64 / win64
    fmi2_dir: str      # binaries/<dir> for FMI 2.0
    fmi3_dir: str      # binaries/<dir> for FMI 3.0
    compiler: str
    suffix: str
    extra: tuple


PLATFORMS = {
    "linux64": Platform("linux64", "linux64", "x86_64-linux", os.environ.get("CC", "gcc"), ".so",
                        ("-fPIC", "-fvisibility=hidden", "-s")),
    "win64": Platform("win64", "win64", "x86_64-windows", "x86_64-w64-mingw32-gcc", ".dll",
                      ("-static-libgcc", "-s")),
}

CFLAGS = ("-O2", "-std=c99", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror")


def compiler_available(platform):
    """True when the compiler of ``platform`` (``linux64``/``win64``) is on PATH."""
    return shutil.which(_platform(platform).compiler) is not None


def _platform(name):
    if name not in PLATFORMS:
        raise InputError(f"unknown platform '{name}'; expected one of {sorted(PLATFORMS)}",
                         column="platforms")
    return PLATFORMS[name]


def compile_binary(src_dir, sources, out_file, platform, uses_libm):
    """Compile ``sources`` (in ``src_dir``) into the shared library ``out_file``.

    Raises
    ------
    CompilerNotFound  (an InputError) when the compiler of the platform is not installed
    NoRoomError  (an InputError) when the compiler could not write its output or temporary files:
                 a full device or quota (the temporary folder, or that of ``out_file``), or the
                 file-size limit
    BuildError   when compilation fails otherwise (with the compiler's messages)
    """
    p = _platform(platform)
    cc = shutil.which(p.compiler)
    if cc is None:
        hint = (" (Debian/Ubuntu: apt-get install gcc-mingw-w64-x86-64)" if platform == "win64"
                else " (install gcc)")
        raise CompilerNotFound(f"the {platform} compiler '{p.compiler}' is not installed{hint}",
                               column="platforms")
    out_file = Path(out_file)
    out_file.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, *CFLAGS, *p.extra, "-shared", "-I", str(src_dir),
           *[str(Path(src_dir) / s) for s in sources], "-o", str(out_file)]
    if uses_libm:
        cmd.append("-lm")
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        code = room_errno(res.stdout + res.stderr)
        if code is not None:      # it writes its temporaries in TMPDIR, the library beside out_file
            tmp = Path(tempfile.gettempdir())
            folder = tmp if code == errno.EFBIG or out_file.is_relative_to(tmp) else out_file.parent
            raise no_room(code, folder, f"the compiled FMU binary ({p.compiler})")
        raise BuildError(f"{p.compiler} failed ({' '.join(cmd)}):\n{res.stdout}{res.stderr}")
    return out_file
