"""Real data: the EMPS drive (train DATA_EMPS, validate DATA_EMPS_PULSES, ``../shared/data/emps``)
with every identifier, the pole search with its default search.

The pole search is told nothing about the controller: it is trained from `qg` and `qm` alone.
The published physics model reaches ~1.8 / 2.2 um RMS (train / test) but needs the controller
law and gains, and its test figure includes the force pulses, which a model driven only by `qg`
cannot know (the ``external`` inputs add them).
"""
import functools

import numpy as np

from checks import ROOT, check
from fdid_fmi.identify import identify_full_ls, identify_quasi_static, identify_siso
from fdid_fmi.io import read_trace
from fdid_fmi.metrics import rms
from fdid_fmi.simulate import simulate

EMPS = ROOT.parent / "shared" / "data" / "emps"


@functools.lru_cache(maxsize=None)
def emps():
    assert EMPS.is_dir(), f"real data folder {EMPS} is absent"
    return read_trace(EMPS / "DATA_EMPS.mat"), read_trace(EMPS / "DATA_EMPS_PULSES.mat")


@functools.lru_cache(maxsize=None)
def models():
    train, _ = emps()
    return {"pole-search": identify_siso(train, "x", integral_action=False, seed=0),
            "full-ls": identify_full_ls(train, "x"),
            "quasi-static": identify_quasi_static(train)}


def position_rms_um(model, trace):
    return rms(simulate(model, trace).axes["x"]["position"] - trace.act("x")) * 1e3


@check("tests/test_identify_emps.py::test_pole_search_on_emps_train")
def pole_search_on_emps_train():
    train, _ = emps()
    m = models()["pole-search"]
    assert max(abs(np.linalg.eigvals(m.A))) < 1
    assert position_rms_um(m, train) < 3.5           # measured 2.7 um (published physics: 1.8)
    # the record starts in motion: the run-up start keeps the first samples close
    first = simulate(m, train).axes["x"]["position"][:50] - train.act("x")[:50]
    assert np.max(np.abs(first)) * 1e3 < 15.0


@check("tests/test_identify_emps.py::test_pole_search_beats_baselines_on_emps")
def pole_search_beats_baselines_on_emps():
    train, _ = emps()
    err = {k: position_rms_um(m, train) for k, m in models().items()}
    assert err["pole-search"] < err["full-ls"] < err["quasi-static"], err


@check("tests/test_identify_emps.py::test_emps_pulses_record_shows_the_unknown_force")
def emps_pulses_record_shows_the_unknown_force():
    _, test = emps()
    err = position_rms_um(models()["pole-search"], test)
    # the pulses are an external force the qg-only model cannot predict: ~94 um
    assert 50.0 < err < 150.0
    # before the first pulse (at 0.344 s) the model still tracks
    quiet = test.slice(0, 0.34)
    assert position_rms_um(models()["pole-search"], quiet) < 15.0
