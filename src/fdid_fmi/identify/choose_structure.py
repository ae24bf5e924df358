"""Automatic structure choice for one axis: candidates ranked by their free run, with parsimony.

The thesis fixes the rigid-body structure (Eqn 4.10-4.15: one real pole, one complex pair, friction
through d0 s/P(s)); which structure a drive needs is a property of the drive, seen in its data:
a feed-forward loop leaves the current loop in the tracking error (one more real pole), a flexible
axis a second complex pair, a P/PD position loop a friction d.c. gain (the 1/P(s) path). So
:func:`identify_auto`

1. chooses the same-sample prediction (``regressors.CHOSEN_FROM``) on one real pole more than the
   rigid body (``r2c1``): a drive with feed-forward needs that pole (the current loop) before
   its look-ahead shows; the rigid structure cannot tell the forms apart there (free runs within
   1 % of each other on the feed-forward virtual drive), r2c1 separates them clearly with and
   without feed-forward;
2. identifies every other candidate -- rigid body, two real poles, two complex pairs, both; each
   with and without integral action -- with that prediction;
3. tries the other friction law: the thesis's sat(v / v_tilde) builds the friction force up over
   a velocity band; friction with presliding (LuGre's bristles) builds it up over a travel after
   each reversal and holds it at rest, which the play of half-width b (``model``'s ``play``
   feature) describes. Its width is picked among ``PLAY_WIDTHS_MM`` on the largest candidate
   (r2c2, where missing dynamics cannot stand in for it); when that fit comes within
   ``PARSIMONY`` of the best sat-law candidate, every other candidate is identified with the
   play as well;
4. keeps the structure with the fewest parameters whose free-run RMS is within ``PARSIMONY`` of
   the best one (a more complex structure must win by that margin; a play width counts as one);
5. fits that structure in the other same-sample forms and takes one whose free run is lower by
   the ``PARSIMONY`` margin: the form chosen on r2c1 need not be the kept structure's (plant2's
   record delay, r1c2: hold 0.254 against quadratic 0.277 um, held out 0.57-0.61x). The margin
   was set on the virtual drive, where without it the periodic run's r2c2 went from cubic to
   quadratic (-4.0 % training, +8.4 % held out); with it no virtual run changes form.

Search. Every candidate is a pole search with LS projection (``pole_search.identify_mimo``); by
default with variable projection (``search.py``, method ``vp``): each candidate's Gauss-Newton
searches start from its Sobol screen and from the poles of a fitted neighbour (:func:`warm_starts`:
r2c1's for the other structures, each sat-law structure's for its play version, the kept
structure's for its other forms), and the play widths are ranked at r2c2's poles
(:func:`screen_play`) so that only the best width is searched. Fits that do not depend on each
other run side by side. ``method="de"`` fits every candidate by differential evolution from
scratch: the thorough search, at about ten times the CPU time.

Determined predictions. The kept structure's rounding sensitivity is measured and
recorded (``sensitivity_mm``: how far its training free run moves when its commands carry 1e-12 mm
of noise, :func:`~fdid_fmi.simulate.rounding_sensitivity`); above ``SENSITIVITY_MAX`` (a tenth)
of its own free-run RMS it is flagged "not determined" in the table, with a note. Stick/slip
decisions amplify rounding, more with slow real poles: EMPS's r2c2 cubic (two real poles at 0.156
and 0.159 Hz) moves 2.41 µm against its 1.46 µm RMS; measured on every candidate, every EMPS
candidate with two complex pairs or r1c2 moves 0.35-2.4 µm, rigid and r2c1 below 1 %. Only the
kept structure is measured: measuring every candidate takes the test suite's CPU to 1147 of its
1200 s. Such candidates are not excluded from the choice: with a 1 % rule EMPS would fall to
rigid-noI at 2.72 µm (above the published physics model's 1.8 µm), and on the virtual
feed-forward axis, where the sensitivity ranges from 1e-6 to 10 of the RMS across candidates
(the chosen r2c1 quadratic 0.038), the choice would move to the rigid body. The tenth is a
reporting rule, not fitted to a plant: it flags the bundled two-axis example's kept r2c2-noI
hold (0.074 µm against 0.081 µm on x, 0.117 against 0.154 µm on y) and EMPS's r2c2, not the
feed-forward axis's r2c1. What it means for an FMU: it computes what the model computes from the input
doubles it is given (exact there); a master that rounds or interpolates its inputs differently
from ``fdid simulate`` gets outputs that differ by up to the sensitivity (docs/fmu-interface.md).

The score is the free-run RMS (mm) of the predicted minus measured tracking error on the training
data: the model driven by the commands alone, which the LS projection does not minimise (it fits
the one-step equation error). When every training trace records the axis's tool-side position
(role ``tool``), every candidate also predicts it (outputs error and tool_position) and the
score covers both: a drive-train mode shows on the tool side far more than in the motor-side
error (the virtual flexible Y axis: the error-only choice put two pairs at 6.6 and 15.2 Hz; with
the tool side, r1c2 finds the 25.66 Hz mode within 0.1 %).

The score is not a held-out score (the last 30 % of the training moves, the model fitted on the
rest): on the feed-forward virtual axis such a score ranks the structures against their
validation on a circle and a diamond (it chooses two complex pairs, 1.16-1.25x the validation
error of the structure the free run chooses), because the few moves held out say less about a
structure than all of them run freely; with at most 18 parameters against thousands of samples
the free run is not fitting noise. The candidates run in parallel processes. Every candidate,
its score and the choice are the model's ``identification["structure_choice"]``
(:class:`StructureChoice`).
"""
from __future__ import annotations

import dataclasses
import time
import warnings
from concurrent.futures import Future
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import LinAlgWarning

from ..errors import InputError
from ..metrics import rms
from ..simulate import rounding_sensitivity
from ..workers import process_pool, worker_count
from .pole_search import identify_mimo
from .ranges import training_ranges
from .record import PoleSearchRecord
from .regressors import CHOSEN_FROM
from .structure import Bounds, default_bounds, mimo_structure, siso_structure

PARSIMONY = 0.05            # a structure with more parameters must lower the free-run RMS by 5 %
# a candidate whose free run moves by more than this fraction of its own free-run RMS when its
# commands carry 1e-12 mm of noise (simulate.rounding_sensitivity) is flagged: its prediction is
# not determined by its inputs to within its error (module docstring, "Determined predictions")
SENSITIVITY_MAX = 0.1
ZETA_TWO_PAIRS = (0.005, 2.0)  # a structural mode is lightly damped: below the default 0.05
# half-widths b (mm) of the play (presliding) friction law tried on r2c2: a prior, not fitted to
# either plant -- presliding displacements of ball screws and guides are micrometres
PLAY_WIDTHS_MM = (0.001, 0.002, 0.004, 0.008, 0.016)


@dataclass(frozen=True)
class Candidate:
    """One candidate structure: ``rigid`` is the thesis's SISO model (Eqn 4.10-4.15; with a
    tool-side output, which that model lacks, the MIMO r1c1), ``rNcM`` a MIMO structure with N
    real poles and M complex pairs and the default numerator masks (``structure.default_mask``);
    ``integral_action=False`` (``-noI``) adds the friction d.c. path (1/P(s)) of a P/PD position
    loop; ``play_mm`` replaces the friction law sat(v / v_tilde) by the play of half-width b
    (``-play<b>um``, see :func:`with_play`)."""

    label: str
    n_real: int
    n_complex: int
    integral_action: bool = True
    play_mm: float | None = None

    def structure(self, axis, same_sample, velocity="backward", ma_order=1, outputs=("error",)):
        if self.play_mm is not None:
            return mimo_structure((axis,), tuple(outputs), n_real=self.n_real, n_complex=self.n_complex,
                                  integral_action=self.integral_action, velocity=velocity, ma_order=ma_order,
                                  same_sample=same_sample, friction=False, play_mm=self.play_mm)
        if self.label.startswith("rigid") and tuple(outputs) == ("error",):
            return siso_structure(axis, integral_action=self.integral_action, velocity=velocity,
                                  ma_order=ma_order, same_sample=same_sample)
        return mimo_structure((axis,), tuple(outputs), n_real=self.n_real, n_complex=self.n_complex,
                              integral_action=self.integral_action, velocity=velocity, ma_order=ma_order,
                              same_sample=same_sample)

    def bounds(self, Ts):
        zeta = ZETA_TWO_PAIRS if self.n_complex > 1 else (0.05, 2.0)
        return default_bounds(Ts, self.n_real, self.n_complex, zeta=zeta)


def family(integral_action):
    """The rigid-body structure first, then the larger ones, of one friction family."""
    sfx = "" if integral_action else "-noI"
    return [Candidate("rigid" + sfx, 1, 1, integral_action)] + \
        [Candidate(f"r{r}c{c}{sfx}", r, c, integral_action) for r, c in ((2, 1), (1, 2), (2, 2))]


def with_play(cand, b):
    """``cand`` with the play friction law of half-width ``b`` (mm) in place of sat(v / v_tilde)."""
    return dataclasses.replace(cand, label=f"{cand.label}-play{b * 1e3:g}um", play_mm=float(b))


@dataclass
class CandidateScore:
    """Result of one candidate (``free_run_rms_mm``: free-run RMS of the predicted minus measured
    tracking error on the training data; inf when its identification failed)."""

    label: str
    parameters: int
    same_sample: str
    free_run_rms_mm: float
    wall_s: float
    real_hz: list = field(default_factory=list)
    complex_hz_zeta: list = field(default_factory=list)
    on_bound: bool = False
    error: str | None = None
    chosen: bool = False
    sensitivity_mm: float | None = None     # simulate.rounding_sensitivity on the training traces (kept one)

    @property
    def determined(self):
        """Its free run moves by at most ``SENSITIVITY_MAX`` of its RMS under 1e-12 mm of command
        noise (True when not measured: a record that has no ``sensitivity_mm``)."""
        return self.sensitivity_mm is None or self.sensitivity_mm <= SENSITIVITY_MAX * self.free_run_rms_mm

    def to_dict(self):
        d = dataclasses.asdict(self)
        d["free_run_rms_mm"] = d["free_run_rms_mm"] if np.isfinite(d["free_run_rms_mm"]) else None
        return d

    @classmethod
    def from_dict(cls, d):
        d = dict(d)
        if d.get("free_run_rms_mm") is None:
            d["free_run_rms_mm"] = float("inf")
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls) if f.name in d})


@dataclass
class StructureChoice:
    """How the structure of one axis was chosen (``identification["structure_choice"]``)."""

    axis: str
    chosen: str
    same_sample: str
    candidates: list                 # CandidateScore
    parsimony: float
    workers: int
    wall_s: float
    outputs: list = field(default_factory=lambda: ["error"])   # fitted and scored

    def to_dict(self):
        d = dataclasses.asdict(self)
        d["candidates"] = [c.to_dict() for c in self.candidates]
        return d

    @classmethod
    def from_dict(cls, d):
        d = dict(d)
        d["candidates"] = [CandidateScore.from_dict(c) for c in d.get("candidates", [])]
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls) if f.name in d})

    def table(self):
        """Lines for the CLI summary and the report."""
        best = min(c.free_run_rms_mm for c in self.candidates)
        lines = [f"structure of axis {self.axis}: {self.chosen}, {self.same_sample} (training free run "
                 f"of {' + '.join(self.outputs)}, {len(self.candidates)} fits, parsimony "
                 f"{self.parsimony:.0%}, {self.wall_s:.0f} s)"]
        for c in sorted(self.candidates, key=lambda c: (c.parameters, c.same_sample)):
            ok = np.isfinite(c.free_run_rms_mm)
            rms = f"{c.free_run_rms_mm * 1e3:8.3f} µm {c.free_run_rms_mm / best:5.2f}x" if ok else "  failed"
            lines.append(f"  {'*' if c.chosen else ' '} {c.label:<14} {c.parameters:3d} parameters "
                         f"{c.same_sample:<9} {rms}{'  (a pole on its search bound)' if c.on_bound else ''}"
                         + ("" if c.determined else f"  (not determined: moves {c.sensitivity_mm * 1e3:.3g} µm "
                                                    f"under 1e-12 mm of command noise)"))
        kept = next((c for c in self.candidates if c.chosen), None)
        if kept is not None and not kept.determined:
            lines.append(f"  note: the kept structure's free run moves by up to {kept.sensitivity_mm * 1e3:.3g} µm "
                         f"when its commands carry 1e-12 mm of noise (stick/slip decisions amplify rounding): "
                         f"its FMU gives fdid simulate's numbers for the same input doubles, and differs by up to "
                         f"that where a master rounds or interpolates its inputs otherwise (fmpy's input table)")
        return lines


def parameter_count(structure):
    """Poles plus free numerator terms minus d.c.-gain constraints: the size of the structure."""
    n_terms = sum(len(v) for v in structure.mask.values())
    return structure.n_real + 2 * structure.n_complex + n_terms - len(structure.dc_gain)


def scored_outputs(traces, axis):
    """The outputs every candidate fits and is scored on: the tracking error, and the tool-side
    position when every trace records it."""
    return ["error", "tool_position"] if all(tr.has(axis, "tool") for tr in traces) else ["error"]


def free_run_rms(model, traces, axis, outputs=("error",)):
    """Free-run RMS (mm) of the predicted minus measured tracking error (and tool-side position,
    if in ``outputs``) over ``traces``."""
    from ..simulate import simulate
    res = []
    for tr in traces:
        sim = simulate(model, tr).axes[axis]
        res.append(sim["error"] - tr.error(axis))
        if "tool_position" in outputs:
            res.append(sim["tool_position"] - tr.get(axis, "tool"))
    r = rms(np.concatenate(res))
    return r if np.isfinite(r) else float("inf")


def _on_bound(rec: PoleSearchRecord, bounds: Bounds):
    """True when a searched pole sits on its search bound (within 0.1 %)."""
    tol = 1e-3
    for f, (lo, hi) in zip(rec.real_hz, bounds.real_hz):
        if f <= lo * (1 + tol) or f >= hi * (1 - tol):
            return True
    for (w, z), (lo, hi), (zl, zh) in zip(rec.complex_hz_zeta, bounds.omega_hz, bounds.zeta):
        if w <= lo * (1 + tol) or w >= hi * (1 - tol) or z <= zl * (1 + tol) or z >= zh * (1 - tol):
            return True
    return False


def fit_candidate(job):
    """Identify one candidate and score its free run (a process-pool task:
    ``job`` = (candidate, same_sample, traces, axis, options[, warm]), ``warm`` the start points
    of a ``vp`` search, see :func:`warm_starts`). Returns (CandidateScore, model)."""
    cand, same_sample, traces, axis, opts = job[:5]
    warm = job[5] if len(job) > 5 else ()
    t0 = time.perf_counter()
    st = cand.structure(axis, same_sample, opts["velocity"], opts["ma_order"], opts["outputs"])
    bounds = cand.bounds(traces[0].Ts)
    # a play width counts as a parameter: it is picked from PLAY_WIDTHS_MM on the same data, so
    # the play law must win by the parsimony margin over the same poles with sat(v / v_tilde)
    res = CandidateScore(cand.label, parameter_count(st) + (cand.play_mm is not None), same_sample,
                         float("inf"), 0.0)
    model = None
    try:
        with warnings.catch_warnings():   # ill-conditioned LS of the larger structures: scored anyway
            warnings.simplefilter("ignore", LinAlgWarning)
            model = identify_mimo(traces, st, bounds=bounds, v_tilde=opts["v_tilde"], seed=opts["seed"],
                                  maxiter=opts["maxiter"], method=opts["method"], warm=warm)
        res.free_run_rms_mm = free_run_rms(model, traces, axis, opts["outputs"])
        rec = PoleSearchRecord.from_dict(model.identification)
        res.real_hz, res.complex_hz_zeta = rec.real_hz, rec.complex_hz_zeta
        res.on_bound = _on_bound(rec, bounds)
    except InputError as exc:   # e.g. no feasible friction sign in this structure
        res.error = str(exc)
    res.wall_s = time.perf_counter() - t0
    return res, model


def choose(scores, parsimony=PARSIMONY):
    """The score of the structure with the fewest parameters whose free-run RMS is within
    ``parsimony`` of the best (ties: the lower RMS)."""
    ok = [s for s in scores if np.isfinite(s.free_run_rms_mm)]
    if not ok:
        errors = list(dict.fromkeys(s.error for s in scores))
        if len(errors) == 1:     # the data's fault, not a structure's: say it once
            raise InputError(f"no candidate structure could be identified: {errors[0]}", column="structure")
        raise InputError("no candidate structure could be identified: "
                         + "; ".join(f"{s.label}: {s.error}" for s in scores), column="structure")
    best = min(s.free_run_rms_mm for s in ok)
    good = [s for s in ok if s.free_run_rms_mm <= best * (1 + parsimony)]
    return min(good, key=lambda s: (s.parameters, s.free_run_rms_mm))


def candidate(label):
    """The :class:`Candidate` of a label (``r1c2-noI-play8um`` ...; the inverse of its naming)."""
    base, _, play = label.partition("-play")
    cand = next(c for c in family(True) + family(False) if c.label == base)
    return with_play(cand, float(play[:-2]) * 1e-3) if play else cand


def fit_options(traces, axis, v_tilde, seed, maxiter, method, velocity, ma_order):
    """The options every candidate's fit shares (``fit_candidate``'s ``options``)."""
    return dict(v_tilde=v_tilde, seed=seed, maxiter=maxiter, method=method, velocity=velocity,
                ma_order=ma_order, outputs=scored_outputs(traces, axis))


def _run(jobs, workers):
    """fit_candidate over ``jobs``, in ``workers`` processes when more than one."""
    if workers <= 1 or len(jobs) < 2:
        return [fit_candidate(j) for j in jobs]
    with process_pool(min(workers, len(jobs))) as pool:
        return list(pool.map(fit_candidate, jobs))


def other_forms(best, traces, axis, options, workers=1, parsimony=PARSIMONY, fitted=(), model=None):
    """Step 5 of the module docstring: the chosen structure fitted in the other same-sample forms.

    ``fitted``: (CandidateScore, DriveModel) already at hand (step 1's r2c1 fits), not fitted again.
    ``model``: ``best``'s model, whose poles start the ``vp`` searches of the other forms.
    Returns (taken, fits): ``taken`` the (CandidateScore, DriveModel) whose free run is lower
    than ``best``'s by ``parsimony`` (the lowest; None when none is), ``fits`` all of them.
    """
    forms = [f for f in CHOSEN_FROM if f != best.same_sample]
    have = [rm for rm in fitted if rm[0].label == best.label and rm[0].same_sample in forms]
    todo = [f for f in forms if f not in {r.same_sample for r, _ in have}]
    warm = warm_starts(candidate(best.label), model) if model is not None else ()
    fits = have + _run([(candidate(best.label), f, traces, axis, options, warm) for f in todo], workers)
    better = [rm for rm in fits if rm[0].free_run_rms_mm <= (1 - parsimony) * best.free_run_rms_mm]
    return (min(better, key=lambda rm: rm[0].free_run_rms_mm) if better else None), fits


def keep(results, probes, traces, axis, options, workers=1, parsimony=PARSIMONY, own_form=True):
    """Steps 4 and 5 of the module docstring on the fits of :func:`fit_structures`.

    Returns (best, results, probes): the kept CandidateScore, and the lists with step 5's fits
    added (the one taken to ``results``, the others to ``probes``). ``own_form``: False when the
    user pinned the same-sample form (no step 5).
    """
    best = choose([r for r, _ in results], parsimony)
    if not own_form:
        return best, results, probes
    model = next((m for r, m in results if r is best), None)
    taken, fits = other_forms(best, traces, axis, options, workers, parsimony, fitted=probes, model=model)
    new = [rm for rm in fits if rm is not taken and not any(rm is q for q in probes)]
    probes = [rm for rm in probes if rm is not taken] + new
    return (taken[0] if taken else best), results + ([taken] if taken else []), probes


def poles_of(model):
    """(real_hz, complex_hz_zeta, v_tilde dict) of a pole-search model: a warm start."""
    rec = PoleSearchRecord.from_dict(model.identification)
    return (list(rec.real_hz), [tuple(c) for c in rec.complex_hz_zeta],
            dict(rec.extra.get("v_tilde_regressor_mm_s", {})))


def warm_starts(cand, model, Ts=None):
    """Start points of ``cand``'s ``vp`` search from a fitted ``model`` of a neighbouring
    structure: its poles, a real pole dropped (each in turn) or added, a complex pair dropped
    (each in turn) or added, until the counts are ``cand``'s. An added pole sits at a quarter of
    the sampling rate (a pair with zeta 0.7): fast enough to leave the neighbour's fit nearly as
    it was, so the search starts no worse than that fit and moves the new pole where the data
    need it (a lightly damped drive-train mode is left to the Sobol screen beside these starts).
    At most two start points (plant2's r2c1 to rigid: either real pole may be the rigid body's)."""
    real, cplx, vt = poles_of(model)
    fast = 0.25 / (Ts or model.Ts)
    new_pair = (fast, 0.7)
    reals = [real]
    while len(reals[0]) > cand.n_real:
        reals = [r[:k] + r[k + 1:] for r in reals for k in range(len(r))]
    reals = [r + [fast] * (cand.n_real - len(r)) for r in reals]
    pairs = [cplx]
    while len(pairs[0]) > cand.n_complex:
        pairs = [c[:k] + c[k + 1:] for c in pairs for k in range(len(c))]
    pairs = [c + [new_pair] * (cand.n_complex - len(c)) for c in pairs]
    out = []
    for r in reals:
        for c in pairs:
            if (r, c) not in [(a, b) for a, b, _ in out]:
                out.append((r, c, vt))
    return out[:2]


def _fit_structures_vp(traces, axis, forms, opts, submit, run):
    """Steps 1 to 3 with the ``vp`` search: each structure's search starts from the poles of a
    fitted neighbour (:func:`warm_starts`) beside its Sobol screen, and the play widths are
    ranked at r2c2's poles before one of them is searched.

    Stage 1 fits r2c1 in every form; stage 2 every other sat-law structure in the chosen form,
    from r2c1's poles; stage 3 ranks the play widths by the free run of r2c2's poles with the
    numerators projected for each width (:func:`screen_play`), searches the best one from there,
    and where the play law comes within the parsimony margin, every other structure with the
    play from its own sat-law fit's poles."""
    probe = family(True)[1]                          # r2c1
    largest = family(True)[-1]                       # r2c2
    rest = [c for c in family(True) + family(False) if c != probe]
    first = [f.result() for f in [submit((probe, f)) for f in forms]]
    r2c1 = min(first, key=lambda rm: rm[0].free_run_rms_mm)
    form = r2c1[0].same_sample
    ok = r2c1[1] is not None
    # the largest first: the play widths are ranked at its poles while the others run
    rest = sorted(rest, key=lambda c: c != largest)
    futures = [submit((c, form, warm_starts(c, r2c1[1]) if ok else ())) for c in rest]
    base = futures[0].result()
    if base[1] is None:
        width_futures = [submit((with_play(largest, b), form)) for b in PLAY_WIDTHS_MM]
        sat = [r2c1] + [f.result() for f in futures]
        widths = [f.result() for f in width_futures]
        width = min(widths, key=lambda rm: rm[0].free_run_rms_mm)
    else:
        screened = [screen_play(with_play(largest, b), form, traces, axis, opts, base[1])
                    for b in PLAY_WIDTHS_MM]
        k = min(range(len(screened)), key=lambda i: screened[i][0].free_run_rms_mm)
        cand = with_play(largest, PLAY_WIDTHS_MM[k])
        width_future = submit((cand, form, warm_starts(cand, base[1])))
        sat = [r2c1] + [f.result() for f in futures]
        width = width_future.result()
        widths = screened[:k] + [width] + screened[k + 1:]
    by_label = {r.label: (r, m) for r, m in sat}
    b = candidate(width[0].label).play_mm
    play = []
    if width[0].free_run_rms_mm <= (1 + PARSIMONY) * min(r.free_run_rms_mm for r, _ in sat):
        jobs = []
        for c in family(True) + family(False):
            if c == largest:
                continue
            m = by_label[c.label][1]
            jobs.append((with_play(c, b), form, warm_starts(c, m) if m is not None else ()))
        play = run(jobs)
    return sat + [width] + play, [rm for rm in first if rm is not r2c1] + [rm for rm in widths if rm is not width]


def screen_play(cand, form, traces, axis, opts, model):
    """``cand`` (a play-law structure) with ``model``'s poles held, its numerators projected
    (one LS projection and the free runs of :func:`~.pole_search.identify_mimo`'s finish):
    a candidate that ranks play widths for the price of a projection. Returns
    (CandidateScore, DriveModel)."""
    t0 = time.perf_counter()
    real, cplx, _ = poles_of(model)
    st = cand.structure(axis, form, opts["velocity"], opts["ma_order"], opts["outputs"])
    res = CandidateScore(cand.label, parameter_count(st) + 1, form, float("inf"), 0.0,
                         real_hz=real, complex_hz_zeta=[list(c) for c in cplx])
    held = dataclasses.replace(st, n_real=0, n_complex=0, locked_real_hz=list(st.locked_real_hz) + real,
                               locked_complex=list(st.locked_complex) + [tuple(c) for c in cplx])
    out = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LinAlgWarning)
            out = identify_mimo(traces, held, bounds=Bounds([], [], []), v_tilde=opts["v_tilde"])
        res.free_run_rms_mm = free_run_rms(out, traces, axis, opts["outputs"])
    except InputError as exc:
        res.error = str(exc)
    res.wall_s = time.perf_counter() - t0
    return res, out


def fit_structures(traces, axis="x", same_sample=None, v_tilde=None, method="vp", seed=0, maxiter=None,
                   velocity="backward", ma_order=1, workers=1):
    """Steps 1 to 3 of the module docstring: every candidate identified and scored
    (``workers`` > 1: in that many processes).

    Returns
    -------
    (results, probes): lists of (CandidateScore, DriveModel or None); ``results`` share the
    same-sample prediction chosen on r2c1 and are the choice's candidates (:func:`keep` may add
    the kept structure in another form), ``probes`` are the r2c1 fits
    with the other predictions and the r2c2 play fits at the other widths.
    """
    traces = [traces] if not isinstance(traces, (list, tuple)) else list(traces)
    opts = fit_options(traces, axis, v_tilde, seed, maxiter, method, velocity, ma_order)
    forms = [same_sample] if same_sample else list(CHOSEN_FROM)
    pool = process_pool(workers) if workers > 1 else None

    def run(cands, forms):
        jobs = [(c, f, traces, axis, opts) for c in cands for f in forms]
        return list(pool.map(fit_candidate, jobs)) if pool is not None else [fit_candidate(j) for j in jobs]

    probe = family(True)[1]                          # r2c1
    largest = family(True)[-1]                       # r2c2
    rest = [c for c in family(True) + family(False) if c != probe]
    try:
        if method == "vp":
            def submit(job):
                job = (job[0], job[1], traces, axis, opts) + tuple(job[2:])
                if pool is not None:
                    return pool.submit(fit_candidate, job)
                done = Future()
                done.set_result(fit_candidate(job))
                return done

            def run_jobs(jobs):
                return [f.result() for f in [submit(j) for j in jobs]]
            return _fit_structures_vp(traces, axis, forms, opts, submit, run_jobs)
        first = run([probe], forms)
        form = min(first, key=lambda rm: rm[0].free_run_rms_mm)[0].same_sample
        # the play law's width on the largest structure (where missing dynamics cannot stand in
        # for it), fitted beside the sat-law candidates
        both = run(rest + [with_play(largest, b) for b in PLAY_WIDTHS_MM], [form])
        sat, widths = both[:len(rest)], both[len(rest):]
        sat = [rm for rm in first if rm[0].same_sample == form] + sat
        width = min(widths, key=lambda rm: rm[0].free_run_rms_mm)
        b = PLAY_WIDTHS_MM[widths.index(width)]
        # the other structures with the play only where the law can win: its largest structure
        # within the parsimony margin of the best sat-law one (the virtual drive: 4.6x off)
        play = []
        if width[0].free_run_rms_mm <= (1 + PARSIMONY) * min(r.free_run_rms_mm for r, _ in sat):
            play = run([with_play(c, b) for c in family(True) + family(False) if c != largest], [form])
        results = sat + [width] + play
    finally:
        if pool is not None:
            pool.shutdown()
    return results, [rm for rm in first if rm[0].same_sample != form] + [rm for rm in widths if rm is not width]


def identify_auto(traces, axis="x", same_sample=None, v_tilde=None, method="vp", seed=0, maxiter=None,
                  velocity="backward", ma_order=1, workers=None, parsimony=PARSIMONY):
    """Pole search with the structure chosen from the data (see module docstring).

    Parameters
    ----------
    traces : Trace or list[Trace], training data ranges
    axis : the axis to identify
    same_sample : ``hold`` / ``quadratic`` / ``cubic`` to pin the same-sample prediction
        (default: every form of ``regressors.CHOSEN_FROM`` tried on r2c1, then on the kept
        structure: steps 1 and 5 of the module docstring)
    v_tilde, method, seed, maxiter, velocity, ma_order : as :func:`~.pole_search.identify_mimo`
        (``method``: ``vp``, the default, runs the warm-started searches of the module
        docstring's "Search"; any other method fits every candidate from scratch)
    workers : processes fitting candidates in parallel (None: every core, ``os.cpu_count()``; 1: in
        this process; :func:`fdid_fmi.workers.process_pool`); the fits are the same for any
        number, to the last bit when this process runs BLAS on one thread as the workers do
    parsimony : relative free-run margin a structure with more parameters must win by

    Returns
    -------
    DriveModel, method ``pole-search``, with ``identification["structure_choice"]``
    (:meth:`StructureChoice.to_dict`).
    """
    t0 = time.perf_counter()
    traces = training_ranges(traces, [axis])     # one line, not the same one from every candidate
    workers = worker_count(workers)
    results, probes = fit_structures(traces, axis, same_sample, v_tilde, method, seed, maxiter, velocity,
                                     ma_order, workers)
    opts = fit_options(traces, axis, v_tilde, seed, maxiter, method, velocity, ma_order)
    best, results, probes = keep(results, probes, traces, axis, opts, workers, parsimony,
                                 own_form=same_sample is None)
    best.chosen = True
    model = next(m for r, m in results if r is best)
    # the kept structure's only: with every candidate measured the suite neared its CPU budget
    best.sensitivity_mm = max(rounding_sensitivity(model, tr) for tr in traces)
    model.method = "pole-search"
    choice = StructureChoice(axis=axis, chosen=best.label, same_sample=best.same_sample,
                             candidates=[r for r, _ in results + probes], parsimony=parsimony,
                             workers=workers, wall_s=time.perf_counter() - t0,
                             outputs=scored_outputs(traces, axis))
    rec = PoleSearchRecord.from_dict(model.identification)
    rec.structure_choice = choice.to_dict()
    model.identification = rec.to_dict()
    model.metrics["wall_time_s"] = choice.wall_s
    return model
