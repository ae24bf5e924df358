"""Global search over the poles (and v_tilde) with scipy optimisers (thesis Figure 4-3 / 5-6).

The thesis used MATLAB GlobalSearch / MultiStart / pattern search; here the user picks one of

``de``          scipy.optimize.differential_evolution (default; Sobol initialisation, polished)
``multistart``  Sobol starting points, each refined by a bounded local search (L-BFGS-B)
``direct``      scipy.optimize.direct (deterministic DIRECT pattern search), then polished

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

METHODS = ("de", "multistart", "direct")


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
    out = []
    for f, x in sorted(points, key=lambda p: p[0]):
        if all(np.max(np.abs((x - y) / scale)) > rtol for _, y in out):
            out.append((float(f), np.array(x)))
        if len(out) >= keep:
            break
    return out


def run_search(fun, lo, hi, method="de", seed=0, maxiter=None, popsize=None, progress=False,
               starts=None, local_polish=True, x0=None):
    """Minimise ``fun`` over the box [lo, hi].

    Parameters
    ----------
    fun : callable(x) -> float
    lo, hi : arrays, the box
    method : one of METHODS
    seed : int, makes the search deterministic
    maxiter : DE generations (default 40 + 10 dim), iterations of each multistart local search
        (default 200), DIRECT evaluations (default 1500)
    popsize : DE population per dimension (default 8)
    starts : number of multistart points (default 8 + 4 dim)
    x0 : array, optional, a start point (clipped to the box): a member of DE's first population,
        the first multistart point; for every method the result is no worse than ``fun(x0)``

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
        if method == "multistart":
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
                        minima=distinct_minima(pts + cnt.seen, scale, rtol=0.1), nfev=cnt.nfev,
                        method=method)

