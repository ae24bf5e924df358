"""The fleet layer: an entry whose FMU validation fails is not "ok", the missing compiler
is an error type (not a column name), manifest options are not abbreviated, and entry names that
differ only in case are refused. Each test fails without the code it guards."""
import json
from pathlib import Path

import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.fleet.manifest import load_manifest, parse_manifest_text

ENTRY = '[[entry]]\nmachine = "m01"\naxis = "x"\ntraces = ["a.csv"]\n'


def _entries(text, fmt="toml"):
    return parse_manifest_text(text, fmt, base="/tmp/fleet", source=f"plant.{fmt}").entries


@pytest.fixture(scope="module")
def unmeasured(tmp_path_factory):
    """``fdid fleet run`` (CLI, local pool of one process) on one real entry whose held-out trace
    has no measured position of the axis (its ``x_mm`` column removed): the FMU is exported and run
    through fmpy, but no discrepancy to the measurement can be computed."""
    from fdid_fmi.cli import main
    from fdid_fmi.fleet.virtual import VirtualAxis, axis_trace, write_trace_csv
    root = tmp_path_factory.mktemp("fleet_entry")
    va = VirtualAxis("m01", "x", "deckel_maho_like")
    write_trace_csv(axis_trace(va, 1, n_moves=3), "x", root / "x.csv")
    full = write_trace_csv(axis_trace(va, 2, n_moves=3), "x", root / "full.csv")
    rows = [ln.split(",") for ln in full.read_text().splitlines()]
    drop = rows[0].index("x_mm")
    (root / "held.csv").write_text("\n".join(",".join(c for i, c in enumerate(r) if i != drop) for r in rows) + "\n")
    man = root / "plant.toml"
    man.write_text('[[entry]]\nmachine = "m01"\naxis = "x"\ntraces = ["x.csv", "held.csv"]\n'
                   'options = { diagnose = false, structure = "rigid", maxiter = 4 }\n')
    out = root / "out"
    rc = main(["fleet", "run", str(man), "--out", str(out), "--no-progress", "--workers", "1"])
    return {"root": root, "man": man, "out": out, "rc": rc, "edir": out / "entries" / "m01__x"}


# ----------------------------------------------------------------------------- 1. validation verdict
def test_entry_whose_fmu_validation_fails_is_not_ok(unmeasured, capsys):
    # the entry was "ok" (exit code 0, counts ok 1) with an FMU discrepancy of NaN -> null in
    # fleet.json: nothing said the FMU had not been checked against the measurement
    from fdid_fmi.fleet.manifest import entry_hash, software_version
    from fdid_fmi.fleet.runner import _finished
    out, edir = unmeasured["out"], unmeasured["edir"]
    assert unmeasured["rc"] == 1
    d = json.loads((out / "fleet.json").read_text())
    assert d["counts"] == {"entries": 1, "ok": 0, "failed": 1, "validation_failed": 1, "changed": 0}
    row, = d["table"]
    assert row["status"] == "validation_failed"
    assert "held.csv" in row["error"] and "discrepancy" in row["error"] and "\n" not in row["error"]
    assert row["fmu_rms_um"] is None and row["fmu_vs_reference_mm"] <= 1e-9   # the FMU itself ran fine
    # the summary (printed by the CLI, in fleet.html) names it and why
    html = (out / "fleet.html").read_text()
    assert "validation_failed" in html and "VALIDATION FAILED m01/x" in html
    # every stage ran: the model, the FMU and the report are kept for inspection
    ent = json.loads((edir / "entry.json").read_text())
    assert ent["status"] == "validation_failed" and ent["validation"][0]["passed"] is True
    assert {"model.json", "m01_x.fmu", "validation.json", "entry.html"} <= {p.name for p in edir.iterdir()}
    # not kept as done: the next run redoes it
    spec, = load_manifest(unmeasured["man"]).entries
    assert _finished(edir, entry_hash(spec, software_version()), None) is None


def test_validation_verdict_is_fdid_validate_s(unmeasured):
    # the fleet's decision is ValidationResult.ok (fdid validate's exit code) plus a finite
    # discrepancy: an FMU that misses the reference tolerance fails the entry, one that meets it
    # passes (the successful path is unchanged)
    from fdid_fmi.fleet.work import validation_failure, validation_figures
    from fdid_fmi.fmu.validate import validate_fmu
    from fdid_fmi.io import read_trace
    edir = unmeasured["edir"]
    trace = read_trace(unmeasured["root"] / "x.csv")
    fmu, model = edir / "m01_x.fmu", edir / "model.json"
    good = validation_figures(validate_fmu(fmu, trace, model=model), trace, "x")
    assert good.passed and good.ok and validation_failure([good]) is None
    # the FMU's positions equal the reference's bit for bit (the same C core): a reference one
    # rounding away from the FMU's model makes them differ, by far less than the default tolerance
    from fdid_fmi.model import load_model
    near = load_model(model)
    near.C = near.C * (1 + 1e-12)
    strict = validate_fmu(fmu, trace, model=near, tolerance_mm=1e-300)
    assert 0 < strict.max_abs_diff_reference_mm < 1e-9 and not strict.ok
    bad = validation_figures(strict, trace, "x")
    assert bad.passed is False and not bad.ok
    reason = validation_failure([good, bad])
    assert reason.startswith("FMU validation failed: x.csv: FMU and reference simulator differ")


# ----------------------------------------------------------------------------- 2. missing compiler
def test_missing_compiler_is_told_by_its_type_not_by_a_column_name(unmeasured, tmp_path, monkeypatch):
    # work.from_inputs took every InputError of column 'platforms' for "the compiler is not
    # installed": an unknown platform name (an input's fault, refused by export_fmu with that
    # column) was retried by every run as if a worker lacked gcc
    from fdid_fmi.fleet.work import from_inputs
    from fdid_fmi.fmu import export_fmu
    from fdid_fmi.fmu.build import CompilerNotFound
    edir, model = unmeasured["edir"], unmeasured["edir"] / "model.json"
    with pytest.raises(InputError, match="unknown platform 'solaris'") as ei:
        export_fmu(model, tmp_path / "m.fmu", platforms="solaris")
    assert ei.value.column == "platforms" and not isinstance(ei.value, CompilerNotFound)
    assert from_inputs(ei.value, edir)                      # kept: the inputs name no such platform
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))     # gcc is not on this "worker"
    with pytest.raises(CompilerNotFound, match="not installed") as ei:
        export_fmu(model, tmp_path / "m.fmu")
    assert isinstance(ei.value, InputError)                 # the CLI still reports it in one line, exit 2
    assert not from_inputs(ei.value, edir)                  # retried: the worker's environment
    assert not (tmp_path / "m.fmu").exists()


# ----------------------------------------------------------------------------- 3. abbreviated options
@pytest.mark.parametrize("fmt,text", [
    ("toml", ENTRY + "options = { max = 5 }\n"),
    ("csv", "machine,axis,traces,options\nm01,x,a.csv,max=5\n")])
def test_abbreviated_option_is_refused(fmt, text):
    # 'max = 5' is not taken by argparse as --maxiter 5 without a word
    e, = _entries(text, fmt)
    assert e.error is not None and "\n" not in e.error
    assert e.error.startswith(f"plant.{fmt}, column 'max': entry ") and "(m01/x)" in e.error
    assert "option 'max'" in e.error and "maxiter" in e.error and "in full" in e.error


def test_option_parser_allows_no_abbreviation():
    # the fleet's fdid identify parser (also used by the workers) completed --max to --maxiter
    from fdid_fmi.fleet.manifest import EntrySpec, identify_args
    spec = EntrySpec("m01", "x", ("/tmp/fleet/a.csv",), identify=("--max", "5"))
    with pytest.raises(InputError, match="--max"):
        identify_args("/tmp/fleet/a.csv", spec)
    full = EntrySpec("m01", "x", ("/tmp/fleet/a.csv",), identify=("--maxiter", "5"))
    assert identify_args("/tmp/fleet/a.csv", full).maxiter == 5
    ok, = _entries(ENTRY + "options = { maxiter = 5, ma_order = 2 }\n")
    assert ok.error is None and ok.identify == ("--maxiter", "5", "--ma-order", "2")


# ----------------------------------------------------------------------------- 4. names and case
@pytest.mark.parametrize("second", ['machine = "M01"\naxis = "x"', 'machine = "m01"\naxis = "X"'])
def test_entries_differing_only_in_case_are_refused(second):
    # m01/x and M01/x (or m01/X) wrote entries/m01__x and entries/M01__x: one folder on macOS and
    # Windows, where the second entry overwrote the first's model and FMU
    text = ENTRY + ENTRY.replace('machine = "m01"\naxis = "x"', second).replace("a.csv", "b.csv")
    with pytest.raises(InputError) as ei:
        _entries(text)
    msg = str(ei.value)
    other = "M01/x" if "M01" in second else "m01/X"
    assert msg.startswith("plant.toml: ") and "m01/x" in msg and other in msg and "\n" not in msg
    assert "entries 1 and 2" in msg and "case" in msg
    # a CSV manifest too
    with pytest.raises(InputError, match="case"):
        _entries("machine,axis,traces\nm01,x,a.csv\nM01,x,b.csv\n", "csv")
    # different names still pass
    assert len(_entries(ENTRY + ENTRY.replace('"m01"', '"m011"'))) == 2


def test_tool_channel_is_compared_with_the_model_tool_output():
    """A model with a tool-side output (the default structure when the traces record the tool)
    predicts the tool channel itself: the fleet compared that channel with the motor-side position
    instead (measured on plant2's backlash axis: 7.93 µm, the lost motion, for a model predicting
    the tool side to 3.14 µm)."""
    from fdid_fmi.diagnose.residuals import residuals
    from fdid_fmi.fleet.work import channel_errors
    from plant2_fits import backlash_tool_r1c1
    _, va, _, m = backlash_tool_r1c1()
    errors, _ = channel_errors(m, [va], "x")
    table = residuals(m, va).table()                  # measured minus predicted, per output
    assert errors["tool"] == pytest.approx(table["x.tool"]["rms_um"], rel=1e-9)
    assert errors["motor"] == pytest.approx(table["x"]["rms_um"], rel=1e-9)
