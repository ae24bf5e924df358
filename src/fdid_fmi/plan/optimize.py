"""Per-block feed overrides that keep the predicted contour error within a tolerance.

1. **First pass, quasi-static (thesis Eqn 3.4-3.6).** The tracking-error transfer function of the
   model's linear part is expanded around s = 0, G_er(s) ~ K_vel s + K_acc s^2 + K_jerk s^3
   (Taylor coefficients by Cauchy's integral on a circle inside the slowest pole). For each
   cutting block the error *normal to the path* has the same form with effective gains:

   * a straight block with unit direction u and normal n: K_eff = |sum_i n_i u_i K_i| (only the
     axes' *mismatch* leaves the path);
   * an arc of radius R at feed v: the velocity mismatch |K_vel,x - K_vel,y| / 2 v, the radial
     (centripetal) error (K_acc + K_vel^2 / 2) v^2 / R of the mean axis (the K_vel^2 / 2 term is
     the lag along a curved path) and the centripetal jerk v^3 / R^2 through |K_jerk|.

   :func:`fdid_fmi.identify.quasi_static.feed_limits` (Eqn 3.6: |K_vel v| + |K_acc a| +
   |K_jerk j| <= e_max) then checks a candidate feed with the accelerations and jerks the
   interpolator uses at that feed; the largest feed that passes (bisection) is the first guess.
2. **Dynamic correction, block by block.** With an exact stop at every block end, a block's
   contour error depends on its own feed and on the lag the block before it leaves at the
   corner, and on nothing further away. So, in program order, each cutting block's override is
   bracketed and bisected (to 3 %) with the twin (model or FMU) run on the block triple
   (neighbours at their current overrides): the largest override whose |contour error| stays
   within the tolerance in the block's own window *and* in the next block's window (a next
   window that is over whatever this block does is left to that block). Two such sweeps from
   the first pass, then a run of the whole program checks the feeds together and lowers any
   block (and the one before it) that still exceeds the tolerance.
   A dwell (G4) right after a cutting block counts against that block
   (:func:`~fdid_fmi.plan.predict.dwell_owners`): the axes settle there, and the block is
   slowed for it.
3. **Never worse than one uniform override.** The uniform override (the largest single
   override for all cutting blocks that keeps every block within the tolerance, by bisection
   on the whole program) is found first; if the per-block result is slower, one sweep starts
   from the uniform override and only raises blocks, and the faster feasible result is kept.

4. **As written.** The final check, and the "after" figures, plan the program as
   :func:`~fdid_fmi.plan.ncprogram.write_program` writes it (F to 6 significant digits), read
   back: planning the written ``-o`` program gives the reported figures (a twin with friction
   moved 0.2 um for F273.7369 -> F273.737). A block over the aim then is lowered and checked
   again.

Overrides never exceed 100 % (the programmed feed is the planner's cutting choice; rapids are
left alone). With ``in_position`` every re-plan keeps the in-position wait after rapids
(:class:`~fdid_fmi.plan.interpolate.InPosition`).
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model import QuasiStaticModel
from .interpolate import AXES, block_profile, interpolate
from .ncprogram import Program, parse_program, write_program
from .predict import dwell_owners, predict


def check_optimisable(axes, source=None):
    """InputError unless the twin's ``axes`` span a plane: the feeds are set by the contour error,
    which is measured there (``fdid plan`` checks it before printing its table)."""
    if len(axes) < 2:
        raise InputError("feed optimisation needs a model of (at least) two axes: the contour error "
                         "is in their plane", source=source, column="axes")


def quasi_static_gains(model, axes=None):
    """K_vel [s], K_acc [s^2], K_jerk [s^3] of each axis from a DriveModel's linear part.

    Taylor coefficients at s = 0 of G_er(s) = e(s)/x_r(s) with z = exp(s Ts) (Eqn 3.2-3.3),
    from the model's ``error`` output (or 1 - position/command).

    Returns
    -------
    QuasiStaticModel
    """
    from ..virtual.drive import taylor_coefficients
    A, B, C, D, Ts = model.A, model.B, model.C, model.D, model.Ts
    poles = [abs(p) for p in model.poles if abs(p) > 0]
    rho = 0.2 * (min(poles) if poles else 1.0 / Ts * 0.01)
    gains = {}
    n = A.shape[0]
    for ax in axes or model.axes:
        i = model.input_index("command", ax)
        oe = model.output_index("error", ax)
        op = model.output_index("position", ax)

        def G(s, i=i, oe=oe, op=op):
            out = np.empty(s.shape, complex)
            for k, sk in enumerate(s):
                z = np.exp(sk * Ts)
                x = np.linalg.solve(z * np.eye(n) - A, B[:, i])
                if oe is not None:
                    out[k] = C[oe] @ x + D[oe, i]
                else:
                    out[k] = 1.0 - (C[op] @ x + D[op, i])
            return out

        c = taylor_coefficients(G, rho, n_terms=4, n_points=32)
        gains[ax] = {"K_vel": c[1], "K_acc": c[2], "K_jerk": c[3]}
    return QuasiStaticModel(Ts=Ts, gains=gains, cutoff_hz=min(50.0, 0.1 / Ts),
                            method="quasi-static (Taylor series of the model)")


def _block_gains(block, qs, axes):
    """Effective normal-error gains of a block (see module docstring) and its radius (or inf).

    Returns ``(k, dk, R)``: k = gains of the path-normal terms (line: mismatch gains; arc: the
    radial gains K_vel mismatch / 2, K_acc + K_vel^2 / 2, K_jerk of the mean axis), dk = the
    mismatch gains that act on the tangential acceleration and jerk of an arc (zeros for lines).
    """
    ix = [AXES.index(a) for a in axes[:2]]
    g = [qs.gains[a] for a in axes[:2]]
    keys = ("K_vel", "K_acc", "K_jerk")
    zero = {key: 0.0 for key in keys}
    if block.kind == "line":
        d = (block.end - block.start)[ix]
        L = float(np.linalg.norm(d))
        if L == 0:
            return zero, zero, math.inf
        u = d / L
        nrm = np.array([-u[1], u[0]])
        frac = L / block.length                  # share of the move in the model's plane
        k = {key: frac * abs(sum(nrm[m] * u[m] * g[m][key] for m in range(2))) for key in keys}
        return k, zero, math.inf
    kv = [gg["K_vel"] for gg in g]
    ka = [gg["K_acc"] for gg in g]
    kj = [gg["K_jerk"] for gg in g]
    k = {"K_vel": abs(kv[0] - kv[1]) / 2,
         "K_acc": abs(np.mean(ka) + np.mean(kv) ** 2 / 2),
         "K_jerk": abs(float(np.mean(kj)))}
    dk = {"K_vel": 0.0, "K_acc": abs(ka[0] - ka[1]) / 2, "K_jerk": abs(kj[0] - kj[1]) / 2}
    return k, dk, 0.5 * (block.r0 + block.r1)


def first_pass(program, limits, Ts, qs, axes, tol_mm, min_override=0.05):
    """Quasi-static overrides per cutting block: the largest feed v whose feed-dependent terms
    pass :func:`~fdid_fmi.identify.quasi_static.feed_limits` (Eqn 3.6) with the block's
    effective gains: v itself and, on arcs, the centripetal acceleration v^2/R and jerk
    v^3/R^2. (The tangential acceleration and jerk are set by the axis limits, not by F: the
    dynamic check judges them.)

    Returns
    -------
    dict block index -> override in [min_override, 1]
    """
    from ..identify.quasi_static import feed_limits
    out = {}
    for b in program.blocks:
        if b.kind not in ("line", "arc") or b.length == 0:
            continue
        k, _, R = _block_gains(b, qs, axes)
        m = QuasiStaticModel(Ts=Ts, gains={"n": k}, cutoff_hz=qs.cutoff_hz)
        prof, _, c = block_profile(b, limits, Ts, 1.0)
        v1 = prof.v_peak * c

        def within(f):
            v = v1 * f
            if math.isfinite(R):
                return feed_limits(m, "n", tol_mm, v_max=v, a_max=v * v / R, j_max=v ** 3 / R ** 2)["within"]
            return feed_limits(m, "n", tol_mm, v_max=v)["within"]

        if within(1.0):
            out[b.index] = 1.0
            continue
        lo, hi = min_override, 1.0
        if not within(lo):
            out[b.index] = lo
            continue
        while hi / lo > 1.02:
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if within(mid) else (lo, mid)
        out[b.index] = lo
    return out


@dataclass
class FeedPlan:
    """Result of :func:`optimize_feeds`.

    Attributes
    ----------
    overrides : dict block index (0-based) -> override (new feed / programmed feed), as written
        (the F words of :func:`~fdid_fmi.plan.ncprogram.write_program` over the programmed feed)
    first_pass : dict block index -> quasi-static override
    before, after : Prediction   the programmed and the optimised program
    uniform_override : float     the single override that keeps every block within tol (0.0:
        none does, down to the lowest override)
    uniform_cycle_time_s : float (nan when none does)
    uniform_max_contour_um : float
    rows : list[dict]            the table (block, line, feeds, errors, durations)
    iterations : int             twin runs (block triples) in the dynamic correction
    reachable : bool             every cutting block within tol at the end
    """

    overrides: dict
    first_pass: dict
    before: object
    after: object
    uniform_override: float
    uniform_cycle_time_s: float
    uniform_max_contour_um: float
    rows: list = field(default_factory=list)
    iterations: int = 0
    reachable: bool = True

    def new_feeds_mm_s(self, program):
        return {b.index: b.feed * self.overrides.get(b.index, 1.0) for b in program.blocks
                if b.kind in ("line", "arc")}


def _block_max(pr, idx, dwells=()):
    """Largest |contour error| (mm) of block ``idx`` and of the dwells ``dwells`` after it."""
    sel = np.isin(pr.interp.block_of_sample, [idx, *dwells])
    return float(np.max(np.abs(pr.contour[sel]))) if sel.any() else 0.0


def _dwells_after(program):
    """{cutting block index: [indices of the dwells whose error counts against it]}."""
    out = {}
    for d, c in dwell_owners(program.blocks).items():
        out.setdefault(c, []).append(d)
    return out


def as_written(program, overrides):
    """The program as :func:`~fdid_fmi.plan.ncprogram.write_program` writes it with these
    overrides, read back, and the overrides as written {cutting block: written feed / programmed
    feed}; (None, overrides) when it cannot be written back (a program built without its text)."""
    feeds = {b.index: b.feed * overrides.get(b.index, 1.0) for b in program.blocks if b.kind in ("line", "arc")}
    if not program.lines:
        return None, dict(overrides)
    prog = parse_program(write_program(program, feeds), source=program.source, start=program.start)
    if [(b.kind, b.length) for b in prog.blocks] != [(b.kind, b.length) for b in program.blocks]:
        return None, dict(overrides)
    out = {}
    for k in overrides:
        b, w = program.blocks[k], prog.blocks[k]
        out[k] = w.feed / b.feed if (math.isfinite(b.feed) and b.feed > 0 and math.isfinite(w.feed)) else overrides[k]
    return prog, out


def optimize_feeds(program, limits, Ts, tol_mm, model=None, fmu=None, qs=None, margin=0.02,
                   rel_tol=0.03, min_override=0.05, progress=False, before=None, corner_angle_deg=None,
                   in_position=None):
    """Per-block feed overrides within ``tol_mm`` of contour error (see module docstring).

    Parameters
    ----------
    program : Program
    limits : dict axis -> AxisLimits
    Ts : float, s
    tol_mm : float, contour tolerance (mm)
    margin : float   the feeds aim at tol_mm * (1 - margin): room for the twin's own error
        (about 1 % of the contour error on the virtual machine, benchmarks/bench_plan.py)
    model : DriveModel (also gives the quasi-static gains), or
    fmu : path of an fdid FMU (then ``qs`` or the FMU's shipped model gives the gains)
    qs : QuasiStaticModel, optional (default: :func:`quasi_static_gains` of the model)
    before : Prediction of the programmed feeds, optional (computed otherwise)
    corner_angle_deg : float, optional   interpolation without stops at tangent junctions
        (:func:`~fdid_fmi.plan.interpolate.interpolate`)
    in_position : InPosition, optional   the in-position wait after rapids, in every re-plan

    Returns
    -------
    FeedPlan
    """
    if not (tol_mm > 0 and math.isfinite(tol_mm)):
        raise InputError(f"--tol must be > 0, got {tol_mm!r}", column="--tol")
    if not 0 <= margin < 1:
        raise InputError(f"--margin must be in [0, 1), got {margin!r}", column="--margin")
    if not (0 < rel_tol and math.isfinite(rel_tol)):        # 0: the bisections never ended
        raise InputError(f"rel_tol must be a finite number > 0, got {rel_tol!r}", column="rel_tol")
    if not 0 < min_override <= 1:                           # 0: a division by zero
        raise InputError(f"min_override must be in (0, 1], got {min_override!r}", column="min_override")
    target = tol_mm * (1.0 - margin)
    if model is None and fmu is None:
        raise InputError("give a model or an FMU", column="--model/--fmu")
    if fmu is not None and Path(fmu).is_file():
        # unpack once: every twin run then starts from the extracted folder
        from ..fmu.archive import extract_fmu
        with tempfile.TemporaryDirectory(prefix="fdid_plan_") as tmp:
            extract_fmu(fmu, tmp)              # member paths and sizes checked before unpacking
            plan = optimize_feeds(program, limits, Ts, tol_mm, model=model, fmu=tmp,
                                  qs=qs if qs is not None else quasi_static_gains(_fmu_model(fmu)),
                                  margin=margin, min_override=min_override, rel_tol=rel_tol,
                                  progress=progress, before=before, corner_angle_deg=corner_angle_deg,
                                  in_position=in_position)
        return plan
    twin = dict(model=model, fmu=fmu)
    if qs is None:
        if model is None:
            from .predict import model_from_fmu
            qs = quasi_static_gains(model_from_fmu(fmu))
        else:
            qs = quasi_static_gains(model)
    axes = list(qs.axes)
    check_optimisable(axes)

    def run(ov, prog=None):
        tick()
        return predict(interpolate(prog or program, limits, Ts, overrides=None if prog else ov,
                                   corner_angle_deg=corner_angle_deg, in_position=in_position),
                       tol_mm=tol_mm, program=program, **twin)

    cutting = [b.index for b in program.blocks if b.kind in ("line", "arc") and b.length > 0]
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc="feed optimisation", unit=" twin runs", leave=False, disable=None)  # off without a terminal

    def tick():
        if bar is not None:
            bar.update(1)

    if before is None:
        before = run({})
    fp = first_pass(program, limits, Ts, qs, axes, target, min_override)
    blocks = program.blocks
    sims = 0

    dwells = _dwells_after(program)

    def bmax(pr, b):
        return _block_max(pr, b, dwells.get(b, ()))

    def feasible(pr):
        return all(bmax(pr, b) <= target for b in cutting)

    # the uniform override that keeps every block within tol (the reference, and a safe start)
    ulo, uhi, upr = 0.0, 1.0, None
    if feasible(before):
        ulo, upr = 1.0, before
    else:
        g = max(min_override, min(fp.values()) if fp else 1.0)
        for _ in range(20):
            pr = run({b: g for b in cutting})
            if feasible(pr):
                ulo, upr = g, pr
            else:
                uhi = g
            if ulo == 0.0:
                if g <= min_override:
                    break
                g = max(min_override, 0.8 * g)
            elif uhi / ulo <= 1 + rel_tol / 2:
                break
            else:
                g = math.sqrt(ulo * uhi)

    def local_error(f, b, fb, with_next=True):
        """Largest |contour error| in the windows of block b (and b+1) when blocks b-1..b+1 run
        alone with the overrides ``f`` and ``fb`` for block b: with exact stops, the lag a block
        leaves at its end shows in the next block's window, and nothing reaches further."""
        nonlocal sims
        tick()
        lo_i, hi_i = max(0, b - 1), min(len(blocks), b + 2)
        part = blocks[lo_i:hi_i]
        sub = Program(blocks=[_reindex(bb, k) for k, bb in enumerate(part)], start=part[0].start,
                      source=program.source)
        ov = {k: (fb if bb.index == b else f.get(bb.index, 1.0)) for k, bb in enumerate(part)}
        pr = predict(interpolate(sub, limits, Ts, overrides=ov, settle=0.2, corner_angle_deg=corner_angle_deg,
                                 in_position=in_position), tol_mm=tol_mm, program=sub, **twin)
        sims += 1
        sub_dwells = _dwells_after(sub)
        return max(_block_max(pr, k, sub_dwells.get(k, ())) for k, bb in enumerate(part)
                   if bb.index == b or (with_next and bb.index > b))

    def best(f, b, with_next=True):
        """Largest override of block b in [min_override, 1] within tol, its neighbours as in f."""
        def ok(g):
            return local_error(f, b, g, with_next) <= target
        if ok(f[b]):
            lo, hi = f[b], 1.0
            if lo >= 1.0 or ok(1.0):
                return 1.0
        else:
            lo, hi, g = 0.0, f[b], f[b]
            while g > min_override:
                g = max(min_override, g * 0.6)
                if ok(g):
                    lo = g
                    break
                hi = g
            if lo == 0.0:
                return best(f, b, False) if with_next else min_override
        while hi / lo > 1 + rel_tol:
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if ok(mid) else (lo, mid)
        return lo

    def sweeps(f, n=2):
        for _ in range(n):
            old = dict(f)
            for b in cutting:
                f[b] = best(f, b)
            if all(abs(f[b] - old[b]) <= rel_tol * old[b] for b in cutting):
                break
        return f

    def check(f):
        """Run the whole program; lower blocks (and the one before) that still exceed tol."""
        pr = run(f)
        for _ in range(8):
            bad = [b for b in cutting if bmax(pr, b) > target and f[b] > min_override]
            if not bad:
                break
            for b in bad:
                f[b] = max(min_override, 0.9 * f[b])
                i = cutting.index(b)
                if i > 0:
                    f[cutting[i - 1]] = max(min_override, 0.95 * f[cutting[i - 1]])
            pr = run(f)
        return f, pr

    # from the quasi-static first pass: coordinate sweeps with the twin, then the whole program
    f, after = check(sweeps(dict(fp)))
    # never worse than the uniform override: start from it and raise block by block
    if upr is not None and (not feasible(after) or after.interp.cycle_time > upr.interp.cycle_time):
        f2, after2 = check(sweeps({b: ulo for b in cutting}, 1))
        if feasible(after2) and (not feasible(after) or after2.interp.cycle_time < after.interp.cycle_time):
            f, after = f2, after2
        if not feasible(after) or after.interp.cycle_time > upr.interp.cycle_time:
            f, after = {b: ulo for b in cutting}, upr
    # as written: F to 6 significant digits moves a twin with friction (0.2 um seen); plan the
    # program as -o writes it, lower a block the rounding took over the aim and write again (a
    # block over it before the rounding, which the feed could not bring in, is left as it is)
    within = {b for b in cutting if bmax(after, b) <= target}
    for i in range(8):
        prog_w, fw = as_written(program, f)
        if prog_w is None:
            break
        after, f = run(None, prog_w), fw
        bad = [b for b in within if bmax(after, b) > target and f[b] > 1.001 * min_override]
        if not bad or i == 7:
            break
        f = {**f, **{b: max(min_override, 0.98 * f[b]) for b in bad}}
    it = sims
    reachable = all(bmax(after, b) <= tol_mm for b in cutting)
    if bar is not None:
        bar.close()
    rows = []
    for b in program.blocks:
        if b.kind not in ("line", "arc", "rapid"):
            continue
        k0, k1 = before.interp.spans[b.index]
        a0, a1 = after.interp.spans[b.index]
        ov = f.get(b.index, 1.0)
        rows.append({"block": b.index + 1, "line": b.line, "N": b.number if b.number is not None else "",
                     "kind": b.kind,
                     "feed_mm_min": b.feed * 60 if math.isfinite(b.feed) else float("inf"),
                     "first_pass_mm_min": (b.feed * 60 * fp.get(b.index, 1.0)) if math.isfinite(b.feed) else float("inf"),
                     "new_feed_mm_min": b.feed * 60 * ov if math.isfinite(b.feed) else float("inf"),
                     "override_pct": 100 * ov,
                     "contour_max_before_um": bmax(before, b.index) * 1e3,
                     "contour_max_after_um": bmax(after, b.index) * 1e3,
                     "time_before_s": (k1 - k0) * Ts, "time_after_s": (a1 - a0) * Ts})
    return FeedPlan(overrides=f, first_pass=fp, before=before, after=after,
                    uniform_override=ulo,
                    uniform_cycle_time_s=upr.interp.cycle_time if upr is not None else float("nan"),
                    uniform_max_contour_um=(max(bmax(upr, b) for b in cutting) * 1e3
                                            if upr is not None and cutting else float("nan")),
                    rows=rows, iterations=it, reachable=reachable)


def _reindex(block, k):
    from dataclasses import replace
    return replace(block, index=k)


def _fmu_model(fmu):
    from .predict import model_from_fmu
    return model_from_fmu(fmu)
