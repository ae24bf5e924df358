"""The ``suspected`` note (lost motion) on plant2 with the thesis path's models (``identify_siso``,
30 generations): the motor-only backlash still suspected, the largest clean value not
(``diagnose/limits.py``; the statistic's rules: tests/test_diagnose_suspected.py).
"""
import warnings

from checks import check
from fdid_fmi.diagnose import friction
from fdid_fmi.diagnose.limits import REVERSAL_SUSPECT, NoteKind, data_limits
from fdid_fmi.diagnose.residuals import residuals
from fdid_fmi.identify import identify_siso
from plant2 import scenarios as p2


def _thesis_residuals(name, seed):
    train, _, truth = p2.scenario(name, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(train[0], truth["axis"], maxiter=30, seed=0)
    return residuals(m, train[0]), truth["axis"], m.Ts


@check("tests/test_diagnose_suspected.py::test_plant2_motor_only_backlash_still_suspected_and_its_clean_maximum_not")
def plant2_motor_only_backlash_still_suspected_and_its_clean_maximum_not():
    """plant2 (where the gate was set): the motor-only backlash gives 47.1 (thesis path; 28.3 on
    the default path), clean_rigid_2ms seed 2, the largest clean value, 15.95."""
    res, ax, Ts = _thesis_residuals("backlash_motor", 0)
    s = friction.concentration([res], ax, Ts)
    assert s >= 2 * REVERSAL_SUSPECT
    assert [n.kind for n in data_limits([ax], set(), {ax: s}, [])] == [NoteKind.SUSPECTED]
    res, ax, Ts = _thesis_residuals("clean_rigid_2ms", 2)
    s = friction.concentration([res], ax, Ts)
    assert 0.5 * REVERSAL_SUSPECT < s < REVERSAL_SUSPECT
    assert s <= friction.concentration([res], ax, Ts, rest="pooled")
