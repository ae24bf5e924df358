"""Review of the diagnosis library and the FMU validation path: hostile and careless inputs get one
InputError line or a sane result, and a detector that could not run says so."""
import copy

import numpy as np
import pytest

from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose import diagnose, friction, mode, periodic
from fdid_fmi.diagnose.base import Context
from fdid_fmi.diagnose import limits
from fdid_fmi.diagnose.residuals import residuals
from fdid_fmi.errors import InputError
from fdid_fmi.identify import identify_quasi_static, identify_siso
from fdid_fmi.model import DriveModel
from fdid_fmi.trace import Trace


def _first_order(cmd, Ts, seed=0):
    act = np.empty(cmd.size)
    act[0] = cmd[0]
    a = np.exp(-Ts * 60)
    for k in range(1, cmd.size):
        act[k] = a * act[k - 1] + (1 - a) * cmd[k - 1]
    return act + np.random.default_rng(seed).normal(0, 1e-5, cmd.size)


def _ramp_trace(n=3000, Ts=1e-3, seed=0, source="ramp"):
    """A smooth back-and-forth command and a first-order-lag 'measurement'."""
    t = np.arange(n) * Ts
    tm = np.maximum(t - 0.05, 0.0)
    cmd = 10 * (1 - np.cos(2 * np.pi * 0.7 * tm)) + 2 * np.sin(2 * np.pi * 1.15 * tm) ** 2
    return Trace.from_arrays(t, {"x": {"cmd": cmd, "act": _first_order(cmd, Ts, seed)}}, source=source)


@pytest.fixture(scope="module")
def small():
    tr = _ramp_trace()
    return identify_siso(tr, maxiter=5, friction=False), tr, _ramp_trace(seed=1, source="ramp_val")


# ------------------------------------------------------------------ what diagnose() accepts
def test_diagnose_refuses_a_quasi_static_model_with_one_line(small):
    _, tr, va = small
    qs = identify_quasi_static(tr, ["x"])
    with pytest.raises(InputError, match="pole-search or MIMO model.*not a QuasiStaticModel"):
        diagnose(qs, tr, va)


def test_diagnose_refuses_a_command_that_never_moves(small):
    model, tr, va = small
    still = Trace.from_arrays(tr.t, {"x": {"cmd": np.full(tr.n, 5.0), "act": np.full(tr.n, 5.0)}},
                              source="still.csv")
    # before: every detector saw nothing, and on a still held-out trace rounding noise (1e-9 µm)
    # decided what was kept
    with pytest.raises(InputError, match=r"still.csv, column 'x.cmd'.*never moves in the held-out trace"):
        diagnose(model, tr, still, maxiter=2, max_steps=1)
    with pytest.raises(InputError, match=r"never moves in the training trace"):
        diagnose(model, still, va, maxiter=2, max_steps=1)


@pytest.mark.parametrize("kw, match", [
    (dict(min_gain=float("nan")), "min_gain must be a fraction"),      # never kept anything, silently
    (dict(max_loss=-0.1), "max_loss must be a fraction"),
    (dict(max_steps=0), "max_steps must be an integer >= 1"),           # no round, "nothing found"
    (dict(maxiter=0), "maxiter must be an integer >= 1"),
    (dict(max_delay=1), "max_delay must be an integer >= 2"),           # no dead time could be named
    (dict(max_delay=-1), "max_delay must be an integer >= 2"),          # numpy's argmin of nothing
    (dict(detectors=[]), "no detector given"),                          # ran every detector
])
def test_diagnose_checks_its_options(small, kw, match):
    model, tr, va = small
    with pytest.raises(InputError, match=match):
        diagnose(model, tr, va, **kw)


def test_a_single_channel_name_to_exclude_is_one_name_not_its_letters(small):
    from fdid_fmi.diagnose.loop import _options
    *_, dets, exclude = _options(0.05, 0.01, 1, 2, 6, "friction", "pulses_N")
    assert dets == ["friction"] and exclude == ["pulses_N"]


# ------------------------------------------------------------------ damaged model records
def _with_identification(model, change):
    d = copy.deepcopy(model.to_dict())
    change(d["identification"])
    return DriveModel.from_dict(d, source="edited.json")


@pytest.mark.parametrize("change, match", [
    (lambda i: i["structure"].pop("inputs"), r"record is damaged \(KeyError"),
    (lambda i: i.update(structure="rigid"), r"record is damaged \(TypeError"),
    (lambda i: i.update(real_hz=[float("nan")] * len(i["real_hz"])), "not a positive finite frequency"),
    (lambda i: i.update(real_hz=[]), r"lists \d poles .* but the model has \d"),
])
def test_a_damaged_identification_record_is_one_input_error(small, change, match):
    model, tr, va = small
    bad = _with_identification(model, change)
    with pytest.raises(InputError, match=match):
        ag.recipe_from_model(bad)
    with pytest.raises(InputError, match="column 'identification'"):
        diagnose(bad, tr, va, maxiter=2, max_steps=1)


def test_the_untouched_record_still_gives_a_recipe(small):
    model, _, _ = small
    rec = ag.recipe_from_model(model)
    assert rec.order == len(model.poles)


