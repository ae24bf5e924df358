"""Diagnosis on real data (EMPS, ``../shared/data/emps``): a model fitted on DATA_EMPS from ``qg``
only does not know the force pulses of DATA_EMPS_PULSES; the diagnosis must find the unused
``pulses_N`` channel, add it and report the error before and after -- through the CLI, and
reproduced through the FMUs.

The pulses numerator has to be fitted on PULSES data: with no ``--val`` the PULSES record is
split in halves, the first half fits, the second half is held out.
"""
import json
import tempfile
import warnings

import pytest

from checks import ROOT, check
from fdid_fmi.cli import main
from fdid_fmi.identify import identify_siso
from fdid_fmi.io import read_trace

EMPS = ROOT.parent / "shared" / "data" / "emps"


@check("tests/test_diagnose_emps.py::test_emps_pulses_channel_found_and_added")
def emps_pulses_channel_found_and_added(tmp):
    assert EMPS.is_dir(), f"real data folder {EMPS} is absent"
    tr = read_trace(EMPS / "DATA_EMPS.mat")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(tr, integral_action=False, maxiter=30)
    emps_model = tmp / "emps_model.json"
    m.save(emps_model)
    pulses = EMPS / "DATA_EMPS_PULSES.mat"
    out_json, out_html, out_model = tmp / "d.json", tmp / "d.html", tmp / "plus.json"
    scratch = tmp / "tmp"
    scratch.mkdir()
    old_tempdir, tempfile.tempdir = tempfile.tempdir, str(scratch)     # where --fmu's FMUs are exported
    try:
        rc = main(["diagnose", str(emps_model), "--train", str(pulses), "--json", str(out_json),
                   "--report", str(out_html), "-o", str(out_model), "--fmu"])
    finally:
        tempfile.tempdir = old_tempdir
    assert rc == 0
    assert not list(scratch.iterdir())      # the FMUs' folder is removed (none is left per run)
    d = json.loads(out_json.read_text())
    assert [(e["kind"], e["channel"]) for e in d["effects_added"]] == [("extra_input", "pulses_N")]
    before, after = d["before"]["val"]["x"], d["after"]["val"]["x"]
    assert before["rms_um"] > 50                  # the unknown pulses: measured 95.6 um
    assert after["rms_um"] < 5                    # with pulses_N as an input: measured 2.3 um
    assert d["after"]["train"]["x"]["rms_um"] < 5
    # the loop-internal controller output 'vir' was a candidate too, and was not used
    kinds = {(c["kind"], c["params"].get("channel")): c for c in d["rounds"][0]["candidates"]}
    assert not kinds[("extra_input", "vir")]["detected"]
    # the same numbers through the exported FMUs (FMI 2.0 CS, run by fmpy)
    fmu = d["fmu"]
    assert fmu["after"]["val"]["x"]["rms_um"] == pytest.approx(after["rms_um"], rel=1e-6)
    assert fmu["before"]["val"]["x"]["rms_um"] == pytest.approx(before["rms_um"], rel=1e-6)
    assert fmu["after"]["max_abs_diff_reference_mm"] < 1e-9
    # the augmented model carries the channel as an FMU input, and the report is written
    plus = json.loads(out_model.read_text())
    ext = [p for p in plus["inputs"] if p["kind"] == "external"]
    assert [p["params"]["channel"] for p in ext] == ["pulses_N"]
    html = out_html.read_text()
    assert "extra_input" in html and "data:image/png;base64," in html
