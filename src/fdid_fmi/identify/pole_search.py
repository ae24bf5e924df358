"""Pole search with LS projection: SISO (thesis ch. 4.3) and scaled MIMO LTI (ch. 5).

One engine: :func:`identify_mimo` searches the shared poles (and the friction transition
velocity v_tilde) of a :class:`~fdid_fmi.identify.structure.Structure`, projects every candidate
onto the numerators by LS (``lsfit.py``) and assembles the winner as an UNSCALED discrete state
space (Eqn 5.18-5.25) with its friction nonlinearity: a :class:`~fdid_fmi.model.DriveModel`.
:func:`identify_siso` is the rigid-body special case (Eqn 4.10-4.17).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy.linalg import block_diag

from .. import __version__
from ..errors import InputError
from ..model import DriveModel, Port, delayed_input, is_play
from . import regressors as rg
from .limits import recorded_limits
from .lsfit import LSProblem
from .record import PoleSearchRecord
from .regressors import CHOSEN_FROM, SAME_SAMPLE
from .search import run_search
from .structure import Bounds, Structure, default_bounds, siso_structure


# ------------------------------------------------------------------ parameters
class _Params:
    """Maps the search vector to poles and v_tilde (see search.py for the layout)."""

    def __init__(self, structure: Structure, bounds: Bounds, fric_axes, v_tilde_fixed):
        self.s, self.b = structure, bounds
        self.fric_axes = fric_axes
        self.v_fixed = v_tilde_fixed
        nr, nc = structure.n_real, structure.n_complex
        lo = [np.log10(l) for l, _ in bounds.real_hz] + [np.log10(l) for l, _ in bounds.omega_hz] + \
             [l for l, _ in bounds.zeta]
        hi = [np.log10(h) for _, h in bounds.real_hz] + [np.log10(h) for _, h in bounds.omega_hz] + \
             [h for _, h in bounds.zeta]
        self.v_search = [a for a in fric_axes if a not in v_tilde_fixed]
        for _ in self.v_search:
            lo.append(np.log10(bounds.v_tilde[0]))
            hi.append(np.log10(bounds.v_tilde[1]))
        self.lo, self.hi = np.array(lo), np.array(hi)
        self.nr, self.nc = nr, nc

    def decode(self, x):
        nr, nc = self.nr, self.nc
        real = list(10 ** x[:nr])
        cplx = list(zip(10 ** x[nr:nr + nc], x[nr + nc:nr + 2 * nc]))
        vt = dict(self.v_fixed)
        for k, ax in enumerate(self.v_search):
            vt[ax] = float(10 ** x[nr + 2 * nc + k])
        return real, cplx, vt

    def v_start(self):
        """v_tilde in the middle of its log range for every searched axis (a start point)."""
        return {a: float(np.sqrt(self.b.v_tilde[0] * self.b.v_tilde[1])) for a in self.v_search}

    def encode(self, real, cplx, vt):
        x = list(np.log10(real)) + [np.log10(w) for w, _ in cplx] + [z for _, z in cplx]
        x += [np.log10(vt[a]) for a in self.v_search]
        return np.array(x)

    def canonical(self, x):
        """Canonical order of a pole set (same objective value). Poles that share their bounds
        are sorted (real ascending, complex pairs by omega); a pair with zeta > 1 whose real
        roots bracket the free real pole trades places with it when the result stays in bounds."""
        real, cplx, vt = self.decode(x)
        if len(set(self.b.real_hz)) <= 1:
            real = sorted(real)
        if len(set(zip(self.b.omega_hz, self.b.zeta))) <= 1:
            cplx = sorted(cplx)
        xc = self.encode(real, cplx, vt)
        # the (p, omega, zeta > 1) mirror: the free real pole is the fastest of the three
        if self.nr >= 1 and self.nc >= 1:
            w, z = cplx[0]
            if z > 1:
                # a huge zeta rounds the slow root to 0 (log10 -inf): that mirror is out of bounds
                with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
                    r1, r2 = w * (z - np.sqrt(z * z - 1)), w * (z + np.sqrt(z * z - 1))
                    trio = sorted([real[-1], r1, r2])
                    if trio[2] != real[-1]:
                        nw = np.sqrt(trio[0] * trio[1])
                        cand = self.encode(real[:-1] + [trio[2]],
                                           [(nw, (trio[0] + trio[1]) / (2 * nw))] + cplx[1:], vt)
                        if np.all(cand >= self.lo - 1e-12) and np.all(cand <= self.hi + 1e-12):
                            return cand
        return xc

    def polynomial(self, real, cplx):
        return rg.characteristic_polynomial(list(real) + list(self.s.locked_real_hz),
                                            list(cplx) + list(self.s.locked_complex))


# ------------------------------------------------------------------ API
def identify_mimo(traces, structure: Structure, bounds: Bounds | None = None, v_tilde=None,
                  method="de", seed=0, maxiter=None, popsize=None, progress=False, refine=True,
                  start=None, warm=(), select=True):
    """Scaled MIMO LTI pole search (thesis ch. 5) -> unscaled DriveModel.

    Parameters
    ----------
    traces : Trace or list[Trace]
        Training data ranges (each filtered from its own consistent initial state).
    structure : Structure
    bounds : Bounds, optional
        Default: :func:`default_bounds` from Ts, and v_tilde in [1e-4, 0.3] x max |v|.
    v_tilde : float or dict axis -> float, optional
        Fix the friction transition velocity (mm/s) instead of searching it.
    method, seed, maxiter, popsize : search settings (see ``search.run_search``)
    progress : bool, show a progress bar
    refine : bool
        After the search, make the friction simulation-consistent (:func:`refine_friction`):
        keep it only if the free-run error on the training data falls.
    start : (real_hz, complex_hz_zeta), optional
        Poles to start the search from (the free ones, in the structure's order; clipped to the
        bounds; a searched v_tilde starts in the middle of its range): the search then ends no
        worse, in the LS objective, than that start (the model is still picked by training free
        run among the minima within ``SELECT_MARGIN`` of the best).
    warm : sequence of (real_hz, complex_hz_zeta[, v_tilde dict]), more start points of the
        ``vp`` search (as ``start``; v_tilde of the searched axes from the dict where given)
    select : bool
        Pick the model by training free run among the minima within ``SELECT_MARGIN`` of the
        best and, with ``vp``, the free-run polish (:func:`_polish_free_run`). False: the best
        LS minimum alone, for a caller that reads only the LS objective (a scan of an effect's
        parameter), which selection and polish do not lower.

    Returns
    -------
    DriveModel, with ``identification["minima"]`` the ranked local minima found.
    """
    t_start = time.perf_counter()
    traces = [traces] if not isinstance(traces, (list, tuple)) else list(traces)
    if structure.same_sample is None:
        return _choose_same_sample(traces, structure, bounds=bounds, v_tilde=v_tilde, method=method,
                                   seed=seed, maxiter=maxiter, popsize=popsize, progress=progress,
                                   refine=refine, start=start, warm=warm, select=select)
    prob = LSProblem(traces, structure)
    Ts = prob.Ts
    fric_axes = [s.axis for s in structure.inputs if s.kind == "friction"]
    if bounds is None:
        bounds = default_bounds(Ts, structure.n_real, structure.n_complex)
    if len(bounds.real_hz) != structure.n_real or len(bounds.omega_hz) != structure.n_complex \
            or len(bounds.zeta) != structure.n_complex:
        raise InputError(f"bounds give {len(bounds.real_hz)} real and {len(bounds.omega_hz)} complex "
                         f"ranges, the structure has {structure.n_real} and {structure.n_complex}",
                         column="bounds")
    vfix = {}
    if v_tilde is not None:
        vfix = dict(v_tilde) if isinstance(v_tilde, dict) else {a: float(v_tilde) for a in fric_axes}
        for a, v in vfix.items():
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"v_tilde must be > 0 mm/s, got {v!r}", column=f"{a}.v_tilde")
    # a friction law needs the measured motion: the default v_tilde range would be [0, 0] (an
    # error naming 'bounds') and a play of a constant position fits a silently wrong model
    play_axes = [s.axis for s in structure.inputs if is_play(s)]
    searched = [a for a in fric_axes if a not in vfix and bounds.v_tilde is None]
    for a in dict.fromkeys(searched + play_axes):
        if not max(np.max(np.abs(sg.vel[a][sg.R:])) for sg in prob.segments) > 0:
            tr = prob.traces[0]
            raise InputError(f"the measured position of axis '{a}' never moves while its command "
                             f"does: no motion to identify its friction from; check the channel (a "
                             f"stuck axis or a dead encoder)", source=tr.source,
                             column=tr.roles[a].get("act", f"{a}.act"))
    if bounds.v_tilde is None and any(a not in vfix for a in fric_axes):
        vmax = max(np.max(np.abs(sg.vel[a])) for sg in prob.segments for a in fric_axes)
        bounds = Bounds(bounds.real_hz, bounds.omega_hz, bounds.zeta, (1e-4 * vmax, 0.3 * vmax))
    bounds.check(Ts)
    nyq = 0.5 / Ts    # a locked pole, like a searched one, must be one the sampled model can have
    for f in list(structure.locked_real_hz) + [w for w, _ in structure.locked_complex]:
        if not (np.isfinite(f) and 0 < f <= nyq * (1 + 1e-9)):
            raise InputError(f"locked pole {f:g} Hz must satisfy 0 < f <= Nyquist = {nyq:g} Hz (the "
                             f"Tustin map would put it elsewhere)", column="locked poles")
    for w, z in structure.locked_complex:
        if not (np.isfinite(z) and z > 0):
            raise InputError(f"locked pair {w:g} Hz has damping {z!r}; expected a finite zeta > 0",
                             column="locked poles")
    par = _Params(structure, bounds, fric_axes, vfix)

    def objective(x):
        real, cplx, vt = par.decode(x)
        return prob.project(par.polynomial(real, cplx), vt).J

    def residuals(x):
        """The scaled prediction errors whose norm is the objective (section 5.2.3): each output
        divided by its W_z, all by sqrt(N p); a pole set whose friction gain has the wrong sign
        is scaled up by the objective's penalty."""
        real, cplx, vt = par.decode(x)
        fit, res = prob.project(par.polynomial(real, cplx), vt, want_residuals=True)
        if res is None:
            return np.full(prob.N * prob.p, fit.J / np.sqrt(prob.N * prob.p))
        r = (res / prob.Wz[:, None]).ravel() / np.sqrt(prob.N * prob.p)
        if not fit.feasible:
            r *= fit.J / max(fit.J - 10.0, 1e-300)
        return r

    if par.lo.size == 0:  # everything locked: a single LS projection
        xbest, minima, nfev, fun = np.array([]), [], 1, objective(np.array([]))
    else:
        x0 = None if start is None else par.encode(*start, par.v_start())
        res = run_search(objective, par.lo, par.hi, method=method, seed=seed, maxiter=maxiter,
                         popsize=popsize, progress=progress, x0=x0, residuals=residuals,
                         warm=[par.encode(w[0], w[1], {**par.v_start(), **(w[2] if len(w) > 2 else {})})
                               for w in warm])
        xbest, nfev, fun = par.canonical(res.x), res.nfev, res.fun
        minima = [(f, par.canonical(x)) for f, x in res.minima]
    # the LS objective is nearly flat between basins that free-run very differently: the best
    # points of the other basins the search visited within SELECT_MARGIN of the best are finished
    # too, and the candidate with the lowest free-run error on the training data is kept
    cands = [(fun, xbest)] + [(f, x) for f, x in minima[1:] if f <= fun * (1 + SELECT_MARGIN)][:MAX_ALTERNATIVES]
    if not select:
        cands = cands[:1]
    do_refine = refine and fric_axes and not any(o.integrators for o in structure.outputs)
    if method == "vp" and do_refine and len(cands) > VP_REFINED:
        # the vp search's alternatives are the points on its local searches' paths: ranked by
        # their free run without the refinement (one projection and one free run each), the best
        # LS minimum and the VP_REFINED - 1 best of the rest get the refinement's free runs
        plain = [_finish(prob, structure, par, f, par.canonical(x), False) for f, x in cands[1:]]
        order = sorted((k for k, c in enumerate(plain) if c is not None), key=lambda k: plain[k]["free_run"])
        cands = cands[:1] + [cands[1 + k] for k in order[:VP_REFINED - 1]]
    polished = None
    if method == "vp" and select and par.lo.size and _selection_outputs(structure):
        polished, (k0, done) = _polish_free_run(prob, structure, par, cands, fun, do_refine)
        cands = cands + [polished]
    finished = [done if polished and k == k0 and done is not None
                else _finish(prob, structure, par, f, par.canonical(x), do_refine) for k, (f, x) in enumerate(cands)]
    if finished[0] is None:
        real, cplx, vt = par.decode(par.canonical(cands[0][1]))
        if not np.all(np.isfinite(prob.project(par.polynomial(real, cplx), vt).rms)):
            raise InputError("no usable model in the search space: the best candidate's filters or numerators are not "
                             "finite numbers (poles, damping, v_tilde or a d.c.-gain value far out of "
                             "range, e.g. a zeta bound of 1e308); narrow the bounds", source=traces[0].source, column="bounds")
        raise InputError("no feasible model in the search space (every candidate had a friction gain "
                         "of the wrong sign); widen the bounds or check the friction structure",
                         source=traces[0].source, column="bounds")
    finished = [f for f in finished if f is not None]
    chosen = min(finished, key=lambda c: c["free_run"])
    model, fit, refinement, (real, cplx, vt) = (chosen[k] for k in ("model", "fit", "refinement", "params"))
    fun = chosen["objective"]
    model.poles = rg.poles_from_parameters(list(real) + list(structure.locked_real_hz),
                                           list(cplx) + list(structure.locked_complex))
    model.method = "mimo"
    model.identification = PoleSearchRecord(
        structure=structure, real_hz=list(real), complex_hz_zeta=[list(c) for c in cplx],
        locked_real_hz=list(structure.locked_real_hz), locked_complex=[list(c) for c in structure.locked_complex],
        v_tilde_mm_s={p.axis: p.params["v_tilde"] for p in model.inputs if p.kind == "friction"},
        numerators={k: b.tolist() for k, b in fit.b.items()}, denominator=fit.a.tolist(),
        extra={"v_tilde_regressor_mm_s": vt, "friction_refinement": refinement,
               "tracking_zeros_hz_zeta": tracking_zeros(structure, fit),
               "search": {"method": method, "seed": seed, "nfev": nfev, "objective": fun,
                          "bounds": {"real_hz": bounds.real_hz, "omega_hz": bounds.omega_hz,
                                     "zeta": bounds.zeta, "v_tilde": bounds.v_tilde}},
               "minima": [{"objective": f, **_describe(par, x)} for f, x in minima],
               "candidates": [{"objective": c["objective"], "selection_free_run": c["free_run"],
                               **_describe(par, c["x"]), "chosen": c is chosen} for c in finished]},
    ).to_dict()
    model.metrics = {
        "objective_scaled_rms": fit.J,
        "fit_rms": {o.name: float(r) for o, r in zip(structure.outputs, fit.rms)},
        "samples": prob.N, "wall_time_s": time.perf_counter() - t_start,
    }
    model.provenance = {
        "software": f"fdid-fmi {__version__}",
        "data": [{"source": tr.source, "sha256": tr.meta.get("sha256") or tr.fingerprint(),
                  "t_start_s": float(tr.t[0]), "t_stop_s": float(tr.t[-1]), "samples": tr.n}
                 for tr in traces],
    }
    model.limits = recorded_limits(traces, model.axes)
    return model


def identify_siso(traces, axis="x", integral_action=True, v_tilde=None, bounds=None, method="de",
                  seed=0, ma_order=1, velocity="backward", maxiter=None, popsize=None, progress=False,
                  friction=True, refine=True, same_sample=None):
    """SISO rigid-body pole search with LS projection (thesis Eqn 4.10-4.17).

    Inputs x_r and d_nf = sat(v/v_tilde) (v: moving-average-filtered encoder derivative), output
    e = x_r - x; P(s) = (s + p)(s^2 + 2 zeta omega s + omega^2); candidates with d0 < 0 rejected.
    ``integral_action=False`` adds the 1/P(s) friction term for P/PD position loops (EMPS).
    v_tilde (mm/s) is searched with the poles unless given. ``same_sample``: ``hold``,
    ``quadratic``, ``cubic`` or None (one of ``regressors.CHOSEN_FROM``, chosen from the data),
    see :class:`~.structure.Structure`.
    """
    st = siso_structure(axis, integral_action=integral_action, ma_order=ma_order, friction=friction,
                        velocity=velocity, same_sample=same_sample)
    model = identify_mimo(traces, st, bounds=bounds, v_tilde=v_tilde, method=method, seed=seed,
                          maxiter=maxiter, popsize=popsize, progress=progress, refine=refine)
    model.method = "pole-search"
    return model


def _choose_same_sample(traces, structure, **kw):
    """Identify with each same-sample prediction of ``regressors.CHOSEN_FROM`` and keep the model
    with the lower free-run error of its position-type outputs on the training data: whether the
    drive looks one sample ahead (feed-forward) is a property of the drive, seen in its data."""
    t0 = time.perf_counter()
    fits = {}
    for name in CHOSEN_FROM:
        m = identify_mimo(traces, dataclasses.replace(structure, same_sample=name), **kw)
        fits[name] = (next(c["selection_free_run"] for c in m.identification["candidates"] if c["chosen"]), m)
    name = min(fits, key=lambda k: fits[k][0])
    model = fits[name][1]
    model.identification["same_sample_choice"] = {"chosen": name,
                                                  "selection_free_run": {k: v[0] for k, v in fits.items()}}
    model.metrics["wall_time_s"] = time.perf_counter() - t0
    return model


SELECT_MARGIN = 0.05     # alternative minima within 5 % of the best LS objective are finished
MAX_ALTERNATIVES = 8
VP_REFINED = 3           # candidates of a vp search that get the friction refinement (see identify_mimo)
POSITION_KINDS = ("position", "error", "tool_position", "tool_error")


# free runs of the vp search's polish per search coordinate (see _polish_free_run): 20 took the
# rigid body of the virtual drive without feed-forward (hold) to a training free run of 0.037 um
# that ran 0.52 um on the validation circle (10: 0.044, circle 0.038 um)
POLISH_EVALS_PER_DIM = 10


def _polish_free_run(prob, structure, par, cands, best, refine):
    """A pole set with a lower training free run among those whose LS objective is within
    ``SELECT_MARGIN`` of ``best``: a Nelder-Mead search on the free-run objective from the
    candidate with the lowest free run. Returns ((LS objective, search vector), (index of the
    start in ``cands``, its :func:`_finish` with the refinement or None)): the caller need not
    finish the start again.

    Each pole set's model is the LS projection's; with ``refine``, as in
    :func:`refine_friction`, its friction regressor is then replaced by the friction its own
    simulation applied and projected again, once, in the simulation band (v_tilde x band) that
    the refinement chose at the start point (none when it kept the search's model): the
    refinement's own choice at ten free runs a point is too dear here, and without it the
    friction-dominated plant2 rigid body's polish ranked by a free run that the refinement
    then changes (validation circle 0.26 against 0.20 um).

    The LS objective is nearly flat along some directions that the free run is not: on the
    virtual drive without feed-forward the rigid body's LS minima at 117 and 270 Hz (fast real
    pole) free-run 0.18 um, a point between them within 0.5 % of the objective 0.05 um. A
    population search (DE) finds such points among the members it finishes; the local searches
    of ``vp`` end at the LS minima, and this search walks the flat region instead. Its start
    simplex spans 5 % of the search box per coordinate."""
    from scipy import optimize
    sel = _selection_outputs(structure)
    limit = best * (1 + SELECT_MARGIN)
    fidx = [i for i, s in enumerate(prob.s.inputs) if s.kind == "friction"]
    band = [None]      # the simulation band of the refinement, set once the start is known

    def free_run(x):
        x = np.clip(x, par.lo, par.hi)
        real, cplx, vt = par.decode(x)
        with np.errstate(all="ignore"):
            fit = prob.project(par.polynomial(real, cplx), vt)
            if not fit.feasible or not fit.J <= limit:
                return 1e3 + min(fit.J, 1e6)
            model = assemble(structure, fit, prob.Ts)
            if band[0] is not None:
                vs = {a: v * band[0] for a, v in vt.items()}
                _, sims = free_run_objective(prob, _with_v_tilde(model, vs))
                fit2 = prob.project(fit.a, vt, overrides=[{i: sim.u[:, i] for i in fidx} for sim in sims])
                if fit2.feasible:
                    model = _with_v_tilde(assemble(structure, fit2, prob.Ts), vs)
            v = free_run_objective(prob, model, sel)[0]
        return v if np.isfinite(v) else 1e3

    k0 = min(range(len(cands)), key=lambda k: free_run(par.canonical(cands[k][1])))
    x0 = par.canonical(cands[k0][1])
    done = None
    if refine and fidx:
        done = _finish(prob, structure, par, cands[k0][0], x0, True)
        if done is not None and done["refinement"]["chosen"]["iterations"] > 0:
            band[0] = done["refinement"]["chosen"]["band"]
    simplex = np.vstack([x0] + [x0 + 0.05 * e * (par.hi - par.lo) for e in np.eye(x0.size)])
    res = optimize.minimize(free_run, x0, method="Nelder-Mead",
                            options={"maxfev": POLISH_EVALS_PER_DIM * x0.size, "initial_simplex": simplex})
    x = np.clip(res.x, par.lo, par.hi)
    real, cplx, vt = par.decode(x)
    return (prob.project(par.polynomial(real, cplx), vt).J, x), (k0, done)


def _finish(prob, structure, par, fun, x, refine):
    """One search minimum as a model: LS projection, assembly, friction refinement, and the
    free-run objective on the training data that ranks the candidates (None if infeasible)."""
    real, cplx, vt = par.decode(x)
    fit, _ = prob.project(par.polynomial(real, cplx), vt, want_residuals=True)  # exact RMS
    if not fit.feasible:
        return None
    model = assemble(structure, fit, prob.Ts)
    refinement = None
    if refine:
        model, fit, refinement = refine_friction(prob, model, fit)
    sel = _selection_outputs(structure)
    free_run = free_run_objective(prob, model, sel)[0] if sel else float(fun)
    return {"model": model, "fit": fit, "refinement": refinement, "params": (real, cplx, vt),
            "objective": float(fun), "free_run": float(free_run), "x": x}


# ------------------------------------------------------------------ refinement
def free_run_objective(prob, model, outputs=None):
    """Free-run counterpart of the LS objective: RMS over the fitted outputs (or the indices
    ``outputs`` of them), each scaled by W_z, of measured - simulated (the model driven by the
    commands alone)."""
    from ..simulate import simulate
    names = [p.name for p in model.outputs]
    js = range(prob.p) if outputs is None else outputs
    total, sims = 0.0, []
    for tr, sg in zip(prob.traces, prob.segments):
        sim = simulate(model, tr)
        sims.append(sim)
        for j in js:
            r = sg.Z[j] - sim.y[:, names.index(prob.s.outputs[j].name)]
            total += float(r @ r) / prob.Wz[j] ** 2
    return float(np.sqrt(total / (prob.N * max(1, len(js))))), sims


def _selection_outputs(structure):
    """Fitted outputs that rank search candidates: the position-type ones (what a twin is judged
    by: tracking, contour and tool-side errors), else every output; none when the fit is only
    through appended integrators (its fitted signal has no free-run counterpart)."""
    plain = [j for j, o in enumerate(structure.outputs) if not o.integrators]
    pos = [j for j in plain if structure.outputs[j].kind in POSITION_KINDS]
    return pos or plain


def refine_friction(prob, model, fit, bands=(1.0, 0.1, 0.01), iterations=2):
    """Simulation-consistent friction (a refinement of the thesis's LS projection).

    The pole search builds the friction regressor from the MEASURED velocity, sat(v/v_tilde). In
    free run the model closes the loop on its own velocity, and while an axis sticks the measured
    velocity is ~0 although the friction holding it is not. So: simulate the model, take the
    friction input it actually applied as the regressor, solve the LS again with the same poles,
    and repeat. A narrower transition band in simulation (v_tilde x ``bands``) lets the exact
    friction solve hold the axis still (stiction). Every candidate is judged by the free-run
    error on the training data; the search result itself is one of the candidates, so the
    refinement never makes the training free run worse.

    Returns
    -------
    model, fit, record (dict of the candidates' free-run objectives and the choice)
    """
    fidx = [i for i, s in enumerate(prob.s.inputs) if s.kind == "friction"]
    base_vt = dict(fit.v_tilde)
    best_J, _ = free_run_objective(prob, model)
    best = (best_J, model, fit, 1.0, 0)
    record = {"search": best_J}
    for band in bands:
        vt_sim = {a: v * band for a, v in base_vt.items()}
        cand_fit = fit
        cand = _with_v_tilde(assemble(prob.s, cand_fit, prob.Ts), vt_sim)
        for it in range(iterations):
            J, sims = free_run_objective(prob, cand)
            record[f"band {band:g}, iteration {it}"] = J
            if J < best[0]:
                best = (J, cand, cand_fit, band, it)
            overrides = [{i: sim.u[:, i] for i in fidx} for sim in sims]
            new_fit = prob.project(cand_fit.a, base_vt, overrides=overrides)
            if not new_fit.feasible:
                break
            cand_fit = new_fit
            cand = _with_v_tilde(assemble(prob.s, cand_fit, prob.Ts), vt_sim)
        J, _ = free_run_objective(prob, cand)
        record[f"band {band:g}, iteration {iterations}"] = J
        if J < best[0]:
            best = (J, cand, cand_fit, band, iterations)
    record["chosen"] = {"band": best[3], "iterations": best[4], "free_run_objective": best[0]}
    return best[1], best[2], record


def _with_v_tilde(model, vt):
    for p in model.inputs:
        if p.kind == "friction":
            p.params["v_tilde"] = float(vt[p.axis])
    return model


# ------------------------------------------------------------------ assembly
def assemble(structure: Structure, fit, Ts):
    """Unscaled discrete state space of a fit (Eqn 5.18-5.25) as a DriveModel.

    One SIMO block (A0, B0, C0, D0) per input (Eqn 5.22); each output row is the numerator-weighted
    sum of the blocks' regressor outputs (Eqn 5.23). Integrators are appended by shifting the
    numerators (Eqn 5.26-5.29). Derived outputs complete each axis: position = x_r - error (or
    the reverse), so every axis has a position, an error and (through the simulator) a velocity.

    Causal (DESIGN.md): the same-sample term of inputs from outside the drive uses their
    prediction from earlier samples (``structure.same_sample``, :func:`extrapolate_late_inputs`),
    as the pole search's LS was fitted (``lsfit``, ``regressors.same_sample_part``).
    """
    if structure.same_sample not in SAME_SAMPLE:
        raise InputError("assembling a model needs the same-sample prediction of its commands "
                         f"(structure.same_sample one of {sorted(SAME_SAMPLE)})", column="same_sample")
    n = len(fit.a) - 1
    den, F = rg.tustin_basis(fit.a, Ts)
    ins = structure.inputs
    m = len(ins)
    A0, B0, C0, D0 = rg.simo_realisation(den, F)
    A = block_diag(*([A0] * m))
    B = block_diag(*([B0] * m))
    rows_C, rows_D, outs = [], [], []
    cmd_col = {s.axis: i for i, s in enumerate(ins) if s.kind == "command"}
    for o in structure.outputs:
        c = np.zeros(n * m)
        d = np.zeros(m)
        for i, s in enumerate(ins):
            b = fit.b[(o.name, s.name)]
            if o.integrators:
                b = np.concatenate([np.zeros(o.integrators), b[: n + 1 - o.integrators]])   # Eqn 5.29
            c[i * n:(i + 1) * n] = b @ C0
            d[i] = (b @ D0)[0]
        rows_C.append(c)
        rows_D.append(d)
        kind = {"tool_error": "other"}.get(o.predicts, o.predicts)
        unit = {"velocity": "mm_s", "acceleration": "mm_s2"}.get(kind, "mm")
        outs.append(Port(name=o.name if not o.integrators else f"{o.axis}_{o.predicts}", unit=unit,
                         kind=kind, axis=o.axis, description=_out_description(o)))
    # derived outputs: x = x_r - e, e = x_r - x, tool position from tool error
    for ax in structure.axes:
        kinds = {p.kind for p in outs if p.axis == ax}
        names = {p.kind: k for k, p in enumerate(outs) if p.axis == ax}
        ic = cmd_col[ax]

        def derived(src, kind, name, desc):
            c = -rows_C[src]
            d = -rows_D[src].copy()
            d[ic] += 1.0
            rows_C.append(c)
            rows_D.append(d)
            outs.append(Port(name=name, unit="mm", kind=kind, axis=ax, description=desc,
                             params=dict(outs[src].params)))

        if "error" in kinds and "position" not in kinds:
            derived(names["error"], "position", f"{ax}_pos", "predicted position x = x_r - e")
        elif "position" in kinds and "error" not in kinds:
            derived(names["position"], "error", f"{ax}_err", "predicted tracking error e = x_r - x")
        if "other" in kinds and "tool_position" not in kinds:
            k = next(k for k, p in enumerate(outs) if p.axis == ax and p.name.endswith("tool_error"))
            derived(k, "tool_position", f"{ax}_tool", "predicted tool-side position")
        kinds = {p.kind for p in outs if p.axis == ax}
        if "position" not in kinds and "tool_position" in kinds:
            # the tool-side position is the axis position of this model
            k = next(k for k, p in enumerate(outs) if p.axis == ax and p.kind == "tool_position")
            rows_C.append(rows_C[k].copy())
            rows_D.append(rows_D[k].copy())
            outs.append(Port(name=f"{ax}_pos", unit="mm", kind="position", axis=ax, params={"side": "tool"},
                             description="predicted position (tool side: no motor-side output)"))
        if "error" not in {p.kind for p in outs if p.axis == ax}:
            derived(next(k for k, p in enumerate(outs) if p.axis == ax and p.kind == "position"),
                    "error", f"{ax}_err", "predicted tracking error e = x_r - x")
    in_ports = []
    for s in ins:
        if s.kind == "command":
            in_ports.append(Port(s.name, "mm", "command", s.axis, {}, "commanded position x_r"))
        elif s.kind == "friction":
            in_ports.append(Port(s.name, "1", "friction", s.axis,
                                 {"v_tilde": float(fit.v_tilde[s.axis]), "level": 1.0},
                                 "normalised Coulomb friction sat(v / v_tilde)"))
        elif s.kind == "external":
            in_ports.append(Port(s.name, "1", "external", s.axis, {"channel": s.channel},
                                 f"measured input '{s.channel}'"))
        else:
            in_ports.append(Port(s.name, "1", "feature", s.axis, dict(s.params), "nonlinear feature"))
    A, B, C, D = extrapolate_late_inputs(A, B, np.array(rows_C), np.array(rows_D), in_ports, outs,
                                         rg.SAME_SAMPLE[structure.same_sample])
    return DriveModel(Ts=Ts, A=A, B=B, C=C, D=D, inputs=in_ports, outputs=outs)


def extrapolate_late_inputs(A, B, C, D, inputs, outputs, coef):
    """Causal form of a state space: D u[k] -> D u^[k] for inputs from outside the drive.

    u^[k] = sum_j coef[j] u[k-1-j] (``regressors.SAME_SAMPLE``), held in one register per
    coefficient and such input; the state update keeps the true u[k]. Error outputs keep
    e[k] = x_r[k] - x[k]: their same-sample gain on the own command is 1, the rest of it moves
    to the registers.
    """
    coef = np.asarray(coef, float)
    q = len(coef)
    late = [i for i, p in enumerate(inputs) if delayed_input(p.kind, p.params) and np.any(D[:, i])]
    n = A.shape[0]
    A2 = np.zeros((n + q * len(late),) * 2)
    A2[:n, :n] = A
    B2 = np.zeros((A2.shape[0], B.shape[1]))
    B2[:n] = B
    C2 = np.hstack([C, np.zeros((C.shape[0], q * len(late)))])
    D2 = D.copy()
    for j, i in enumerate(late):
        r = n + q * j                               # registers u[k-1], u[k-2], u[k-3]
        B2[r, i] = 1.0
        for s in range(1, q):
            A2[r + s, r + s - 1] = 1.0
        for o, p in enumerate(outputs):
            own = p.kind == "error" and inputs[i].kind == "command" and p.axis == inputs[i].axis
            C2[o, r:r + q] += (D[o, i] - (1.0 if own else 0.0)) * coef
            D2[o, i] = 1.0 if own else 0.0
    return A2, B2, C2, D2


def tracking_zeros(structure, fit):
    """Zeros (Hz, damping) of each tracking transfer function x/x_r = 1 - e/x_r (Table 4-2)."""
    out = {}
    a = fit.a
    for o in structure.outputs:
        for s in structure.inputs:
            if s.kind != "command" or s.axis != o.axis:
                continue
            b = fit.b[(o.name, s.name)]
            if o.kind == "error":
                num = a - b
            elif o.kind in ("position", "tool_position") and not o.integrators:
                num = b
            else:
                continue
            num = np.trim_zeros(num, "f")
            if num.size < 2:
                continue
            zs = np.roots(num)
            out[o.name] = [[float(abs(z) / (2 * np.pi)), float(-z.real / abs(z)) if abs(z) > 0 else -1.0]
                           for z in zs]
    return out


def _describe(par, x):
    real, cplx, vt = par.decode(x)
    return {"real_hz": [float(r) for r in real], "complex_hz_zeta": [[float(w), float(z)] for w, z in cplx],
            "v_tilde_mm_s": vt}


def _out_description(o):
    text = {"error": "predicted tracking error e = x_r - x", "position": "predicted position",
            "velocity": "predicted velocity", "tool_position": "predicted tool-side position",
            "tool_error": "predicted tool-side tracking error", "acceleration": "predicted acceleration"}
    d = text.get(o.predicts, o.predicts)
    if o.integrators:
        d += f" (fitted on {o.kind}, {o.integrators} integrator(s) appended)"
    return d
