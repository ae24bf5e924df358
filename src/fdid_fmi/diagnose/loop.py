"""The diagnosis loop: residual -> detectors -> augment -> refit -> keep only what helps held out.

Each round:

1. free-run residuals of the current model on the training and held-out traces;
2. every detector proposes candidates; those whose statistic passes its calibrated threshold
   are refitted on the training data (:func:`.augment.fit`, poles in a local window, or the
   engine's default space for a dead time); the same refit without any new effect (the "null
   refit") is the reference, so a better pole fit is never credited to an effect (a ``locked``
   refit keeps the current poles and the current predictions of the channels it does not add,
   and is measured against the current model);
3. candidates are tried in order of their training improvement; the first one that meets the
   KEEP CRITERION on the held-out trace is kept, and the next round starts from it.

Thresholds rank, held-out data decides: when the current model leaves a large share of the
held-out error unexplained -- the largest share of a scored channel's held-out residual variance
that is not white (:func:`unexplained_share`, :func:`.whiteness.structured_share`) is at least
``UNEXPLAINED_SHARE`` -- the strongest candidate (statistic over threshold) of each detector family
that has none past its gate is prepared (:attr:`.base.Candidate.prepare`) and refitted as well, at
most ``below_trials`` per round (off by default), each at least ``MIN_BELOW_RATIO`` of its
threshold, and ordered by that ratio after the candidates past their gates; the keep criterion
decides, and such a trial must also lower the training free run of some channel by ``min_gain``
(below its threshold the statistic is no evidence, and a refit that gains only held out has found
another point of a flat valley: on the family's clean cases, without this, a periodic force was
kept 0.7 % better on training and 33 % held out). The candidate table says the candidate was
tried below its threshold (``tried_below_threshold``). A white residual is
noise no model explains: there the gates alone decide what is refitted.

Order check (a residual explained by one more pole means the model's order is too low, not that
there is a dead time): before an effect can be named, i.e. in the first round with a candidate
(and, once that check was met, in every later round with a dead-time or mode candidate), the
current structure is also refitted with one more real pole
(:mod:`.order`). The check is met when that refit meets the keep criterion and no training
channel rises by more than ``max_loss`` either (a refit that predicts only the held-out data
better, while its free run on the training data is worse, is no evidence of missing dynamics:
plant2's delay run shows such a refit, see docs/method.md, section 6).
When it is met, a dead time or a mode is kept only if it also beats that refit, and in the first
round the diagnosis reports the note ``order_too_low`` (:mod:`.limits`; the model is not changed
by it).

Keep criterion: on the held-out trace, the RMS residual of some scored channel (each axis's
position, and its tool side when measured) falls by at least ``min_gain`` (default 5 %) relative
to the better of the current model and the null refit, and no scored channel rises by more than
``max_loss`` (default 1 %). The loop stops when no candidate is detected or none is kept, or after
``max_steps`` effects. Without a held-out trace (the training trace split at a standstill) the
given model's figures on the held-out part are, as a rule, in-sample: it is then no reference
(until a refit on the first part replaces it) and the null refit alone is (for a locked refit:
its reference refit; the given model only when neither can be fitted), and what is kept is
refitted on the whole trace at the end when no channel gets worse there (:func:`_refit_on_whole`).

Combined per-axis models (``fdid identify`` on a trace with several axes: ``DriveModel.combine``,
``identification["blocks"]``) are diagnosed block by block: :func:`split_blocks` rebuilds each
axis's block as the model it was identified as, each is diagnosed on its own axis (detectors,
refits and the keep criterion see only that axis's channels; other axes' commands are candidate
coupling inputs), and the diagnosed blocks are combined again. ``Diagnosis.axes`` holds the
per-axis results.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..model import DriveModel
from ..simulate import fits_sample_time
from . import augment as ag
from . import coupling, delay, friction, mode, order, periodic, whiteness
from .base import Context, command_velocity, implausible
from .limits import (Note, NoteKind, data_limits, held_out_unlike, lost_motion_carried, not_checked,
                     order_too_low, play_input)
from .refits import Refits
from .residuals import Residuals, residuals, split_at_standstill

DETECTORS = {"friction": friction, "mode": mode, "delay": delay, "periodic": periodic,
             "coupling": coupling}
MIN_SAMPLES = 200       # samples of each trace the diagnosis fits or judges on (as fdid diagnose)
# effects that one more pole can imitate: they must also beat the order check's refit
ORDER_RIVALS = ("delay", "mode")
# below-threshold trials (module docstring): the held-out residual's structured share at or above
# which they run, and the number per round the plant family was measured with (each trial is one
# refit, and one of its reference when the candidate has one, besides its own preparation, e.g. a
# Stribeck velocity's scan)
UNEXPLAINED_SHARE = 0.5
MAX_BELOW_TRIALS = 3
MIN_BELOW_RATIO = 0.5   # a candidate below half its threshold is not tried


@dataclass
class Step:
    """One kept effect."""

    effect: dict
    model: DriveModel
    before: dict            # {"train"|"val": {channel: {rms_um, max_um}}}
    after: dict
    residual_before: dict   # {"train"|"val": Residuals}
    residual_after: dict
    candidates: list        # summaries of every candidate of the round


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`."""

    model: DriveModel               # the given model
    final: DriveModel               # with every kept effect
    train: object
    val: object
    steps: list = field(default_factory=list)
    rounds: list = field(default_factory=list)      # per round: candidates and trials
    before: dict = field(default_factory=dict)
    after: dict = field(default_factory=dict)
    residual_before: dict = field(default_factory=dict)
    residual_after: dict = field(default_factory=dict)
    tests_before: dict = field(default_factory=dict)
    tests_after: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    wall_time_s: float = 0.0
    split: str = ""
    whole_refit: dict = field(default_factory=dict)  # no held-out trace: the final refit on the whole
    axes: dict = field(default_factory=dict)        # combined model: axis -> Diagnosis of its block
    notes: list = field(default_factory=list)       # limits.Note (limits.NoteKind)

    @property
    def effects_added(self):
        return [s.effect for s in self.steps]

    @property
    def tried(self):
        """Kinds of the candidates that passed their detector's gate in some round (refitted)."""
        return sorted({c["kind"] for r in self.rounds for c in r["candidates"] if c["detected"]})

    def to_json(self):
        """The JSON summary (``effects_added``, ``candidates``: every candidate of every round with
        its statistic, threshold, held-out gain and outcome (:func:`.reporting.candidate_table`),
        ``before`` / ``after`` per trace and axis)."""
        from ..report import _jsonable
        from .reporting import candidate_table
        out = {
            "effects_added": self.effects_added,
            "candidates": candidate_table(self.rounds),
            "before": _per_axis(self.before), "after": _per_axis(self.after),
            "steps": [{"effect": s.effect, "before": _per_axis(s.before), "after": _per_axis(s.after),
                       "candidates": s.candidates} for s in self.steps],
            "rounds": [{k: v for k, v in r.items() if k != "plots"} for r in self.rounds],
            "tests": {"before": self.tests_before, "after": self.tests_after},
            "criterion": {"min_gain": self.settings.get("min_gain"), "max_loss": self.settings.get("max_loss")},
            "split": self.split, "whole_refit": self.whole_refit, "wall_time_s": self.wall_time_s,
            "notes": [n.to_dict() for n in self.notes],
        }
        if self.axes:       # combined per-axis model: the findings of every axis
            out["per_axis"] = {a: {"effects_added": d.effects_added, "before": _per_axis(d.before),
                                   "after": _per_axis(d.after), "rounds": len(d.rounds),
                                   "tried": d.tried, "whole_refit": d.whole_refit}
                               for a, d in self.axes.items()}
        return _jsonable(out)


def _per_axis(table):
    """{trace: {axis: {rms_um, max_um, tool: {...}}}} from {trace: {channel: ...}}."""
    out = {}
    for tname, chans in table.items():
        d = {}
        for ch, v in chans.items():
            if "." in ch:
                ax, sub = ch.split(".", 1)
                d.setdefault(ax, {})[sub] = dict(v)
            else:
                d.setdefault(ch, {}).update(v)
        out[tname] = d
    return out


def _tests(res: Residuals):
    out = {}
    for a, ar in res.axes.items():
        out[a] = whiteness.summary(whiteness.correlation_tests(ar.residual, command_velocity(ar.cmd, res.trace.Ts)))
    return out


def _already(recipe, cand):
    """An effect of this kind is already in the model for this axis (a mode or an input channel
    may be added again when it is a different one)."""
    for e in recipe.effects:
        if e.get("kind") != cand.kind or e.get("axis") != cand.axis:
            continue
        if cand.kind in ("coupling", "extra_input"):
            if e.get("channel") == cand.params.get("channel"):
                return True
        elif cand.kind == "mode":
            f = e.get("frequency_hz", e.get("detected_hz"))
            if f and abs(cand.params.get("peak_hz", 0) / f - 1) < 0.15:
                return True
        else:
            return True
    return False


RMS_FLOOR_UM = 1e-6     # a reference RMS below this is rounding, not a residual (1 pm)


def _gain(ref, new):
    """Relative RMS reduction per channel (positive = better). Below ``RMS_FLOOR_UM`` the
    reduction is taken relative to the floor: a residual of rounding noise (a held-out axis that
    stands still, exactly at its command) cannot show a gain of 99 %."""
    out = {}
    for ch in ref:
        if ch in new:
            r, n = ref[ch]["rms_um"], new[ch]["rms_um"]
            out[ch] = 1.0 - n / r if r >= RMS_FLOOR_UM else (r - n) / RMS_FLOOR_UM
    return out


def _better(a, b):
    """Per channel, the entry of the two residual tables with the lower RMS (a reference); None
    is no table."""
    if a is None or b is None:
        return b if a is None else a
    return {ch: min(a[ch], b[ch], key=lambda v: v["rms_um"]) for ch in a}


def _runs(ports, what):
    """[(axis, [indices])] of consecutive ports of the same axis."""
    runs = []
    for i, p in enumerate(ports):
        if p.axis is None:
            raise InputError(f"{what} '{p.name}' of a combined model has no axis; the model cannot be "
                             "split into its per-axis blocks", column="identification")
        if runs and runs[-1][0] == p.axis:
            runs[-1][1].append(i)
        else:
            runs.append((p.axis, [i]))
    return runs


def _block_part(d, k):
    """Entry k of ``d["blocks"]`` (metrics, provenance of a combined model), or {}."""
    blocks = d.get("blocks") if isinstance(d, dict) else None
    return blocks[k] if isinstance(blocks, list) and k < len(blocks) and isinstance(blocks[k], dict) else {}


def split_blocks(model: DriveModel):
    """The per-axis blocks of a combined model (:meth:`DriveModel.combine`), each as a DriveModel.

    ``combine`` stacks the blocks' A, B, C, D block-diagonally and concatenates their inputs,
    outputs, poles and effects; ``identification``, ``metrics`` and ``provenance`` hold one entry
    per block under ``"blocks"``. Each block's ports are the consecutive run of its axis; its
    states are those connected (through non-zero entries of A, B, C) to its ports, and must be one
    contiguous range not connected to any other block (exact zeros off the block diagonal).

    Returns
    -------
    list of DriveModel, one per block (the model itself in a list when it is not combined)

    Raises
    ------
    InputError
        ``identification["blocks"]`` does not describe the ports and states of the model.
    """
    blocks = (model.identification or {}).get("blocks")
    if not blocks:
        return [model]
    rin, rout = _runs(model.inputs, "input"), _runs(model.outputs, "output")
    nb = len(blocks)
    if len(rin) != nb or len(rout) != nb or [a for a, _ in rin] != [a for a, _ in rout]:
        raise InputError(f"identification lists {nb} blocks but the model's ports form "
                         f"{len(rin)} input and {len(rout)} output runs of one axis each; the combined "
                         "model cannot be split into its per-axis blocks", column="identification")
    n = model.n_states
    parent = list(range(n + nb))            # union-find: states, then one node per block

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def union(i, j):
        parent[find(i)] = find(j)

    for k, ((_, ii), (_, oo)) in enumerate(zip(rin, rout)):
        for s_ in np.flatnonzero(np.any(model.B[:, ii] != 0, axis=1) | np.any(model.C[oo, :] != 0, axis=0)):
            union(int(s_), n + k)
    for i, j in zip(*np.nonzero(model.A)):
        union(int(i), int(j))
    roots = {find(n + k): k for k in range(nb)}
    if len(roots) != nb:
        raise InputError("the blocks of the combined model are coupled (non-zero entries between "
                         "blocks); it cannot be diagnosed block by block", column="identification")
    owner = [roots.get(find(i)) for i in range(n)]
    for i in range(n):                      # a state connected to no port: the block before it
        if owner[i] is None:
            owner[i] = owner[i - 1] if i and owner[i - 1] is not None else 0
    if any(b < a for a, b in zip(owner, owner[1:])):
        raise InputError("the states of the combined model's blocks are interleaved; it cannot be "
                         "split into its per-axis blocks", column="identification")
    out = []
    disc = [np.linalg.eigvals(model.A[np.ix_(S, S)]) for S in
            [[i for i in range(n) if owner[i] == k] for k in range(nb)]]
    counts = [len(b.get("real_hz", [])) + len(b.get("locked_real_hz", [])) + 2 * (
        len(b.get("complex_hz_zeta", [])) + len(b.get("locked_complex", [])))
        if isinstance(b, dict) else -1 for b in blocks]
    if sum(counts) == len(model.poles) and min(counts) >= 0:    # in block order, as combined
        edges = np.cumsum([0] + counts)
        poles_of = [list(model.poles[edges[k]:edges[k + 1]]) for k in range(nb)]
    else:                       # each continuous pole to the block whose discrete poles hold it
        poles_of = [[] for _ in range(nb)]
        for p in model.poles:
            z = (1 + complex(p) * model.Ts / 2) / (1 - complex(p) * model.Ts / 2)   # Tustin, as realised
            k = min(range(nb), key=lambda b: np.min(np.abs(disc[b] - z)) if disc[b].size else np.inf)
            poles_of[k].append(p)
    for k, ((ax, ii), (_, oo)) in enumerate(zip(rin, rout)):
        S = [i for i in range(n) if owner[i] == k]
        ident = blocks[k] if isinstance(blocks[k], dict) else {}
        out.append(DriveModel(
            Ts=model.Ts, A=model.A[np.ix_(S, S)], B=model.B[np.ix_(S, ii)], C=model.C[np.ix_(oo, S)],
            D=model.D[np.ix_(oo, ii)], inputs=[model.inputs[i] for i in ii],
            outputs=[model.outputs[o] for o in oo], method=model.method, poles=poles_of[k],
            identification=ident, metrics=_block_part(model.metrics, k),
            provenance=_block_part(model.provenance, k),
            effects=[e for e in model.effects if e.get("axis") == ax],
            limits={a: v for a, v in model.limits.items() if a == ax}))
    return out


def _combined(model, blocks, train, val, split, kw, say, t0, whole, refits):
    """Diagnose every block of a combined model on its own axis and combine the results."""
    names = {p.name for p in model.inputs} | {p.name for p in model.outputs}
    subs = {}
    for b in blocks:
        ax = b.axes[0] if b.axes else b.outputs[0].axis
        own = {p.name for p in b.inputs} | {p.name for p in b.outputs}
        if _still(b.axes, train):
            say(f"axis {ax}: its command never moves in the training trace; its block is left as it is")
            subs[ax] = _left_as_is(b, train, val, kw, split, Note(
                NoteKind.NOT_CHECKED, ax, "diagnosis", f"axis {ax}: not diagnosed: its commanded position "
                "never moves in the training trace; its block is left as it is"))
            continue
        say(f"axis {ax}: diagnosing its block")
        subs[ax] = diagnose(b, train, val, progress=lambda m, ax=ax: say(f"axis {ax}: {m}"),
                            _reserved=names - own, _block=True, _whole=whole, _refits=refits, **kw)
    changed = any(d.final is not d.model for d in subs.values())
    if changed:
        final = DriveModel.combine([d.final for d in subs.values()],
                                   method=model.method + "+diagnose" if "diagnose" not in model.method
                                   else model.method)
    else:
        final = model
    diag = Diagnosis(model=model, final=final, train=train, val=val, settings=next(iter(subs.values())).settings,
                     split=split, axes=subs)

    def merged(attr):
        out = {}
        for d in subs.values():
            for tname, v in getattr(d, attr).items():
                out.setdefault(tname, {}).update(v)
        return out

    diag.before, diag.after = merged("before"), merged("after")
    diag.tests_before, diag.tests_after = merged("tests_before"), merged("tests_after")
    for attr in ("residual_before", "residual_after"):
        res = {}
        for tname, tr in (("train", train), ("val", val)):
            r = Residuals(trace=tr, t=np.asarray(tr.t))
            for d in subs.values():
                r.axes.update(getattr(d, attr)[tname].axes)
            res[tname] = r
        setattr(diag, attr, res)
    for ax, d in subs.items():
        diag.notes.extend(d.notes)
        diag.steps.extend(d.steps)
        diag.rounds.extend({**r, "axis": ax} for r in d.rounds)
    diag.wall_time_s = time.perf_counter() - t0
    return diag


def _options(min_gain, max_loss, max_steps, maxiter, max_delay, detectors, exclude):
    """The options of :func:`diagnose`, checked (InputError naming the option otherwise)."""
    def frac(v, name):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                or not 0 <= float(v) < 1:
            raise InputError(f"{name} must be a fraction in [0, 1), got {v!r}", column=name)
        return float(v)

    def count(v, name, lo):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise InputError(f"{name} must be an integer >= {lo}, got {v!r}", column=name)
        return int(v)

    def names(v, name):
        if v is None:
            return None
        v = [v] if isinstance(v, str) else list(v)
        if not all(isinstance(x, str) for x in v):
            raise InputError(f"{name} must be names (strings), got {v!r}", column=name)
        return v

    detectors = names(detectors, "detectors")
    if detectors is not None and not detectors:
        raise InputError(f"no detector given; choose from {sorted(DETECTORS)} (or leave detectors out "
                         "for all)", column="detectors")
    # a best shift equal to max_delay is never named (delay.shift_statistic): below 2 no dead
    # time could be named at all
    return (frac(min_gain, "min_gain"), frac(max_loss, "max_loss"), count(max_steps, "max_steps", 1),
            count(maxiter, "maxiter", 1), count(max_delay, "max_delay", 2), detectors,
            names(exclude, "exclude") or [])


def _still(axes, trace):
    """Axes whose commanded position never moves in ``trace``."""
    return [a for a in axes if trace.has(a, "cmd") and not np.ptp(np.asarray(trace.cmd(a), float)) > 0]


def _left_as_is(model, train, val, kw, split, note):
    """The Diagnosis of a block that is not diagnosed (its command never moves in the training
    trace): its residual tables and tests, no round, and the note saying why."""
    res0 = {"train": residuals(model, train), "val": residuals(model, val)}
    d = Diagnosis(model=model, final=model, train=train, val=val, split=split,
                  settings={**kw, "exclude": list(kw.get("exclude") or [])})
    d.before = d.after = {k: r.table() for k, r in res0.items()}
    d.residual_before = d.residual_after = res0
    d.tests_before = d.tests_after = {k: _tests(r) for k, r in res0.items()}
    d.notes = [note]
    return d


def _refit_on_whole(recipe, model, res, whole, train, val, maxiter, max_loss, diag, say):
    """The augmented structure refitted on the whole trace, its poles searched from the kept
    model's, when its free run there is better: the effects were chosen on the first part, the
    given model was identified on the whole (as a rule), and a model fitted on half the moves
    predicts the other half worse (plant2's coupling scenario: the null refit 61 % worse held out
    than the given model). Taken when no channel's free-run RMS over the whole trace rises by
    more than ``max_loss`` and one falls, and no kept effect becomes implausible
    (:func:`whole_refit_taken`); the kept effects are then described from it.
    ``diag.whole_refit`` records what happened. Returns (model, residuals on the two parts)."""
    say("refit of the augmented model on the whole trace")
    try:
        m = ag.fit(recipe, ag.model_velocity_traces(model, [whole]), search="local", maxiter=maxiter,
                   from_current=True)
    except InputError as exc:
        diag.whole_refit = {"taken": False, "error": str(exc)}
        return model, res
    before, after = residuals(model, whole).table(), residuals(m, whole).table()
    added = len(diag.steps)
    described = [ag.describe_fitted(m, e) for e in m.effects[-added:]]
    taken, why = whole_refit_taken(_gain(before, after), described, max_loss)
    diag.whole_refit = {"taken": taken, "whole_before": before, "whole_after": after}
    if why:
        diag.whole_refit["implausible"] = why
    if not taken:
        return model, res
    m.effects[-added:] = described
    for st, e in zip(diag.steps, described):
        st.effect = e
    return m, {"train": residuals(m, train), "val": residuals(m, val)}


def whole_refit_taken(gain, effects, max_loss):
    """(taken, reason) for the whole-trace refit: taken when no channel's free-run RMS rises by
    more than ``max_loss`` and one falls (``gain``: per channel, the relative fall), and every
    kept effect, described from the refit, is still plausible (:func:`.base.implausible`: a mode
    whose pair the refit damped beyond a resonance is no mode any more); the reason names the
    first that is not."""
    why = first_implausible(effects)
    return bool(min(gain.values()) >= -max_loss and max(gain.values()) > 0 and not why), why


def first_implausible(effects):
    """'kind: reason' of the first implausible effect (:func:`.base.implausible`), or ''."""
    return next((f"{e['kind']}: {w}" for e in effects if (w := implausible(e))), "")


def _order_check(recipe, vel_train, train, val, maxiter):
    """Residual tables of the refit with one more real pole, or {"error": why} when it cannot be
    fitted."""
    try:
        plus = order.one_more_pole(recipe, vel_train, maxiter)
    except InputError as exc:
        return {"error": str(exc)}
    return {"train": residuals(plus, train).table(), "val": residuals(plus, val).table()}


def diagnose(model: DriveModel, train, val=None, detectors=None, min_gain=0.05, max_loss=0.01,
             max_steps=4, maxiter=25, exclude=(), max_delay=6, progress=None, workers=1, search="de",
             below_trials=0, _reserved=(), _block=False, _whole=None, _refits=None) -> Diagnosis:
    """Find what the residual says the model lacks, add it, and report the error before and after.

    Parameters
    ----------
    model : DriveModel from the pole search (``identify_siso`` / ``identify_mimo``), or their
        per-axis combination (``DriveModel.combine``, what ``fdid identify`` writes for several
        axes): each block is then diagnosed on its own axis and the results combined again
        (module docstring; ``Diagnosis.axes``)
    train : Trace, measured data the effects are fitted on
    val : Trace, held-out data the keep criterion is judged on. Default: ``train`` is split in
        two (:func:`~fdid_fmi.diagnose.residuals.split_at_standstill`: at the standstill nearest its
        middle), the first part to fit, the second held out.
    detectors : names from DETECTORS to run (default all)
    min_gain, max_loss : keep criterion (module docstring)
    max_steps : at most this many effects added (per block of a combined model)
    maxiter : iterations of each refit's pole search: residual evaluations of each local search
        of ``vp`` (besides its Jacobians), generations of ``de``
    exclude : channel names never used as inputs
    max_delay : largest command shift tried (samples); a best shift equal to it is not named
        (:func:`.delay.shift_statistic`), so the largest dead time named is max_delay - 1
    progress : callable(str) for progress messages, optional
    search : pole search of the refits, ``de`` (default: differential evolution, population 8 per
        coordinate) or ``vp`` (variable projection from the current poles or a Sobol screen, as
        ``fdid identify``'s default: about half the CPU time, and on some runs a different effect
        named, docs/decisions/diagnosis-gates.md)
    workers : processes the independent refits run in (:mod:`.refits`; None: every core; 1: in
        this process); the result is the same for any number, bit for bit when this process
        runs BLAS on one thread as the workers do (``fdid`` does: :mod:`fdid_fmi.workers`)
    below_trials : at most this many candidates below their thresholds tried per round when the
        held-out residual is structured (module docstring; ``MAX_BELOW_TRIALS`` is the value the
        plant family was measured with); default 0: only candidates past their gates, as the
        trials below them named one effect more on the family's held-out half and also one
        false alarm and one wrong effect (docs/decisions/diagnosis-gates.md)

    Returns
    -------
    Diagnosis

    Raises
    ------
    InputError
        The model (or a block of it) is not a pole-search / MIMO model (quasi-static, Full LS:
        no ``identification["structure"]``), a trace does not fit it, no command of its
        axes moves in a trace, or an option is invalid. (A block of a combined model whose
        command never moves in the training trace is left as it is; a ``not_checked`` note says
        so.)
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    if not isinstance(model, DriveModel):
        raise InputError("diagnosis refits the model with the pole search and needs a pole-search or MIMO "
                         f"model (fdid identify --method pole-search or mimo), not a {type(model).__name__}",
                         column="identification")
    min_gain, max_loss, max_steps, maxiter, max_delay, detectors, exclude = _options(
        min_gain, max_loss, max_steps, maxiter, max_delay, detectors, exclude)
    split, whole = "", _whole
    if val is None:
        whole = train
        train, val, split = split_at_standstill(train, MIN_SAMPLES)
        split += ("; effects are judged against the model refitted on the first part, and the "
                  "augmented model is refitted on the whole trace when that fits it better")
    for tr, what in ((train, "training"), (val, "held-out")):
        if not fits_sample_time(tr.Ts, model.Ts):
            raise InputError(f"trace sampled at {tr.Ts:g} s, model at {model.Ts:g} s", source=tr.source,
                             column="Ts")
        if tr.n < MIN_SAMPLES:      # what fdid diagnose requires too (below: numpy errors, NaN tests)
            raise InputError(f"the {what} {'part of the ' if split else ''}trace has {tr.n} samples; diagnosis "
                             f"needs at least {MIN_SAMPLES}", source=tr.source)
    if max_delay >= train.n // 2:       # a shift longer than the record: a broadcast error after many refits
        raise InputError(f"max_delay {max_delay} samples is not shorter than half the training trace "
                         f"({train.n} samples)", column="max_delay")
    names = list(detectors if detectors is not None else DETECTORS)
    for nm in names:
        if nm not in DETECTORS:
            raise InputError(f"unknown detector '{nm}'; choose from {sorted(DETECTORS)}", column="detectors")
    if isinstance(below_trials, bool) or not isinstance(below_trials, (int, np.integer)) or below_trials < 0:
        raise InputError(f"below_trials must be an integer >= 0, got {below_trials!r}", column="below_trials")
    settings = {"min_gain": min_gain, "max_loss": max_loss, "max_steps": max_steps, "maxiter": maxiter,
                "exclude": list(exclude), "max_delay": max_delay, "detectors": names, "search": search,
                "below_trials": int(below_trials), "unexplained_share": UNEXPLAINED_SHARE}
    blocks = split_blocks(model)
    for b in blocks:                    # refuse a block that cannot be refitted before any work
        ag.recipe_from_model(b, method=search)
    # no command of the model moves: nothing to fit (every detector sees no motion) or to judge
    # (a residual of rounding noise would decide what is kept). A block of a combined model whose
    # own command never moves in the training trace is left as it is, with a note (_combined)
    for tr, what in ((train, "training"), (val, "held-out")):
        still = _still(model.axes, tr)
        if not _block and model.axes and len(still) == len(model.axes):
            raise InputError(f"the commanded position of axis {', '.join(still)} never moves in the {what} "
                             "trace; diagnosis needs moves", source=tr.source, column=f"{still[0]}.cmd")
    refits = _refits or Refits(workers)
    try:
        if len(blocks) > 1 or blocks[0] is not model:
            kw = dict(detectors=names, min_gain=min_gain, max_loss=max_loss, max_steps=max_steps,
                      maxiter=maxiter, exclude=exclude, max_delay=max_delay, search=search,
                      below_trials=below_trials)
            return _combined(model, blocks, train, val, split, kw, say, t0, whole, refits)
        return _diagnose_block(model, train, val, settings, split, whole, _reserved, say, t0, refits)
    finally:
        if _refits is None:
            refits.close()


def _diagnose_block(model, train, val, settings, split, whole, reserved, say, t0, refits):
    """:func:`diagnose` of a model that is one block (rounds of detectors, trials and keeping),
    its options checked (``settings``)."""
    names, maxiter, min_gain, max_loss = (settings[k] for k in ("detectors", "maxiter", "min_gain", "max_loss"))
    # without a held-out trace the held-out part is, as a rule, data the given model was
    # identified on: its figures there are in-sample and no reference for refits fitted on the
    # first part (plant2's default path: the order check's refits lost 10-107 % held out to them on
    # 10 of 11 runs); the null refit, fitted on the first part as the candidates are, is the reference,
    # and what is kept is refitted on the whole trace at the end (_refit_on_whole)
    in_sample = whole is not None   # the current model predicts the held-out part in-sample
    recipe = ag.recipe_from_model(model, reserved=reserved, method=settings["search"])
    current = model
    res0 = {"train": residuals(model, train), "val": residuals(model, val)}
    diag = Diagnosis(model=model, final=model, train=train, val=val, settings=settings, split=split)
    diag.before = {k: r.table() for k, r in res0.items()}
    diag.residual_before = res0
    diag.tests_before = {k: _tests(r) for k, r in res0.items()}
    res_cur = res0
    order_notes, unchecked = [], []
    for step in range(settings["max_steps"]):
        tab_cur = {k: r.table() for k, r in res_cur.items()}
        vel_train = ag.model_velocity_traces(current, [train])
        ctx = Context(model=current, recipe=recipe, train=vel_train, res=[res_cur["train"]],
                      settings=settings, refits=refits)
        cands, family = [], {}
        for nm in names:
            say(f"round {step + 1}: detector {nm}")
            found = DETECTORS[nm].detect(ctx)
            cands.extend(found)
            family.update({id(c): nm for c in found})
        detected = [c for c in cands if c.detected and c.recipe is not None and not _already(recipe, c)]
        share = unexplained_share(res_cur["val"])
        below, prepare_errors = [], []
        if share >= settings["unexplained_share"] and settings["below_trials"] > 0:
            say(f"round {step + 1}: held-out residual {share:.0%} structured: trying candidates below "
                "their thresholds")
            below, prepare_errors = _below_threshold(cands, family, detected, recipe, settings["below_trials"])
        # the summaries after the below-threshold candidates were prepared (their refined
        # parameters, e.g. a Stribeck velocity, name their trials)
        rnd = {"round": step + 1, "candidates": [c.summary() for c in cands], "trials": list(prepare_errors),
               "unexplained_share": share, "plots": {f"{c.kind}|{c.axis}": c.plot for c in cands if c.plot}}
        diag.rounds.append(rnd)
        if step == 0:           # a detector that could not run says so (not "nothing found")
            unchecked = not_checked(cands)
        if not detected and not below:
            say(f"round {step + 1}: nothing detected")
            break
        detected = detected + below
        # the null refit and every trial's refits, submitted together (they run side by side; a
        # reference is refitted even when its trial's refit fails, which is rare)
        say(f"round {step + 1}: null refit and {len(detected)} trial refit(s)")
        null_fit = refits.submit(ag.fit, recipe, vel_train, search="local", maxiter=maxiter)
        # a trial started from the current poles must also beat the same structure refitted from
        # them: without a held-out trace those poles were fitted on the part it is judged on
        null_cur_fit = (refits.submit(ag.fit, recipe, vel_train, search="local", maxiter=maxiter, from_current=True)
                        if any(c.from_current for c in detected) else None)
        fits = [[refits.submit(ag.fit, r, vel_train, search=c.search, maxiter=maxiter,
                               refine=c.search != "locked", from_current=c.from_current) if r is not None else None
                 for r in (c.recipe, c.reference)] for c in detected]
        try:
            null = null_fit.result()
            tab_null = {"train": residuals(null, train).table(), "val": residuals(null, val).table()}
        except InputError as exc:   # no feasible refit of the same structure: the current model
            rnd["null_refit_error"] = str(exc)
            tab_null = tab_cur
        tab_null_cur = None
        if null_cur_fit is not None:
            try:
                m0 = null_cur_fit.result()
                tab_null_cur = {"train": residuals(m0, train).table(), "val": residuals(m0, val).table()}
            except InputError as exc:   # then the trials face the other references only
                rnd["null_refit_from_current_error"] = str(exc)
        # the current model is a reference unless it saw the held-out part (the given model, or a
        # locked refit composed with it, which keeps its predictions of the other channels)
        cur = dict.fromkeys(tab_cur) if in_sample else tab_cur
        ref_val, ref_train = _better(cur["val"], tab_null["val"]), _better(cur["train"], tab_null["train"])
        tab_plus = None
        rivals = any(c.kind in ORDER_RIVALS for c in detected)
        if step == 0 or (order_notes and rivals):       # is the structure adequate?
            say(f"round {step + 1}: order check (one more real pole)")
            tab_plus = _order_check(recipe, vel_train, train, val, maxiter)
            if "error" in tab_plus:         # recorded, and nothing is compared with it
                rnd["order_check"], tab_plus = tab_plus, None
            else:
                g_train, g_val = _gain(ref_train, tab_plus["train"]), _gain(ref_val, tab_plus["val"])
                # held out better while the training free run is worse: no missing dynamics
                met = (max(g_val.values()) >= min_gain and min(g_val.values()) >= -max_loss
                       and min(g_train.values()) >= -max_loss)
                rnd["order_check"] = {"gain_train": g_train, "gain_val": g_val, "criterion_met": bool(met)}
                if not met:
                    tab_plus = None
                elif step == 0:
                    ch = max(g_val, key=g_val.get)
                    order_notes.append(order_too_low(ch.split(".")[0], g_val[ch], min_gain,
                                                     recipe.structure_chosen))
        trials = []
        for c, (fit_c, fit_ref) in zip(detected, fits):
            say(f"round {step + 1}: refit with {c.kind} {_params_words(c.params)}".rstrip())
            try:
                m = fit_c.result()
            except InputError as exc:
                rnd["trials"].append({**_trial_of(c), "error": str(exc)})
                continue
            # a locked refit keeps the current poles and, composed with the current model, its
            # predictions of the channels the effect does not feed: its reference is then the
            # current model, not the null refit's new poles, which it cannot have
            kept_base = False
            if c.search == "locked":
                composed = ag.keep_base_outputs(current, m)
                kept_base, m = composed is not m, composed
            rt, rv = residuals(m, train), residuals(m, val)
            tt, tv = rt.table(), rv.table()
            rtr, rva = (cur["train"], cur["val"]) if kept_base else (ref_train, ref_val)
            if rtr is None and c.reference is None:     # nothing fitted on the first part to beat
                rtr, rva = tab_cur["train"], tab_cur["val"]
            if tab_plus is not None and c.kind in ORDER_RIVALS:   # and one more real pole
                rtr, rva = _better(rtr, tab_plus["train"]), _better(rva, tab_plus["val"])
            if c.from_current and tab_null_cur is not None:
                rtr, rva = _better(rtr, tab_null_cur["train"]), _better(rva, tab_null_cur["val"])
            # candidates are ranked against one baseline; a reference only decides the keeping
            # (a play-law Stribeck's gain over the play law alone is no measure against the others)
            rank = max(_gain(tab_cur["train"] if rtr is None else rtr, tt).values())
            if c.reference is not None:     # the effect must also beat its reference structure
                try:
                    mr = fit_ref.result()
                except InputError as exc:   # then it cannot be compared: not kept
                    rnd["trials"].append({**_trial_of(c),
                                          "error": f"reference refit: {exc}"})
                    continue
                if kept_base:
                    mr = ag.keep_base_outputs(current, mr)
                t2, v2 = residuals(mr, train).table(), residuals(mr, val).table()
                rtr, rva = _better(rtr, t2), _better(rva, v2)
            g_train, g_val = _gain(rtr, tt), _gain(rva, tv)
            keep = max(g_val.values()) >= min_gain and min(g_val.values()) >= -max_loss
            # below its threshold the statistic is no evidence: the effect must also explain the
            # training data it was fitted on by the same margin (a refit that gains held out only
            # has found another point of a flat valley, not the effect)
            if not c.detected:
                keep = keep and max(g_train.values()) >= min_gain
            # the effects kept so far, described from this refit, must stay plausible too (a
            # later round's local search may damp a kept mode's pair beyond a resonance)
            ours = [ag.describe_fitted(m, e) for e in m.effects[-(len(diag.steps) + 1):]]
            effect, why = ours[-1], first_implausible(ours)
            trials.append((rank, c, m, rt, rv, keep and not why, kept_base))
            rnd["trials"].append({**_trial_of(c), "fitted": effect,
                                  "gain_train": g_train, "gain_val": g_val, "kept": False,
                                  "criterion_met": bool(keep), "implausible": why})
        # candidates past their gate first, by training improvement; then those tried below it, in
        # the order of their statistic over its threshold (as _below_threshold returns them)
        late = {id(c): k for k, c in enumerate(below)}
        trials.sort(key=lambda x: (id(x[1]) in late, late.get(id(x[1]), -x[0])))
        chosen = next((t for t in trials if t[5]), None)
        if chosen is None:
            say(f"round {step + 1}: no candidate met the keep criterion")
            break
        _, c, m, rt, rv, _, kept_base = chosen
        in_sample = in_sample and kept_base
        for tr_ in rnd["trials"]:
            if tr_.get("label") == c.label and (tr_.get("axis"), tr_.get("params")) == (c.axis, c.params):
                tr_["kept"] = True
        effect = ag.describe_fitted(m, m.effects[-1])
        effect.update({k: v for k, v in c.params.items() if k not in effect})
        m.effects[-1] = effect
        res_new = {"train": rt, "val": rv}
        diag.steps.append(Step(effect=effect, model=m, before=tab_cur,
                               after={k: r.table() for k, r in res_new.items()},
                               residual_before=res_cur, residual_after=res_new,
                               candidates=[x.summary() for x in cands]))
        say(f"round {step + 1}: kept {effect['kind']}")
        recipe = ag.updated_recipe(c.recipe, m)
        recipe.effects = list(m.effects)
        current, res_cur = m, res_new
    if whole is not None and diag.steps:
        current, res_cur = _refit_on_whole(recipe, current, res_cur, whole, train, val, maxiter,
                                           max_loss, diag, say)
    diag.final = current
    diag.after = {k: r.table() for k, r in res_cur.items()}
    diag.residual_after = res_cur
    diag.tests_after = {k: _tests(r) for k, r in res_cur.items()}
    tool_axes = {a for a, ar in res0["train"].axes.items() if ar.tool_residual is not None}
    conc = ({a: friction.concentration([res_cur["train"]], a, model.Ts) for a in model.axes}
            if "friction" in names else {})
    lost = {a: lost_motion_carried(current, a) for a in tool_axes}
    play = {a: current.inputs[i].params["width_mm"] for a in model.axes
            if (i := play_input(current, a)) is not None}
    kept = diag.effects_added + [e for e in (model.effects or []) if e not in diag.effects_added]
    unseen = sorted(set(val.extra_channels) - set(train.extra_channels))
    diag.notes = (held_out_unlike(diag.before, split=bool(split), unseen=unseen) + order_notes + unchecked
                  + data_limits(model.axes, tool_axes, conc, kept, lost, play))
    diag.wall_time_s = time.perf_counter() - t0
    return diag


def _trial_of(c):
    """A trial's record names its candidate: kind, the statistic's label (a kind may have two),
    axis and parameters, and whether it was tried below its threshold."""
    return {"kind": c.kind, "label": c.label, "axis": c.axis, "params": c.params,
            "below_threshold": not c.detected}


def unexplained_share(res):
    """The largest share of a scored channel's residual variance that is not white
    (:func:`.whiteness.structured_share`) in ``res`` (a Residuals, the held-out trace's): what a
    better model could still explain, against the noise it cannot."""
    return max((whiteness.structured_share(r) for r in res.channels().values()), default=0.0)


def _below_threshold(cands, family, detected, recipe, limit):
    """The candidates tried below their thresholds: per detector family without a candidate past
    its gate, the one with the largest statistic over its threshold, at least ``MIN_BELOW_RATIO``,
    that can be tried (not already in the model, checked, a finite gate); the ``limit`` largest of
    those, in that order,
    each prepared (:attr:`.base.Candidate.prepare`). Returns (candidates with a recipe, trial
    records of those whose preparation failed)."""
    passed = {family[id(c)] for c in detected}
    best = {}
    for c in cands:
        nm = family[id(c)]
        if c.detected or nm in passed or c.prepare is None or c.not_checked or _already(recipe, c):
            continue
        if not (np.isfinite(c.statistic) and np.isfinite(c.threshold) and c.threshold > 0):
            continue
        ratio = c.statistic / c.threshold
        if ratio < MIN_BELOW_RATIO:
            continue
        if nm not in best or ratio > best[nm][0]:
            best[nm] = (ratio, c)
    out, errors = [], []
    for ratio, c in sorted(best.values(), key=lambda rc: -rc[0])[:limit]:
        try:
            c.prepare()
        except InputError as exc:   # e.g. no feasible refit in a Stribeck velocity's scan
            errors.append({**_trial_of(c), "error": f"preparing the trial: {exc}"})
            continue
        if c.recipe is not None:
            out.append(c)
    return out, errors


def _params_words(params):
    """An effect's parameters for the progress line: ``v_s_mm_s 1.258`` (4 significant digits),
    not a Python dict."""
    return ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in params.items())
