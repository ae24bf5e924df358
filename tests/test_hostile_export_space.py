"""An export that fails for want of room -- the temporary folder or the output folder full, or a
file over the process's file-size limit -- says so in one line, naming the folder and what to do,
instead of blaming a template source file it was copying or printing a compiler's raw command
line; no FMU and no temporary file is left behind.

The file-size limit (RLIMIT_FSIZE, set in a child process) works for any user; a full folder
needs a small tmpfs, mounted only where the tests may (root with CAP_SYS_ADMIN), skipped
otherwise.
"""
import os
import resource
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

import fmu_support as fs
from cli_support import one_line, run_cli as run
from fdid_fmi.fleet.work import from_inputs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import NoRoomError, compiler_available

pytestmark = pytest.mark.skipif(not compiler_available("linux64"), reason="gcc is not installed")
FDID = [sys.executable, "-m", "fdid_fmi.cli"]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A model file and the sizes of an FMU exported from it (sources, binary)."""
    d = tmp_path_factory.mktemp("space")
    model = d / "m.json"
    fs.siso_model().save(model)
    fmu = export_fmu(model, d / "ok.fmu")
    with zipfile.ZipFile(fmu) as zf:
        sizes = {i.filename: i.file_size for i in zf.infolist()}
    return model, sizes


def _export_limited(model, out, limit):
    """``fdid export`` in a child whose files may not grow beyond ``limit`` bytes."""
    def cap():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run(FDID + ["export", str(model), "-o", str(out)], capture_output=True, text=True,
                          preexec_fn=cap, timeout=300)


def _left(folder):
    return sorted(p.name for p in Path(folder).iterdir())


def test_file_size_limit_while_copying_the_sources(tmp_path, built):
    model, _ = built
    out = tmp_path / "d.fmu"
    r = _export_limited(model, out, 1024)     # smaller than any template source
    line = one_line(r.returncode, r.stderr, "cannot write the FMU's build files",
                    "file-size limit (ulimit -f: 1024 bytes)", "raise the limit")
    assert "fmu_templates" not in line       # not the template being copied
    assert not out.exists() and _left(tmp_path) == []


def test_file_size_limit_while_compiling(tmp_path, built):
    model, sizes = built
    largest_source = max(n for k, n in sizes.items() if not k.startswith("binaries/"))
    binary = max(n for k, n in sizes.items() if k.startswith("binaries/"))
    if binary <= largest_source + 1024:
        pytest.skip("the binary is no larger than the sources: no limit stops the compiler alone")
    out = tmp_path / "d.fmu"
    r = _export_limited(model, out, largest_source + 1024)
    line = one_line(r.returncode, r.stderr, "cannot write the compiled FMU binary (gcc)",
                    f"file-size limit (ulimit -f: {largest_source + 1024} bytes)")
    assert "-O2" not in line and "internal compiler error" not in line    # not gcc's raw lines
    assert not out.exists() and _left(tmp_path) == []


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 64 kB tmpfs (a full disk in miniature), or skip where this process may not mount one."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True,
                       text=True) if os.geteuid() == 0 else None
    if r is None or r.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root with CAP_SYS_ADMIN)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


def test_full_temporary_folder(capsys, monkeypatch, tmp_path, built, small_tmpfs):
    model, _ = built
    monkeypatch.setenv("TMPDIR", str(small_tmpfs))             # gcc's temporaries too
    monkeypatch.setattr(tempfile, "tempdir", str(small_tmpfs))
    out = tmp_path / "d.fmu"
    code, _, err = run(capsys, "export", model, "-o", out)
    line = one_line(code, err, f"{small_tmpfs}: cannot write the", "in the temporary folder",
                    "no space is left on its device", "set TMPDIR to a folder with room")
    assert "fmu_templates" not in line and "-O2" not in line
    assert not out.exists() and _left(small_tmpfs) == []


def test_full_output_folder(capsys, built, small_tmpfs):
    model, sizes = built
    assert sum(sizes.values()) > 64 * 1024 // 2           # the FMU does not fit
    out = small_tmpfs / "d.fmu"
    (small_tmpfs / "filler").write_bytes(b"\0" * (40 * 1024))
    code, _, err = run(capsys, "export", model, "-o", out)
    one_line(code, err, f"{small_tmpfs}: cannot write the FMU d.fmu in this folder",
             "no space is left on its device", "write the FMU to another folder")
    assert _left(small_tmpfs) == ["filler"]               # no partial FMU, no temporary file


def test_a_full_disk_is_not_the_inputs_fault():
    """The fleet reruns an entry that failed for want of room instead of keeping the failure."""
    exc = NoRoomError("cannot write the FMU's build files in the temporary folder: no space is left",
                      source=tempfile.gettempdir())
    assert not from_inputs(exc, Path(tempfile.gettempdir()) / "entry")
