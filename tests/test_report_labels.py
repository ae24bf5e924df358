"""Report tables in the reader's words: every column a key of the package is shown with its label
and unit (one table, fdid_fmi.labels), wide tables scroll, the model's training record is
labelled, and the measured tracking error stands beside the twin's discrepancy."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.diagnose.reporting import error_rows
from fdid_fmi.labels import LABELS, label
from fdid_fmi.model import load_model
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program
from fdid_fmi.plan.predict import predict
from fdid_fmi.plan.reporting import plan_report
from fdid_fmi.report import Report, metric_rows
from fdid_fmi.trace import Trace

DATA = Path(__file__).parent / "data"
KEY = re.compile(r"^[A-Za-z0-9]+(_[A-Za-z0-9]+)+$")        # a snake_case key, not words
UNIT_SUFFIX = ("_um", "_mm", "_s", "_mm_min", "_pct", "_mm_s")


def _headers(html_text):
    """{table id: [header cells]} of a report page."""
    out = {}
    for m in re.finditer(r"<table id='table-([^']+)'>(.*?)</table>", html_text, re.S):
        first = re.search(r"<tr>(.*?)</tr>", m.group(2), re.S)
        out[m.group(1)] = re.findall(r"<th>(.*?)</th>", first.group(1)) if first else []
    return out


def test_every_key_with_a_unit_has_a_label_with_that_unit():
    for key, term in LABELS.items():
        if key.endswith(UNIT_SUFFIX):
            assert re.search(r"\[.+\]", term.label), key
    assert label("x_max_err_um") == "x predicted tracking error MAX [µm]"
    assert label("y_max_err_um") == "y predicted tracking error MAX [µm]"
    assert label("v [mm/s]") == "v [mm/s]"                  # words stay as they are


def test_table_shows_labels_keeps_keys_in_the_json_and_scrolls(tmp_path):
    rep = Report("t")
    rep.add_table("blocks", [{"block": 1, "feed_mm_min": 6000.0, "contour_max_um": 1.5, "flag": True}])
    page = rep.html()
    assert _headers(page)["blocks"] == ["block", "programmed feed [mm/min]", "contour error MAX [µm]",
                                        "above the tolerance"]
    assert "<td>6000</td>" in page and "<td>yes</td>" in page
    assert "<div class='table-wrap'><table id='table-blocks'>" in page
    assert re.search(r"\.table-wrap\{[^}]*overflow-x:auto", page)
    t = json.loads(rep.write_json(tmp_path / "r.json").read_text())["tables"]["blocks"]
    assert t["columns"] == ["block", "feed_mm_min", "contour_max_um", "flag"]
    assert t["labels"][1] == "programmed feed [mm/min]" and t["rows"][0][3] is True


def test_model_training_record_is_labelled_in_units():
    model = load_model(DATA / "xy_twin_model.json")
    rows = metric_rows(model)
    assert rows and not any(" / " in r["quantity"] or KEY.match(r["quantity"]) for r in rows)
    x = {r["quantity"]: r["value"] for r in rows if r["part"] == "axis x"}
    fit = model.metrics["blocks"][0]["fit_rms"]["x_error"]
    assert x["x_error: RMS of the fit residual [µm]"] == pytest.approx(fit * 1e3)
    assert x["training samples"] == model.metrics["blocks"][0]["samples"]
    assert {r["part"] for r in rows} == {"axis x", "axis y"}


def test_diagnose_table_puts_the_measured_tracking_error_beside_the_discrepancy():
    t = np.arange(200) * 1e-3
    cmd = 50.0 * t
    tr = Trace.from_arrays(t, {"x": {"cmd": cmd, "act": cmd - 0.004}})
    before = {"train": {"x": {"rms_um": 1.0, "max_um": 2.0}}}
    after = {"train": {"x": {"rms_um": 0.5, "max_um": 1.0}}}
    rows = error_rows(before, after, traces={"train": tr})
    assert rows[0]["measured_rms_um"] == pytest.approx(4.0) and rows[0]["rms_before_um"] == 1.0
    labels = [label(k) for k in rows[0]]
    assert labels[2:5] == ["measured tracking error RMS [µm]", "measured tracking error MAX [µm]",
                           "discrepancy RMS before [µm]"]


def test_plan_report_headers_are_labels():
    model = load_model(DATA / "xy_twin_model.json")
    prog = parse_program("G21 G90 G17 G94\nN10 G1 X12 F3000\nN20 G3 X24 Y0 R6\nN30 G4 P0.05\n")
    limits = {a: AxisLimits(100, 2000, 1e5) for a in model.axes}
    pr = predict(interpolate(prog, limits, model.Ts), model=model, tol_mm=0.01, program=prog)
    page = plan_report(prog, pr, model=model, tol_mm=0.01).html()
    heads = _headers(page)
    assert {"blocks", "program", "model_fit"} <= set(heads)
    for name, cells in heads.items():
        for c in cells:
            assert not KEY.match(c), (name, c)
    assert "contour error MAX with the dwells after it [µm]" in heads["blocks"]
    assert "<div class='table-wrap'><table id='table-blocks'>" in page
