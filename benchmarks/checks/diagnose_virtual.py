"""Diagnosis on virtual-drive data with ONE undeclared effect at a time, and on clean data.

Each scenario (``fdid_fmi.diagnose.scenarios``) is a seeded training trace and a held-out trace
with a different move sequence. The model is the SISO pole search fitted on the training trace
(as a user would have it); ``diagnose`` must name the right effect, estimate its parameter, and
lower the held-out RMS by at least the keep criterion (5 %); on clean data nothing is added.
"""
import json
import warnings

import numpy as np
import pytest

from checks import check
from fdid_fmi.diagnose import diagnose
from fdid_fmi.diagnose.limits import NoteKind
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario
from fdid_fmi.diagnose.thresholds import threshold
from fdid_fmi.identify import identify_siso


def _run(name, axis="x", base_maxiter=30, **kw):
    """Few search iterations keep each run short; where the searches do not converge in them, the
    result follows the last bits of the BLAS kernels (AVX2 / AVX-512) and the check gives more."""
    tr, va = scenario(name)
    kw.setdefault("maxiter", 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(tr, axis=axis, maxiter=base_maxiter, integral_action=INTEGRAL_ACTION.get(name, True))
        d = diagnose(m, tr, va, **kw)
    return d, tr


def _default_candidate(tr, label, same_sample):
    """The candidate of ``fdid identify``'s structure choice that it picks on this trace (one fit
    of it instead of the whole choice)."""
    from fdid_fmi.identify.choose_structure import family
    from fdid_fmi.identify.pole_search import identify_mimo
    from fdid_fmi.identify.ranges import training_ranges
    (cand,) = [c for c in family(True) + family(False) if c.label == label]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_mimo(training_ranges(tr, ["x"]), cand.structure("x", same_sample),
                             bounds=cand.bounds(tr.Ts), seed=0)


def _val_gain(d, channel="x"):
    b = d.before["val"][channel]["rms_um"]
    a = d.after["val"][channel]["rms_um"]
    return 1.0 - a / b


@check("tests/test_diagnose_virtual.py::test_clean_data_gets_nothing[{name}]", {'name': 'clean'}, {'name': 'clean_fast'}, {'name': 'clean_xy'}, {'name': 'clean_p'})
def clean_data_gets_nothing(name):
    d, _ = _run(name)
    assert d.effects_added == []
    assert d.final is d.model
    j = d.to_json()
    assert j["effects_added"] == [] and j["before"] == j["after"]
    # no tool-side channel: backlash is reported as not checked, and nothing is suspected
    assert [(n.kind, n.effect) for n in d.notes] == [(NoteKind.NOT_OBSERVABLE, "backlash")]
    assert j["notes"][0]["kind"] == "not_observable"


@check("tests/test_diagnose_virtual.py::test_stribeck")
def stribeck():
    d, tr = _run("stribeck")
    kinds = [e["kind"] for e in d.effects_added]
    assert kinds == ["stribeck"]
    e = d.effects_added[0]
    truth = tr.meta["truth"]["machine"]["axes"][0]
    assert truth["stribeck_velocity"] == 2.0
    assert 0.5 * 2.0 <= e["v_s_mm_s"] <= 2.5 * 2.0           # Stribeck velocity, 2 mm/s
    assert e["ratio_to_coulomb"] > 0                          # breakaway ABOVE Coulomb
    assert _val_gain(d) >= 0.2                                # measured: about 30 %


@check("tests/test_diagnose_virtual.py::test_stribeck_on_the_default_structure")
def stribeck_on_the_default_structure():
    """``fdid identify``'s default choice on this trace is r2c2 (cubic): its second pair takes
    part of the breakaway, and the residual's concentration at motion ends (2.01) falls below
    the largest clean thesis-path value (2.17). The Stribeck gate is a floor (1.0), so
    the refit is tried and the held-out criterion keeps it (measured: 0.396 -> 0.360 um)."""
    tr, va = scenario("stribeck")
    m = _default_candidate(tr, "r2c2", "cubic")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = diagnose(m, tr, va, detectors=["friction"])
    stat = next(c["statistic"] for c in d.rounds[0]["candidates"] if c["kind"] == "stribeck")
    assert threshold("stribeck") <= stat < 2.6          # below the thesis-path clean runs' 2.6: the gate must pass it
    assert [e["kind"] for e in d.effects_added] == ["stribeck"]
    assert d.effects_added[0]["ratio_to_coulomb"] > 0      # breakaway ABOVE Coulomb
    assert _val_gain(d) >= 0.05                            # the keep criterion; measured: 9 %


@check("tests/test_diagnose_virtual.py::test_backlash_on_the_tool_side")
def backlash_on_the_tool_side():
    d, _ = _run("backlash")
    assert [e["kind"] for e in d.effects_added] == ["backlash"]
    e = d.effects_added[0]
    assert e["backlash_mm"] == pytest.approx(0.02, rel=0.25)  # 20 um lost motion
    assert _val_gain(d, "x.tool") >= 0.5                       # measured: about 70 %
    # the motor side is not made worse
    assert d.after["val"]["x"]["rms_um"] <= 1.01 * d.before["val"]["x"]["rms_um"]
    # the model now has a tool-side output fed by the backlash input
    assert d.final.output_index("tool_position", "x") is not None
    assert d.notes == []                                       # the tool side was recorded


@check("tests/test_diagnose_virtual.py::test_position_periodic_force")
def position_periodic_force():
    d, _ = _run("periodic")
    assert [e["kind"] for e in d.effects_added] == ["periodic_position"]
    e = d.effects_added[0]
    assert abs(e["period_mm"] / 5.0 - 1) < 0.02              # within 2 % of the 5 mm pitch
    assert _val_gain(d) >= 0.5                               # measured: about 74 %
    fns = sorted(p.params["function"] for p in d.final.inputs if p.kind == "feature")
    assert fns == ["cos_position", "sin_position"]


@check("tests/test_diagnose_virtual.py::test_unmodelled_mode")
def unmodelled_mode():
    # converged searches: at 30 / 20 iterations the base model and the mode's refit end in
    # different points of a flat valley on AVX2 and AVX-512 (52.6-53.9 Hz); from 60 / 40 on they
    # agree (53.86 Hz)
    d, tr = _run("mode", base_maxiter=60, maxiter=40)
    assert [e["kind"] for e in d.effects_added] == ["mode"]
    e = d.effects_added[0]
    poles = tr.meta["truth"]["linear"]["continuous"]["poles"]
    flex = min((p for p in poles if p["zeta"] < 0.5), key=lambda p: abs(p["hz"] - 55.0))
    assert abs(e["frequency_hz"] / flex["hz"] - 1) < 0.03      # closed-loop mode, 54.2 Hz
    assert abs(e["frequency_hz"] / 55.0 - 1) < 0.03            # the tool-side mode, 55 Hz
    assert e["damping"] < 0.2
    assert _val_gain(d) >= 0.2                                 # measured: 37 %


@check("tests/test_diagnose_virtual.py::test_cross_axis_coupling")
def cross_axis_coupling():
    d, _ = _run("coupling")
    assert [e["kind"] for e in d.effects_added] == ["coupling"]
    e = d.effects_added[0]
    assert e["source_axis"] == "y" and e["channel"] == "y_cmd"
    assert _val_gain(d) >= 0.15                                # measured: about 24 %
    ext = [p for p in d.final.inputs if p.kind == "external"]
    assert [p.params["channel"] for p in ext] == ["y_cmd"]
    # the JSON summary is plain JSON with the required keys
    j = json.loads(json.dumps(d.to_json()))
    assert j["effects_added"][0]["kind"] == "coupling"
    assert set(j["before"]["val"]["x"]) >= {"rms_um", "max_um"}
    assert j["after"]["val"]["x"]["rms_um"] < j["before"]["val"]["x"]["rms_um"]


@check("tests/test_diagnose_virtual.py::test_asymmetric_coulomb_in_a_p_loop")
def asymmetric_coulomb_in_a_p_loop():
    d, _ = _run("asymmetric")
    assert [e["kind"] for e in d.effects_added] == ["asymmetric_friction"]
    e = d.effects_added[0]
    assert e["ratio_to_coulomb"] < 0          # more friction in the negative direction (40 vs 20 N)
    assert _val_gain(d) >= 0.3                # measured: about 56 %


@check("tests/test_diagnose_virtual.py::test_asymmetric_coulomb_under_a_structure_with_integral_action")
def asymmetric_coulomb_under_a_structure_with_integral_action():
    """``fdid identify``'s default choice on the P loop's trace is r1c2 with integral action
    (0.54 um training free run against 1.22-1.47 um without it): it rejects a constant force and
    leaves no offset to see (|t| 0.13). The detector then looks at the model's twin without
    integral action, refitted (|t| 5.7), and the term goes on that twin (measured: 1.10 -> 0.61 um
    held out)."""
    from fdid_fmi.diagnose import augment as ag
    tr, va = scenario("asymmetric")
    m = _default_candidate(tr, "r1c2", "cubic")
    assert ag.has_integral_action(ag.recipe_from_model(m), "x")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = diagnose(m, tr, va, detectors=["friction"])
    (c,) = [c for c in d.rounds[0]["candidates"] if c["kind"] == "asymmetric_friction"]
    assert c["evidence"]["t_p_loop_twin"] >= threshold("asymmetric_friction")
    assert [e["kind"] for e in d.effects_added] == ["asymmetric_friction"]
    assert d.effects_added[0]["ratio_to_coulomb"] < 0      # more friction in the negative direction
    assert not ag.has_integral_action(ag.recipe_from_model(d.final), "x")
    assert _val_gain(d) >= 0.3                             # measured: 44 %


@check("tests/test_diagnose_virtual.py::test_dead_time_statistics_separate_a_delay_from_its_clean_twin[{name}-{delayed}]", {'name': 'delay', 'delayed': True}, {'name': 'clean_soft', 'delayed': False})
def dead_time_statistics_separate_a_delay_from_its_clean_twin(name, delayed):
    """Both dead-time statistics (``delay.py``: the residual's early answer to the command, and
    the refined refits' free run, with the command shifted) on the thesis-path model: the
    3-sample recording delay passes both gates, the same soft loop on the same kind of moves
    without it passes neither. On this 3-pole model the early answer's shift loses to one more
    pole held out (the order check); the free run's, 3 samples, is kept (docs/method.md, section 6)."""
    from fdid_fmi.diagnose import augment as ag, delay
    from fdid_fmi.diagnose.base import Context
    from fdid_fmi.diagnose.residuals import residuals
    tr, _ = scenario(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(tr, axis="x", maxiter=30)
        ctx = Context(model=m, recipe=ag.recipe_from_model(m), train=ag.model_velocity_traces(m, [tr]),
                      res=[residuals(m, tr)], settings={"maxiter": 20})
        early, free = delay.detect(ctx)
    chi2 = early.evidence["early_response_chi2_by_shift"]
    assert free.threshold == pytest.approx(threshold("delay (refined free run)")) and free.from_current and free.search == "local"
    if delayed:     # measured: statistic 176, 4 samples (chi-square 1014 at no shift, 5.8 at 4)
        assert early.detected and early.statistic > 20 * threshold("delay (early answer)")
        assert early.params["samples"] in (3, 4)
        # measured: 1.37 at 3 samples (free run 0.384 um without a shift, 0.280 at 3)
        assert free.detected and free.params["samples"] in (3, 4)
        if free.params == early.params:     # one shift, one trial
            assert free.recipe is None
        else:
            assert free.recipe.delays == {"x": free.params["samples"]}
    else:           # measured: 1.0, no shift helps (5.8 at no shift, 11 at one sample)
        assert not early.detected and early.params["samples"] == 0
        assert min(chi2[1:]) > chi2[0]
        assert np.isfinite(free.evidence["refined_free_run_rms_um_by_shift"]).all() and not free.not_checked
        assert not free.detected            # measured: 1.0, 0.276 um without a shift, 0.280 at one


@check("tests/test_diagnose_virtual.py::test_a_heavily_damped_pair_is_not_named_a_mode")
def a_heavily_damped_pair_is_not_named_a_mode():
    """A mode multiplies every numerator by a quadratic (``augment._times_quadratic``), so a
    heavily damped pair can act as a Padé approximant of a dead time: on the 3-sample recording
    delay the mode's refit would be kept (190 Hz, damping 0.47; held out 11 % better than the
    better of the null refit and one more real pole). A mode is a resonance
    (``base.MODE_MAX_DAMPING``: a 3 dB peak), so that refit is implausible and no mode is named; the order note stays. The
    dead time itself is kept (the refined refits' free run, 3 samples)."""
    from fdid_fmi.diagnose.base import MODE_MAX_DAMPING
    d, _ = _run("delay", detectors=["mode", "delay"], max_steps=1)
    assert [(e["kind"], e.get("samples")) for e in d.effects_added] == [("delay", 3)]
    (mode,) = [t for r in d.rounds for t in r["trials"] if t["kind"] == "mode"]
    assert mode["criterion_met"] and mode["fitted"]["damping"] > MODE_MAX_DAMPING
    assert "not lightly damped" in mode["implausible"]
    assert d.notes[0].kind == NoteKind.ORDER_TOO_LOW
