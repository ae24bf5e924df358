"""Diagnosis building blocks: delay line, masks, residual sign, position spectrum, events, report."""
import json
import re

import numpy as np
import pytest

from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose.base import motion_events
from fdid_fmi.diagnose.periodic import constant_velocity_segments, position_spectrum
from fdid_fmi.diagnose.residuals import delayed, residuals, split_at_standstill, with_channels
from fdid_fmi.diagnose.whiteness import correlation_tests
from fdid_fmi.errors import InputError
from fdid_fmi.identify import identify_siso
from fdid_fmi.report import Report
from fdid_fmi.simulate import simulate
from fdid_fmi.trace import Trace


def _ramp_trace(n=3000, Ts=1e-3, seed=0):
    """A smooth back-and-forth command and a first-order-lag 'measurement'."""
    t = np.arange(n) * Ts
    tm = np.maximum(t - 0.05, 0.0)                     # at rest for the first 50 samples
    cmd = 10 * (1 - np.cos(2 * np.pi * 0.7 * tm)) + 2 * np.sin(2 * np.pi * 1.15 * tm) ** 2
    act = np.empty(n)
    act[0] = cmd[0]
    a = np.exp(-Ts * 60)
    for k in range(1, n):
        act[k] = a * act[k - 1] + (1 - a) * cmd[k - 1]
    act += np.random.default_rng(seed).normal(0, 1e-5, n)
    return Trace.from_arrays(t, {"x": {"cmd": cmd, "act": act}})


@pytest.fixture(scope="module")
def small_model():
    tr = _ramp_trace()
    return identify_siso(tr, maxiter=10, friction=False), tr


def test_split_without_val_is_at_the_standstill_nearest_the_middle():
    """The held-out part must start at rest (the free run's start): it opens with the last two
    samples of the standstill (every commanded axis still for 50 ms or more) that ends nearest the
    middle, not at the middle while an axis moves; without such a standstill, at the middle."""
    Ts = 1e-3
    t = np.arange(4000) * Ts
    ramp = lambda a, b: np.clip((t - a) / (b - a), 0, 1)
    zero = np.zeros_like(t)
    # every axis still over [1.2, 1.4), [2.1, 2.4) and [2.7, 2.9) s (ends 600, 400, 900 ms from the
    # middle), and over [1.95, 1.98) and [2.47, 2.5), too short; x alone is still over [1.5, 2.5)
    x = 5 * ramp(0.2, 1.2) + ramp(1.4, 1.5) - 2 * ramp(2.5, 2.7) - 2 * ramp(2.9, 3.5)
    y = ramp(1.5, 1.95) + 2 * ramp(1.98, 2.1) + ramp(2.4, 2.47)
    tr = Trace.from_arrays(t, {"x": {"cmd": x, "act": zero}, "y": {"cmd": y, "act": zero},
                               "z": {"act": zero}})            # an axis without a command is no bar
    fit, held, how = split_at_standstill(tr)
    assert held.t[0] == pytest.approx(2.399) and fit.t[-1] == pytest.approx(2.398)
    assert fit.n + held.n == tr.n and "standstill ending at t = 2.4 s" in how
    assert held.cmd("x")[0] == held.cmd("x")[1] and held.cmd("y")[0] == held.cmd("y")[1]
    # x moving on through the middle, no standstill: split at the middle
    tr2 = Trace.from_arrays(t, {"x": {"cmd": 5 * ramp(0.2, 3.8), "act": zero}})
    fit2, held2, how2 = split_at_standstill(tr2)
    assert held2.t[0] == pytest.approx(2.0) and fit2.n + held2.n == tr2.n and "no standstill" in how2
    # a standstill that would leave a part shorter than min_part is not taken
    _, held3, how3 = split_at_standstill(tr, min_part=1700)
    assert "no standstill" in how3 and held3.t[0] == pytest.approx(2.0)


def test_delay_line_delays_position_but_not_error_command(small_model):
    model, tr = small_model
    d = 3
    md = ag.add_command_delay(model, "x", d)
    assert md.n_states == model.n_states + d
    # the delayed model on the command equals the undelayed one on the shifted command (position)
    shifted = with_channels(tr, {"x_cmd": delayed(tr.cmd("x"), d)})
    a = simulate(md, tr, start_velocity={"x": 0.0})
    b = simulate(model, shifted, start_velocity={"x": 0.0})
    assert np.max(np.abs(a.axes["x"]["position"] - b.axes["x"]["position"])) < 1e-9
    # and its error output is the UNDELAYED command minus that position
    e = a.axes["x"]["error"]
    assert np.max(np.abs(e - (tr.cmd("x") - a.axes["x"]["position"]))) < 1e-9
    # a step in the command reaches the position d samples later than without the delay line
    n = 60
    step = {"x": np.r_[np.zeros(10), np.ones(n - 10)]}
    p0 = simulate(model, step, Ts=model.Ts).axes["x"]["position"]
    p1 = simulate(md, step, Ts=model.Ts).axes["x"]["position"]
    assert np.max(np.abs(p1[d:] - p0[:-d])) < 1e-12
    assert np.all(p1[:10 + d] == pytest.approx(0.0, abs=1e-12))


def test_delay_line_rejects_unknown_axis(small_model):
    model, _ = small_model
    with pytest.raises(InputError, match="no command input for axis 'y'"):
        ag.add_command_delay(model, "y", 2)


def test_residual_is_measured_minus_prediction(small_model):
    model, tr = small_model
    r = residuals(model, tr)
    sim = simulate(model, tr)
    assert np.allclose(r.axes["x"].residual, tr.act("x") - sim.axes["x"]["position"])
    tab = r.table()["x"]
    assert tab["rms_um"] == pytest.approx(np.sqrt(np.mean(r.axes["x"].residual ** 2)) * 1e3)


def test_residuals_need_measured_position(small_model):
    model, tr = small_model
    cmd_only = Trace.from_arrays(tr.t, {"x": {"cmd": tr.cmd("x")}})
    with pytest.raises(InputError, match="measured position"):
        residuals(model, cmd_only)


def test_mask_shift_keeps_low_powers_and_extends_full_numerators():
    assert ag._shift_mask({3, 2, 1}, 3, 5) == frozenset({1, 2, 3, 4, 5})   # all but d.c. stays so
    assert ag._shift_mask({1}, 3, 5) == frozenset({1})                      # s/P(s) stays s/P(s)
    assert ag._shift_mask({1, 0}, 3, 5) == frozenset({0, 1})


def test_a_mode_multiplies_every_numerator_by_a_quadratic(small_model):
    assert ag._times_quadratic({1}, 5) == frozenset({1, 2, 3})          # d0 s -> s (d0 + d1 s + d2 s^2)
    assert ag._times_quadratic({3, 2, 1}, 5) == frozenset({1, 2, 3, 4, 5})
    assert ag._times_quadratic({1, 0}, 5) == frozenset({0, 1, 2, 3})    # the d.c. term stays
    assert ag._times_quadratic({4, 1}, 5) == frozenset({1, 2, 3, 4, 5})  # capped at the new order
    _, tr = small_model
    rec = ag.recipe_from_model(identify_siso(tr, maxiter=10))      # with the friction path d0 s
    assert rec.masks == {("x_error", "x_cmd"): {1, 2, 3}, ("x_error", "x_dnf"): {1}}
    r = ag.add_mode(rec, "x", 40.0)
    assert r.order == rec.order + 2
    # the friction path s d0 becomes s (d0 + d1 s + d2 s^2), not s d0 shifted (_shift_mask: {1})
    assert r.masks == {("x_error", "x_cmd"): {1, 2, 3, 4, 5}, ("x_error", "x_dnf"): {1, 2, 3}}


def test_recipe_needs_pole_search_model(small_model):
    model, _ = small_model
    m = model.copy()
    m.identification = {}
    with pytest.raises(InputError, match="pole-search"):
        ag.recipe_from_model(m)


def test_position_spectrum_finds_the_period():
    rng = np.random.default_rng(3)
    pairs = []
    for x0, L, v in ((0.0, 30.0, 0.05), (40.0, 25.0, 0.08), (-35.0, 22.0, 0.03)):
        x = x0 + np.arange(0, L, v)
        r = 1e-3 * np.sin(2 * np.pi * x / 4.2 + rng.uniform(0, 6)) + rng.normal(0, 3e-4, x.size)
        pairs.append((x, r))
    kap, P, dx = position_spectrum(pairs)
    lam = 1 / kap[np.argmax(P)]
    assert abs(lam / 4.2 - 1) < 0.05


def test_constant_velocity_segments_and_events():
    Ts = 1e-3
    t = np.arange(4000) * Ts
    v = np.interp(t, [0, 0.5, 0.6, 1.5, 1.6, 2.0, 2.1, 3.0, 3.1, 4.0], [0, 0, 50, 50, 0, 0, -50, -50, 0, 0])
    x = np.cumsum(v) * Ts
    segs = constant_velocity_segments(x, Ts)
    assert len(segs) == 2
    assert all(b - a > 800 for a, b in segs)
    ev = motion_events(x, Ts)
    kinds = [(k, d) for _, k, d in ev]
    assert kinds == [("start", 1.0), ("stop", 1.0), ("start", -1.0), ("stop", -1.0)]


def test_whiteness_of_white_noise_and_of_a_filtered_one():
    rng = np.random.default_rng(1)
    w = rng.normal(size=20000)
    u = rng.normal(size=20000)
    t = correlation_tests(w, u)
    assert t["acf_outside"] < 0.1 and t["xcf_outside"] < 0.1
    coloured = np.convolve(w, np.ones(20) / 20, mode="same")
    t2 = correlation_tests(coloured, u)
    assert t2["acf_outside"] > 0.3


def test_early_response_chi2_sees_an_answer_in_the_first_lags_only():
    """The dead-time statistic: about M (its degrees of freedom) for a residual that does not
    answer the command, far above it for one that answers within the first M samples, and blind
    to an answer that comes later (that is the poles' business, not a dead time's)."""
    from fdid_fmi.diagnose.delay import early_response_chi2
    rng = np.random.default_rng(3)
    n, Ts, M = 20000, 1e-3, 12
    # a smooth command: filtered random velocity, integrated (mm)
    v = np.convolve(rng.normal(size=n), np.hanning(40) / 20, mode="same")
    cmd = np.cumsum(v) * 1e-2
    noise = np.cumsum(rng.normal(0, 1e-5, n))           # white increments
    du = np.diff(cmd, prepend=cmd[0])

    def answering(lag, gain=0.01):                      # residual increments answer du at a lag
        return noise + np.cumsum(np.concatenate([np.zeros(lag), gain * du[:n - lag]]))

    assert 0.3 * M < early_response_chi2(cmd, noise, Ts, M) < 2.5 * M
    assert early_response_chi2(cmd, answering(2), Ts, M) > 50 * M
    assert early_response_chi2(cmd, answering(M + 5), Ts, M) < 2.5 * M
    # too short a record for the FIR (4 x 100 lags at 1 ms): nan, not a number from nothing
    assert np.isnan(early_response_chi2(cmd[:300], noise[:300], Ts, M))


def test_early_response_chi2_keeps_its_accuracy_on_a_jerk_limited_command_with_dwells():
    """Jerk-limited moves with 0.5 s pauses at 0.5 ms (62 % of the command's increments exactly 0)
    make the FIR's regressors ill-conditioned (cond ~4e7): the normal equations lose up to 10x on
    a null chi-square there (1.0 against 11.2). Against a dense QR."""
    from numpy.lib.stride_tricks import sliding_window_view
    from fdid_fmi.diagnose.delay import EarlyResponse, fir_length
    from fdid_fmi.virtual.trajectories import linear_moves
    Ts, M = 5e-4, 12
    cmd = linear_moves(n_moves=8, d_min=5.0, d_max=40.0, v=200.0, acc=2000.0, jerk=1e5, Ts=Ts,
                       pause=(0.5, 0.5), seed=0).positions["x"]
    L = fir_length(Ts, M)
    A = np.ascontiguousarray(sliding_window_view(np.diff(cmd), L))     # tested lags last
    Q, R = np.linalg.qr(A)
    test = EarlyResponse(cmd, Ts, M)
    for seed in range(3):
        r = np.random.default_rng(seed).normal(0, 1e-5, cmd.size)
        b = np.diff(r)[L - 1:]
        h = np.linalg.solve(R, Q.T @ b)
        e = b - A @ h
        reference = float(np.sum((R[-M:, -M:] @ h[-M:]) ** 2) / (e @ e / (b.size - L)))
        assert test.chi2(r) == pytest.approx(reference, rel=1e-6)
    assert np.isnan(test.chi2(np.r_[np.nan, np.zeros(cmd.size - 1)]))     # not finite: no number


def test_report_is_self_contained_html_with_figure_data(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rep = Report("a test report", meta={"who": "tests"})
    rep.add_text("first paragraph <b>escaped</b>\n\nsecond", heading="Summary")
    rep.add_table("errors", [{"trace": "val", "RMS [µm]": 1.23456}], caption="table caption")
    fig, ax = plt.subplots()
    ax.plot([0, 1, 2], [1, 0, 1])
    rep.add_figure("curve", fig, data={"x": np.array([0, 1, 2]), "y": [1.0, 0.0, float("nan")]})
    path = rep.write(tmp_path / "r.html")
    text = path.read_text()
    assert "data:image/png;base64," in text
    assert "&lt;b&gt;escaped&lt;/b&gt;" in text and "<b>escaped" not in text
    assert "src='http" not in text and "<link" not in text        # nothing external
    blob = re.search(r"<script type='application/json' id='report-data'>(.*?)</script>", text, re.S).group(1)
    data = json.loads(blob)
    assert data["figures"]["curve"]["data"]["x"] == [0, 1, 2]
    assert data["figures"]["curve"]["data"]["y"][2] is None
    assert data["tables"]["errors"]["rows"][0][1] == pytest.approx(1.23456)
    j = json.loads(rep.write_json(tmp_path / "r.json").read_text())
    assert j["title"] == "a test report"


def test_report_data_survives_hostile_text_and_never_writes_through_a_symlink(tmp_path):
    """A meta value '<!--<script>' does not leave the embedded JSON unclosed, and
    ``Report.write`` does not follow a symlink at the output path onto the file it points to."""
    evil = "run <!--<script> A </script>"
    rep = Report("t", meta={"source": evil})
    text = rep.html()
    blob = re.search(r"<script type='application/json' id='report-data'>(.*?)</script>", text, re.S).group(1)
    assert "<" not in blob and json.loads(blob)["meta"]["source"] == evil
    target = tmp_path / "input_trace.csv"
    target.write_text("t_s,x_cmd_mm,x_mm\n")
    link = tmp_path / "report.html"
    link.symlink_to(target)
    rep.write(link)
    assert target.read_text() == "t_s,x_cmd_mm,x_mm\n"          # the link is replaced, not followed
    assert not link.is_symlink() and "report-data" in link.read_text()


def test_refits_keep_the_users_locked_poles():
    """A pole the user locked (``--lock-complex``) stays locked in every refit of the diagnosis:
    searched in none, and read back as locked after a refit (the old recipe searched it)."""
    from fdid_fmi.identify import identify_mimo, mimo_structure
    tr = _ramp_trace()
    st = mimo_structure(("x",), ("error",), n_real=1, n_complex=0, friction=False,
                        locked_complex=[(30.0, 0.3)], same_sample="hold")
    m = identify_mimo(tr, st, maxiter=3, refine=False)
    r = ag.recipe_from_model(m)
    assert r.complex_hz_zeta == [] and r.locked_complex == [(30.0, 0.3)] and r.order == 3
    for search in ("local", "wide", "locked"):
        s2, n_real, n_cplx = ag.structure_of(r, search)
        assert n_cplx == 0 and (30.0, 0.3) in [tuple(c) for c in s2.locked_complex], search
        assert len(ag._bounds(r, tr.Ts, search).omega_hz) == 0, search
    refit = ag.fit(r, tr, maxiter=2, refine=False)
    assert refit.identification["locked_complex"] == [[30.0, 0.3]]
    r2 = ag.updated_recipe(r, refit)
    assert r2.complex_hz_zeta == [] and r2.locked_complex == [(30.0, 0.3)] and len(r2.real_hz) == 1
    locked = ag.fit(r2, tr, search="locked", refine=False)
    assert ag.updated_recipe(r2, locked).real_hz == r2.real_hz


def test_a_scan_point_without_a_feasible_refit_is_inf_not_the_end(small_model):
    """One grid point of a Stribeck or period scan whose refit the pole search cannot make
    (InputError) scores inf; the scan and the diagnosis go on."""
    from fdid_fmi.diagnose.base import scan_refine
    model, tr = small_model
    r = ag.recipe_from_model(model)
    bad = r.copy()
    bad.same_sample = "none such"           # the engine refuses it with an InputError
    with pytest.raises(InputError):
        ag.fit(bad, tr, maxiter=2, refine=False)
    assert ag.fit_objective(bad, tr, maxiter=2, refine=False) == np.inf
    ok = ag.fit_objective(r, tr, maxiter=2, refine=False)
    assert np.isfinite(ok)
    best, vals = scan_refine(lambda x: ag.fit_objective(bad if x < 1 else r, tr, maxiter=2, refine=False),
                             np.array([0.0, 1.0]))
    assert best == 1.0 and vals[0] == np.inf


def test_local_windows_keep_a_slow_pole_where_it_is(small_model):
    """A real pole below the 0.05 Hz floor (user bounds allow it) is searched around itself, not
    near Nyquist; ordinary poles keep the floor and the cap."""
    model, tr = small_model
    r = ag.recipe_from_model(model)
    r.real_hz = [0.01] + list(r.real_hz)[1:]
    lo, hi = ag._bounds(r, tr.Ts, "local").real_hz[0]
    assert (lo, hi) == (0.005, 0.02)
    assert ag._window(1.0, 2.0, 400.0) == (0.5, 2.0) and ag._window(0.06, 2.0, 400.0) == (0.05, 0.12)
    assert ag._window(300.0, 2.0, 400.0) == (150.0, 400.0)


def test_the_whole_trace_refit_is_not_taken_when_a_kept_effect_becomes_implausible():
    """Without --val the kept effects are refitted on the whole trace; a refit that damps a kept
    mode's pair beyond a resonance (or turns a Stribeck excess negative) would relabel it as
    what it is not, so it is not taken, however much better it predicts."""
    from fdid_fmi.diagnose.loop import whole_refit_taken
    mode = {"kind": "mode", "axis": "x", "frequency_hz": 49.4, "damping": 0.22}
    assert whole_refit_taken({"x": 0.10}, [mode], 0.01) == (True, "")
    assert not whole_refit_taken({"x": -0.02, "y": 0.3}, [mode], 0.01)[0]     # one channel worse
    assert not whole_refit_taken({"x": 0.0}, [mode], 0.01)[0]                 # better on none
    taken, why = whole_refit_taken({"x": 0.10}, [mode, dict(mode, damping=0.45)], 0.01)
    assert not taken and why.startswith("mode: ") and "not lightly damped" in why
    taken, why = whole_refit_taken({"x": 0.10}, [{"kind": "stribeck", "ratio_to_coulomb": -0.1}], 0.01)
    assert not taken and why.startswith("stribeck: ")
