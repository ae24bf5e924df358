"""The detectors' threshold table (diagnose.thresholds): the quantile rule that sets a threshold
from a false-alarm rate on clean statistics, the table every detector reads, and the loop's
trials below a threshold, recorded as such in the candidate table."""
import math

import numpy as np
import pytest

from fdid_fmi.diagnose import diagnose, loop, thresholds
from fdid_fmi.diagnose.reporting import candidate_table
from fdid_fmi.diagnose.thresholds import THRESHOLDS, Threshold, key, quantile_threshold, threshold
from fdid_fmi.diagnose.whiteness import structured_share
from fdid_fmi.identify import identify_siso
from fdid_fmi.trace import Trace
from small_plants import first_order_lag


def test_at_most_the_stated_share_of_clean_values_pass():
    rng = np.random.default_rng(0)
    for n, rate in ((40, 0.05), (60, 0.05), (100, 0.1), (41, 0.05), (7, 0.2)):
        v = rng.lognormal(size=n)
        thr, k, used = quantile_threshold(v, rate)
        assert used == n and k == math.floor(rate * n)
        assert np.sum(v >= thr) == k            # exactly k pass: the midpoint of the two order statistics
        s = np.sort(v)[::-1]
        assert s[k] < thr < (s[k - 1] if k else np.inf)
        if k:
            assert thr == pytest.approx(0.5 * (s[k] + s[k - 1]))


def test_too_few_values_for_the_rate_put_the_threshold_above_the_largest():
    thr, k, n = quantile_threshold([1.0, 2.0, 4.0], 0.05)
    assert (k, n) == (0, 3) and thr == pytest.approx(4.0 * (1 + thresholds.TOP_MARGIN))


def test_ties_across_the_cut_and_non_finite_values():
    thr, k, n = quantile_threshold([3.0, 3.0, 1.0, 1.0] + [0.5] * 16 + [np.nan, None, np.inf], 0.05)
    assert (k, n) == (1, 20)                    # nan, None and inf left out
    assert thr > 3.0                            # the tied pair stays below: fewer than k pass
    assert quantile_threshold([], 0.05)[1:] == (0, 0) and math.isnan(quantile_threshold([], 0.05)[0])
    with pytest.raises(ValueError):
        quantile_threshold([1.0], 1.0)


def test_every_entry_states_where_it_comes_from():
    for k, t in THRESHOLDS.items():
        assert isinstance(t, Threshold) and t.value > 0 and t.source and t.statistic
        assert (t.rate is None) == (t.n_clean == 0), k      # a rate is measured on some clean cases
        if t.rate is not None:
            assert 0 < t.rate < 1 and t.n_clean >= 1
    assert key("coupling") == key("extra_input") == "channel"
    assert threshold("mode") == THRESHOLDS["mode"].value
    assert threshold("mode", {"thresholds": {"mode": 0.5}}) == 0.5
    assert threshold("coupling", {"thresholds": {"channel": np.inf}}) == np.inf


def test_structured_share_of_white_and_of_slow_residuals():
    rng = np.random.default_rng(1)
    white = rng.normal(size=20000)
    assert structured_share(white) < 0.03
    slow = np.sin(np.linspace(0, 20, 20000)) + 0.01 * white
    assert structured_share(slow) > 0.99
    assert structured_share(np.zeros(10)) == 0.0


def _trace(seed, n=3000, Ts=1e-3):
    """A smooth back-and-forth command, a first-order-lag measurement and a channel that does not
    act on it (a candidate input whose R^2 is small)."""
    t = np.arange(n) * Ts
    tm = np.maximum(t - 0.05, 0.0)
    cmd = 10 * (1 - np.cos(2 * np.pi * 0.7 * tm)) + 2 * np.sin(2 * np.pi * 1.15 * tm) ** 2
    load = np.random.default_rng(seed + 10).normal(size=n).cumsum()
    return Trace.from_arrays(t, {"x": {"cmd": cmd, "act": first_order_lag(cmd, Ts, seed)}}, extra={"x_load_N": load},
                             source=f"ramp{seed}")


@pytest.fixture(scope="module")
def ramp():
    tr = _trace(0)
    return identify_siso(tr, maxiter=5, friction=False), tr, _trace(1)


def test_a_candidate_below_its_threshold_is_tried_when_the_held_out_residual_is_structured(ramp, monkeypatch):
    model, tr, va = ramp
    monkeypatch.setattr(loop, "UNEXPLAINED_SHARE", 0.0)         # every residual counts as structured
    monkeypatch.setattr(loop, "MIN_BELOW_RATIO", 0.0)           # however far below its threshold
    monkeypatch.setitem(THRESHOLDS, "channel", Threshold(0.999, None, 0, "test", "R^2"))
    d = diagnose(model, tr, va, detectors=["coupling"], maxiter=2, max_steps=1, below_trials=3)
    (trial,) = d.rounds[0]["trials"]
    assert trial["below_threshold"]
    if trial["criterion_met"]:       # below its threshold a kept effect also gains on training
        assert max(trial["gain_train"].values()) >= 0.05
    (row,) = [r for r in candidate_table(d.rounds) if r["kind"] == "extra_input"]
    assert not row["detected"] and row["tried_below_threshold"] and row["refitted"]
    assert row["outcome"] != "below threshold" and row["gain_val"] is not None
    assert d.rounds[0]["unexplained_share"] >= 0.0
    assert d.to_json()["candidates"][0]["tried_below_threshold"]
    # no trials below the thresholds (the default): the candidate is only listed
    d0 = diagnose(model, tr, va, detectors=["coupling"], maxiter=2, max_steps=1)
    (row0,) = [r for r in candidate_table(d0.rounds) if r["kind"] == "extra_input"]
    assert row0["outcome"] == "below threshold" and not row0["tried_below_threshold"] and not d0.rounds[0]["trials"]


@pytest.mark.parametrize("share, ratio", [(1.01, 0.0), (0.0, 1.0)])
def test_a_white_held_out_residual_or_a_weak_statistic_tries_nothing_below_the_thresholds(
        ramp, monkeypatch, share, ratio):
    model, tr, va = ramp
    monkeypatch.setattr(loop, "UNEXPLAINED_SHARE", share)       # 1.01: no residual is that structured
    monkeypatch.setattr(loop, "MIN_BELOW_RATIO", ratio)         # 1.0: every candidate below it is too weak
    monkeypatch.setitem(THRESHOLDS, "channel", Threshold(0.999, None, 0, "test", "R^2"))
    d = diagnose(model, tr, va, detectors=["coupling"], maxiter=2, max_steps=1, below_trials=3)
    assert not d.rounds[0]["trials"]
    assert [r["outcome"] for r in candidate_table(d.rounds)] == ["below threshold"]


def test_below_trials_is_checked(ramp):
    from fdid_fmi.errors import InputError
    model, tr, va = ramp
    with pytest.raises(InputError, match="below_trials must be an integer >= 0"):
        diagnose(model, tr, va, below_trials=-1)
