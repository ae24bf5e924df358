"""``fdid diagnose`` takes every model ``fdid identify`` writes.

* A two-axis trace gives a combined per-axis model (``DriveModel.combine``); diagnosis splits it
  into its blocks (here) and diagnoses each on its own axis and combines the results again (the
  checks of ``benchmarks/bench_end_to_end.py``, ``checks/diagnose_combined.py``).
* A model fitted on a tool-side acceleration (two integrators, predicts ``tool_position``) is a
  tool-side model: the backlash effect goes on its fitted output instead of failing for want of
  a tracking-error output.
* Quasi-static and Full-LS models are refused in one line naming the file and ``identification``.

Data: the ``coupling`` scenario (two axes, force on x = 0.02 kg times y's commanded
acceleration) and the ``backlash`` scenario, both with 6 moves (seconds of CPU, not minutes).
"""
import warnings
from pathlib import Path

import numpy as np
import pytest

from cli_support import write_positions_csv
from fdid_fmi.cli import main
from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose import diagnose
from fdid_fmi.diagnose.loop import split_blocks
from fdid_fmi.diagnose.residuals import with_channels
from fdid_fmi.diagnose.scenarios import scenario
from fdid_fmi.model import DriveModel, load_model


@pytest.fixture(scope="module")
def two_axis(tmp_path_factory):
    """(train trace, held-out trace, train CSV, model JSON from ``fdid identify``).

    The model is stored (``tests/data/make_fitted_models.py``): ``fdid identify`` on this CSV with
    its default method and structure choice (pole search, structure chosen per axis, combined
    per-axis model), only the DE iterations cut (``--maxiter 5``).
    """
    d = tmp_path_factory.mktemp("combined")
    tr, va = scenario("coupling", n_moves=6)
    write_positions_csv(tr, d / "train.csv")
    return tr, va, d / "train.csv", Path(__file__).parent / "data" / "coupling_two_axis_model.json"


def test_split_blocks_round_trip(two_axis):
    m = load_model(two_axis[3])
    blocks = split_blocks(m)
    assert [b.axes for b in blocks] == [["x"], ["y"]]
    assert sum(len(b.poles) for b in blocks) == len(m.poles)
    for b in blocks:            # each block's continuous poles are poles of its own A (Tustin map)
        z = np.linalg.eigvals(b.A)
        zp = [(1 + p * b.Ts / 2) / (1 - p * b.Ts / 2) for p in b.poles]
        assert zp and all(np.min(np.abs(z - q)) < 1e-6 for q in zp)
    assert DriveModel.combine(blocks, method=m.method).to_dict() == m.to_dict()


@pytest.mark.parametrize("method", ["quasi-static", "full-ls"])
def test_other_methods_refused_in_one_line(two_axis, tmp_path, capsys, method):
    _, _, csv, _ = two_axis
    mpath = tmp_path / f"{method}.json"
    assert main(["identify", str(csv), "--method", method, "-o", str(mpath)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(mpath), "--train", str(csv)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]
    assert str(mpath) in err[0] and "identification" in err[0] and "pole-search" in err[0]


# ----------------------------------------------------------------- tool-side acceleration
@pytest.fixture(scope="module")
def acc_model():
    """Backlash scenario with a tool-side acceleration channel (second difference of the tool
    position); model fitted on that acceleration with two integrators (predicts tool_position)."""
    from fdid_fmi.identify import identify_mimo, mimo_structure
    tr, va = scenario("backlash", n_moves=6)

    def with_acc(t):
        a = np.gradient(np.gradient(t.get("x", "tool"), t.Ts), t.Ts)
        t2 = with_channels(t, {"x_acc": a})
        t2.roles["x"]["acc"] = "x_acc"
        return t2

    tr, va = with_acc(tr), with_acc(va)
    st = mimo_structure(("x",), ("acceleration",), 1, 1, integrators={"acceleration": 2},
                        same_sample="hold", dc_gain={"acceleration": (2, 1.0)})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_mimo(tr, st, seed=0, maxiter=15)
    return m, tr, va


def test_acceleration_fit_is_a_tool_side_output(acc_model):
    m, tr, _ = acc_model
    assert m.output_index("tool_position", "x") is not None
    recipe = ag.recipe_from_model(m)
    (acc,) = recipe.outputs
    assert acc.kind == "acceleration" and acc.predicts == "tool_position" and ag.is_tool_side(acc)
    # no tool_error output is added: the fitted acceleration already predicts the tool side
    assert [o.name for o in ag.add_tool_output(recipe, "x").outputs] == [acc.name]
    r = ag.add_backlash(recipe, "x", recipe.v_tilde["x"])
    inp = r.inputs[-1].name
    assert r.masks[(acc.name, inp)]                          # the backlash feeds the tool side
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fitted = ag.fit(r, ag.model_velocity_traces(m, [tr]), search="locked", refine=False)
    e = ag.describe_fitted(fitted, fitted.effects[-1])
    assert e["kind"] == "backlash" and e["output"] == acc.name
    assert np.isfinite(e["backlash_mm"]) and e["backlash_mm"] >= 0
    _, _, G1 = fitted.steady_state_maps()
    j, i = fitted.output_index("tool_position", "x"), fitted.input_index("feature", "x", name=inp)
    assert G1[j, i] != 0                                     # a d.c. offset per direction


def test_diagnose_acceleration_model_does_not_raise(acc_model):
    m, tr, va = acc_model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = diagnose(m, tr, va, detectors=["friction"], max_steps=1, maxiter=5)
    # the tool side is scored (measured tool channel vs. the integrated acceleration fit)
    assert "x.tool" in d.before["val"]
    cands = [c for r in d.rounds for c in r["candidates"] if c["kind"] == "backlash"]
    assert cands and cands[0]["axis"] == "x"
    for r in d.rounds:                                      # a refit that raised is recorded so
        assert not any("error" in t for t in r["trials"]), r["trials"]
