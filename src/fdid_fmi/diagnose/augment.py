"""Augmentation: add a detected effect to a model's structure and refit it with the pole search.

A :class:`Recipe` is everything needed to refit a pole-search model: its structure (inputs,
outputs, numerator masks), its current poles, the friction transition velocity, the dead time per
axis and the effects added so far. Effects change the recipe; :func:`fit` turns a recipe into a
:class:`~fdid_fmi.model.DriveModel` with the pole-search engine (``identify_mimo``), so every
effect is an ordinary part of the state space and the exported FMU carries it without special
code:

==========================  ======================================================================
effect (``kind``)           how the model carries it
==========================  ======================================================================
``stribeck``                feature input s exp(-(v/v_s)^2), s = sat(v / v_tilde), through the
                            friction path's numerator terms; on a play-law axis s is the play
                            (``play_stribeck``), and a sat-law axis can also be tried in the
                            play law (:func:`to_play_law`)
``asymmetric_friction``     feature input |sat(v / v_tilde)| (a direction-independent friction
                            offset), friction path terms
``backlash``                feature input sat(v / v_b) on a fitted tool-side output (all numerator
                            terms: a d.c. offset of -b/2 per direction), none on the motor side
``periodic_position``       feature inputs sin / cos(2 pi x / lambda) of the model's own position,
                            friction (force) path terms
``coupling``                external input: another axis's commanded position (all terms but
                            the d.c. one)
``extra_input``             external input: an unused trace channel (all numerator terms)
``mode``                    one more complex pole pair, searched near the detected frequency
(order check)               one more real pole (:func:`add_real_pole`, :mod:`.order`): a
                            structure check, not an effect
``delay``                   a d-sample delay line on the COMMAND input inside A/B: the LTI part is
                            fitted to x_r(k - d) and the derived error row still uses x_r(k)
==========================  ======================================================================

Numerator masks are kept as sets of powers of s relative to the order n (``b[l]`` multiplies
s^(n-l)); a mode multiplies every numerator by a quadratic (:func:`_times_quadratic`); the order
check's real pole keeps the powers, a path that had the highest power keeping all high powers
(:func:`_shift_mask`). In both the low powers (d.c. terms) keep their meaning.

Refits (``search``): ``locked`` one LS projection with every pole fixed (screening of effect
parameters); ``local`` the poles searched in a window around their current values (real poles
/ 2 .. x 2, natural frequencies / 1.5 .. x 1.5, damping / 3 .. x 3), new pairs in their own
bounds; ``wide`` the default search space of the engine (a dead time moves the poles far).
v_tilde stays at the model's value. The pole search of every refit is the recipe's ``method``
(``identify_mimo``'s): ``de`` (default: differential evolution) or ``vp`` (variable projection,
Gauss-Newton from a Sobol screen and the start point); ``maxiter`` counts the residual evaluations
of each ``vp`` local search (besides its Jacobians) or the generations of ``de``.
"""
from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import LinAlgWarning

from ..errors import InputError
from ..identify.pole_search import identify_mimo
from ..identify.record import PoleSearchRecord
from ..identify.structure import Bounds, InputSpec, OutputSpec, Structure, default_bounds
from ..model import DriveModel, is_play, port_name
from .residuals import delayed, with_channels


@dataclass
class Recipe:
    """How to (re)build a diagnosed model; see module docstring."""

    inputs: list                    # InputSpec
    outputs: list                   # OutputSpec
    masks: dict                     # (out name, in name) -> frozenset of s-powers
    dc_gain: dict
    friction_sign: dict
    velocity: str
    ma_order: int
    same_sample: str
    real_hz: list                   # searched poles (current values)
    complex_hz_zeta: list           # [(hz, zeta)]
    v_tilde: dict                   # axis -> mm/s
    locked_real_hz: list = field(default_factory=list)      # known poles the user kept out of the
    locked_complex: list = field(default_factory=list)      # search: locked in every refit too
    new_pairs: list = field(default_factory=list)    # bounds [(lo_hz, hi_hz, zlo, zhi)] searched
    delays: dict = field(default_factory=dict)       # axis -> samples
    effects: list = field(default_factory=list)      # effect dicts added by diagnosis
    structure_chosen: bool = False                   # its structure was chosen from data (fdid
                                                     # identify's default), kept through refits
    reserved: set = field(default_factory=set)       # port names new inputs must not take (the
                                                     # other blocks of a combined per-axis model)
    method: str = "de"                               # pole search of every refit (METHODS)

    @property
    def order(self):
        return (len(self.real_hz) + len(self.locked_real_hz)
                + 2 * (len(self.complex_hz_zeta) + len(self.locked_complex) + len(self.new_pairs)))

    def copy(self):
        return copy.deepcopy(self)

    @property
    def axes(self):
        return [s.axis for s in self.inputs if s.kind == "command"]

    def input_names(self):
        return [s.name for s in self.inputs]


METHODS = ("vp", "de")      # pole searches of a refit (identify_mimo's method)


def recipe_from_model(model: DriveModel, reserved=(), method="de") -> Recipe:
    """Recipe of a pole-search / MIMO model (``identification["structure"]`` must be present).
    Its refits use the pole search ``method`` (one of :data:`METHODS`).

    A combined per-axis model (``identification["blocks"]``) is diagnosed block by block
    (:func:`.loop.split_blocks`); ``reserved`` are port names of the other blocks, which inputs
    added to this block must not take (the combined model needs unique names).
    """
    if method not in METHODS:
        raise InputError(f"unknown refit search '{method}'; choose one of {METHODS}", column="search")
    ident = model.identification or {}
    if not isinstance(ident, dict):
        raise InputError(f"the model's identification record is a {type(ident).__name__}, not a table; "
                         "identify the model again", column="identification")
    if not ident.get("structure"):
        what = ("a combined per-axis model: diagnose its blocks (diagnose() splits it)"
                if ident.get("blocks") else f"method '{model.method or 'unknown'}'")
        raise InputError(f"diagnosis refits the model with the pole search and needs a pole-search or "
                         f"MIMO model (fdid identify --method pole-search or mimo); this model's "
                         f"identification has no 'structure' ({what})", column="identification")
    try:
        rec = PoleSearchRecord.from_dict(ident)
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:    # a damaged or hand-edited record
        raise InputError(f"the model's identification record is damaged ({type(exc).__name__}: {exc}); "
                         "identify the model again", column="identification") from None
    st = rec.structure
    hz = list(rec.all_real_hz) + [w for w, _ in rec.all_complex]
    zeta = [z for _, z in rec.all_complex]
    if not all(np.isfinite(f) and f > 0 for f in hz) or not all(np.isfinite(z) and z > 0 for z in zeta):
        raise InputError(f"the model's identification record has a pole that is not a positive finite "
                         f"frequency / damping (real_hz {list(rec.all_real_hz)}, complex_hz_zeta "
                         f"{[list(c) for c in rec.all_complex]}); identify the model again",
                         column="identification")
    n_rec = len(rec.all_real_hz) + 2 * len(rec.all_complex)
    if model.poles is not None and len(model.poles) and n_rec != len(model.poles):
        raise InputError(f"the model's identification record lists {n_rec} poles (real_hz, "
                         f"complex_hz_zeta and the locked ones) but the model has {len(model.poles)}; "
                         "the record does not describe this model: identify it again",
                         column="identification")
    n = len(rec.all_real_hz) + 2 * len(rec.all_complex)
    vt = dict(rec.v_tilde_mm_s)
    for a in [s.axis for s in st.inputs if s.kind == "friction"]:
        if a not in vt:
            vt[a] = float(model.inputs[model.input_index("friction", a)].params["v_tilde"])
    return Recipe(inputs=st.inputs, outputs=st.outputs,
                  masks={k: frozenset(n - l for l in ls) for k, ls in st.mask.items()},
                  dc_gain=dict(st.dc_gain), friction_sign=dict(st.friction_sign), velocity=st.velocity,
                  ma_order=st.ma_order, same_sample=st.same_sample or "quadratic",
                  real_hz=list(rec.real_hz), complex_hz_zeta=[tuple(c) for c in rec.complex_hz_zeta],
                  locked_real_hz=list(rec.locked_real_hz),
                  locked_complex=[tuple(c) for c in rec.locked_complex], v_tilde=vt,
                  delays={a: int(d) for a, d in rec.diagnose.get("delays", {}).items()},
                  effects=list(model.effects), reserved=set(reserved), method=method,
                  structure_chosen=bool(rec.structure_choice or rec.diagnose.get("structure_chosen")))


# ------------------------------------------------------------------------- structure
def _shift_mask(powers, n_old, n_new):
    """Masks as s-powers survive an order change; a mask that reached s^n_old reaches s^n_new."""
    p = set(powers)
    if n_old in p:
        p |= set(range(n_old + 1, n_new + 1))
    return frozenset(p)


def _times_quadratic(powers, n_new):
    """The s-powers of a numerator multiplied by a general quadratic a s^2 + b s + c: a mode is a
    compliant drive train, and a path through it gains up to two zeros (a force on the motor
    side, two-mass, to the motor position: (m_t s^2 + c s + k) / (s^2 (m_m m_t s^2 + (m_m + m_t)
    (c s + k))), the load's anti-resonance; a force on the tool side: c s + k, a general
    quadratic with a = 0). The rigid body's friction path d0 s (Eqn 4.10) becomes
    s (d0 + d1 s + d2 s^2); its lowest power, the d.c. meaning, is kept. Found on plant2's mode
    (the measuring plant): with d0 s alone the fitted pair sat 5 % below the closed loop's
    (docs/method.md, section 6)."""
    p = set(powers)
    return frozenset(q for q in p | {x + 1 for x in p} | {x + 2 for x in p} if q <= n_new)


def structure_of(recipe: Recipe, search="local"):
    """(Structure, Bounds or None) for a refit of the recipe."""
    n = recipe.order
    locked_real, locked_cplx = list(recipe.locked_real_hz), list(recipe.locked_complex)
    if search == "locked":
        n_real, n_cplx = 0, 0
        locked_real += list(recipe.real_hz)
        locked_cplx += list(recipe.complex_hz_zeta) + [((lo * hi) ** 0.5, (zl * zh) ** 0.5)
                                                       for lo, hi, zl, zh in recipe.new_pairs]
    else:
        n_real, n_cplx = len(recipe.real_hz), len(recipe.complex_hz_zeta) + len(recipe.new_pairs)
    mask = {}
    for key, pw in recipe.masks.items():
        ls = tuple(sorted(n - p for p in pw if 0 <= n - p <= n))
        mask[key] = ls
    st = Structure(inputs=copy.deepcopy(recipe.inputs), outputs=copy.deepcopy(recipe.outputs),
                   n_real=n_real, n_complex=n_cplx, locked_real_hz=locked_real,
                   locked_complex=locked_cplx, mask=mask, dc_gain=dict(recipe.dc_gain),
                   friction_sign=dict(recipe.friction_sign), velocity=recipe.velocity,
                   ma_order=recipe.ma_order, same_sample=recipe.same_sample)
    return st, n_real, n_cplx


def _window(f, factor, hi_cap):
    """Local search window (f / factor, f * factor) in Hz, floored at 0.05 Hz unless that empties
    it (a pole slower than 0.05 Hz, possible with user bounds) and capped below Nyquist."""
    hi = min(hi_cap, f * factor)
    lo = max(0.05, f / factor)
    return (lo if lo < hi else f / factor), hi


def _bounds(recipe: Recipe, Ts, search):
    nyq = 0.5 / Ts
    hi_cap = 0.95 * nyq
    if search == "locked":
        return Bounds([], [], [], None)
    if search == "wide":
        b = default_bounds(Ts, len(recipe.real_hz), len(recipe.complex_hz_zeta))
        real, om, ze = list(b.real_hz), list(b.omega_hz), list(b.zeta)
    else:
        real = [_window(p, 2.0, hi_cap) for p in recipe.real_hz]
        om = [_window(w, 1.5, hi_cap) for w, _ in recipe.complex_hz_zeta]
        ze = [(max(0.003, z / 3.0), min(4.0, max(z * 3.0, 0.01))) for _, z in recipe.complex_hz_zeta]
    for lo, hi, zl, zh in recipe.new_pairs:
        om.append((max(0.05, lo), min(hi_cap, hi)))
        ze.append((zl, zh))
    return Bounds(real, om, ze, None)


def shifted_traces(recipe: Recipe, traces):
    """Training traces with each delayed axis's command shifted by its dead time."""
    if not any(recipe.delays.values()):
        return list(traces)
    out = []
    for tr in traces:
        rep = {tr.roles[a]["cmd"]: delayed(tr.cmd(a), d) for a, d in recipe.delays.items() if d}
        out.append(with_channels(tr, rep, source_suffix=""))
    return out


def model_velocity_traces(model: DriveModel, traces):
    """Traces whose ``vel`` role is the free-run velocity of ``model`` (mm/s).

    The engine computes friction and feature regressors from the trace's velocity. The encoder's
    backward difference is noisy at low speed (quantisation / noise over one sample: a few tenths
    of mm/s), where friction features live; the model's own free-run velocity is smooth and is
    what the features see in simulation and in the FMU, so refits use it.
    """
    from ..simulate import simulate
    out = []
    for tr in traces:
        sim = simulate(model, tr)
        rep, roles = {}, {a: dict(r) for a, r in tr.roles.items()}
        for a in model.axes:
            name = f"{a}_vel_model"
            rep[name] = sim.axes[a]["velocity"]
            roles[a]["vel"] = name
        t2 = with_channels(tr, rep)
        t2.roles = roles
        t2._check()
        out.append(t2)
    return out


def fit(recipe: Recipe, traces, search="local", maxiter=25, popsize=8, seed=0, refine=True,
        from_current=False, select=True) -> DriveModel:
    """Refit a recipe on training traces with the pole-search engine (see module docstring).

    ``traces`` should carry the velocity the features are to see (:func:`model_velocity_traces`).
    The pole search is the recipe's ``method``; ``maxiter`` and ``popsize`` are its settings
    (``search.run_search``: residual evaluations of each ``vp`` local search, generations and
    population of ``de``).
    ``refine``: the engine's simulation-consistent friction refinement (off for quick screening).
    ``select``: the engine's pick by training free run among near-best minima, with ``vp`` its
    free-run polish (``identify_mimo``; off where only the LS objective is read).
    ``from_current``: start the search from the recipe's poles (new pairs: the middle of their
    bounds), so that the search ends no worse in the LS objective than that start.

    Returns
    -------
    DriveModel with ``effects`` = the recipe's effects, dead times as delay lines, and
    ``identification["diagnose"]`` recording the recipe's delays.
    """
    traces = [traces] if not isinstance(traces, (list, tuple)) else list(traces)
    st, n_real, n_cplx = structure_of(recipe, search)
    Ts = traces[0].Ts
    bounds = _bounds(recipe, Ts, search)
    if search != "locked":
        bounds = Bounds(bounds.real_hz[:n_real], bounds.omega_hz[:n_cplx], bounds.zeta[:n_cplx], None)
    with warnings.catch_warnings():   # near-collinear regressors of a candidate: LS still solved
        warnings.simplefilter("ignore", LinAlgWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        model = identify_mimo(shifted_traces(recipe, traces), st, bounds=bounds,
                              v_tilde=dict(recipe.v_tilde), method=recipe.method, seed=seed, maxiter=maxiter,
                              popsize=popsize, refine=refine, select=select,
                              start=_start(recipe) if from_current and search != "locked" else None)
    model.method = "pole-search+diagnose"
    for a, d in recipe.delays.items():
        if d:
            model = add_command_delay(model, a, d)
    model.identification["diagnose"] = {"delays": {a: int(d) for a, d in recipe.delays.items() if d}}
    if recipe.structure_chosen:     # a diagnosed model's notes still know how its structure came about
        model.identification["diagnose"]["structure_chosen"] = True
    model.effects = copy.deepcopy(recipe.effects)
    return model


def fit_objective(recipe: Recipe, traces, **kw):
    """The scaled LS objective of :func:`fit` (one point of a parameter scan); inf when the
    pole search finds no feasible model there (``identify_mimo`` raises InputError).

    Under ``vp`` a local scan point's search starts from the recipe's poles (``from_current``,
    unless given) and its best LS minimum is the result (``select`` off): the scan reads
    differences of the LS objective between neighbouring parameter values, which searches from
    one start read without the scatter of where searches from a screen end, and which the pick
    by free run and the polish, at a higher objective, only blur.
    """
    if recipe.method == "vp":
        kw = {"from_current": True, "select": False, **kw}
    try:
        return fit(recipe, traces, **kw).metrics["objective_scaled_rms"]
    except InputError:
        return np.inf


def _start(recipe: Recipe):
    """The recipe's poles as a search start: (real_hz, complex_hz_zeta), new pairs at the
    geometric middle of their bounds."""
    pairs = [(np.sqrt(lo * hi), np.sqrt(zl * zh)) for lo, hi, zl, zh in recipe.new_pairs]
    return list(recipe.real_hz), [tuple(c) for c in recipe.complex_hz_zeta] + pairs


def _reached_by(model: DriveModel, first_input):
    """Boolean mask of the outputs that inputs ``first_input:`` feed (through D or the states
    their B columns drive, closed under A)."""
    reach = np.any(model.B[:, first_input:] != 0, axis=1)
    while True:
        more = reach | np.any(model.A[:, reach] != 0, axis=1)
        if (more == reach).all():
            break
        reach = more
    return np.any(model.D[:, first_input:] != 0, axis=1) | np.any(model.C[:, reach] != 0, axis=1)


def keep_base_outputs(base: DriveModel, fitted: DriveModel) -> DriveModel:
    """``fitted`` with every output it shares with ``base`` (by name) and that its added inputs
    do not feed predicted as ``base`` predicts it (to rounding: the composition's
    steady-state maps are computed on larger matrices).

    A ``locked`` refit keeps the poles and adds inputs and outputs (a backlash input on a
    tool-side output); its LS also refits the numerators of the outputs the effect does not
    concern, from the model's free-run velocity and without the engine's refinement, which moved
    plant2's motor side 11-14 % (held out). The result is the parallel composition: states
    [base; fitted]; outputs the added inputs do not reach come from base's states, the others
    (the effect's) from fitted's. Its ``poles``, ``identification`` and ``metrics`` are those of
    ``fitted`` (the refit that the next round's recipe continues from). ``fitted`` itself is
    returned when base's inputs are not its leading inputs.
    """
    k = len(base.inputs)
    if [(p.name, p.kind, p.params) for p in fitted.inputs[:k]] != [(p.name, p.kind, p.params) for p in base.inputs]:
        return fitted
    nb, nf, m = base.n_states, fitted.n_states, len(fitted.inputs)
    A = np.zeros((nb + nf, nb + nf))
    A[:nb, :nb], A[nb:, nb:] = base.A, fitted.A
    B = np.zeros((nb + nf, m))
    B[:nb, :k], B[nb:] = base.B, fitted.B
    C = np.hstack([np.zeros((len(fitted.outputs), nb)), fitted.C])
    D = np.array(fitted.D, float)
    rows = {p.name: i for i, p in enumerate(base.outputs)}
    touched = _reached_by(fitted, k)
    for j, p in enumerate(fitted.outputs):
        i = rows.get(p.name)
        if i is not None and not touched[j]:
            C[j] = 0.0
            C[j, :nb] = base.C[i]
            D[j] = 0.0
            D[j, :k] = base.D[i]
    out = copy.deepcopy(fitted)
    out.A, out.B, out.C, out.D = A, B, C, D
    return out


def other_same_sample(recipe: Recipe) -> Recipe:
    """The recipe with the other kind of causal same-sample prediction: hold for a look-ahead form
    (quadratic, cubic), quadratic for hold."""
    r = recipe.copy()
    r.same_sample = "hold" if recipe.same_sample != "hold" else "quadratic"
    return r


def _without(values, remove):
    """``values`` with one occurrence of each of ``remove`` taken out (exact: locked poles are
    passed through the pole search unchanged)."""
    out = list(values)
    for v in remove:
        out.remove(v)
    return out


def updated_recipe(recipe: Recipe, model: DriveModel) -> Recipe:
    """The recipe with the poles of a fitted model as the new current values (pairs found)."""
    r = recipe.copy()
    rec = PoleSearchRecord.from_dict(model.identification)
    # a refit with search="locked" records every pole as locked: the user's stay locked, the rest
    # are the recipe's searched poles
    r.real_hz = _without(rec.all_real_hz, r.locked_real_hz)
    r.complex_hz_zeta = _without(rec.all_complex, [tuple(c) for c in r.locked_complex])
    r.new_pairs = []
    return r


# --------------------------------------------------------------------------- delay line
def add_command_delay(model: DriveModel, axis, d):
    """Append a d-sample delay line to the command input of ``axis`` inside A/B.

    The LTI part then sees x_r(k - d): every output row that used x_r now reads the last register
    z_d = x_r(k - d), and the ``error`` output becomes e = x_r(k) - x (undelayed command minus
    delayed-response position). The position output is not delayed itself, so the friction
    solve stays exact (DESIGN.md, simulation semantics).
    """
    d = int(d)
    if d <= 0:
        return model
    ic = model.input_index("command", axis)
    if ic is None:
        raise InputError(f"model has no command input for axis '{axis}'", column="delay")
    A, B, C, D = model.A, model.B, model.C, model.D
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    N = n + d
    A2 = np.zeros((N, N))
    A2[:n, :n] = A
    A2[:n, n + d - 1] = B[:, ic]               # LTI part driven by z_d
    A2[n + 1:, n:n + d - 1] = np.eye(d - 1)    # z_j <- z_{j-1}
    B2 = np.zeros((N, m))
    B2[:n] = B
    B2[:n, ic] = 0.0
    B2[n, ic] = 1.0                            # z_1 <- x_r(k)
    C2 = np.zeros((p, N))
    C2[:, :n] = C
    C2[:, n + d - 1] = D[:, ic]
    D2 = D.copy()
    D2[:, ic] = 0.0
    ie = model.output_index("error", axis)
    if ie is not None:                          # e = x_r(k) - x: correct the fitted e' = x_r(k-d) - x
        C2[ie, n + d - 1] -= 1.0
        D2[ie, ic] += 1.0
    out = DriveModel(Ts=model.Ts, A=A2, B=B2, C=C2, D=D2, inputs=model.inputs, outputs=model.outputs,
                     method=model.method, poles=model.poles, identification=model.identification,
                     metrics=model.metrics, effects=model.effects, provenance=model.provenance,
                     limits=model.limits)
    return out


# --------------------------------------------------------------------------- effects
def friction_path(inputs, axis):
    """Index in ``inputs`` (model ports or structure inputs) of the friction force of ``axis``:
    its friction input sat(v/v_tilde), else its play feature (the play friction law), else None."""
    for law in (lambda s: s.kind == "friction", is_play):
        for i, s in enumerate(inputs):
            if s.axis == axis and law(s):
                return i
    return None


def _friction_input(recipe, axis):
    i = friction_path(recipe.inputs, axis)
    return None if i is None else recipe.inputs[i]


def _force_path_masks(recipe, axis, new_name, outputs=None):
    """Masks for a force-like input: those of the axis's friction input (thesis: the disturbance
    path), or s^(n-1)..s^1 when the model has no friction input."""
    fr = _friction_input(recipe, axis)
    n = recipe.order
    out = {}
    for o in recipe.outputs:
        if o.axis != axis or (outputs is not None and o.name not in outputs):
            continue
        if fr is not None and (o.name, fr.name) in recipe.masks:
            out[(o.name, new_name)] = recipe.masks[(o.name, fr.name)]
        else:
            out[(o.name, new_name)] = frozenset(range(1, n))
    return out


def _unique(recipe, name):
    names = set(recipe.input_names()) | set(recipe.reserved)
    base, k = name, 2
    while name in names:
        name = f"{base}_{k}"
        k += 1
    return name


def add_feature(recipe: Recipe, axis, function, params, kind, effect_params, name=None):
    """Recipe with a feature input on the axis's force path (Stribeck, asymmetry, periodic)."""
    r = recipe.copy()
    nm = _unique(r, name or f"{axis}_{function}")
    spec = InputSpec("feature", axis, params={"function": function, **params}, name=nm)
    r.inputs.append(spec)
    r.masks.update(_force_path_masks(r, axis, nm))
    for o in r.outputs:      # outputs of other axes: no path
        if o.axis != axis:
            r.masks[(o.name, nm)] = frozenset()
    if kind:
        r.effects.append({"kind": kind, "axis": axis, **effect_params})
    return r


def to_play_law(recipe, axis, b):
    """Recipe with the axis's friction law sat(v / v_tilde) replaced by the play of half-width
    ``b`` (mm), with the friction's numerator terms and sign (the structure choice's play law,
    ``identify.structure.mimo_structure``)."""
    r = recipe.copy()
    i = friction_path(r.inputs, axis)       # its sat(v / v_tilde) input
    old, new = r.inputs[i].name, _unique(r, f"{axis}_play")
    r.inputs[i] = InputSpec("feature", axis, params={"function": "play", "width_mm": float(b),
                                                     "source": "position"}, name=new)
    r.masks = {(o, new if n == old else n): v for (o, n), v in r.masks.items()}
    r.friction_sign = {(o, new if n == old else n): v for (o, n), v in r.friction_sign.items()}
    r.v_tilde.pop(axis, None)
    return r


def add_stribeck(recipe, axis, v_s):
    """Recipe with the Stribeck term of the axis's friction law: s exp(-(v / v_s)^2) with s its
    sat(v / v_tilde), or its play (``play_stribeck``: the breakaway then holds at rest as the
    play does)."""
    fr = _friction_input(recipe, axis)
    if fr is not None and is_play(fr):
        b = float(fr.params["width_mm"])
        r = add_feature(recipe, axis, "play_stribeck", {"width_mm": b, "v_s": float(v_s), "source": "position"},
                        "stribeck", {"v_s_mm_s": float(v_s), "width_mm": b}, name=f"{axis}_stribeck")
    else:
        vt = recipe.v_tilde.get(axis, max(1e-3, v_s / 10))
        r = add_feature(recipe, axis, "stribeck", {"v_tilde": vt, "v_s": float(v_s), "source": "position"},
                        "stribeck", {"v_s_mm_s": float(v_s), "v_tilde_mm_s": vt}, name=f"{axis}_stribeck")
    r.effects[-1]["input"] = r.inputs[-1].name      # its port (a name taken by another input is suffixed)
    return r


def add_asymmetry(recipe, axis):
    vt = recipe.v_tilde.get(axis, 1.0)
    r = add_feature(recipe, axis, "abs_sat", {"v_tilde": vt, "source": "position"},
                    "asymmetric_friction", {"v_tilde_mm_s": vt}, name=f"{axis}_asym")
    r.effects[-1]["input"] = r.inputs[-1].name
    return r


def _dc_outputs(recipe, axis):
    """The axis's motor-side error and position outputs: where a constant force has a d.c. effect
    unless an integrator in the loop holds the motor (not velocity or acceleration)."""
    return [o for o in recipe.outputs if o.axis == axis and o.predicts in ("error", "position")
            and not is_tool_side(o)]


def has_integral_action(recipe, axis):
    """True when the axis's friction reaches its motor-side error or position through a path
    without a d.c. gain: the thesis's s/P(s) (Eqn 4.10), an integrator in the loop that holds the
    motor against a constant force (``identify.structure.default_mask``)."""
    i = friction_path(recipe.inputs, axis)
    if i is None:
        return False
    name = recipe.inputs[i].name
    return any((m := recipe.masks.get((o.name, name))) and 0 not in m for o in _dc_outputs(recipe, axis))


def without_integral_action(recipe, axis):
    """The recipe's P-loop twin: the axis's friction reaches its motor-side error and position with
    a d.c. gain (the s^0 term, 1/P(s), as in the ``-noI`` structures of
    ``identify.choose_structure``; features added earlier keep their paths)."""
    r = recipe.copy()
    name = r.inputs[friction_path(r.inputs, axis)].name
    for o in _dc_outputs(r, axis):
        if r.masks.get((o.name, name)):
            r.masks[(o.name, name)] = r.masks[(o.name, name)] | {0}
    return r


def add_periodic(recipe, axis, period_mm):
    r = add_feature(recipe, axis, "sin_position", {"period_mm": float(period_mm), "source": "position"},
                    None, {}, name=f"{axis}_sin")
    r = add_feature(r, axis, "cos_position", {"period_mm": float(period_mm), "source": "position"},
                    None, {}, name=f"{axis}_cos")
    r.effects.append({"kind": "periodic_position", "axis": axis, "period_mm": float(period_mm),
                      "inputs": [r.inputs[-2].name, r.inputs[-1].name]})
    return r


TOOL_KINDS = ("tool_error", "tool_position")


def is_tool_side(o):
    """True for a fitted output that is or predicts the tool side: measured there (``tool_error``,
    ``tool_position``) or integrated to it (a tool-side ``acceleration`` with two integrators
    predicts ``tool_position``, Eqn 5.26-5.29)."""
    return o.kind in TOOL_KINDS or getattr(o, "predicts", None) in TOOL_KINDS


def carries_lost_motion(recipe, axis):
    """True when the friction input of ``axis`` reaches a tool-side output with a d.c. term
    (``identify.structure.default_mask``): the model carries a lost motion itself, and a backlash
    feature sat(v/v_b) at v_b = v_tilde would be the same regressor there (recipe masks hold
    s-powers: the d.c. term is power 0)."""
    fr = _friction_input(recipe, axis)
    return fr is not None and any(0 in recipe.masks.get((o.name, fr.name), ()) for o in recipe.outputs
                                  if o.axis == axis and o.kind in TOOL_KINDS)


def add_tool_output(recipe, axis):
    """Recipe with a fitted tool-side output (tool_error, same inputs and masks as the error);
    unchanged when an output of the axis already is or predicts the tool side (:func:`is_tool_side`)."""
    r = recipe.copy()
    if any(o.axis == axis and is_tool_side(o) for o in r.outputs):
        return r
    ref = next((o for o in r.outputs if o.axis == axis and o.kind == "error"), None)
    if ref is None:
        raise InputError(f"a tool-side output needs a fitted tracking-error output of axis '{axis}'",
                         column="backlash")
    to = OutputSpec("tool_error", axis)
    r.outputs.append(to)
    for s in r.inputs:
        if (ref.name, s.name) in r.masks:
            r.masks[(to.name, s.name)] = r.masks[(ref.name, s.name)]
    return r


def add_backlash(recipe, axis, v_b):
    """Feature sat(v / v_b) on a tool-side output (added if missing), none on the motor side."""
    r = add_tool_output(recipe, axis)
    n = r.order
    tool = [o for o in r.outputs if o.axis == axis and is_tool_side(o)]
    nm = _unique(r, f"{axis}_backlash")
    r.inputs.append(InputSpec("feature", axis, params={"function": "sat", "v_tilde": float(v_b),
                                                      "source": "position"}, name=nm))
    for o in r.outputs:
        r.masks[(o.name, nm)] = frozenset(range(0, n + 1)) if o in tool else frozenset()
    r.effects.append({"kind": "backlash", "axis": axis, "v_b_mm_s": float(v_b), "input": nm,
                      "output": tool[0].name})
    return r


def add_external(recipe, axis, channel, kind, effect_params, powers=None):
    """External input from a trace channel with its own numerator on the axis's outputs."""
    r = recipe.copy()
    n = r.order
    nm = _unique(r, port_name(channel))
    r.inputs.append(InputSpec("external", axis, channel=channel, name=nm))
    pw = frozenset(range(0, n + 1)) if powers is None else frozenset(powers)
    for o in r.outputs:
        r.masks[(o.name, nm)] = pw if o.axis == axis else frozenset()
    r.effects.append({"kind": kind, "axis": axis, "channel": channel, "input": nm, **effect_params})
    return r


def add_mode(recipe, axis, frequency_hz, rel=0.15, zeta=(0.005, 0.5)):
    """One more complex pair, searched in frequency_hz / (1 + rel) .. x (1 + rel), and every
    numerator multiplied by a quadratic (:func:`_times_quadratic`)."""
    r = recipe.copy()
    r.new_pairs.append((frequency_hz / (1 + rel), frequency_hz * (1 + rel), zeta[0], zeta[1]))
    r.masks = {k: _times_quadratic(v, r.order) for k, v in r.masks.items()}
    r.effects.append({"kind": "mode", "axis": axis, "detected_hz": float(frequency_hz)})
    return r


def add_real_pole(recipe, frequency_hz):
    """One more real pole at ``frequency_hz``: the structure of the order check (:mod:`.order`),
    not an effect (nothing is added to ``effects``). Numerators keep their s-powers
    (:func:`_shift_mask`; a mode multiplies them by a quadratic, :func:`_times_quadratic`), so a
    strictly proper path gains one degree of relative order: the new structure does not contain
    the given one exactly.
    """
    r = recipe.copy()
    n_old = r.order
    r.real_hz = list(r.real_hz) + [float(frequency_hz)]
    r.masks = {k: _shift_mask(v, n_old, r.order) for k, v in r.masks.items()}
    return r


def add_delay(recipe, axis, samples):
    r = recipe.copy()
    r.delays[axis] = int(r.delays.get(axis, 0)) + int(samples)
    r.effects.append({"kind": "delay", "axis": axis, "samples": int(r.delays[axis])})
    return r


def describe_fitted(model: DriveModel, effect: dict) -> dict:
    """Effect parameters read back from the fitted model (frequency / damping of a mode,
    numerator ratios of friction features to the Coulomb path)."""
    e = dict(effect)
    rec = PoleSearchRecord.from_dict(model.identification)
    nums = rec.numerators
    if e["kind"] == "mode":
        pairs = [tuple(c) for c in rec.complex_hz_zeta]
        if pairs:
            f0 = e.get("detected_hz", pairs[-1][0])
            w, z = min(pairs, key=lambda c: abs(np.log(c[0] / f0)))
            e["frequency_hz"], e["damping"] = float(w), float(z)
    if e["kind"] in ("stribeck", "asymmetric_friction"):
        default = {"stribeck": f"{e['axis']}_stribeck", "asymmetric_friction": f"{e['axis']}_asym"}[e["kind"]]
        name = e.get("input", default)      # effects written before the input was recorded: the default
        ratio = _ratio_to_friction(model, e["axis"], name, nums)
        if ratio is not None:
            e["ratio_to_coulomb"] = ratio
    if e["kind"] == "backlash":
        b, a = nums.get((e["output"], e["input"])), rec.denominator
        if b is not None and a:
            # d.c. offset = -b/2 per direction, of the predicted position: an output fitted before
            # q integrators (Eqn 5.29) has its s^0 term of the position at b[n - q]
            q = next((o.integrators for o in rec.structure.outputs if o.name == e["output"]), 0)
            e["backlash_mm"] = float(abs(2.0 * b[len(b) - 1 - q] / a[-1]))
    if e["kind"] == "periodic_position":
        amp = _periodic_amplitude(model, e)
        if amp is not None:
            e["ratio_to_coulomb"] = amp
    return e


def _ratio_to_friction(model, axis, name, nums):
    """Ratio of input ``name``'s numerator to the friction path's, at the friction path's lowest
    nonzero term at or above s^1 (``nums``: (output, input) -> b; the d.c. term only where the path
    has no other). With integral action the path starts at s^1 (Eqn 4.10). Without it the d.c.
    term is the static force-to-error gain, which a velocity-loop integrator in the drive makes
    zero, and a force acting only around starts and stops leaves it to noise: plant2's
    Stribeck axis from a CSV without velocity (rigid-noI): d.c. ratio -0.78, s^1 ratio 0.91,
    true 1.25."""
    fr = friction_path(model.inputs, axis)
    if fr is None:
        return None
    fname = model.inputs[fr].name
    for (o, i), b in nums.items():
        if i != fname:
            continue
        bf = np.asarray(b)
        bs = np.asarray(nums.get((o, name), []))
        if bs.size != bf.size:
            continue
        nz = np.flatnonzero(np.abs(bf[:-1]) > 0)
        nz = nz if nz.size else np.flatnonzero(np.abs(bf) > 0)
        if nz.size:
            l = nz[-1]
            return float(bs[l] / bf[l])
    return None


def _periodic_amplitude(model, e):
    """Force amplitude of the periodic input relative to the Coulomb level (hypot of the sin and
    cos numerator terms over the friction path's term: F_periodic / F_coulomb)."""
    ins = e.get("inputs", [])
    if len(ins) != 2:
        return None
    nums = PoleSearchRecord.from_dict(model.identification).numerators
    rs = _ratio_to_friction(model, e["axis"], ins[0], nums)
    rc = _ratio_to_friction(model, e["axis"], ins[1], nums)
    if rs is None or rc is None:
        return None
    return float(np.hypot(rs, rc))
