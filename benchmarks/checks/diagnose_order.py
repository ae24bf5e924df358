"""The order check of the diagnosis on a drive whose closed loop has four poles, identified with
the three-pole rigid structure: the diagnosis must say the order is too low (the search's start
point it relies on, and the added pole: tests/test_diagnose_order.py).
"""
import warnings

from checks import check
from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose import diagnose
from fdid_fmi.diagnose.limits import NoteKind
from fdid_fmi.identify import identify_siso
from fdid_fmi.model import DriveModel
from test_diagnose_order import four_pole_trace


@check("tests/test_diagnose_order.py::test_one_pole_short_model_gets_the_order_note")
def one_pole_short_model_gets_the_order_note():
    tr, va = four_pole_trace(1), four_pole_trace(2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = identify_siso(tr, maxiter=10, friction=False)
        d = diagnose(model, tr, va, maxiter=10)
    notes = [n for n in d.notes if n.kind == NoteKind.ORDER_TOO_LOW]
    assert len(notes) == 1 and notes[0].axis == "x"
    # measured: one more real pole lowers the held-out RMS by 43 %
    assert notes[0].statistic >= 0.2
    assert "order is too low" in notes[0].text and "identify with the default structure choice" in notes[0].text
    check = d.rounds[0]["order_check"]
    assert check["criterion_met"] and check["gain_val"]["x"] == notes[0].statistic
    # the note does not change the model, and nothing else was named
    assert d.effects_added == [] and d.final is model
    assert d.to_json()["notes"][0]["kind"] == "order_too_low"
    # a structure fdid identify chose from the data: the note does not advise choosing it again
    chosen = DriveModel.from_dict(model.to_dict())
    chosen.identification["structure_choice"] = {"note": "as fdid identify records it"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (note,) = [n for n in diagnose(chosen, tr, va, maxiter=10).notes if n.kind == NoteKind.ORDER_TOO_LOW]
    assert "chosen on the training data" in note.text and "default structure choice" not in note.text
    # ... and a model diagnosis wrote from it still knows (the refit must keep it)
    r = ag.recipe_from_model(chosen)
    refit = ag.fit(r, tr, search="local", maxiter=2, refine=False)
    assert r.structure_chosen and ag.recipe_from_model(refit).structure_chosen
    assert not ag.recipe_from_model(model).structure_chosen
