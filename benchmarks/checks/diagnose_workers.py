"""A diagnosis's refits in worker processes (``diagnose(workers=N)``, ``fdid diagnose --jobs N``)
give the same diagnosis as in one process, bit for bit when this process runs BLAS on one thread
as the workers do (the final models of a kept effect: ``benchmarks/bench_diagnose.py``)."""
import json
import warnings

from checks import check
from fdid_fmi.diagnose import diagnose
from fdid_fmi.diagnose.scenarios import scenario
from fdid_fmi.identify import identify_siso


def _summary(d):
    j = d.to_json()
    j.pop("wall_time_s")
    return json.dumps(j, sort_keys=True)


@check("tests/test_diagnose_workers.py::test_two_workers_give_the_same_diagnosis_as_one")
def two_workers_give_the_same_diagnosis_as_one():
    # the delay scenario exercises every parallel path: the dead time's shifts, the Stribeck
    # velocity's grid in both friction laws and the play's widths, the null refit and the trials
    # (the play law's and the dead time's with their references); the whole first round is
    # compared. Few search iterations: the property does not need converged searches
    tr, va = scenario("delay")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(tr, axis="x", maxiter=8)
        one, two = (diagnose(m, tr, va, maxiter=3, max_steps=1, workers=w) for w in (1, 2))
    trials = {(t["kind"], t["params"].get("law")) for t in two.rounds[0]["trials"]}
    assert {("stribeck", None), ("stribeck", "play"), ("delay", None)} <= trials
    # every statistic, fitted parameter and gain, to the last bit (the JSON writes floats exactly)
    assert _summary(one) == _summary(two)
