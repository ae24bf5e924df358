"""The fleet and alignment layers: hostile manifests, the rerun cache, the sensor readers and the
align CLI. Each test fails without the code it guards."""
import ast
import json
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.fleet.manifest import load_manifest, parse_manifest_text

ENTRY = '[[entry]]\nmachine = "m01"\naxis = "x"\ntraces = ["a.csv"]\n'


def _one(text, fmt="toml"):
    m = parse_manifest_text(text, fmt, base="/tmp/fleet", source=f"plant.{fmt}")
    return m.entries


# ----------------------------------------------------------------------------- fleet manifests
@pytest.mark.parametrize("thresholds", ["3", '"ab"', "[1, 2]"])
def test_thresholds_not_a_table_is_one_input_error(thresholds):
    # not TypeError 'int' object is not iterable / ValueError from dict("ab")
    with pytest.raises(InputError, match=r"\[thresholds\] must be a table"):
        _one(f"thresholds = {thresholds}\n" + ENTRY)


def test_csv_row_with_more_fields_than_the_header_is_that_entry_only():
    # not AttributeError: 'list' object has no attribute 'strip' (DictReader's restkey)
    entries = _one("machine,axis,traces\nm01,x,a.csv,extra\nm01,y,b.csv\n", "csv")
    assert "4 fields" in entries[0].error and "header 3" in entries[0].error
    assert entries[1].error is None and entries[1].key == "m01/y"


def test_csv_header_naming_a_column_twice_is_refused():
    # the second 'traces' column silently won
    with pytest.raises(InputError, match="twice"):
        _one("machine,axis,traces,traces\nm01,x,a.csv,b.csv\n", "csv")


def test_csv_key_value_given_twice_is_refused():
    # 't=t_s t=time' silently kept 'time' (the CLI's --map refuses a key mapped twice)
    e, = _one("machine,axis,traces,map\nm01,x,a.csv,t=t_s t=time\n", "csv")
    assert e.error and "'t' is given twice" in e.error


@pytest.mark.parametrize("suffix,text", [
    (".csv", "\ufeffmachine,axis,traces\nm01,x,a.csv\n"),
    (".toml", "\ufeff" + ENTRY)])
def test_manifest_with_a_byte_order_mark_is_read(tmp_path, suffix, text):
    # a spreadsheet's "CSV UTF-8" starts with a BOM, not refused as having no machine/axis header
    p = tmp_path / f"plant{suffix}"
    p.write_bytes(text.encode("utf-8"))
    e, = load_manifest(p).entries
    assert e.error is None and e.key == "m01/x"


def test_very_long_name_is_that_entry_s_error_not_the_fleet_s():
    # a 300-character machine name passed, and run_fleet then died on 'File name too long' for
    # every entry (the others' results lost)
    text = ENTRY.replace('"m01"', '"' + "m" * 300 + '"') + ENTRY.replace('"x"', '"y"')
    long, other = _one(text)
    assert long.error and "300 characters" in long.error
    assert other.error is None


@pytest.mark.parametrize("traces,words", [('[""]', "not a trace file name"),
                                          ('["a\\u0000.csv"]', "not a trace file name"),
                                          ('["a.csv", "./a.csv"]', "twice")])
def test_bad_trace_names(traces, words):
    # '' resolved to the manifest's folder; a NUL byte raised ValueError; a file listed twice was
    # "held out" while being the training trace
    e, = _one(ENTRY.replace('["a.csv"]', traces))
    assert e.error and words in e.error


@pytest.mark.parametrize("det", ["1", "[]", '""'])
def test_detectors_not_a_list_or_empty(det):
    # 1 raised TypeError; [] ran every detector (fdid diagnose --detectors "" is refused)
    e, = _one(ENTRY + f"options = {{ detectors = {det} }}\n")
    assert e.error and "detectors" in e.error


def test_option_list_for_a_single_valued_option():
    # seed = [1, 2] identified with seed 2 without a word (argparse keeps the last)
    e, = _one(ENTRY + "options = { seed = [1, 2] }\n")
    assert e.error and "one value" in e.error
    ok, = _one(ENTRY + 'options = { range = ["0:1", "2:3"] }\n')     # repeatable: accepted
    assert ok.error is None


@pytest.mark.parametrize("opt,words", [('{ axis = "y" }', "entry's axis"),
                                       ('{ output = "m.json" }', "cannot be set")])
def test_options_the_fleet_cannot_honour(opt, words):
    # refused at load: axis = "y" on entry m01/x would identify y and fail with "KeyError: 'x'",
    # retried every run; output would be accepted and ignored
    e, = _one(ENTRY + f"options = {opt}\n")
    assert e.error and words in e.error
    ok, = _one(ENTRY + 'options = { axis = "x" }\n')
    assert ok.error is None


def test_two_entries_without_axis_are_two_failed_entries():
    # was: the whole manifest refused as "m01/? is listed twice"
    text = '[[entry]]\nmachine = "m01"\ntraces = ["a.csv"]\n' * 2 + ENTRY
    a, b, c = _one(text)
    assert "no 'axis'" in a.error and "no 'axis'" in b.error and a.key != b.key
    assert c.error is None


def test_previous_fleet_result_of_another_shape_is_one_input_error(tmp_path):
    from fdid_fmi.fleet import load_fleet_result
    for i, doc in enumerate([{"format": "fdid-fmi-fleet"}, [1, 2],
                             {"format": "fdid-fmi-fleet", "out": "o", "manifest": "m", "executor": "e",
                              "workers": 1, "entries": [{"machine": "m01", "surprise": 1}]}]):
        d = tmp_path / f"prev{i}"
        d.mkdir()
        (d / "fleet.json").write_text(json.dumps(doc))
        with pytest.raises(InputError, match="fleet result"):      # not KeyError / TypeError / AttributeError
            load_fleet_result(d)


# ----------------------------------------------------------------------------- fleet cache
def _import_closure(root, start):
    """Package files reachable from ``start`` through imports (module level and in functions)."""
    def modfile(parts):
        p = root.joinpath(*parts)
        if p.with_suffix(".py").is_file():
            return p.with_suffix(".py")
        return p / "__init__.py" if (p / "__init__.py").is_file() else None

    seen, todo = set(), [root / s for s in start]
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        here = list(f.relative_to(root).parts[:-1])
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom):
                if node.level == 0:
                    if not (node.module or "").startswith("fdid_fmi"):
                        continue
                    base = node.module.split(".")[1:]
                else:
                    base = here[:len(here) - node.level + 1] + (node.module.split(".") if node.module else [])
                names = [base] + [base + [a.name] for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name.split(".")[1:] for a in node.names if a.name.startswith("fdid_fmi.")]
            for parts in names:
                for i in range(len(parts) + 1):
                    mf = modfile(parts[:i])
                    if mf is not None and mf not in seen:
                        todo.append(mf)
    return seen


def test_software_version_hashes_every_module_an_entry_runs():
    # the compiled kernel's Python side and C (regressor filter, simulation), the option value
    # parsers and the entry report were not hashed: a fix there reused the old models
    import fdid_fmi
    from fdid_fmi.fleet.manifest import pipeline_files
    root = Path(fdid_fmi.__file__).resolve().parent
    hashed = set(pipeline_files())
    used = _import_closure(root, ["fleet/work.py", "fleet/runner.py"])
    # the package and CLI package __init__s hold the version (in the string) and the CLI boundary
    missing = sorted(str(f.relative_to(root)) for f in used - hashed
                     if f not in (root / "__init__.py", root / "cli" / "__init__.py"))
    assert not missing, missing
    assert (root / "kernel.py") in used
    assert {f for f in (root / "kernel_ext").glob("*.c")} <= hashed


@pytest.fixture(scope="module")
def built_entry(tmp_path_factory):
    """One real entry (virtual axis, rigid structure, short search, no diagnosis), run in process."""
    from fdid_fmi.fleet.manifest import entry_hash, software_version
    from fdid_fmi.fleet.virtual import VirtualAxis, axis_trace, write_trace_csv
    from fdid_fmi.fleet.work import WorkItem, run_entry
    root = tmp_path_factory.mktemp("entry")
    write_trace_csv(axis_trace(VirtualAxis("m01", "x", "deckel_maho_like"), 1, n_moves=3), "x", root / "x.csv")
    (root / "plant.toml").write_text(
        ENTRY.replace("a.csv", "x.csv") + 'map = { t = "t_s", "x.cmd" = "x_cmd_mm", "x.act" = "x_mm" }\n'
        'options = { diagnose = false, structure = "rigid", maxiter = 4 }\n')
    spec, = load_manifest(root / "plant.toml").entries
    version = software_version()
    h = entry_hash(spec, version)
    edir = root / "out" / "entries" / spec.dirname
    res = run_entry(WorkItem(spec, str(edir), h, version))
    assert res.ok, res.error
    return {"edir": edir, "hash": h, "res": res, "spec": spec, "version": version}


def test_outputs_replaced_by_a_killed_run_are_not_taken_as_done(built_entry):
    # a run for other inputs (changed options, then changed back) killed after writing model.json
    # left the new model beside the old entry.json; the rerun reused that mixture as done
    from fdid_fmi.fleet.runner import _finished
    from fdid_fmi.fleet.work import _existing
    edir, h = built_entry["edir"], built_entry["hash"]
    assert _finished(edir, h, None) is not None and _existing(edir, h) is not None   # intact: reused
    model = edir / "model.json"
    original = model.read_bytes()
    try:
        d = json.loads(original)
        d["metrics"] = {"replaced": 1.0}            # another run's model.json
        model.write_text(json.dumps(d))
        assert _finished(edir, h, None) is None
        assert _existing(edir, h) is None
    finally:
        model.write_bytes(original)
    assert _finished(edir, h, None) is not None


def test_failure_of_the_comparison_is_not_reused_with_another_previous_result(built_entry, tmp_path):
    # a deterministic failure was reused whatever the previous result: an entry whose comparison
    # failed against one --previous folder stayed failed (skipped) when run against another
    import shutil
    from fdid_fmi.fleet.runner import _finished
    from fdid_fmi.fleet.work import PreviousModel, WorkItem, run_entry
    edir = tmp_path / "m01__x"
    shutil.copytree(built_entry["edir"], edir)
    h = built_entry["hash"]
    prev = PreviousModel(str(tmp_path / "gone" / "model.json"), {}, {}, "night0/m01/x")
    res = run_entry(WorkItem(built_entry["spec"], str(edir), h, built_entry["version"], prev, {}, "K1"))
    assert not res.ok and res.deterministic and "model.json" in res.error
    assert _finished(edir, h, "K1") is not None          # the same previous: the failure stands
    assert _finished(edir, h, "K2") is None               # another previous: run again
    assert _finished(edir, h, None) is None               # no previous: run again


def test_report_does_not_call_an_entry_that_never_ran_reused(tmp_path):
    # the fleet table's "run" column said "reused" for an entry refused by the manifest (the
    # summary counted it neither run nor reused)
    from fdid_fmi.fleet import run_fleet
    man = tmp_path / "plant.toml"
    man.write_text(ENTRY + 'options = { seed = [1, 2] }\n')
    fr = run_fleet(man, tmp_path / "out", progress=False)
    row, = json.loads((tmp_path / "out" / "fleet.json").read_text())["table"]
    assert row["status"] == "failed" and row["run"] == "not run"
    assert fr.executed == [] and fr.skipped == []


# ----------------------------------------------------------------------------- alignment
@pytest.fixture(scope="module")
def raw_run(tmp_path_factory):
    """A 3.5 s two-axis run (flexible_y) with an accelerometer and a grid encoder on their own clocks."""
    from fdid_fmi.virtual import presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    from fdid_fmi.virtual.sensors import write_raw_run
    cfg = presets.flexible_y()
    sim = simulate_machine(cfg, tj.linear_moves(n_moves=8, axes=("x", "y"), Ts=cfg.Ts, seed=4, d_max=20.0),
                           seed=4)
    return write_raw_run(sim, tmp_path_factory.mktemp("raw"))


def _with_column_negated(src, dst, col):
    lines = Path(src).read_text().splitlines()
    out = [lines[0]]
    for ln in lines[1:]:
        cells = ln.split(",")
        cells[col] = repr(-float(cells[col]))
        out.append(",".join(cells))
    Path(dst).write_text("\n".join(out) + "\n")
    return dst


@pytest.mark.parametrize("how", ["swapped", "negated"])
def test_mirrored_grid_encoder_is_refused(raw_run, tmp_path, how):
    # swapped columns (or axes=y,x, or one axis counting the other way) were aligned with a
    # -53 deg "plate angle" and tool positions 6.4 mm RMS off the encoders, reported as success
    from fdid_fmi.align import align, read_grid_encoder
    from fdid_fmi.io import read_trace
    src = raw_run["sensors"]["kgm"]
    if how == "swapped":
        rec = read_grid_encoder(src, columns=["kgm_y_um", "kgm_x_um"])
    else:
        rec = read_grid_encoder(_with_column_negated(src, tmp_path / "kgm.csv", 2))
    with pytest.raises(InputError, match="mirror image") as ei:
        align(read_trace(raw_run["controller"]), [rec])
    assert "kgm" in str(ei.value) and "\n" not in str(ei.value)


def test_mirrored_accelerometer_is_refused(raw_run):
    # ay, ax, az (a left-handed frame): the x/y acceleration came out right, but the calibration
    # held gamma 179 deg and a "bias" of 2 g (1.97e4 mm/s^2) along z
    from fdid_fmi.align import align, read_accelerometer
    from fdid_fmi.io import read_trace
    rec = read_accelerometer(raw_run["sensors"]["acc_tool"], columns=["ay_m_s2", "ax_m_s2", "az_m_s2"])
    with pytest.raises(InputError, match="mirror image"):
        align(read_trace(raw_run["controller"]), [rec])


@pytest.mark.parametrize("kw,words", [({"iterations": 0}, "iterations"), ({"window_s": 0.0}, "window_s"),
                                      ({"window_s": float("nan")}, "window_s"),
                                      ({"window_s": 1e-9}, "shorter than"),
                                      ({"lowpass_hz": 1e-300}, "two cycles"),
                                      ({"lowpass_hz": 0.01}, "two cycles"),
                                      ({"lowpass_hz": "5"}, "lowpass_hz"),
                                      ({"min_overlap_s": float("nan")}, "min_overlap_s")])
def test_align_parameters_checked(raw_run, kw, words):
    # iterations=0: KeyError 'residual_s'; window_s=nan: ValueError; window_s=0 or 1e-9 ran and
    # returned an offset 1.2 ms off (truth -0.413 s: -0.4117 +- 0.4 ms); lowpass '5': TypeError;
    # lowpass 1e-300 Hz: LinAlgError in the filter design, 0.01 Hz: "the sensor record is at rest
    # throughout"; min_overlap nan: accepted
    from fdid_fmi.align import align, read_grid_encoder
    from fdid_fmi.io import read_trace
    with pytest.raises(InputError, match=words):
        align(read_trace(raw_run["controller"]), [read_grid_encoder(raw_run["sensors"]["kgm"])], **kw)


def test_sensor_setting_given_twice_is_refused():
    # unit=g unit=m_s2 read the file in m/s^2 without a word
    from fdid_fmi.cli.align import parse_sensor
    with pytest.raises(InputError, match="given twice"):
        parse_sensor(["acc.csv", "unit=g", "unit=m_s2"], "accelerometer")


def test_sensor_file_in_a_folder_with_an_equals_sign(tmp_path):
    # .../date=2026-11-23/acc.csv is a file, not a setting ("unknown setting '.../date'")
    from fdid_fmi.cli.align import parse_sensor
    d = tmp_path / "date=2026-11-23"
    d.mkdir()
    f = d / "acc.csv"
    f.write_text("t_s,ax_g,ay_g,az_g\n")
    kw = parse_sensor([str(f), "axes=x,y", "unit=g"], "accelerometer")
    assert kw["path"] == str(f) and kw["axes"] == ("x", "y") and kw["unit"] == "g"
    with pytest.raises(InputError, match="unknown setting 'bogus'"):
        parse_sensor([str(f), "bogus=1"], "accelerometer")


def test_unknown_uncertainty_is_printed_as_unknown():
    # the JSON wrote a NaN uncertainty as null, the printed table as "± nan" (a number)
    from fdid_fmi.align.result import Estimate
    assert Estimate("timing", "time_offset", 1.5, float("nan"), "s", "m").text() == "1.5 s"
    assert Estimate("gravity_bias", "c", [1.0, 2.0], [float("nan"), 0.5], "mm/s^2", "m").text() == \
        "(1, 2) ± (?, 0.5) mm/s^2"


def test_sensor_column_given_twice_is_refused(tmp_path):
    # cols=ax,ax,az (or a name and its number) is refused; read, align() would blame the time
    # overlap ("no common motion ... the records do not overlap in time")
    from fdid_fmi.align import read_accelerometer
    t = np.arange(40) * 2e-4
    f = tmp_path / "acc.csv"
    f.write_text("t_s,ax_g,ay_g,az_g\n" + "\n".join(f"{v:.4f},0.01,0.02,1" for v in t) + "\n")
    with pytest.raises(InputError, match="two sensor axes"):
        read_accelerometer(f, columns=["ax_g", "2", "az_g"])


def _renamed_header(src, dst, header):
    lines = Path(src).read_text().splitlines()
    Path(dst).write_text("\n".join([header] + lines[1:]) + "\n")
    return dst


@pytest.mark.parametrize("kind,unit,words", [("accelerometer", "g", "9.81x"), ("grid_encoder", "mm", "1000x")])
def test_sensor_unit_off_by_a_factor_is_refused(raw_run, tmp_path, kind, unit, words):
    # m/s^2 read as g: the aligned acceleration came out 9.8x too large (gain_x 9.8 printed as a
    # "check"); um read as mm: a plate origin at 1.5e4 mm and tool positions 1000x, both "aligned"
    from fdid_fmi.align import align, read_sensor
    from fdid_fmi.io import read_trace
    if kind == "accelerometer":
        f = _renamed_header(raw_run["sensors"]["acc_tool"], tmp_path / "acc.csv", "t_s,ax,ay,az")
    else:
        f = _renamed_header(raw_run["sensors"]["kgm"], tmp_path / "kgm.csv", "t_s,kx,ky")
    with pytest.raises(InputError, match=words) as ei:
        align(read_trace(raw_run["controller"]), [read_sensor(f, kind, unit=unit)])
    assert "column 'unit'" in str(ei.value)


@pytest.mark.parametrize("n", [0, -2, 1.5])
def test_virtual_fleet_needs_a_machine(tmp_path, n):
    # n_machines=0 wrote night manifests without an entry (fdid fleet run then refused them)
    from fdid_fmi.fleet.virtual import write_virtual_fleet
    with pytest.raises(InputError, match="n_machines"):
        write_virtual_fleet(tmp_path, n_machines=n, nights=(1,))
    assert not (tmp_path / "night1.toml").exists()


@pytest.mark.parametrize("address", ["foo", "xyz://host:1", ""])
def test_malformed_scheduler_address_is_one_input_error(tmp_path, address):
    # not "internal error: ValueError: missing port number in address 'foo' -- this is a bug", exit 3
    pytest.importorskip("distributed")
    from fdid_fmi.fleet import run_fleet
    man = tmp_path / "plant.toml"
    man.write_text(ENTRY)                 # a usable entry (its trace is missing: a worker would say so)
    with pytest.raises(InputError, match="Dask scheduler"):
        run_fleet(man, tmp_path / "out", scheduler=address, progress=False)


def test_identification_range_does_not_apply_to_held_out_traces(built_entry, tmp_path):
    # options range = "0.5:1.0" was checked against every trace: a held-out trace of 0.3 s failed
    # the entry ("range outside the data" of the held-out file), though validation uses it whole
    from fdid_fmi.fleet.work import _read_traces
    src = Path(built_entry["spec"].traces[0])
    lines = src.read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:301]) + "\n")           # 0.3 s
    (tmp_path / "plant.toml").write_text(
        ENTRY.replace('["a.csv"]', f'["{src}", "short.csv"]')
        + 'map = { t = "t_s", "x.cmd" = "x_cmd_mm", "x.act" = "x_mm" }\noptions = { range = "0.5:1.0" }\n')
    spec, = load_manifest(tmp_path / "plant.toml").entries
    assert spec.error is None
    train, held = _read_traces(spec)
    assert train.meta["ranges"] == [(0.5, 1.0)] and "ranges" not in held.meta
    assert held.t[-1] < 0.31


def test_calibration_entry_without_a_rotation_is_one_input_error(raw_run):
    # align(orientation={"acc_tool": {"estimates": []}}) raised KeyError 'rotation'
    from fdid_fmi.align import align, read_accelerometer
    from fdid_fmi.io import read_trace
    with pytest.raises(InputError, match="not a 3x3 rotation"):
        align(read_trace(raw_run["controller"]), [read_accelerometer(raw_run["sensors"]["acc_tool"])],
              orientation={"acc_tool": {"estimates": []}})


def test_sensor_unit_off_by_a_factor_with_a_calibration(raw_run, tmp_path):
    # with the rotation of a calibration run no gain was estimated: m/s^2 read as g passed
    from fdid_fmi.align import align, read_accelerometer
    from fdid_fmi.io import read_trace
    f = _renamed_header(raw_run["sensors"]["acc_tool"], tmp_path / "acc.csv", "t_s,ax,ay,az")
    R = raw_run["truth"]["accelerometers"]["acc_tool"]["rotation_matrix"]
    with pytest.raises(InputError, match="9.81x"):
        align(read_trace(raw_run["controller"]), [read_accelerometer(f, unit="g", name="acc_tool")],
              orientation={"acc_tool": R})


def test_fleet_table_keeps_a_figure_that_was_not_computed_and_writes_strict_json(tmp_path):
    # max() lets a NaN figure vanish when it comes after a number (the table would say 3 um while
    # the entry's validation has a trace without a figure), and a diverged FMU's inf must not be
    # written as the non-JSON token Infinity
    from fdid_fmi.fleet.report import write_fleet_report
    from fdid_fmi.fleet.runner import FleetResult
    from fdid_fmi.fleet.work import EntryResult, ValidationFigures
    v = [ValidationFigures("a.csv", 3.0, 5.0, 1e-15), ValidationFigures("b.csv", float("nan"), float("nan"),
                                                                        float("inf"), ["not finite"])]
    e = EntryResult("m01", "x", "ok", "h", validation=v)
    fr = FleetResult(out=str(tmp_path), manifest="plant.toml", previous=None, executor="none", workers=0,
                     entries=[e], executed=["m01/x"])
    j, _ = write_fleet_report(fr, tmp_path)

    def no_constants(name):
        raise ValueError(f"non-JSON token {name}")
    d = json.loads(Path(j).read_text(), parse_constant=no_constants)
    row, = d["table"]
    assert row["fmu_rms_um"] is None and row["fmu_max_um"] is None and row["fmu_vs_reference_mm"] is None


def test_entry_files_are_strict_json(tmp_path):
    # validation.json / diagnosis.json have no NaN tokens for a figure not computed
    from fdid_fmi.fleet.work import ValidationFigures, _save_json
    from dataclasses import asdict
    p = tmp_path / "validation.json"
    _save_json(p, [asdict(ValidationFigures("b.csv", float("nan"), float("nan"), float("inf")))])

    def no_constants(name):
        raise ValueError(f"non-JSON token {name}")
    d = json.loads(p.read_text(), parse_constant=no_constants)
    assert d[0]["rms_um"] is None and d[0]["max_abs_diff_reference_mm"] is None


def test_orientation_without_an_accelerometer_is_refused(raw_run, tmp_path, capsys):
    # --orientation with only --kgm is refused, not read and ignored (the run "succeeding")
    from fdid_fmi.cli import main
    calib = tmp_path / "calib.json"
    calib.write_text(json.dumps({"format": "fdid-fmi alignment", "sensors": [
        {"name": "acc_tool", "kind": "accelerometer", "rotation": np.eye(3).tolist(), "estimates": []}]}))
    out = tmp_path / "o.csv"
    rc = main(["align", str(raw_run["controller"]), "--kgm", str(raw_run["sensors"]["kgm"]),
               "--orientation", str(calib), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "--orientation" in err and "--acc" in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_missing_compiler_on_a_worker_is_retried_not_kept(built_entry, tmp_path, monkeypatch):
    # a worker without gcc failed the entry "deterministically": every rerun skipped it as failed,
    # also after gcc was installed (the inputs had not changed)
    from fdid_fmi.fleet.runner import _finished
    from fdid_fmi.fleet.work import WorkItem, from_inputs, run_entry
    from fdid_fmi.errors import InputError as IE
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    edir = tmp_path / "m01__x"
    res = run_entry(WorkItem(built_entry["spec"], str(edir), built_entry["hash"], built_entry["version"]))
    assert not res.ok and "not installed" in res.error
    assert not res.deterministic and _finished(edir, built_entry["hash"], None) is None
    # an output of the entry's folder that cannot be written (disk full) is no input's fault either
    assert not from_inputs(IE("cannot write (No space left on device)", source=str(edir / "model.json")), edir)
    assert from_inputs(IE("not found", source=str(tmp_path / "x.csv")), edir)


def test_trace_notes_are_kept_in_the_entry_not_printed_by_the_worker(tmp_path, capsys):
    # the readers' notes (here: columns that state no unit, read as mm) are kept with the entry,
    # not printed by the worker (interleaved in the console, or lost in a Dask worker's log)
    from fdid_fmi.fleet.manifest import entry_hash, software_version
    from fdid_fmi.fleet.runner import FleetResult, table_rows
    from fdid_fmi.fleet.virtual import VirtualAxis, axis_trace, write_trace_csv
    from fdid_fmi.fleet.work import EntryResult, WorkItem, run_entry
    write_trace_csv(axis_trace(VirtualAxis("m01", "x", "deckel_maho_like"), 1, n_moves=3), "x", tmp_path / "x.csv")
    lines = (tmp_path / "x.csv").read_text().splitlines()
    (tmp_path / "x.csv").write_text("\n".join([lines[0].replace("x_cmd_mm", "x_cmd").replace("x_mm", "x")]
                                              + lines[1:]) + "\n")
    (tmp_path / "plant.toml").write_text(
        ENTRY.replace("a.csv", "x.csv") + 'map = { t = "t_s", "x.cmd" = "x_cmd", "x.act" = "x" }\n'
        'options = { diagnose = false, structure = "rigid", maxiter = 2 }\n')
    spec, = load_manifest(tmp_path / "plant.toml").entries
    version = software_version()
    capsys.readouterr()
    res = run_entry(WorkItem(spec, str(tmp_path / "out" / spec.dirname), entry_hash(spec, version), version))
    assert res.ok, res.error
    assert "note:" not in capsys.readouterr().out
    assert res.notes == ["x.csv: columns x_cmd (mm), x (mm) state no unit and are read in these units; if one "
                         "is in another, name it like x_um or give units = { COLUMN = \"UNIT\" }"]   # in the manifest's words
    assert EntryResult.from_dict(res.to_dict()).notes == res.notes
    fr = FleetResult(out=str(tmp_path / "out"), manifest="plant.toml", previous=None, executor="test", workers=1,
                     entries=[res])
    assert table_rows(fr)[0]["notes"] == res.notes
