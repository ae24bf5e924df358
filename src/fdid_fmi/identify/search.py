"""Global search over the poles (and v_tilde) with scipy optimisers (thesis Figure 4-3 / 5-6).

The thesis used MATLAB GlobalSearch / MultiStart / pattern search; here the user picks one of

``vp``          variable projection: a Sobol screen, then bounded Gauss-Newton (trust-region
                reflective) searches on the residual vector from the best distinct screen points
                and the given start points (default of the structure choice)
``de``          scipy.optimize.differential_evolution (Sobol initialisation, polished): the
                thorough global search
``multistart``  Sobol starting points, each refined by a bounded local search (L-BFGS-B)
``direct``      scipy.optimize.direct (deterministic DIRECT pattern search), then polished

Variable projection (Golub and Pereyra): the LS projection eliminates the numerators, which
enter linearly, so the objective is the norm of a residual vector that depends on the poles
(and v_tilde) alone. Its Jacobian (finite differences, one projection per search coordinate)
gives Gauss-Newton steps that converge in a few iterations where DE's population needs thousands
of projections. The search is local; its global part is the screen and the start points (a
smaller structure's optimum, another same-sample form's), and the distinct local minima it
ends in are kept for the free-run selection of the caller.

Every method is deterministic for a given seed and keeps the distinct local minima it found,
ranked by objective, among all the points it evaluated (thesis section 7.2.2: all local minima
were kept and tested).

Search vector: [log10 p_k (Hz), log10 omega_k (Hz), zeta_k, log10 v_tilde (mm/s) per axis].
Pole sets are put in canonical order (real poles ascending, complex pairs by omega; a pair with
zeta > 1 whose real roots bracket a free real pole trades places with it), which removes the
mirror minimum of the (p, omega, zeta) form.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize
from scipy.stats import qmc

METHODS = ("vp", "de", "multistart", "direct")
VP_SCREEN_PER_DIM = 8       # Sobol screen of ``vp``: this many points per search coordinate
VP_STARTS = 3               # local searches of ``vp`` from the best distinct screen points ...
VP_WARM_STARTS = 1          # ... of them beside warm start points
VP_MAX_STARTS = 4           # ... more, up to this many in all, while the best end point is not confirmed
# two local searches ending within this relative objective agree; two of three agreeing are
# needed: two of two agreed on a minimum 1 % above the best on the feed-forward virtual drive
VP_CONFIRM_RTOL = 1e-3
# relative finite-difference step of the Jacobian: the projected residual carries rounding of the
# normal equations (conditions near 1e12); steps of 1e-6 stalled the searches on plant2's r2c1
# 4-8 % above the minimum that steps of 1e-4 reach
VP_DIFF_STEP = 1e-4
# steps (residual evaluations besides the Jacobians') of each local search: most end in 5-40;
# the few that crawl on (110 Jacobians of r1c2-noI on the feed-forward virtual drive) end in
# minima no better than the others'
VP_MAXITER = 20
VP_TOL = 1e-4               # relative change of cost / step size that ends a local search


@dataclass
class SearchResult:
    x: np.ndarray
    fun: float
    minima: list = field(default_factory=list)    # [(fun, x)] distinct, best first
    nfev: int = 0
    method: str = "de"


class _Counter:
    """Wraps the objective: counts calls, keeps the best points seen, drives a progress bar."""

    def __init__(self, fun, progress, total, desc):
        self.fun, self.nfev, self.n_finite = fun, 0, 0
        self.seen = []         # every finite (value, point): the basins the search visited
        self.bar = None
        if progress:
            from tqdm.auto import tqdm
            self.bar = tqdm(total=total, desc=desc, unit="eval", leave=False)

    def __call__(self, x):
        self.nfev += 1
        if self.bar is not None:
            self.bar.update(1)
            if self.nfev > self.bar.total:
                self.bar.total = self.nfev
        # a finite-difference step of L-BFGS-B can reach a pole set whose Tustin denominator is
        # 0 at q = 1: its division warnings reached the user's terminal, the value is refused here
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v = float(self.fun(x))
        if not np.isfinite(v):
            return np.inf      # a NaN objective would stall the optimisers; see run_search
        self.n_finite += 1
        self.seen.append((v, np.array(x)))
        return v

    def close(self):
        if self.bar is not None:
            self.bar.close()


def distinct_minima(points, scale, rtol=0.02, keep=10):
    """Distinct (fun, x) pairs, best first: drop points within ``rtol`` (relative to the
    search box ``scale``) of a better one."""
    ranked = sorted(points, key=lambda p: p[0])
    kept = distinct_points([x for _, x in ranked], scale, rtol, keep)
    return [(float(ranked[k][0]), np.array(ranked[k][1])) for k in kept]


def _vp(cnt, residuals, lo, hi, seed, maxiter, starts, warm):
    """The ``vp`` search (module docstring): returns its local searches' end points, best first.

    The screen ranks Sobol points by the objective (one projection each, no residual vector);
    the local searches start from the warm points, then from the best screen points that are
    distinct (10 % of the box apart): ``starts`` of them without warm points, ``VP_WARM_STARTS``
    with them.
    Then more run (up to ``VP_MAX_STARTS`` in all) while no two searches end at the same best
    objective: an unconfirmed optimum means the basins are not yet covered."""
    dim = lo.size
    scale = hi - lo
    n = int(2 ** np.ceil(np.log2(VP_SCREEN_PER_DIM * dim)))     # Sobol points come in powers of 2
    screen = qmc.scale(qmc.Sobol(dim, seed=seed).random(n), lo, hi)
    vals = np.array([cnt(p) for p in screen])
    order = [screen[k] for k in np.argsort(vals, kind="stable") if np.isfinite(vals[k])]
    queue = list(warm) + [order[k] for k in distinct_points(order, scale, rtol=0.1)]

    def rfun(x):
        cnt.nfev += 1
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            r = np.asarray(residuals(x), float)
        v = float(np.sqrt(r @ r))
        if not np.isfinite(v):
            return np.full(r.size, 1e6)
        cnt.n_finite += 1
        cnt.seen.append((v, np.array(x)))
        return r

    # every warm start is searched, and one screen point (``starts`` of them without a warm start)
    n_min = len(warm) + (VP_WARM_STARTS if warm else starts)
    n_max = max(VP_MAX_STARTS, n_min)
    ends = []
    for k, x in enumerate(queue):
        if k >= n_max or (k >= n_min and _confirmed(ends)):
            break
        x = np.clip(x, lo, hi)
        # a start on the bound: trf moves it strictly inside itself. gtol is off: the gradient
        # J^T r scales with the residual (1e-4 of W_z on a good fit) and ended searches at once
        with np.errstate(invalid="ignore", over="ignore"):
            res = optimize.least_squares(rfun, x, bounds=(lo, hi), method="trf", x_scale=scale,
                                         diff_step=VP_DIFF_STEP, max_nfev=maxiter,
                                         ftol=VP_TOL, xtol=VP_TOL, gtol=None)
        f = float(np.sqrt(2 * res.cost))
        ends.append((f if np.isfinite(f) else np.inf, np.array(res.x)))
    if not ends:
        ends = [(float(vals.min()), screen[int(np.argmin(vals))])]
    return sorted(ends, key=lambda p: p[0])


def _confirmed(ends):
    """Two local searches end within ``VP_CONFIRM_RTOL`` of the best objective."""
    fs = sorted(f for f, _ in ends)
    return len(fs) >= 2 and fs[1] <= fs[0] * (1 + VP_CONFIRM_RTOL)


def distinct_points(points, scale, rtol, keep=None):
    """Indices of ``points`` (best first) that are not within ``rtol`` (relative to the search box
    ``scale``) of an earlier kept one; at most ``keep`` of them."""
    out = []
    for k, x in enumerate(points):
        if all(np.max(np.abs((x - points[j]) / scale)) > rtol for j in out):
            out.append(k)
            if keep is not None and len(out) >= keep:
                break
    return out


def run_search(fun, lo, hi, method="de", seed=0, maxiter=None, popsize=None, progress=False,
               starts=None, local_polish=True, x0=None, residuals=None, warm=()):
    """Minimise ``fun`` over the box [lo, hi].

    Parameters
    ----------
    fun : callable(x) -> float
    lo, hi : arrays, the box
    method : one of METHODS
    seed : int, makes the search deterministic
    maxiter : DE generations (default 40 + 10 dim), iterations of each multistart local search
        (default 200), DIRECT evaluations (default 1500), residual evaluations of each ``vp``
        local search besides its finite-difference Jacobians (default ``VP_MAXITER``, 20)
    popsize : DE population per dimension (default 8)
    starts : number of multistart points (default 8 + 4 dim)
    x0 : array, optional, a start point (clipped to the box): a member of DE's first population,
        the first multistart point, ``vp``'s first local search; for every method the result is
        no worse than ``fun(x0)``
    residuals : callable(x) -> 1-D array, needed by ``vp``: the residual vector whose norm is
        ``fun(x)``
    warm : sequence of arrays, more start points of ``vp``'s local searches (after ``x0``)

    Returns
    -------
    SearchResult

    Raises
    ------
    InputError
        When no candidate had a finite objective (NaN or inf everywhere: data far outside the
        range the model's numbers can represent, e.g. positions scaled by 1e300 or 1e-300).
    """
    from ..errors import InputError
    if method not in METHODS:
        raise InputError(f"unknown search method '{method}'; choose one of {METHODS}", column="method")
    # numpy's errors (or silence: a negative maxiter ran the default) instead of one line naming it
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= 2 ** 32 - 1:
        raise InputError(f"seed must be an integer in 0 .. 2**32-1, got {seed!r}", column="seed")
    for name, v in (("maxiter", maxiter), ("popsize", popsize), ("starts", starts)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1):
            raise InputError(f"{name} must be a positive integer, got {v!r}", column=name)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    dim = lo.size
    scale = hi - lo
    bounds = list(zip(lo, hi))
    if method == "de":
        popsize = popsize or 8
        maxiter = maxiter or (40 + 10 * dim)
        total = (maxiter + 1) * popsize * dim
    elif method == "multistart":
        starts = starts or (8 + 4 * dim)
        total = starts * 40 * dim
    elif method == "vp":
        if residuals is None:
            raise InputError("the vp search needs the residual vector (residuals=)", column="method")
        starts = starts or VP_STARTS
        maxiter = maxiter or VP_MAXITER
        total = VP_SCREEN_PER_DIM * dim + VP_MAX_STARTS * maxiter * (dim + 1)
    else:
        maxiter = maxiter or 1500
        total = maxiter
    cnt = _Counter(fun, progress, total, f"pole search ({method})")
    if x0 is not None:
        x0 = np.clip(np.asarray(x0, float), lo, hi)

    def local(start, iterations=200):
        with np.errstate(invalid="ignore", over="ignore"):   # inf objectives (see _Counter)
            res = optimize.minimize(cnt, start, method="L-BFGS-B", bounds=bounds,
                                    options={"maxiter": iterations})
        return res.fun, res.x

    pts = []
    try:
        if method == "vp":
            pts = _vp(cnt, residuals, lo, hi, seed, maxiter, starts,
                      ([x0] if x0 is not None else []) + [np.clip(np.asarray(w, float), lo, hi) for w in warm])
            best = pts[0]
        elif method == "multistart":
            sob = qmc.Sobol(dim, seed=seed)
            X0 = qmc.scale(sob.random(int(2 ** np.ceil(np.log2(starts))))[:starts], lo, hi)
            if x0 is not None:
                X0 = np.vstack([x0, X0[:-1]])
            pts = [local(p, maxiter or 200) for p in X0]     # maxiter: of each local search
            best = min(pts, key=lambda p: p[0])
        else:
            if method == "de":
                res = optimize.differential_evolution(
                    cnt, bounds, seed=seed, popsize=popsize, maxiter=maxiter, tol=1e-7, atol=0,
                    init="sobol", polish=False, updating="deferred", mutation=(0.5, 1.0),
                    recombination=0.8, x0=x0)
                pts.extend(zip(res.population_energies, res.population))
            else:
                res = optimize.direct(cnt, bounds, maxfun=maxiter, locally_biased=True)
            best = (res.fun, res.x)
            if local_polish:
                best = min(best, local(res.x), key=lambda p: p[0])
            if x0 is not None and method == "direct":   # DE has x0 in its population and keeps the
                best = min(best, (cnt(x0), x0), key=lambda p: p[0])   # better of trial and member
            pts.append(best)
    finally:
        cnt.close()
    if cnt.n_finite == 0 or not np.isfinite(best[0]):
        from ..errors import InputError
        raise InputError(f"the pole search found no candidate with a finite prediction error "
                         f"({cnt.nfev} evaluated, every one NaN or infinite); the data are probably "
                         f"out of range (positions in mm, velocities in mm/s: check the units and "
                         f"the scale of the trace)", column="pole search")
    return SearchResult(x=np.asarray(best[1]), fun=float(best[0]),
                        minima=distinct_minima(pts + cnt.seen, scale, rtol=0.1),
                        nfev=cnt.nfev,
                        method=method)

