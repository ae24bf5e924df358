"""An FMU is a zip archive that says itself where its members go and how large they are.
``fdid validate`` (and whatever else unpacks a user's FMU: the FMU runner, the planner) refuses,
with one line naming the member, a member path that would leave the folder it is unpacked into
("zip slip") and a member that inflates beyond a stated cap ("zip bomb"), before fmpy reads or
unpacks anything."""
import os
import struct
import time
import zipfile

import numpy as np
import pytest

import fmu_support as fs
from cli_support import one_line, run_cli as run
from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu, validate_fmu
from fdid_fmi.fmu.archive import MAX_MEMBER_BYTES, check_fmu_archive, read_member
from fdid_fmi.fmu.validate import FmuRunner
from fdid_fmi.plan.optimize import optimize_feeds
from fdid_fmi.plan.predict import fmu_axes, model_from_fmu
from fdid_fmi.trace import Trace


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    return export_fmu(fs.siso_model(), tmp_path_factory.mktemp("archive") / "good.fmu")


def _copy(good, dst, extra=(), replace=None, stream=None):
    """``good`` rewritten to ``dst`` with ``extra`` (name, bytes) members added, the members named in
    ``replace`` given other bytes, and ``stream`` = (name, block, count): a member written in blocks."""
    replace = replace or {}
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zf:
        for info in src.infolist():
            if stream and info.filename == stream[0]:
                continue
            zf.writestr(info.filename, replace.get(info.filename, src.read(info)))
        for name, data in extra:
            zf.writestr(zipfile.ZipInfo(name), data)
        if stream:
            name, block, count = stream
            with zf.open(name, "w", force_zip64=True) as fh:
                for _ in range(count):
                    fh.write(block)
    return dst


def _trace(n=300):
    t = np.arange(n) * 1e-3
    cmd = fs.smooth_moves(n, np.random.default_rng(1))
    return Trace.from_arrays(t, {"x": {"cmd": cmd, "act": cmd}}, source="run.csv")


SLIPS = ["../evil.txt", "resources/../../evil.txt", "/tmp/evil.txt", "C:evil.txt", "resources\\..\\evil.txt"]


@pytest.mark.parametrize("name", SLIPS)
def test_a_member_path_leaving_the_folder_is_refused(tmp_path, good, name):
    bad = _copy(good, tmp_path / "slip.fmu", extra=[(name, b"x")])
    assert name in zipfile.ZipFile(bad).namelist()         # the archive really holds that path
    with pytest.raises(InputError) as ei:
        check_fmu_archive(bad)
    msg = str(ei.value)
    assert msg.startswith(f"{bad}: member '{name}'") and "refused" in msg and "\n" not in msg
    with pytest.raises(InputError, match="must stay inside the folder"):
        validate_fmu(bad, _trace())
    with pytest.raises(InputError, match="must stay inside the folder"):
        FmuRunner(bad)
    assert not (tmp_path / "evil.txt").exists() and not (tmp_path.parent / "evil.txt").exists()


def test_a_member_over_the_cap_is_refused_without_inflating_it(tmp_path, good):
    """One member 1 MiB over the cap (64 MiB of spaces in a small archive): refused from the
    archive's directory; before, validate inflated it in full and blamed its JSON."""
    big = _copy(good, tmp_path / "bomb.fmu", stream=("resources/model.json", b" " * 2 ** 20,
                                                     MAX_MEMBER_BYTES // 2 ** 20 + 1))
    assert os.path.getsize(big) < 2 ** 20
    t0 = time.process_time()
    for call in (lambda: check_fmu_archive(big), lambda: validate_fmu(big, _trace()),
                 lambda: model_from_fmu(big), lambda: fmu_axes(big), lambda: FmuRunner(big)):
        with pytest.raises(InputError) as ei:
            call()
        msg = str(ei.value)          # from the archive's directory, or (model_from_fmu) the read
        assert msg.startswith(f"{big}: member 'resources/model.json' inflates to ") and "64 MiB" in msg
    assert time.process_time() - t0 < 1.0
    with pytest.raises(InputError, match="inflates to more than 0.0009537 MiB"):
        read_member(big, "resources/model.json", limit=1000)     # the read itself stops at its limit


def test_the_planner_checks_before_unpacking(tmp_path, good):
    bad = _copy(good, tmp_path / "slip.fmu", extra=[("../evil.txt", b"x")])
    with pytest.raises(InputError, match="'../evil.txt' has a '..' component"):
        optimize_feeds(None, None, 1e-3, 0.01, fmu=bad)


def test_a_member_whose_declared_size_is_false_is_refused_in_one_line(tmp_path, good):
    """The archive's directory says 10 bytes, the data inflates to 1 MiB: the read stops at the
    declared size (zipfile checks the CRC then) and the damage is one line."""
    p = _copy(good, tmp_path / "lie.fmu", replace={"resources/model.json": b"{" * 2 ** 20})
    raw = bytearray(p.read_bytes())
    with zipfile.ZipFile(p) as zf:
        info = zf.getinfo("resources/model.json")
    # uncompressed size: local header at offset 22, its central directory entry (the one whose
    # local header offset, at 42, is this member's) at offset 24
    struct.pack_into("<I", raw, info.header_offset + 22, 10)
    cd = [k for k in range(len(raw) - 46) if raw[k:k + 4] == b"PK\x01\x02"
          and struct.unpack_from("<I", raw, k + 42)[0] == info.header_offset]
    assert len(cd) == 1
    struct.pack_into("<I", raw, cd[0] + 24, 10)
    p.write_bytes(bytes(raw))
    with pytest.raises(InputError, match="member 'resources/model.json' cannot be inflated"):
        read_member(p, "resources/model.json")


@pytest.mark.parametrize("case", ["slip", "bomb"])
def test_fdid_validate_says_it_in_one_line(capsys, tmp_path, good, case):
    csv = tmp_path / "run.csv"
    csv.write_text("t_s,x_cmd_mm,x_mm\n" + "".join(f"{k * 1e-3:.3f},{k * 1e-3},{k * 1e-3}\n" for k in range(300)))
    if case == "slip":
        bad = _copy(good, tmp_path / "bad.fmu", extra=[("/etc/evil.conf", b"x")])
        words = ("bad.fmu", "member '/etc/evil.conf' is an absolute path")
    else:
        bad = _copy(good, tmp_path / "bad.fmu", stream=("modelDescription.xml", b" " * 2 ** 20, 65))
        words = ("bad.fmu", "member 'modelDescription.xml' inflates to 65 MiB")
    code, _, err = run(capsys, "validate", bad, csv)
    one_line(code, err, *words)


def test_the_report_lists_no_variables_of_an_unsafe_fmu(tmp_path, good):
    from fdid_fmi.report import Report, _fmu_variables
    bad = _copy(good, tmp_path / "slip.fmu", extra=[("../evil.txt", b"x")])
    rep = Report("FMU")
    _fmu_variables(rep, bad)
    assert "fmu_variables" not in rep.tables
    assert any("could not be read" in str(p) and "'../evil.txt' has a '..' component" in str(p)
               for _, p in rep._blocks)


def test_the_members_together_are_capped_too(good):
    check_fmu_archive(good)                              # an exported FMU is far below both caps
    with pytest.raises(InputError, match=r"the members inflate to 0\.\d+ MiB together, more than the "
                                         r"0\.0009537 MiB an FMU may have; refused"):
        check_fmu_archive(good, max_total=1000)
