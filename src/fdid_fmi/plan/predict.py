"""Predicted tracking and contour errors of a program, per NC block and for the whole program.

The twin is either a :class:`~fdid_fmi.model.DriveModel` run by
:func:`fdid_fmi.simulate.simulate` or an exported FMU run by ``fmpy.simulate_fmu`` with an input
table (outputs recorded after each ``doStep``: the row at t_k + h is the model's position at
t_k + h, input k held; the tracking error is formed here as e = x_cmd - x at the same time).

Contour error (as :func:`fdid_fmi.metrics.contour_error`: the shortest distance from the
predicted point to the commanded path, here the polyline of the commanded samples, which lies
on the programmed geometry to < 0.1 um), **signed** in the plane of the model's two axes, taken
in right-handed order ((x, y), (y, z) or (z, x): :func:`contour_axes`): positive when the tool is
left of the direction of travel seen from the plane's positive normal (inside a counter-clockwise
G3 arc, outside a clockwise G2 one), negative when right.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..metrics import rms


def signed_contour_error(cmd, act, window=400, feet=False, k_nearest=12, chunk=8192):
    """Signed shortest distance from each actual point to the commanded polyline.

    Parameters
    ----------
    cmd, act : (N, d) arrays, mm (d = 2 gives a sign; other d: unsigned distance)
    window : int   only segments within +-window samples of the same index are searched (a path
        that passes the same place twice is not confused)
    feet : bool   also return the nearest path points and the unit left normals there
    k_nearest : int   the segments next to the k nearest commanded samples are the candidates
        (KD-tree); points with no candidate in the window are searched by brute force
    chunk : int   samples searched at a time. The candidates take ~2.6 kB per sample
        (k_nearest + 1 segments x d coordinates in several arrays): the whole program at once
        grew with its length (2.7 GB for 1e6 samples). In chunks the working memory is bounded
        (~20 MB at the default) and each sample's result is the same (samples are independent).

    Returns
    -------
    (N,) ndarray, mm; for d = 2 positive = left of the direction of travel
    (and, with ``feet``, (N, d) foot points and (N, d) unit left normals (d = 2; zeros otherwise))
    """
    from scipy.spatial import cKDTree
    P = np.asarray(cmd, float)
    Q = np.asarray(act, float)
    if P.shape != Q.shape or P.ndim != 2:
        raise InputError(f"contour error needs two (N, d) arrays, got {P.shape} and {Q.shape}",
                         column="contour")
    N, dim = P.shape
    if N < 2:
        d0 = np.linalg.norm(Q - P, axis=1)
        return (d0, P.copy(), np.zeros_like(P)) if feet else d0
    AB = np.diff(P, axis=0)
    L2 = np.einsum("ij,ij->i", AB, AB)
    moving = L2 > 0
    mv_idx = np.flatnonzero(moving)
    best_seg = np.full(N, -1)
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise InputError(f"chunk must be a whole number of samples >= 1, got {chunk!r}", column="chunk")
    if mv_idx.size:
        # candidates: moving segments next to the k nearest moving-segment start points
        tree = cKDTree(P[mv_idx])
        k = min(k_nearest, mv_idx.size)
        for c0 in range(0, N, chunk):
            rows = np.arange(c0, min(N, c0 + chunk))
            n = rows.size
            _, nn = tree.query(Q[rows], k=k)
            nn = np.atleast_2d(nn.reshape(n, -1))
            segs = mv_idx[nn]                                        # (n, k) segment indices
            prev = np.searchsorted(mv_idx, segs) - 1                 # the moving segment before
            segs = np.concatenate([segs, mv_idx[np.maximum(prev, 0)]], axis=1)
            ok = np.abs(segs - rows[:, None]) <= window
            ABs = AB[segs]
            AQ = Q[rows, None, :] - P[segs]
            t = np.clip(np.einsum("ksj,ksj->ks", AQ, ABs) / L2[segs], 0.0, 1.0)
            D = AQ - t[..., None] * ABs
            dist = np.where(ok, np.einsum("ksj,ksj->ks", D, D), np.inf)
            j = _nearest_in_time(dist, segs, rows)
            found = np.isfinite(dist[np.arange(n), j])
            best_seg[rows[found]] = segs[np.arange(n), j][found]
    # brute force where the KD-tree found nothing in the window (e.g. the command at rest): up
    # to m samples at a time that lie within m samples of each other (each is searched over its
    # own +-window; samples far apart, e.g. dwells, would span the whole program's segments),
    # m such that a (m, segments) array has at most 2^20 elements (Ts = 1 us: window 2e5, m = 2)
    todo = np.flatnonzero(best_seg < 0)
    L2s = np.where(moving, L2, 1.0)
    # nothing moves within +-window (a long dwell, the settling time): every segment there is
    # the same point, all equally near; the nearest in time is the sample's own (what the search
    # below returns, without its (m, 2 window) arrays: 170 s for a 2000 s dwell)
    cm = np.concatenate([[0], np.cumsum(moving)])
    still = cm[np.minimum(todo + window + 1, N - 1)] == cm[np.maximum(todo - window, 0)]
    best_seg[todo[still]] = np.minimum(todo[still], N - 2)
    todo = todo[~still]
    m = max(1, min(256, (1 << 20) // (2 * int(window) + 257)))
    c0 = 0
    while c0 < todo.size:
        c1 = min(c0 + m, int(np.searchsorted(todo, todo[c0] + m)))
        ks = todo[c0:c1]
        c0 = c1
        lo, hi = max(0, ks[0] - window), min(N - 1, ks[-1] + window + 1)
        seg = np.arange(lo, hi)
        AQ = Q[ks, None, :] - P[None, seg, :]
        t = np.clip(np.einsum("ksj,sj->ks", AQ, AB[seg]) / L2s[None, seg], 0.0, 1.0)
        D = AQ - t[..., None] * AB[None, seg, :]
        dist = np.einsum("ksj,ksj->ks", D, D)
        dist = np.where(np.abs(seg[None, :] - ks[:, None]) > window, np.inf, dist)
        # a segment of zero length (the command at rest) only counts when nothing moves nearby
        dist_m = np.where(moving[None, seg], dist, np.inf)
        use_m = np.isfinite(dist_m).any(axis=1)
        dd = np.where(use_m[:, None], dist_m, dist)
        best_seg[ks] = seg[_nearest_in_time(dd, np.broadcast_to(seg, dd.shape), ks)]
    ab = AB[best_seg]
    t = np.clip(np.einsum("ij,ij->i", Q - P[best_seg], ab) / L2s[best_seg], 0.0, 1.0)
    foot = P[best_seg] + t[:, None] * ab
    d = Q - foot
    out = np.sqrt(np.einsum("ij,ij->i", d, d))
    nrm = np.zeros((N, dim))
    if dim == 2:
        cross = ab[:, 0] * d[:, 1] - ab[:, 1] * d[:, 0]
        out = np.where(cross < 0, -out, out)
        ln = np.sqrt(np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300))
        nrm = np.column_stack([-ab[:, 1], ab[:, 0]]) / ln[:, None]
    return (out, foot, nrm) if feet else out


def contour_window(Ts):
    """Search window of :func:`signed_contour_error` for commands sampled at Ts: +-400 samples
    and at least +-0.2 s, so that a tool lagging up to 0.2 s behind its command (a position
    loop gain down to 5 1/s) finds its nearest path point at any sample rate (a fixed 400
    samples is only 50 ms at 8 kHz: the error was then measured to a later point of the path)."""
    return max(400, int(math.ceil(0.2 / Ts)))


def contour_axes(axes):
    """The axes the contour error is measured in: a model of two axes gives them in right-handed
    order, (x, y), (y, z) or (z, x) as in G17 / G19 / G18, whatever the model's order, so that
    the sign means the same for every model (positive inside a G3 arc); other models: all axes
    (unsigned)."""
    axes = list(axes)
    if len(axes) == 2 and all(a in ("x", "y", "z") for a in axes):
        i, j = ("x", "y", "z").index(axes[0]), ("x", "y", "z").index(axes[1])
        return axes if (j - i) % 3 == 1 else axes[::-1]
    return axes


def _nearest_in_time(dist, segs, ks):
    """Per row, the column of the smallest squared distance; among columns as near to within
    1 nm (a path that retraces itself: the same line twice, a shared vertex), the segment whose
    index is closest to the sample's own, so that the side (the sign) is taken from the pass
    the tool is on, not from an earlier or later pass over the same place."""
    dmin = np.min(dist, axis=1, keepdims=True)
    with np.errstate(invalid="ignore"):
        tie = dist <= (np.sqrt(dmin) + 1e-6 * 1e-3) ** 2
    key = np.where(tie, np.abs(segs - np.asarray(ks)[:, None]), np.iinfo(np.int64).max)
    return np.argmin(key, axis=1)


@dataclass
class Prediction:
    """What the twin predicts for one interpolated program.

    Attributes
    ----------
    interp : Interpolation      the commanded positions
    axes : list[str]            simulated axes (the model's)
    position, error : dict axis -> (N,) ndarray, mm   predicted position and e = x_cmd - x
    contour : (N,) ndarray, mm  signed contour error (zeros for a one-axis model)
    blocks : list[dict]         per-block figures (see :func:`block_table`)
    summary : dict              whole program: cycle time, RMS / MAX per axis and contour
    engine : str                ``model`` or ``fmu``
    """

    interp: object
    axes: list
    position: dict
    error: dict
    contour: np.ndarray
    blocks: list = field(default_factory=list)
    summary: dict = field(default_factory=dict)
    engine: str = "model"


def run_model(model, interp):
    """Predicted positions {axis: (N,)} from :func:`fdid_fmi.simulate.simulate` (at rest at the
    first commanded position)."""
    from ..simulate import simulate
    missing = [a for a in model.axes if a not in interp.positions]
    if missing:
        raise InputError(f"the model's axes {missing} are not x, y or z", column="axes")
    res = simulate(model, {a: interp.positions[a] for a in model.axes}, Ts=interp.Ts)
    return {a: np.asarray(res.axes[a]["position"], float) for a in model.axes}


def fmu_axes(fmu_path):
    """Axes of an fdid FMU (inputs named ``<axis>_x_cmd``) and its step size (s)."""
    from fmpy import read_model_description
    from ..fmu.archive import check_fmu_archive
    check_fmu_archive(fmu_path)         # member paths and sizes, before fmpy inflates or unpacks it
    try:
        md = read_model_description(str(fmu_path))
    except Exception as exc:  # noqa: BLE001 - fmpy raises many kinds
        raise InputError(f"is not a readable FMU ({exc})", source=str(fmu_path)) from None
    axes = [v.name[:-6] for v in md.modelVariables if v.causality == "input" and v.name.endswith("_x_cmd")]
    step = md.defaultExperiment.stepSize if md.defaultExperiment is not None else None
    if not axes:
        raise InputError("the FMU has no '<axis>_x_cmd' inputs: not an fdid drive FMU", source=str(fmu_path))
    return axes, (float(step) if step else None)


def model_from_fmu(fmu_path):
    """The DriveModel an fdid FMU ships in ``resources/model.json``."""
    import json
    import zipfile
    from ..model import DriveModel
    from pathlib import Path
    try:
        if Path(fmu_path).is_dir():           # an extracted FMU
            d = json.loads((Path(fmu_path) / "resources" / "model.json").read_text())
        else:
            from ..fmu.archive import read_member
            d = json.loads(read_member(fmu_path, "resources/model.json"))
    except InputError:                        # refused by read_member: says why itself
        raise
    except (KeyError, OSError, zipfile.BadZipFile, ValueError) as exc:
        raise InputError(f"carries no readable resources/model.json ({exc})", source=str(fmu_path)) from None
    return DriveModel.from_dict(d, source=f"{fmu_path}:resources/model.json")


def run_fmu(fmu_path, interp, axes):
    """Predicted positions {axis: (N,)} from the FMU through ``fmpy.simulate_fmu`` (an input
    table with the commanded positions at every sample; communication step = Ts)."""
    import fmpy
    Ts, N = interp.Ts, interp.n
    dtype = [("time", np.float64)] + [(f"{a}_x_cmd", np.float64) for a in axes]
    table = np.zeros(N, dtype=dtype)
    table["time"] = interp.t
    for a in axes:
        table[f"{a}_x_cmd"] = interp.positions[a]
    res = fmpy.simulate_fmu(str(fmu_path), start_time=0.0, stop_time=float(interp.t[-1]),
                            step_size=Ts, output_interval=Ts, input=table,
                            output=[f"{a}_x" for a in axes])
    if len(res) != N:
        raise InputError(f"the FMU returned {len(res)} rows for {N} samples", source=str(fmu_path))
    return {a: np.asarray(res[f"{a}_x"], float) for a in axes}


def predict(interp, model=None, fmu=None, tol_mm=None, program=None):
    """Predicted tracking and contour errors of an interpolated program.

    Parameters
    ----------
    interp : Interpolation
    model : DriveModel, optional    (one of model / fmu)
    fmu : path of an fdid FMU, optional
    tol_mm : float, optional        contour tolerance: blocks whose |contour error| exceeds it are
        flagged
    program : Program, optional     for the per-block table's line numbers and feeds

    Returns
    -------
    Prediction
    """
    if (model is None) == (fmu is None):
        raise InputError("give a model or an FMU (one of them)", column="--model/--fmu")
    if model is not None:
        axes = list(model.axes)
        pos = run_model(model, interp)
        engine = "model"
    else:
        axes, _ = fmu_axes(fmu)
        pos = run_fmu(fmu, interp, axes)
        engine = "fmu"
    err = {a: interp.positions[a] - pos[a] for a in axes}
    if len(axes) >= 2:
        c2 = contour_axes(axes)
        cmd = np.column_stack([interp.positions[a] for a in c2])
        act = np.column_stack([pos[a] for a in c2])
        contour = signed_contour_error(cmd, act, window=contour_window(interp.Ts))
    else:
        contour = np.zeros(interp.n)
    pr = Prediction(interp=interp, axes=axes, position=pos, error=err, contour=contour, engine=engine)
    pr.blocks = block_table(pr, program, tol_mm)
    pr.summary = summary(pr, tol_mm)
    return pr


def dwell_owners(blocks):
    """{dwell block index: index of the cutting block whose settling error it shows}.

    A dwell (G4) right after a cutting block (G1/G2/G3 that moves; other dwells and zero-length
    moves in between are passed over) holds the tool at that block's end while the axes settle:
    its contour error counts against that block (flagged there; the optimiser slows that block
    for it). After a rapid (G0) a dwell counts against nothing: errors during and after rapids
    are not flagged (not cutting).
    """
    out, last = {}, None
    for b in blocks:
        if b.kind == "dwell":
            if last is not None:
                out[b.index] = last
        elif b.kind == "rapid":
            last = None
        elif b.length > 0:
            last = b.index if b.kind in ("line", "arc") else None
    return out


def cutting_contour_max_um(pr):
    """The largest |contour error| (um) the tolerance judges: over the cutting blocks (lines and
    arcs) and the dwells after them (``contour_max_with_dwell_um``); rapids are not judged. 0
    when the program cuts nothing."""
    return max((r["contour_max_with_dwell_um"] for r in pr.blocks if r.get("kind") in ("line", "arc")),
               default=0.0)


def block_table(pr, program=None, tol_mm=None):
    """Per-block figures: line, N, kind, feed, duration, max |e| per axis and contour RMS / MAX
    (um), flagged when the max |contour error| exceeds ``tol_mm`` (cutting blocks only).

    ``contour_max_with_dwell_um``: a cutting block's largest |contour error| over its own samples
    and those of the dwells right after it (:func:`dwell_owners`): what its flag judges (the
    dwell's row shows its own figure, unflagged); other blocks: their own. Errors during rapids
    (and their in-position waits) are never flagged: the tool is not cutting."""
    ip = pr.interp
    rows = []
    blocks = program.blocks if program is not None else [None] * len(ip.spans)
    # each block's samples in time order, from one stable sort (a mask per block was
    # blocks x samples work: 18 s for 20000 blocks over 1e6 samples)
    owner = np.asarray(ip.block_of_sample)
    order = np.argsort(owner, kind="stable")
    owner_sorted = owner[order]
    for b, (k0, k1) in zip(blocks, ip.spans):
        idx = b.index if b is not None else len(rows)
        sel = order[np.searchsorted(owner_sorted, idx, "left"):np.searchsorted(owner_sorted, idx, "right")]
        row = {"block": idx + 1}
        if b is not None:
            row.update({"line": b.line, "N": b.number if b.number is not None else "", "kind": b.kind,
                        "feed_mm_min": (b.feed * 60.0 if np.isfinite(b.feed) else float("inf")),
                        "length_mm": b.length})
        row["duration_s"] = (k1 - k0) * ip.Ts
        for a in pr.axes:
            row[f"{a}_max_err_um"] = float(np.max(np.abs(pr.error[a][sel]))) * 1e3 if sel.size else 0.0
        c = pr.contour[sel]
        row["contour_rms_um"] = rms(c) * 1e3 if c.size else 0.0
        row["contour_max_um"] = float(np.max(np.abs(c))) * 1e3 if c.size else 0.0
        row["contour_signed_peak_um"] = float(c[np.argmax(np.abs(c))]) * 1e3 if c.size else 0.0
        row["contour_max_with_dwell_um"] = row["contour_max_um"]
        rows.append(row)
    if program is not None:
        by_index = {r["block"] - 1: r for r in rows}
        for d, c in dwell_owners(program.blocks).items():
            by_index[c]["contour_max_with_dwell_um"] = max(by_index[c]["contour_max_with_dwell_um"],
                                                           by_index[d]["contour_max_um"])
    for b, row in zip(blocks, rows):
        cutting = b is None or b.kind in ("line", "arc")
        row["flag"] = bool(tol_mm is not None and cutting and row["contour_max_with_dwell_um"] > tol_mm * 1e3)
    return rows


def summary(pr, tol_mm=None):
    ip = pr.interp
    out = {"engine": pr.engine, "cycle_time_s": ip.cycle_time, "samples": ip.n, "Ts_s": ip.Ts,
           "axes": {}}
    for a in pr.axes:
        out["axes"][a] = {"error_rms_um": rms(pr.error[a]) * 1e3,
                          "error_max_um": float(np.max(np.abs(pr.error[a]))) * 1e3}
    # axes the program moves that the twin does not model: they follow their commands ideally
    out["not_predicted"] = [a for a, x in ip.positions.items() if a not in pr.axes and np.ptp(x) > 0]
    out["contour_rms_um"] = rms(pr.contour) * 1e3
    out["contour_max_um"] = float(np.max(np.abs(pr.contour))) * 1e3
    if tol_mm is not None:
        out["tol_um"] = tol_mm * 1e3
        out["flagged_blocks"] = [r["block"] for r in pr.blocks if r["flag"]]
    return out
