"""Diagnosis on the second plant (``tests/plant2``): the rules of the notes on what the data cannot
show or only suggest (``diagnose.limits``), the lost motion a tool-side model carries, the locked
refit of a backlash, and the dead-time statistic's edge rule.

The diagnosis runs on this plant (backlash with and without the tool-side channel, the
``suspected`` note, Stribeck in the play law, the mode, the dead time on the stored default
models, the refits judged without a held-out trace) are checks of ``benchmarks/bench_end_to_end.py``
(``checks/diagnose_plant2.py``).
"""
import warnings

import numpy as np
import pytest

from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose.residuals import residuals
from fdid_fmi.diagnose.limits import (LOST_MOTION_NOTE_MM, REVERSAL_SUSPECT, NoteKind, data_limits,
                                      lost_motion_carried)
from fdid_fmi.identify import identify_mimo, mimo_structure
from plant2 import scenarios as p2


def test_rules():
    conc = {"x": 2 * REVERSAL_SUSPECT, "y": 0.5 * REVERSAL_SUSPECT}
    notes = data_limits(["x", "y"], set(), conc, [])
    assert [(n.kind, n.axis) for n in notes] == [(NoteKind.SUSPECTED, "x"), (NoteKind.NOT_OBSERVABLE, "y")]
    assert notes[0].statistic == 2 * REVERSAL_SUSPECT and "tool-side" in notes[0].text
    # a kept Stribeck term explains the concentration; a tool channel lets the detector decide
    assert data_limits(["x"], set(), conc, [{"kind": "stribeck", "axis": "x"}])[0].kind == NoteKind.NOT_OBSERVABLE
    assert data_limits(["x"], {"x"}, conc, []) == []
    assert data_limits(["x"], set(), {}, [])[0].kind == NoteKind.NOT_OBSERVABLE   # friction detector not run
    # a tool channel: the lost motion the model carries is reported above LOST_MOTION_NOTE_MM only,
    # and not beside a kept backlash
    carried = data_limits(["x"], {"x"}, {}, [], {"x": 2 * LOST_MOTION_NOTE_MM})
    assert [(n.kind, n.effect) for n in carried] == [(NoteKind.CARRIED, "backlash")]
    assert "10.0 µm" in carried[0].text
    assert data_limits(["x"], {"x"}, {}, [], {"x": 0.5 * LOST_MOTION_NOTE_MM}) == []
    assert data_limits(["x"], {"x"}, {}, [{"kind": "backlash", "axis": "x"}], {"x": 0.02}) == []


def _without_tool_dc(st):
    """``st`` with the friction's d.c. gain to the tool side taken out (its default carries the
    lost motion: ``structure.default_mask``): a model whose tool side lacks the backlash."""
    for (o, i), terms in st.mask.items():
        if o.endswith("tool_position") and i.endswith("dnf"):
            st.mask[(o, i)] = terms[:-1]
    return st


def _true_lost_motion(truth):
    """The plant's lost motion between motor and tool (mm): its backlash plus the elastic
    deflection of the drive train by the tool side's share of the Coulomb friction, both ways."""
    a = truth["machine"]["axes"][truth["axis"]]
    return a["backlash"] + 2 * a["table_share"] * a["coulomb"] / a["coupling_stiffness_N_mm"]


def test_the_friction_to_the_tool_side_carries_the_lost_motion():
    """With integral action the motor side has no friction d.c. gain, the tool side does: the
    default structure reads the lost motion as 2 level |G_tool - G_motor| (measured: 16.4 µm
    against the plant's 16.0 µm, 15 µm of backlash and 1.0 µm of elastic deflection), also
    without integral action, where the motor lags too (16.5 µm), and predicts both outputs together
    held out far better than the same structure without that d.c. term (measured on the
    reversals: tool side 3.14 against 7.88 µm RMS; the motor side, whose poles it shares, 1.18
    against 1.04 µm)."""
    train, vals, truth = p2.scenario("backlash_tool")
    va = next(v for v in vals if v.meta["name"] == "reversals")
    true = _true_lost_motion(truth)
    rms_um = {}
    for with_dc, ia in ((True, True), (False, True), (True, False)):
        st = mimo_structure(("x",), ("error", "tool_position"), n_real=1, n_complex=1, same_sample="hold",
                            integral_action=ia)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = identify_mimo(train[0], st if with_dc else _without_tool_dc(st), seed=0, maxiter=20)
        if with_dc:
            assert lost_motion_carried(m, "x") == pytest.approx(true, rel=0.1)
        # a backlash feature sat(v/v_b) at v_b = v_tilde would be the friction's own d.c.
        # regressor on the tool side (the LS split the lost motion between them, each at half
        # its size): the detector does not refit it there
        assert ag.carries_lost_motion(ag.recipe_from_model(m), "x") == with_dc
        if ia:
            rms_um[with_dc] = residuals(m, va).table()
    both = {k: np.hypot(r["x"]["rms_um"], r["x.tool"]["rms_um"]) for k, r in rms_um.items()}
    assert both[True] <= 0.6 * both[False]
    # the friction input is level * sat(v/v_tilde): half the level, half the lost motion
    i = m.input_index("friction", "x")
    half = m.copy()
    half.inputs[i].params["level"] = 0.5 * m.inputs[i].params.get("level", 1.0)
    assert lost_motion_carried(half, "x") == pytest.approx(0.5 * lost_motion_carried(m, "x"), rel=1e-12)


def test_locked_refit_keeps_what_the_effect_does_not_feed():
    """A model that already predicts the tool side, but not its lost motion: the backlash input
    feeds that output, which must keep the refit's path; the motor side keeps the given model's
    prediction (measured: held-out tool side 7.88 -> 5.98 µm, motor side 1.036 µm before and
    after)."""
    train, vals, _ = p2.scenario("backlash_tool")
    va = next(v for v in vals if v.meta["name"] == "reversals")
    st = _without_tool_dc(mimo_structure(("x",), ("error", "tool_position"), n_real=1, n_complex=1,
                                         same_sample="hold"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_mimo(train[0], st, seed=0, maxiter=20)
        rec = ag.recipe_from_model(m)
        fitted = ag.fit(ag.add_backlash(rec, "x", rec.v_tilde["x"]), ag.model_velocity_traces(m, train[:1]),
                        search="locked", refine=False)
    composed = ag.keep_base_outputs(m, fitted)
    assert composed is not fitted
    before, after = residuals(m, va).table(), residuals(composed, va).table()
    assert after["x"]["rms_um"] == pytest.approx(before["x"]["rms_um"], rel=1e-6)
    assert after["x.tool"]["rms_um"] <= 0.85 * before["x.tool"]["rms_um"]


def test_a_best_shift_on_the_edge_of_the_range_is_no_dead_time():
    from fdid_fmi.diagnose.delay import shift_statistic
    assert shift_statistic([1.2, 1.0, 1.05]) == (1, 1.2, False)
    # the free run still falls at the largest shift tried: no estimate, statistic 1
    assert shift_statistic([1.3, 1.1, 1.0]) == (2, 1.0, True)
    assert shift_statistic([1.0, 1.1, 1.2]) == (0, 1.0, False)        # no shift helps
    assert shift_statistic([float("inf"), 1.0, 1.1]) == (1, 1.0, False)
