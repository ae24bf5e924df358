"""fdid_fmi's public API (fdid_fmi.api): each function on the bundled example traces, its typed
result, its doctests, the package's public names, and the rule that only the command line
imports from fdid_fmi.cli."""
import ast
import doctest
import importlib
import json
from pathlib import Path

import numpy as np
import pytest

import fdid_fmi as fd
from fdid_fmi.api import ExportResult, PlanResult

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "fdid_fmi"
MOVES = ROOT / "examples" / "virtual_xy_moves.csv"
CIRCLE = ROOT / "examples" / "virtual_circle.csv"
TWIN = ROOT / "tests" / "data" / "xy_twin_model.json"


# ----------------------------------------------------------------------------- the package
def test_public_names():
    assert set(fd.__all__) == {
        "read_trace", "identify", "DriveModel", "QuasiStaticModel", "load_model", "simulate", "export_fmu",
        "ExportResult", "validate", "diagnose", "plan", "PlanResult", "Trace", "Channel", "FdidError",
        "InputError", "__version__"}
    for name in fd.__all__:
        assert hasattr(fd, name), name
        assert not isinstance(getattr(fd, name), type(fd)), f"{name} is a module"


def test_api_names_survive_the_subpackages_of_the_same_name():
    # importing the subpackages (as the library does internally) leaves the API functions in place
    for name in ("identify", "diagnose", "plan", "simulate"):
        importlib.import_module(f"fdid_fmi.{name}")
        assert callable(getattr(fd, name)) and getattr(fd, name) is getattr(fd.api, name), name
    from fdid_fmi.identify import identify_siso
    from fdid_fmi.plan import interpolate
    assert callable(identify_siso) and interpolate.__name__ == "fdid_fmi.plan.interpolate"


def test_nothing_outside_the_command_line_imports_from_it():
    """Same as ``grep -rn "from \\.\\.cli\\|fdid_fmi\\.cli" src/fdid_fmi | grep -v ^src/fdid_fmi/cli``."""
    found = []
    for f in PACKAGE.rglob("*.py"):
        if "cli" in f.relative_to(PACKAGE).parts[:1]:
            continue
        text = f.read_text()
        found += [f"{f.relative_to(PACKAGE)}: {line.strip()}" for line in text.splitlines()
                  if "from ..cli" in line or "fdid_fmi.cli" in line]
        for node in ast.walk(ast.parse(text)):     # and no import that the text search misses
            if isinstance(node, ast.ImportFrom):
                mod = node.module or ""
                depth = len(f.relative_to(PACKAGE).parts) - 1
                if node.level and node.level == depth + 1 and mod.split(".")[0] == "cli":
                    found.append(f"{f.relative_to(PACKAGE)}: from {'.' * node.level}{mod}")
                if not node.level and mod.startswith("fdid_fmi.cli"):
                    found.append(f"{f.relative_to(PACKAGE)}: from {mod}")
    assert not found, found


def test_doctests(monkeypatch):
    monkeypatch.chdir(ROOT)          # the examples name examples/... relative to the checkout
    res = doctest.testmod(fd.api, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted >= 8, res


# ----------------------------------------------------------------------------- traces
def test_read_trace():
    tr = fd.read_trace(MOVES)
    assert isinstance(tr, fd.Trace) and tr.axes == ["x", "y"] and tr.Ts == pytest.approx(6e-4)
    same = fd.read_trace(MOVES, mapping={"t": "t_s", "x.cmd": "x_cmd_mm", "x.act": "x_mm"})
    assert same.axes == ["x"] and np.array_equal(same.cmd("x"), tr.cmd("x"))
    cut = fd.read_trace(MOVES, ranges=[(0.5, 1.5), (2, 3)])
    assert cut.meta["ranges"] == fd.read_trace(MOVES, ranges="0.5:1.5,2:3").meta["ranges"]
    assert [p.t[0] for p in cut.select(cut.meta["ranges"])] == pytest.approx([0.5, 2.0], abs=1e-3)


@pytest.mark.parametrize("kw, words", [
    ({"ranges": "0:99"}, "outside the data"),
    ({"mapping": {"x.cmd": "nope"}}, "nope"),
    ({"units": {"x_mm": "furlong"}}, "furlong"),
])
def test_read_trace_refuses_bad_input_in_one_line(kw, words):
    with pytest.raises(fd.InputError) as exc:
        fd.read_trace(MOVES, **kw)
    assert words in str(exc.value) and "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- identify, save, load
def test_identify_quasi_static_and_its_round_trip(tmp_path):
    qs = fd.identify(fd.read_trace(MOVES), method="quasi-static")
    assert isinstance(qs, fd.QuasiStaticModel) and set(qs.gains) == {"x", "y"}
    qs.save(tmp_path / "qs.json")
    back = fd.QuasiStaticModel.load(tmp_path / "qs.json")
    assert back.gains == qs.gains and isinstance(fd.load_model(tmp_path / "qs.json"), fd.QuasiStaticModel)
    with pytest.raises(fd.InputError, match="quasi-static"):
        fd.DriveModel.load(tmp_path / "qs.json")


def test_identify_full_ls_is_a_drive_model(tmp_path):
    m = fd.identify(MOVES, method="full-ls", axes=["x"])       # a path is read as read_trace reads it
    assert isinstance(m, fd.DriveModel) and m.axes == ["x"] and m.records == []
    m.save(tmp_path / "m.json")
    back = fd.DriveModel.load(tmp_path / "m.json")
    assert np.array_equal(back.A, m.A) and back.method == "full-ls"


def test_identify_pole_search_carries_its_typed_record():
    from fdid_fmi.identify.record import PoleSearchRecord
    tr = fd.read_trace(MOVES, ranges="0:1.5")
    m = fd.identify(tr, axes=["x"], structure="rigid", maxiter=2, same_sample="hold")
    (rec,) = m.records
    assert isinstance(rec, PoleSearchRecord)
    assert len(rec.real_hz) == 1 and len(rec.complex_hz_zeta) == 1 and rec.v_tilde_mm_s["x"] > 0
    assert rec.structure.same_sample == "hold"
    # the stored two-axis twin: one record per axis
    assert [type(r) for r in fd.DriveModel.load(TWIN).records] == [PoleSearchRecord] * 2


def test_identify_is_what_the_command_writes(tmp_path, capsys):
    from fdid_fmi.cli import main
    assert main(["identify", str(MOVES), "--method", "full-ls", "--cutoff-hz", "40",
                 "-o", str(tmp_path / "cli.json")]) == 0
    m = fd.identify(fd.read_trace(MOVES), method="full-ls", cutoff_hz=40)
    cli = json.loads((tmp_path / "cli.json").read_text())
    api = m.to_dict()
    for key in ("A", "B", "C", "D", "Ts", "method", "identification"):
        assert json.dumps(cli[key]) == json.dumps(json.loads(json.dumps(api[key]))), key


@pytest.mark.parametrize("kw, words", [
    ({"method": "quasi-static", "seed": 1}, "--seed is read by --method pole-search / mimo only"),
    ({"bogus": 1}, "unknown identification option 'bogus'"),
    ({"seed": -1}, "the seed must be in 0 .. 4294967295"),
    ({"method": "nope"}, "invalid choice: 'nope'"),
    ({"seed": [1, 2]}, "option 'seed' takes one value"),
    ({"v_tilde": 0.5, "v_tilde_range": "0.1:1"}, "give one of them"),
])
def test_identify_refuses_bad_options_in_one_line(kw, words):
    with pytest.raises(fd.InputError) as exc:
        fd.identify(fd.read_trace(MOVES), **kw)
    assert words in str(exc.value) and "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- FMU, validation, simulation
def test_export_validate_simulate(tmp_path):
    model = fd.DriveModel.load(TWIN)
    res = fd.export_fmu(model, tmp_path / "twin.fmu")
    assert isinstance(res, ExportResult)
    assert (res.path, res.fmi_version, res.backend, res.platforms, res.model_identifier) == (
        tmp_path / "twin.fmu", 2, "c", ("linux64",), "twin")
    assert res.size_bytes == res.path.stat().st_size > 0
    circle = fd.read_trace(CIRCLE)
    v = fd.validate(res, circle)
    assert type(v).__name__ == "ValidationResult" and v.ok and not v.problems, v.problems
    assert v.max_abs_diff_reference_mm <= 1e-9 and set(v.axes) == {"x", "y"}
    assert all(np.isfinite(v.axes[a]["rms_um"]) and v.axes[a]["max_um"] >= v.axes[a]["rms_um"] for a in "xy")
    sim = fd.simulate(model, circle)
    # the FMU's discrepancy to the measurement is the reference simulator's
    e = circle.error("x") - sim.axes["x"]["error"]
    assert v.axes["x"]["rms_um"] == pytest.approx(1e3 * np.sqrt(np.mean(e ** 2)), rel=1e-6)


def test_export_refuses_a_quasi_static_model(tmp_path):
    qs = fd.identify(fd.read_trace(MOVES), method="quasi-static")
    with pytest.raises(fd.InputError):
        fd.export_fmu(qs, tmp_path / "qs.fmu")
    with pytest.raises(fd.InputError, match="FMI version"):
        fd.export_fmu(fd.DriveModel.load(TWIN), tmp_path / "m.fmu", fmi=4)
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------- diagnosis, planning
def test_diagnose_returns_the_typed_diagnosis():
    from fdid_fmi.diagnose import Diagnosis
    tr = fd.read_trace(MOVES)
    model = fd.identify(tr.slice(0, 1.5), axes=["x"], structure="rigid", maxiter=2, same_sample="hold")
    d = fd.diagnose(model, tr.slice(0, 1.5), tr.slice(1.5, 3), detectors=["mode"], maxiter=1, max_steps=1,
                    jobs=1)
    assert isinstance(d, Diagnosis) and isinstance(d.final, fd.DriveModel)
    assert set(d.before) == set(d.after) and d.to_json()["effects_added"] == d.effects_added
    with pytest.raises(fd.InputError, match="quasi-static"):
        fd.diagnose(fd.identify(tr, method="quasi-static"), tr)


def test_plan_returns_the_typed_plan():
    model = fd.DriveModel.load(TWIN)
    p = fd.plan(model, ROOT / "examples" / "pocket_corner.nc", tol_mm=0.02)
    assert isinstance(p, PlanResult) and p.axes == ["x", "y"] and p.Ts == model.Ts
    assert len(p.prediction.blocks) == len(p.program.blocks) and p.summary["cycle_time_s"] > 0
    assert set(p.limits) >= {"x", "y"} and p.limit_sources["x"].startswith("recorded in the model")
    assert p.feed_plan is None
    fast = fd.plan(model, ROOT / "examples" / "pocket_corner.nc", tol_mm=0.02,
                   limits={"x": (100, 2000, 1e5), "y": (100, 2000, 1e5)})
    assert fast.limits["x"].v == 100 and fast.limit_sources["x"] == "--limits"
    with pytest.raises(fd.InputError, match="optimize needs tol_mm"):
        fd.plan(model, ROOT / "examples" / "pocket_corner.nc", optimize=True)
    with pytest.raises(fd.InputError, match="one of them"):
        fd.plan(None, ROOT / "examples" / "pocket_corner.nc")
