"""The flat candidate table of a diagnosis (diagnose.reporting.candidate_table, the JSON
summary's ``candidates``): every candidate with its statistic, threshold, held-out gain and
outcome."""
from fdid_fmi.diagnose.loop import Diagnosis
from fdid_fmi.diagnose.reporting import candidate_table


def _cand(kind, stat, thr, params=None, label=None, not_checked=""):
    d = {"kind": kind, "label": label or kind, "axis": "x", "statistic": stat, "threshold": thr,
         "detected": bool(not not_checked and stat >= thr), "params": params or {}, "evidence": {}, "note": ""}
    if not_checked:
        d["not_checked"] = not_checked
    return d


def _rounds():
    cands = [_cand("stribeck", 2.0, 1.0, {"v_s_mm_s": 1.5}),
             _cand("periodic_position", 40.0, 15.0, {"period_mm": 5.0}),
             _cand("mode", 0.1, 0.27),
             _cand("delay", 9.0, 3.0, {"samples": 2}, label="delay (early answer)"),
             _cand("coupling", 0.0, 0.15, not_checked="no other axis"),
             _cand("extra_input", 0.5, 0.15, {"channel": "x_load_N"})]
    trials = [{"kind": "stribeck", "label": "stribeck", "axis": "x", "params": {"v_s_mm_s": 1.5},
               "gain_train": {"x": 0.2}, "gain_val": {"x": 0.08}, "kept": False, "criterion_met": True,
               "implausible": ""},
              {"kind": "periodic_position", "label": "periodic_position", "axis": "x", "params": {"period_mm": 5.0},
               "gain_train": {"x": 0.5}, "gain_val": {"x": 0.4, "x.tool": 0.1}, "kept": True,
               "criterion_met": True, "implausible": ""},
              {"kind": "delay", "label": "delay (early answer)", "axis": "x", "params": {"samples": 2},
               "gain_train": {"x": 0.01}, "gain_val": {"x": 0.01}, "kept": False, "criterion_met": False,
               "implausible": ""}]
    # the extra input was detected but its refit failed
    trials.append({"kind": "extra_input", "label": "extra_input", "axis": "x", "params": {"channel": "x_load_N"},
                   "error": "no feasible refit"})
    return [{"round": 1, "candidates": cands, "trials": trials}]


def test_every_candidate_is_listed_with_its_evidence_and_outcome():
    rows = candidate_table(_rounds())
    by = {r["kind"]: r for r in rows}
    assert len(rows) == 6
    assert by["periodic_position"]["outcome"] == "kept" and by["periodic_position"]["best_gain_val"] == 0.4
    assert by["stribeck"]["outcome"] == "another candidate kept" and by["stribeck"]["gain_val"] == {"x": 0.08}
    assert by["mode"]["outcome"] == "below threshold" and by["mode"]["gain_val"] is None
    assert by["mode"]["statistic"] == 0.1 and by["mode"]["threshold"] == 0.27
    assert by["delay"]["outcome"] == "held-out gain too small" and by["delay"]["label"] == "delay (early answer)"
    assert by["coupling"]["outcome"] == "not checked" and by["coupling"]["not_checked"] == "no other axis"
    assert by["extra_input"]["outcome"] == "refit failed" and not by["extra_input"]["refitted"]
    assert by["extra_input"]["error"] == "no feasible refit"


def test_a_detected_candidate_without_a_trial_is_not_refitted():
    rounds = _rounds()
    rounds[0]["trials"] = []
    by = {r["kind"]: r for r in candidate_table(rounds)}
    assert by["stribeck"]["outcome"] == "not refitted" and by["stribeck"]["best_gain_val"] is None


def test_the_json_summary_carries_the_table():
    d = Diagnosis(model=None, final=None, train=None, val=None, rounds=_rounds(),
                  settings={"min_gain": 0.05, "max_loss": 0.01})
    js = d.to_json()
    assert [c["outcome"] for c in js["candidates"]] == [r["outcome"] for r in candidate_table(_rounds())]
    assert js["candidates"][1]["gain_val"] == {"x": 0.4, "x.tool": 0.1}
