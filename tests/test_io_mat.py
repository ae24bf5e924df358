"""MATLAB reader: the real EMPS files (facts from ../shared/data/README.md) and a generic .mat."""
import hashlib

import numpy as np
import pytest
from scipy.io import savemat

from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.io.matlab import read_mat


@pytest.fixture(scope="module")
def emps(shared_data):
    return read_trace(shared_data / "emps" / "DATA_EMPS.mat")


def test_emps_facts(emps, shared_data):
    assert emps.n == 24841
    assert emps.Ts == pytest.approx(1e-3, rel=1e-4)
    assert emps.t[0] == 0.0 and emps.t[-1] == pytest.approx(24.84)
    assert emps.roles == {"x": {"cmd": "qg", "act": "qm"}}
    assert emps.channels["qg"].unit == "mm" and emps.channels["vir"].unit == "V"
    e = emps.error("x")                                   # qg - qm, converted m -> mm
    assert np.sqrt(np.mean(e ** 2)) == pytest.approx(0.58, abs=0.01)
    assert np.max(np.abs(e)) == pytest.approx(0.9, abs=0.1)
    assert np.max(np.abs(emps.cmd("x"))) < 1000          # mm: the axis travels < 1 m
    assert np.max(np.abs(emps.extra("vir"))) <= 10.0 + 1e-9   # saturates at +-10 V
    assert emps.meta["kp"] == pytest.approx(160.18)
    assert emps.meta["kv"] == pytest.approx(243.45)
    assert emps.meta["gtau"] == pytest.approx(35.15, abs=0.01)
    raw = (shared_data / "emps" / "DATA_EMPS.mat").read_bytes()
    assert emps.meta["sha256"] == hashlib.sha256(raw).hexdigest()
    assert emps.meta["sha256"].startswith("6cf6814a")
    assert "pulses_N" not in emps.channels


def test_emps_train_qm_on_50nm_grid(emps):
    q = emps.act("x") / 50e-6                             # mm / 50 nm
    assert np.max(np.abs(q - np.round(q))) < 1e-3


def test_emps_pulses(shared_data):
    tr = read_trace(shared_data / "emps" / "DATA_EMPS_PULSES.mat")
    assert tr.meta["sha256"].startswith("0eab75bb")
    assert sorted(tr.extra_channels) == ["pulses_N", "vir"]
    p = tr.extra("pulses_N")
    assert tr.channels["pulses_N"].unit == "N"
    assert set(np.unique(p)) == {0.0, 5.0}
    # a 1 Hz square wave: about 2 edges per second over 24.84 s
    edges = np.count_nonzero(np.diff(p))
    assert 45 <= edges <= 52
    assert np.sqrt(np.mean(tr.error("x") ** 2)) == pytest.approx(0.58, abs=0.02)


def test_emps_axis_name(shared_data):
    tr = read_mat(shared_data / "emps" / "DATA_EMPS.mat", axis="a1")
    assert tr.axes == ["a1"]


def test_generic_mat_by_names_and_mapping(tmp_path):
    t = np.arange(5) * 0.01
    p = tmp_path / "run.mat"
    savemat(p, {"t_s": t, "y_cmd_um": 1000 * t, "y_um": 900 * t, "gain": 3.0,
                "note": "hello", "M": np.ones((5, 2))})
    tr = read_trace(p)
    np.testing.assert_allclose(tr.cmd("y"), t)
    np.testing.assert_allclose(tr.act("y"), 0.9 * t)
    assert tr.meta["scalars"] == {"gain": 3.0}
    assert set(tr.meta["skipped_variables"]) == {"note", "M"}
    tr2 = read_trace(p, mapping={"t": "t_s", "z.act": "y_cmd_um"})
    assert tr2.roles == {"z": {"act": "y_cmd_um"}}


def test_mat_errors(tmp_path):
    p = tmp_path / "bad.mat"
    savemat(p, {"t": np.array([0.0, 0.1, 0.2, 0.3]), "x_mm": np.array([1.0, np.nan, 2, 3])})
    with pytest.raises(InputError) as ei:
        read_trace(p)
    assert (ei.value.column, ei.value.row) == ("x_mm", 2)
    savemat(p, {"t": np.array([0.0, 0.1, 0.2]), "x_mm": np.array([1.0, 2.0])})
    with pytest.raises(InputError, match="has 2 samples but column 't' has 3"):
        read_trace(p)
    savemat(p, {"t": np.array([0.0, 0.1, 0.2]), "x_mm": np.array([1.0, 2.0, 3.0])})
    with pytest.raises(InputError, match="names a column that is not in the file"):
        read_trace(p, mapping={"x.cmd": "qg"})
    junk = tmp_path / "junk.mat"
    junk.write_bytes(b"this is not a mat file at all" * 10)
    with pytest.raises(InputError, match="not a readable MATLAB"):
        read_trace(junk)


def test_emps_units_hold_with_an_explicit_map(shared_data):
    """Mapping EMPS's roles by hand (--map t=t x.cmd=qg x.act=qm) keeps the file's metres: the
    same trace as the recognised layout, not positions 1000x too small."""
    path = shared_data / "emps" / "DATA_EMPS.mat"
    auto = read_trace(path)
    mapped = read_trace(path, mapping={"t": "t", "x.cmd": "qg", "x.act": "qm"})
    np.testing.assert_array_equal(mapped.cmd("x"), auto.cmd("x"))
    np.testing.assert_array_equal(mapped.act("x"), auto.act("x"))
