"""Friction at velocity reversals beyond the model's: Stribeck, asymmetric Coulomb, backlash.

Events are the starts, stops and reversals of the commanded motion (:func:`.base.motion_events`).

Stribeck (breakaway above Coulomb)
    Statistic: concentration of the residual energy in short windows (``WINDOW_S``) after each
    start / stop, mean(r^2 in windows) / mean(r^2 elsewhere). A breakaway force acts at low
    speed only, so its residual sits at the ends of each move; white-ish noise gives ~1.
    Parameter v_s (mm/s): the Stribeck velocity minimising the LS objective of a quick refit (poles
    in a local window), over a 7-point log grid from 2 v_tilde to 0.2 max|v|, parabola-refined.
    The term is the friction law's: s exp(-(v / v_s)^2) with s = sat(v / v_tilde), or with s the
    play on a play-law axis. A sat-law axis gets a second candidate in the play law
    (:func:`_play_law_candidate`): a breakaway that holds the axis at rest (LuGre's, plant2's)
    acts through presliding, which sat(v / v_tilde) cannot carry (its refit was worse in free
    run there). That candidate must also beat the play law without the Stribeck term
    (``reference``), so what the law change alone gains is never credited to a Stribeck effect.
Asymmetric Coulomb
    Statistic: |t| of the direction-independent mean residual over moves (a friction level that
    differs by direction acts as a force offset that does not change sign at a reversal):
    t = mean(m_e) / (std(m_e) / sqrt(n_e)), m_e = mean residual while moving in move e. With
    integral action in the loop the offset is rejected and nothing is left to see; P/PD loops
    (EMPS) keep it. A model with integral action (its friction without a d.c. path, the thesis's
    s/P(s)) rejects it too, even where the drive does not: on the virtual P loop with asymmetric
    friction ``fdid identify`` chooses r1c2 with integral action (training free run 0.54 um,
    1.22-1.47 um for every structure without it), whose offset reads |t| = 0.13. So below the gate
    such a model's P-loop twin (:func:`.augment.without_integral_action`, refitted over the
    default space) is read as well (evidence ``t_p_loop_twin``; there 5.70); when the twin passes,
    the term goes on the twin, which is also its reference, so what the d.c. path alone gains is
    not credited to the asymmetry. Calibration with the twin (``examples/diagnose_calibrate.py --effects
    --plant2``; the statistic is the larger of the model's and the twin's |t|): the
    virtual clean runs' twins read 0.41-1.46 (the runs' maximum stays 3.11, clean_p's P-loop
    model, which has no twin), plant2's 9 clean runs at most 1.62 as without the twin (twins up to 1.22),
    its one-effect runs at most 1.69: the gate 4 passes no clean run on either plant.
Backlash / lost motion (needs a tool-side channel)
    Statistic: |t| of the direction-aligned mean tool-side residual while moving, over moves:
    m_e = s_e * mean(r_tool over move e); lost motion b shows as m_e = -b/2 on every move.
    Parameter: b = 2 |mean(m_e)| (mm). The refit keeps the poles (``locked``): a tool-side output
    is added with its own numerators, the motor side keeps its predictions (to rounding)
    (``augment.keep_base_outputs``), and it must beat the same tool-side output without the
    backlash input (``reference``).

Thresholds: ``thresholds.THRESHOLDS`` (``stribeck``, ``asymmetric_friction``, ``backlash``; a 5 %
false-alarm rate on the plant family's clean calibration cases, the asymmetry's statistic with its
P-loop twin's). Measured on the two plants the project wrote, thesis-path models: concentration
on virtual clean runs up to 2.17, its Stribeck run 3.27; plant2 (LuGre friction) clean runs
6.55-17.7 (LuGre's own breakaway is what the statistic sees), its Stribeck run 13.1, inside that
range; on ``fdid identify``'s default models the virtual Stribeck run reads 2.01, its clean runs
1.20-1.55, plant2's runs 8-52. |t| of the asymmetry: virtual clean up to 3.11 (twins 0.41-1.46),
its asymmetric P loop 6.84 (the default r1c2's twin 5.70); plant2 clean up to 1.62. Tool side:
virtual backlash 69, a two-mass axis without backlash 5.8; plant2 backlash 21.7, its 38 Hz
tool-side mode 11.8. The concentration separates neither plant: below the threshold the loop's
trials, the held-out criterion and the plausibility check (the breakaway excess must be positive)
decide (:mod:`.loop`).
"""
from __future__ import annotations

from functools import partial

import numpy as np

from ..errors import InputError
from ..identify.choose_structure import PLAY_WIDTHS_MM
from ..model import is_play
from . import augment as ag
from .base import Candidate, command_velocity, motion_events, scan_refine
from .residuals import residuals
from .thresholds import threshold

WINDOW_S = 0.04
MIN_MOVES = 3           # moves the t statistics need


def _windows(events, n, w):
    mask = np.zeros(n, bool)
    for k, _, _ in events:
        mask[k:min(n, k + w)] = True
    return mask


def detect(ctx):
    out = []
    for a in ctx.model.axes:
        out.extend(_detect_axis(ctx, a))
    return out


def concentration(res_list, a, Ts, rest="larger"):
    """Residual concentration of axis ``a`` after motion starts / stops: the mean residual energy in
    the ``WINDOW_S`` after each start / stop over a reference energy outside those windows
    (``res_list``: Residuals of one model).

    rest : ``"larger"`` (the ``suspected`` note, :mod:`.limits`): the reference is the larger of
        the two regimes outside the windows, the mean energy while the command moves
        (|v_cmd| > 2 % of its maximum, as :func:`.base.motion_events`) and the mean energy while
        it rests, each pooled over the traces; a regime without samples is left out.
        ``"pooled"`` (the Stribeck detector's statistic, as calibrated): the mean over every
        sample outside the windows (the per-trace means summed).

    Why the regimes: at rest the residual is the encoder's noise and the model's settling, while
    moving it is the model's error, and pooled, the reference falls with the share of the trace
    the axis rests. On the bundled example ``virtual_xy_moves.csv`` the Y axis rests 83 % of the
    trace with 0.066 µm of residual there (encoder noise 0.015 µm) against 0.138 µm while moving
    (its default-path model, r2c2-noI): pooled 42.8, larger 14.8; plant2 rests 55-65 % of its
    training traces with 0.20-0.31 µm at rest against 0.13-0.32 µm moving, so the two differ
    less there (clean 4.7-15.9 against 4.8-18.2; motor-only backlash 28.3-47.1 against 29.4-51.9).
    The larger reference is never below the pooled one, so this statistic never exceeds the
    pooled one (for one trace).
    """
    if rest == "larger":
        return _concentration_regimes(res_list, a, Ts)
    if rest != "pooled":
        raise ValueError(f"rest must be 'larger' or 'pooled', got {rest!r}")
    w = max(3, int(round(WINDOW_S / Ts)))
    num, den, n_in = 0.0, 0.0, 0
    for res in res_list:
        ar = res.axes[a]
        win = _windows(motion_events(ar.cmd, Ts), ar.residual.size, w)
        if win.any() and (~win).any():
            num += float(np.sum(ar.residual[win] ** 2))
            n_in += int(win.sum())
            den += float(np.mean(ar.residual[~win] ** 2))
    return (num / max(n_in, 1)) / den if den > 0 else 0.0


def _concentration_regimes(res_list, a, Ts):
    """:func:`concentration` with ``rest="larger"``: in-window mean energy over the larger of the
    moving and resting mean energies outside the windows, each pooled over the traces."""
    w = max(3, int(round(WINDOW_S / Ts)))
    e_in, e_mov, e_rest = [0.0, 0], [0.0, 0], [0.0, 0]     # [sum of r^2, samples]
    for res in res_list:
        ar = res.axes[a]
        r = np.asarray(ar.residual, float)
        win = _windows(motion_events(ar.cmd, Ts), r.size, w)
        if not (win.any() and (~win).any()):
            continue
        v = np.abs(command_velocity(ar.cmd, Ts))
        moving = v > 0.02 * float(np.max(v))
        for acc, m in ((e_in, win), (e_mov, ~win & moving), (e_rest, ~win & ~moving)):
            acc[0] += float(np.sum(r[m] ** 2))
            acc[1] += int(m.sum())
    ref = max((s / n for s, n in (e_mov, e_rest) if n > 0), default=0.0)
    return (e_in[0] / e_in[1]) / ref if ref > 0 and e_in[1] > 0 else 0.0


def _move_offsets(res_list, a, Ts, w):
    """Per move: the mean residual, and (with a tool-side channel) the direction-aligned mean
    tool-side residual (None without one)."""
    means, tool_m, have_tool = [], [], False
    for res in res_list:
        ar = res.axes[a]
        ev = motion_events(ar.cmd, Ts)
        v = command_velocity(ar.cmd, Ts)
        moving = np.abs(v) > 0.02 * np.max(np.abs(v))
        have_tool |= ar.tool_residual is not None
        for seg in _moves(ev, moving, w, ar.residual.size):
            means.append(float(np.mean(ar.residual[seg])))
            if ar.tool_residual is not None:
                tool_m.append(float(np.sign(np.median(v[seg])) * np.mean(ar.tool_residual[seg])))
    return np.array(means), (np.array(tool_m) if have_tool else None)


def _p_loop_twin(ctx, a, w):
    """The current model's P-loop twin (:func:`.augment.without_integral_action`) refitted over
    the default space: (its recipe, |t| and mean (um) of its direction-independent move offsets,
    None) or, when it cannot be fitted, (its recipe, nan, nan, the reason)."""
    twin = ag.without_integral_action(ctx.recipe, a)
    try:
        m = ag.fit(twin, ctx.train, search="wide", maxiter=int(ctx.settings.get("maxiter", 25)))
    except InputError as exc:
        return twin, float("nan"), float("nan"), str(exc)
    me, _ = _move_offsets([residuals(m, tr) for tr in ctx.train], a, ctx.Ts, w)
    return twin, abs(_t(me)), float(np.mean(me) * 1e3), None


def _detect_axis(ctx, a):
    Ts = ctx.Ts
    w = max(3, int(round(WINDOW_S / Ts)))
    me, tm = _move_offsets(ctx.res, a, Ts, w)
    cands = []
    ratio = concentration(ctx.res, a, Ts, rest="pooled")
    cand = Candidate("stribeck", a, ratio, threshold("stribeck", ctx.settings),
                     evidence={"window_s": WINDOW_S, "events": int(me.size)},
                     note="residual energy in the 40 ms after motion starts/stops over the rest")
    if not any(_has_windows(res.axes[a], Ts, w) for res in ctx.res):
        cand.not_checked = ("the training trace has no motion start or stop with samples both in and "
                            "after the 40 ms window that follows it")
    else:
        cand.prepare = partial(_prepare_stribeck, cand, ctx, a)
    if cand.detected:
        cand.prepare()
    cands.append(cand)
    own = [s for s in ctx.recipe.inputs if s.axis == a]
    if cand.detected and any(s.kind == "friction" for s in own) and not any(map(is_play, own)):
        cands.append(_play_law_candidate(ctx, a, cand))     # a sat-law axis without a play

    t_even = _t(me)
    cand = Candidate("asymmetric_friction", a, abs(t_even), threshold("asymmetric_friction", ctx.settings),
                     params={"mean_offset_um": float(np.mean(me) * 1e3) if me.size else 0.0},
                     note="|t| of the direction-independent mean residual over moves")
    has_friction = ctx.model.input_index("friction", a) is not None
    twin_used = None
    if me.size < MIN_MOVES:
        cand.not_checked = f"the training trace has {me.size} move(s); the t statistic needs {MIN_MOVES}"
    elif not cand.detected and has_friction and ag.has_integral_action(ctx.recipe, a):
        # integral action rejects a constant force, so the model leaves no offset to see; a P loop
        # keeps it, and its twin shows it (the virtual P loop's default r1c2: |t| 0.13 -> 5.70)
        twin, t_twin, offset, error = _p_loop_twin(ctx, a, w)
        cand.evidence.update({"t_model": cand.statistic, "t_p_loop_twin": t_twin})
        if error:
            cand.evidence["p_loop_twin_error"] = error
        elif t_twin > cand.statistic:
            cand.statistic, cand.params["mean_offset_um"] = t_twin, offset
            cand.note += " (of the model's refitted twin without integral action)"
            twin_used = twin
    if has_friction and not cand.not_checked:
        cand.prepare = partial(_prepare_asymmetry, cand, ctx.recipe, a, twin_used)
    if cand.detected and has_friction:
        cand.prepare()
    elif cand.detected:
        cand.note += " (the axis has no sat(v / v_tilde) friction input: not tried)"
    cands.append(cand)

    if tm is not None:
        t_tool = _t(tm)
        b = 2.0 * abs(float(np.mean(tm))) if tm.size else 0.0
        cand = Candidate("backlash", a, abs(t_tool), threshold("backlash", ctx.settings), params={"backlash_mm": b}, search="locked",
                         evidence={"moves": int(tm.size)},
                         note="|t| of the direction-aligned tool-side offset over moves; backlash and the "
                              "lost motion of an elastic drive train with friction on the tool side (2 F/k) "
                              "give the same offset in position data")
        if tm.size < MIN_MOVES:
            cand.not_checked = f"the training trace has {tm.size} move(s); the t statistic needs {MIN_MOVES}"
        carried = ag.carries_lost_motion(ctx.recipe, a)
        if not carried and not cand.not_checked:
            cand.prepare = partial(_prepare_backlash, cand, ctx.recipe, a)
        if cand.detected and carried:
            cand.note += ("; not refitted: the model's friction already reaches the tool side with a d.c. "
                          "gain, the same regressor (the note 'carried' gives the lost motion it carries)")
        elif cand.detected:
            cand.prepare()
        cands.append(cand)
    return cands


def _prepare_stribeck(cand, ctx, a):
    cand.params["v_s_mm_s"] = _best_vs(ctx, a, ctx.recipe)
    cand.recipe = ag.add_stribeck(ctx.recipe, a, cand.params["v_s_mm_s"])


def _prepare_asymmetry(cand, recipe, a, twin):
    """The asymmetry's refit; on the P-loop twin when the twin's offset is the statistic (the
    effect then changes the structure, which its record says, and the twin is its reference)."""
    base = recipe
    if twin is not None:
        base, cand.search, cand.reference = twin, "wide", twin
        cand.params["integral_action"] = False
    cand.recipe = ag.add_asymmetry(base, a)


def _prepare_backlash(cand, recipe, a):
    cand.recipe = ag.add_backlash(recipe, a, recipe.v_tilde.get(a, 1.0))
    cand.reference = ag.add_tool_output(recipe, a)


def _moves(ev, moving, w, n):
    """Sample indices of each move (from a start to the next start, moving samples only)."""
    starts = [k for k, kind, _ in ev if kind == "start"]
    out = []
    for i, k in enumerate(starts):
        stop = starts[i + 1] if i + 1 < len(starts) else n
        seg = np.arange(k, stop)
        seg = seg[moving[seg]]
        if seg.size > w:
            out.append(seg)
    return out


def _has_windows(ar, Ts, w):
    """The Stribeck statistic has something to compare on this axis's residual: samples in and
    outside the windows after motion starts / stops."""
    win = _windows(motion_events(ar.cmd, Ts), ar.residual.size, w)
    return bool(win.any() and (~win).any())


def _t(x):
    x = np.asarray(x, float)
    if x.size < MIN_MOVES:
        return 0.0
    sd = float(np.std(x, ddof=1))
    return float(np.mean(x) / (sd / np.sqrt(x.size))) if sd > 0 else 0.0


def _play_law_candidate(ctx, a, sat_cand):
    """The Stribeck candidate of a sat-law axis in the play law: the play's width is the one of
    ``PLAY_WIDTHS_MM`` (the structure choice's) whose quick refit without the Stribeck term has
    the lowest LS objective, then v_s as for the sat law; the play law alone is the reference."""
    J = ctx.refits.map(partial(_play_objective, recipe=ctx.recipe, a=a, train=ctx.train), PLAY_WIDTHS_MM)
    b = PLAY_WIDTHS_MM[int(np.argmin(np.nan_to_num(J, nan=np.inf)))]     # the first of equal ones
    law = ag.to_play_law(ctx.recipe, a, b)
    vs = _best_vs(ctx, a, law)
    cand = Candidate("stribeck", a, sat_cand.statistic, sat_cand.threshold,
                     params={"v_s_mm_s": vs, "law": "play", "width_mm": b}, evidence=dict(sat_cand.evidence),
                     note=sat_cand.note + "; tried in the play friction law (presliding), against the play "
                                          "law without the Stribeck term")
    cand.recipe, cand.reference = ag.add_stribeck(law, a, vs), law
    return cand


def _best_vs(ctx, a, recipe):
    """Stribeck velocity (mm/s) minimising the LS objective of ``recipe`` with its Stribeck term
    (poles in a local window)."""
    vt = recipe.v_tilde.get(a, 0.1)
    vmax = max(float(np.max(np.abs(command_velocity(r.axes[a].cmd, ctx.Ts)))) for r in ctx.res)
    lo, hi = max(2 * vt, 1e-3 * vmax), 0.2 * vmax
    if not hi > lo:
        return float(lo)
    xs = np.linspace(np.log10(lo), np.log10(hi), 7)
    J = partial(_stribeck_objective, recipe=recipe, a=a, train=ctx.train)
    best, _ = scan_refine(J, xs, ctx.refits.map)
    return float(10 ** best)


def _play_objective(b, recipe, a, train):
    """LS objective of a quick refit of ``recipe`` with axis ``a`` in the play law of width b (mm)."""
    return ag.fit_objective(ag.to_play_law(recipe, a, b), train, search="local", maxiter=10, refine=False)


def _stribeck_objective(lx, recipe, a, train):
    """LS objective of a quick refit of ``recipe`` with a Stribeck term of v_s = 10^lx (mm/s)."""
    return ag.fit_objective(ag.add_stribeck(recipe, a, 10 ** lx), train, search="local", maxiter=10,
                            refine=False)
