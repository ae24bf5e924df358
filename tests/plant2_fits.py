"""Models fitted on plant2 scenarios that several test files share (fitted once per process)."""
import functools
import warnings

from fdid_fmi.identify import identify_mimo, mimo_structure
from plant2 import scenarios as p2


@functools.lru_cache(maxsize=None)
def backlash_tool_r1c1():
    """plant2 ``backlash_tool``: (training trace, reversals trace, truth, model), the model the
    default MIMO r1c1 of error and tool position with hold (seed 0, 20 generations)."""
    train, vals, truth = p2.scenario("backlash_tool")
    va = next(v for v in vals if v.meta["name"] == "reversals")
    st = mimo_structure(("x",), ("error", "tool_position"), n_real=1, n_complex=1, same_sample="hold")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_mimo(train[0], st, seed=0, maxiter=20)
    return train[0], va, truth, m
