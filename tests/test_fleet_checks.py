"""The fleet layer: an entry is checked as ``fdid identify`` checks it (option
combinations at manifest load, the data's scale before identification), in the manifest's words;
an axis list is the entry's axis only; ``--previous`` refuses a model file replaced since; a failing
entry names its trace file, keeps the readers' notes (printed in the summary, with the manifest's
``units = {...}`` advice) and lists no unvalidated outputs; figures not computed are said so; held-out
traces are named as the manifest gives them. Each test fails without the code it guards."""
import json
import shutil
from pathlib import Path

import pytest

from fdid_fmi.fleet.manifest import load_manifest, parse_manifest_text

ENTRY = '[[entry]]\nmachine = "m01"\naxis = "x"\ntraces = ["a.csv"]\n'
MAP = 'map = { t = "t_s", "x.cmd" = "x_cmd_mm", "x.act" = "x_mm" }\n'
FAST = 'options = { diagnose = false, structure = "rigid", maxiter = 4 }\n'


def _one(text):
    e, = parse_manifest_text(text, "toml", base="/tmp/fleet", source="plant.toml").entries
    return e


@pytest.fixture(scope="module")
def csv_trace(tmp_path_factory):
    """A short virtual trace (1 ms, 3 moves) as CSV lines: header t_s,x_cmd_mm,x_mm,x_tool_mm."""
    from fdid_fmi.fleet.virtual import VirtualAxis, axis_trace, write_trace_csv
    root = tmp_path_factory.mktemp("fleet_trace")
    va = VirtualAxis("m01", "x", "deckel_maho_like")
    p = write_trace_csv(axis_trace(va, 1, n_moves=3), "x", root / "x.csv")
    h = write_trace_csv(axis_trace(va, 2, n_moves=3), "x", root / "h.csv")
    return {"root": root, "x": p, "lines": p.read_text().splitlines(), "held": h.read_text()}


def _run(root, manifest_text, name="plant.toml"):
    """run_entry on the manifest's one entry (in process); returns (result, entry folder)."""
    from fdid_fmi.fleet.manifest import entry_hash, software_version
    from fdid_fmi.fleet.work import WorkItem, run_entry
    (root / name).write_text(manifest_text)
    spec, = load_manifest(root / name).entries
    assert spec.error is None, spec.error
    version = software_version()
    edir = root / ("out_" + name.split(".")[0]) / "entries" / spec.dirname
    return run_entry(WorkItem(spec, str(edir), entry_hash(spec, version), version)), edir


def _rewrite(lines, fn):
    """CSV text with ``fn`` applied to every data row's cells (floats)."""
    out = [lines[0]]
    for ln in lines[1:]:
        out.append(",".join(repr(v) for v in fn([float(c) for c in ln.split(",")])))
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- 1. fdid identify's checks
@pytest.mark.parametrize("opts,key", [
    ('v_tilde = 0.01, v_tilde_range = "0.001:1"', "options.v_tilde_range"),
    ("no_friction = true, v_tilde = 0.01", "options.v_tilde"),
    ('structure = "rigid", lock_complex = "30:0.05", jobs = 2', "options.lock_complex"),
    ('method = "full-ls", same_sample = "hold"', "options.same_sample"),
    ('structure = "rigid", jobs = 2', "options.jobs"),
    ('structure = "auto", no_friction = true', "options.structure")])
def test_option_combinations_the_cli_refuses_are_refused_at_load(opts, key):
    # each ran "done" with the option silently ignored; fdid identify refuses each in one line
    e = _one(ENTRY + f"options = {{ {opts} }}\n")
    assert e.error is not None and "\n" not in e.error
    assert e.error.startswith(f"plant.toml, column '{key}': entry 1 (m01/x): "), e.error
    assert "--" not in e.error, e.error         # the manifest's words, not the CLI's flags
    assert _one(ENTRY + 'options = { v_tilde = 0.01, structure = "rigid" }\n').error is None


def test_data_scale_is_checked_before_identification(csv_trace, tmp_path):
    # positions x1e10 were identified, exported and failed validation with a misleading message
    # (fdid identify: "positions reach 3.02e+11 mm ... check the unit and scale")
    (tmp_path / "huge.csv").write_text(_rewrite(csv_trace["lines"], lambda r: [r[0]] + [v * 1e10 for v in r[1:]]))
    res, edir = _run(tmp_path, ENTRY.replace("a.csv", "huge.csv") + MAP + FAST)
    assert res.status == "failed" and res.deterministic
    assert res.error.startswith("huge.csv, column 'x_cmd_mm': positions reach"), res.error
    assert "unit and scale" in res.error and "(units)" in res.error
    assert not (edir / "model.json").exists() and res.outputs == {}


# ----------------------------------------------------------------------------- 2. axis lists
@pytest.mark.parametrize("axes", ['["x", "y"]', '["y", "x"]', '["x", "x"]'])
def test_axis_list_other_than_the_entry_s_axis_is_refused(axes):
    # axis = ["x", "y"] on entry m01/x identified a two-axis model; only x was validated
    e = _one(ENTRY + f"options = {{ axis = {axes} }}\n")
    assert e.error and "column 'axis'" in e.error and "entry's axis 'x'" in e.error
    assert _one(ENTRY + 'options = { axis = ["x"] }\n').error is None


# ----------------------------------------------------------------------------- 3. --previous
def _previous_folder(root, model_bytes, digest_of):
    """A previous fleet folder with one ok entry m01/x whose fleet.json records the sha256 of
    ``digest_of`` as its model's, and whose entries/m01__x/model.json holds ``model_bytes``."""
    import hashlib
    from fdid_fmi.fleet.compare import ModelSignature
    from fdid_fmi.fleet.runner import FleetResult
    from fdid_fmi.fleet.work import EntryResult
    from fdid_fmi.fleet.report import write_fleet_report
    prev = root / "night1"
    (prev / "entries" / "m01__x").mkdir(parents=True)
    if model_bytes is not None:
        (prev / "entries" / "m01__x" / "model.json").write_bytes(model_bytes)
    e = EntryResult("m01", "x", "ok", "h", outputs={"model": "model.json"},
                    output_digests={"model": hashlib.sha256(digest_of).hexdigest()},
                    signature=ModelSignature([[-10.0, 0.0]], 1.0, 0.1, [], 1e-3))
    write_fleet_report(FleetResult(str(prev), "night1.toml", None, "test", 1, entries=[e]), prev)
    return prev


@pytest.mark.parametrize("model_bytes", [b'{"replaced": 1}', None])
def test_previous_model_replaced_since_is_refused_for_that_entry(tmp_path, model_bytes):
    # a model.json left by an interrupted rerun into the previous folder was compared as if it
    # were the model whose signature and errors that folder's fleet.json holds
    from fdid_fmi.fleet import run_fleet
    from fdid_fmi.fleet.runner import _previous_models
    prev = _previous_folder(tmp_path, model_bytes, b'{"original": 1}')
    models, problems, _, _ = _previous_models(prev)
    assert "m01/x" not in models
    msg = problems["m01/x"]
    assert str(prev / "entries" / "m01__x" / "model.json") in msg and "fleet.json" in msg
    assert ("sha256 differs" if model_bytes else "missing") in msg
    man = tmp_path / "night2.toml"
    man.write_text(ENTRY + MAP + FAST)
    fr = run_fleet(man, tmp_path / "night2", previous=prev, progress=False)
    e, = fr.entries
    assert e.status == "failed" and e.error == msg and fr.executed == []
    assert any(f"FAILED m01/x: {msg}" == ln.strip() for ln in fr.summary())
    # the model fleet.json recorded is used
    prev2 = _previous_folder(tmp_path / "ok", b'{"original": 1}', b'{"original": 1}')
    models, problems, _, _ = _previous_models(prev2)
    assert "m01/x" in models and not problems


# ----------------------------------------------------------------------------- 5. failing entry's trace and notes
def test_failing_entry_names_its_trace_file_and_keeps_the_notes(csv_trace, tmp_path):
    # a trace in ms labelled t_s fails naming its file, not only "column 'bounds': ...", and its
    # note "column 't_s' steps by 1 s ... give --unit t_s=ms" is kept with the failure
    (tmp_path / "ms.csv").write_text(_rewrite(csv_trace["lines"], lambda r: [r[0] * 1000] + r[1:]))
    res, edir = _run(tmp_path, ENTRY.replace("a.csv", "ms.csv") + MAP + FAST)
    assert res.status == "failed"
    assert res.error.startswith("ms.csv, column 'bounds': "), res.error
    note, = res.notes
    assert note.startswith("ms.csv: column 't_s' steps by 1 s")
    # 6. the advice in the manifest's words, not a CLI flag
    assert 'give units = { t_s = "ms" }' in note and "--unit" not in note
    stored = json.loads((edir / "entry.json").read_text())
    assert stored["notes"] == [note] and stored["outputs"] == {}


def test_an_entry_keeps_identifys_note_on_a_swapped_command(csv_trace, tmp_path):
    # fdid identify notes a command swapped with the measured position; the fleet keeps that note
    (tmp_path / "a.csv").write_text("\n".join(csv_trace["lines"]) + "\n")
    swapped = MAP.replace('"x.cmd" = "x_cmd_mm", "x.act" = "x_mm"', '"x.cmd" = "x_mm", "x.act" = "x_cmd_mm"')
    res, _ = _run(tmp_path, ENTRY + swapped + FAST)
    ahead = [n for n in res.notes if "runs ahead" in n]
    assert len(ahead) == 1 and ahead[0].startswith("a.csv: axis x: x_cmd_mm runs ahead of x_mm"), res.notes
    res, _ = _run(tmp_path, ENTRY + MAP + FAST, name="plain.toml")
    assert not any("runs ahead" in n for n in res.notes)


def test_a_missing_or_unreadable_trace_is_named_as_the_manifest_gives_it(csv_trace, tmp_path):
    # as the manifest gives it, not "FAILED m01/y: /abs/path/night1/nosuch.csv: file not found"
    (tmp_path / "night1").mkdir()
    res, _ = _run(tmp_path, ENTRY.replace("a.csv", "night1/nosuch.csv") + MAP + FAST)
    assert res.status == "failed" and res.error.startswith("night1/nosuch.csv: "), res.error
    assert str(tmp_path) not in res.error
    (tmp_path / "night1" / "a.csv").write_text("\n".join(csv_trace["lines"]) + "\n")
    res, _ = _run(tmp_path, ENTRY.replace("a.csv", "night1/a.csv") + MAP.replace('"x_mm"', '"x_mmm"') + FAST,
                  name="typo.toml")
    assert res.status == "failed" and res.error.startswith("night1/a.csv"), res.error
    assert str(tmp_path) not in res.error


# ----------------------------------------------------------------------------- 6. notes in the summary
def test_summary_prints_the_trace_notes():
    # the notes reached only fleet.json / fleet.html, not the console
    from fdid_fmi.fleet.report import MAX_NOTED_AXES, summary_lines
    from fdid_fmi.fleet.runner import FleetResult
    from fdid_fmi.fleet.work import EntryResult
    entries = [EntryResult("m01", "x", "ok", "h", notes=["a.csv: note one", "b.csv: note two"]),
               EntryResult("m01", "y", "ok", "h")]
    entries += [EntryResult(f"m{k:02d}", "x", "ok", "h", notes=["c.csv: n"]) for k in range(2, 2 + MAX_NOTED_AXES)]
    lines = summary_lines(FleetResult("out", "plant.toml", None, "test", 1, entries=entries))
    assert "  NOTE m01/x: a.csv: note one (+1 more note(s) in fleet.html)" in lines
    assert not any("m01/y" in ln for ln in lines)
    assert sum(ln.startswith("  NOTE ") for ln in lines) == MAX_NOTED_AXES         # capped
    assert lines[-1] == "  ... and 1 more axes with notes: see fleet.html"


# ----------------------------------------------------------------------------- 7. held-out sample time
def test_held_out_trace_of_another_sample_time_fails_before_identification(csv_trace, tmp_path):
    # a held-out trace at 2 ms (training 1 ms) failed after identification and export, and the
    # failed entry listed the unvalidated model and FMU as its outputs
    lines = csv_trace["held"].splitlines()
    (tmp_path / "x.csv").write_text("\n".join(csv_trace["lines"]) + "\n")
    (tmp_path / "h2.csv").write_text("\n".join(lines[:1] + lines[1::2]) + "\n")
    res, edir = _run(tmp_path, ENTRY.replace('["a.csv"]', '["x.csv", "h2.csv"]') + MAP + FAST)
    assert res.status == "failed" and res.deterministic
    assert res.error.startswith("h2.csv, column 't_s': this held-out trace is sampled at 0.002 s"), res.error
    assert "x.csv" in res.error and "0.001 s" in res.error
    assert res.timings.identify_s == 0 and not (edir / "model.json").exists() and res.outputs == {}


# ----------------------------------------------------------------------------- 8. figures not computed
def test_fleet_html_says_not_computed_where_fleet_json_has_null(tmp_path):
    # fleet.html showed "inf" for a figure never computed (runner._worst mapped None to inf)
    from fdid_fmi.fleet.report import write_fleet_report
    from fdid_fmi.fleet.runner import FleetResult, _worst
    from fdid_fmi.fleet.work import EntryResult, ValidationFigures
    v = [ValidationFigures("a.csv", 1.0, 2.0, 0.0), ValidationFigures("b.csv", float("nan"), float("nan"), 0.0)]
    e = EntryResult("m01", "x", "validation_failed", "h", validation=v)
    write_fleet_report(FleetResult(str(tmp_path), "plant.toml", None, "test", 1, entries=[e]), tmp_path)
    row, = json.loads((tmp_path / "fleet.json").read_text())["table"]
    assert row["fmu_rms_um"] is None and row["fmu_vs_reference_mm"] == 0.0
    html = (tmp_path / "fleet.html").read_text()
    assert "not computed" in html and ">inf<" not in html
    assert _worst([1.0, float("inf")]) == float("inf") and _worst([]) is None      # a diverged FMU stays inf


# ----------------------------------------------------------------------------- 8, 9, 7: one real entry
@pytest.fixture(scope="module")
def no_friction_entry(csv_trace):
    """One real entry without friction (rigid, short search, no diagnosis), its held-out traces
    two files of one name in two folders."""
    root = csv_trace["root"]
    for night in ("night1", "night2"):
        (root / night).mkdir()
        (root / night / "m01_x.csv").write_text(csv_trace["held"])
    res, edir = _run(root, ENTRY.replace('["a.csv"]', '["x.csv", "night1/m01_x.csv", "night2/m01_x.csv"]') + MAP
                     + 'options = { diagnose = false, structure = "rigid", maxiter = 4, no_friction = true }\n',
                     name="nofric.toml")
    assert res.ok, res.error
    return {"res": res, "edir": edir, "root": root}


def test_entry_report_says_none_for_a_model_without_friction(no_friction_entry):
    # entry.html said "friction step peak 0 µm; v_tilde 0 mm/s" where fleet.json has null
    res = no_friction_entry["res"]
    assert res.signature.friction_peak_um is None and res.signature.v_tilde_mm_s is None
    html = (no_friction_entry["edir"] / "entry.html").read_text()
    assert "friction step peak none; v_tilde none;" in html
    assert "friction step peak 0 " not in html


def test_held_out_traces_are_named_as_the_manifest_gives_them(no_friction_entry):
    # night1/m01_x.csv and night2/m01_x.csv were both "m01_x.csv" in validation.json / entry.html
    res = no_friction_entry["res"]
    assert [v.trace for v in res.validation] == ["night1/m01_x.csv", "night2/m01_x.csv"]
    stored = json.loads((no_friction_entry["edir"] / "validation.json").read_text())
    assert [v["trace"] for v in stored] == ["night1/m01_x.csv", "night2/m01_x.csv"]


def test_entry_failing_after_its_build_lists_and_keeps_no_outputs(no_friction_entry, tmp_path):
    # an entry failing after identification and export (here: its comparison, the previous model
    # being gone) kept the model and FMU listed as its outputs in entry.json / fleet.json
    from fdid_fmi.fleet.manifest import entry_hash, software_version
    from fdid_fmi.fleet.work import PreviousModel, WorkItem, run_entry
    root = no_friction_entry["root"]
    spec, = load_manifest(root / "nofric.toml").entries
    edir = tmp_path / "m01__x"
    shutil.copytree(no_friction_entry["edir"], edir)
    version = software_version()
    prev = PreviousModel(str(tmp_path / "gone" / "model.json"), {}, {}, "night0/m01/x")
    res = run_entry(WorkItem(spec, str(edir), entry_hash(spec, version), version, prev, {}, "K1"))
    assert res.status == "failed" and "model.json" in res.error
    assert res.outputs == {} and res.output_digests == {}
    assert not (edir / "model.json").exists() and not list(edir.glob("*.fmu"))
    assert json.loads((edir / "entry.json").read_text())["outputs"] == {}


# ----------------------------------------------------------------------------- 11. map key in the manifest's words
def test_map_typo_names_the_manifest_key_not_a_cli_flag():
    # "FAILED m01/x: --map, column 'x.tol': ..." cited a flag the user never gave
    e = _one(ENTRY + 'map = { "x.tol" = "x_tool_mm" }\n')
    assert e.error.startswith("plant.toml, column 'map': entry 1 (m01/x): mapping key 'x.tol'"), e.error
    assert "--map" not in e.error
    u = _one(ENTRY + 'units = { x_mm = "furlong" }\n')
    assert "column 'units'" in u.error and "--unit" not in u.error, u.error
