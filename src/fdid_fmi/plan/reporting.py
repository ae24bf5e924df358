"""The planner's report: programmed and predicted tool path, errors over time and path length,
the per-block table and, with an optimisation, the feed table (HTML one file + JSON)."""
from __future__ import annotations

import numpy as np

from ..report import Report, add_model_section, decimate


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def path_figure(rep, name, pr, magnify=None, title=""):
    """XY path: programmed (black) and predicted with the contour error magnified and coloured."""
    plt = _plt()
    from matplotlib.collections import LineCollection
    from .predict import contour_axes, contour_window, signed_contour_error
    a, b = contour_axes(pr.axes)[:2]
    ip = pr.interp
    cx, cy = ip.positions[a], ip.positions[b]
    c, foot, nrm = signed_contour_error(np.column_stack([cx, cy]),
                                        np.column_stack([pr.position[a], pr.position[b]]), feet=True,
                                        window=contour_window(ip.Ts))
    span = max(np.ptp(cx), np.ptp(cy), 1e-9)
    emax = max(float(np.max(np.abs(c))), 1e-12)
    if magnify is None:
        magnify = float(10 ** np.floor(np.log10(max(1.0, 0.05 * span / emax))))
    # the deviation drawn normal to the path at the nearest path point, magnified
    px, py = foot[:, 0] + magnify * c * nrm[:, 0], foot[:, 1] + magnify * c * nrm[:, 1]
    fig, ax = plt.subplots(figsize=(8, 7))
    ax.plot(cx, cy, "k-", lw=0.8, label="programmed (commanded) path")
    ax.plot([], [], "-", color="C3", lw=2, label=f"predicted path, contour error x{magnify:g}")
    pts = np.column_stack([px, py]).reshape(-1, 1, 2)
    segs = np.concatenate([pts[:-1], pts[1:]], axis=1)
    c_um = pr.contour * 1e3
    lim = max(float(np.max(np.abs(c_um))), 1e-9)
    lc = LineCollection(segs, cmap="coolwarm", norm=plt.Normalize(-lim, lim), lw=2)
    lc.set_array(c_um[:-1])
    ax.add_collection(lc)
    cb = fig.colorbar(lc, ax=ax)
    cb.set_label("contour error [µm] (+ left of travel)")
    ax.set_xlabel(f"{a} [mm]")
    ax.set_ylabel(f"{b} [mm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{title} predicted tool path, contour error magnified x{magnify:g}".strip())
    ax.legend(fontsize=8, loc="best")
    rep.add_figure(name, fig, data={"x_cmd_mm": decimate(cx), "y_cmd_mm": decimate(cy),
                                    "x_pred_mm": decimate(pr.position[a]), "y_pred_mm": decimate(pr.position[b]),
                                    "x_plot_mm": decimate(px), "y_plot_mm": decimate(py),
                                    "contour_um": decimate(c_um), "magnification": magnify},
                   caption=f"Programmed path (black) and the tool path the twin predicts: its deviation normal "
                           f"to the path (the contour error) magnified {magnify:g} times and coloured by its "
                           f"signed value (red: left of the direction of travel, blue: right).")


def error_figures(rep, name, pr, tol_mm=None):
    plt = _plt()
    ip = pr.interp
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    data = {"t_s": decimate(ip.t)}
    for a in pr.axes:
        a1.plot(ip.t, pr.error[a] * 1e3, label=f"{a} tracking error")
        data[f"{a}_e_um"] = decimate(pr.error[a] * 1e3)
    a2.plot(ip.t, pr.contour * 1e3, "C3", label="contour error")
    data["contour_um"] = decimate(pr.contour * 1e3)
    if tol_mm:
        for s in (1, -1):
            a2.axhline(s * tol_mm * 1e3, color="k", ls="--", lw=0.8)
    a1.set_ylabel("tracking error [µm]")
    a2.set_ylabel("contour error [µm]")
    a2.set_xlabel("time [s]")
    a1.legend(fontsize=8)
    a2.legend(fontsize=8)
    rep.add_figure(f"{name}_time", fig, data=data, caption="Predicted tracking error per axis and signed "
                   "contour error over time (dashed: the tolerance).")
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(ip.path_s, pr.contour * 1e3, "C3")
    if tol_mm:
        for s in (1, -1):
            ax.axhline(s * tol_mm * 1e3, color="k", ls="--", lw=0.8)
    for k0, _ in ip.spans[1:]:
        ax.axvline(ip.path_s[k0], color="0.8", lw=0.6)
    ax.set_xlabel("programmed path length [mm]")
    ax.set_ylabel("contour error [µm]")
    rep.add_figure(f"{name}_path", fig, data={"path_mm": decimate(ip.path_s), "contour_um": decimate(pr.contour * 1e3)},
                   caption="Contour error over the programmed path length (grey: block boundaries).")


_BLOCK_COLS = ["block", "line", "N", "kind", "feed_mm_min", "length_mm", "duration_s"]


def _rows_text(rows, n=8):
    head = ", ".join(map(str, rows[:n]))
    return head + (f", ... ({len(rows)} rows)" if len(rows) > n else "")


def words_table(program):
    """Every word the program carries, once: its rows, how it was read (applied / noted, from
    :data:`fdid_fmi.plan.words.VOCABULARY`), what it is and what the planner does with it."""
    from .words import BY_KEY, lookup
    out = []
    for key, rows in program.words.items():
        w = BY_KEY.get(key) or lookup(key[0], float(key[1:]))
        out.append({"word": key, "rows": _rows_text(rows), "read as": w.action.value,
                    "what it is": w.meaning, "what the planner does": w.effect})
    return out


def words_summary(program):
    """One line: the words applied and the words noted (read, not acting on the path)."""
    from .words import Action, BY_KEY, lookup
    by = {Action.APPLIED: [], Action.NOTED: []}
    for key in program.words:
        w = BY_KEY.get(key) or lookup(key[0], float(key[1:]))
        by[w.action].append(key)
    parts = []
    if by[Action.APPLIED]:
        parts.append("applied " + " ".join(by[Action.APPLIED]))
    if by[Action.NOTED]:
        parts.append("noted (read, not acting on the path in the twin's plane) " + " ".join(by[Action.NOTED]))
    return "; ".join(parts)


def limits_table(info):
    """The axis limits the interpolation used and where each came from."""
    src = info.get("limit_sources", {})
    return [{"axis": a, "v [mm/s]": v["v"], "a [mm/s²]": v["a"], "j [mm/s³]": v["j"],
             "from": src.get(a, "given")} for a, v in sorted(info.get("limits", {}).items())]


def plan_report(program, pr, model=None, tol_mm=None, feed_plan=None, fmu=None, validation=None,
                title=None, meta=None):
    """:class:`~fdid_fmi.report.Report` of a prediction (and optionally of a feed optimisation).

    JSON ``data.feed_plan.overrides``: {block: new feed / programmed feed}, keyed by the tables'
    ``block`` number (1-based; it was the 0-based block index before).
    """
    rep = Report(title or f"Process plan: {program.source}", meta=meta)
    s = pr.summary
    flagged = s.get("flagged_blocks", [])
    words = (f"The program ({len(program.blocks)} blocks) takes {s['cycle_time_s']:.3f} s on this machine "
             f"(interpolated at Ts = {pr.interp.Ts * 1e3:.4g} ms, {pr.interp.info.get('corner_rule', '')}). "
             f"The twin ({'FMU through fmpy' if pr.engine == 'fmu' else 'identified model'}) predicts a "
             f"largest contour error of {s['contour_max_um']:.2f} µm (RMS {s['contour_rms_um']:.2f} µm): how far "
             "the tool leaves the programmed path, measured normal to it. Tracking errors (commanded minus "
             "actual position per axis) are larger: most of them lie along the path and do not mark the part. ")
    if tol_mm is not None:
        words += (f"With a tolerance of {tol_mm * 1e3:.3g} µm, "
                  + (f"{len(flagged)} block(s) exceed it: {', '.join(map(str, flagged))}." if flagged
                     else "every block stays inside it."))
    srcs = pr.interp.info.get("limit_sources", {})
    if srcs:
        words += (" Axis limits: " + "; ".join(f"{a}: {t.split(' (')[0]}" for a, t in sorted(srcs.items()))
                  + " (the limits table).")
    if s.get("not_predicted"):
        words += (f" The twin does not model {', '.join(s['not_predicted'])}: they follow their commands "
                  "ideally, and their errors are not predicted.")
    rep.add_text(words, heading="Summary")
    if program.notes:       # how blocks were read (block delete): as the console says them
        rep.add_text("How the program was read: " + "; ".join(f"line {r}: {w}" for r, w in program.notes[:60])
                     + ("; ..." if len(program.notes) > 60 else ""))
    waits = pr.interp.info.get("in_position", {}).get("waits", [])
    if waits:
        rep.add_text(f"In-position wait after each rapid (G0) until every axis's predicted tracking error is within "
                     f"{pr.interp.info['in_position']['window_mm'] * 1e3:.3g} µm: "
                     + "; ".join(f"line {w['line']}: {w['wait_s']:.3f} s" for w in waits[:60])
                     + ("; ..." if len(waits) > 60 else "") + ". "
                     + " ".join(pr.interp.info.get("notes", [])))
    unread = [(r, w) for r, w in program.ignored if w.startswith("not ")]
    if unread:
        rep.add_text("Lines not run: " + ", ".join(f"line {r}: {w}" for r, w in unread[:60])
                     + (", ..." if len(unread) > 60 else ""))
    if program.words:
        rep.add_table("words", words_table(program),
                      caption="the words the program carries, each once: the rows where it stands; applied "
                              "(it shapes the motion) or noted (read, not acting on the path in the twin's "
                              "plane); docs/plan-words.md lists every word the reader knows")
    lims = limits_table(pr.interp.info)
    if lims:
        rep.add_table("limits", lims, caption="axis limits the program was interpolated within "
                      "(velocity, acceleration, jerk) and where each came from")
    rows = [{"quantity": f"{a} tracking error", "predicted_rms_um": v["error_rms_um"],
             "predicted_max_um": v["error_max_um"]} for a, v in s["axes"].items()]
    rows += [{"quantity": f"{a} tracking error", "predicted_rms_um": "not predicted", "predicted_max_um": "not predicted"}
             for a in s.get("not_predicted", [])]
    rows.append({"quantity": "contour error", "predicted_rms_um": s["contour_rms_um"],
                 "predicted_max_um": s["contour_max_um"]})
    rep.add_table("program", rows, columns=["quantity", "predicted_rms_um", "predicted_max_um"],
                  caption="whole program: the twin's predicted tracking error per axis (commanded minus "
                          "predicted position) and contour error (normal to the path)")
    if len(pr.axes) >= 2:
        path_figure(rep, "path", pr)
    error_figures(rep, "errors", pr, tol_mm)
    cols = _BLOCK_COLS + [f"{a}_max_err_um" for a in pr.axes] + ["contour_rms_um", "contour_max_um",
                                                                  "contour_signed_peak_um",
                                                                  "contour_max_with_dwell_um", "flag"]
    rep.add_table("blocks", [{c: r.get(c, "") for c in cols} for r in pr.blocks], columns=cols,
                  caption="per NC block: the twin's predicted errors; MAX is the largest magnitude, the signed "
                          "peak keeps the side (+ left of the direction of travel); with the dwells after it: "
                          "a cutting block's MAX including the dwells (G4) right after it, what the tolerance "
                          "judges (rapids, and their in-position waits, are not judged)")
    if feed_plan is not None:
        fpn = feed_plan
        after = fpn.after.summary
        rep.add_heading("Feed optimisation")
        rep.add_text(
            f"Per-block feed overrides keeping the predicted contour error within {tol_mm * 1e3:.3g} µm: a "
            "quasi-static first pass (thesis Eqn 3.6 with each block's path-normal gains), corrected block by "
            "block with the twin. Cycle time: programmed "
            f"{fpn.before.interp.cycle_time:.3f} s (largest contour error {fpn.before.summary['contour_max_um']:.2f} µm); "
            f"optimised {fpn.after.interp.cycle_time:.3f} s ({after['contour_max_um']:.2f} µm); "
            + (f"one uniform feed override of {100 * fpn.uniform_override:.1f} % for the same tolerance: "
               f"{fpn.uniform_cycle_time_s:.3f} s ({fpn.uniform_max_contour_um:.2f} µm). "
               if fpn.uniform_override > 0 else "no uniform feed override meets the tolerance. ")
            + ("Every cutting block is within the tolerance." if fpn.reachable else
               "Some blocks stay above the tolerance even at the lowest override: the feed alone cannot "
               "bring them in (the axis jerk or acceleration limits set their error)."))
        rep.add_table("feeds", fpn.rows, caption="per block: programmed, first-pass and new feed, the override, "
                      "the predicted contour error MAX and the block time before and after the optimisation")
        path_figure(rep, "path_optimised", fpn.after, title="optimised:")
        # overrides keyed by the tables' block number (1-based), not the 0-based block index
        rep.add_data("feed_plan", {"overrides": {str(k + 1): v for k, v in fpn.overrides.items()},
                                   "overrides_keyed_by": "block (1-based, as the tables' 'block' column)",
                                   "cycle_time_before_s": fpn.before.interp.cycle_time,
                                   "cycle_time_after_s": fpn.after.interp.cycle_time,
                                   "uniform_override": fpn.uniform_override,
                                   "uniform_cycle_time_s": fpn.uniform_cycle_time_s,
                                   "reachable": fpn.reachable})
    rep.add_data("summary", s)
    rep.add_data("interpolation", pr.interp.info)
    rep.add_data("program", {"source": str(program.source), "notes": [[r, w] for r, w in program.notes],
                             "passed_over": [[r, w] for r, w in program.ignored],
                             "words": {k: list(v) for k, v in program.words.items()}})
    if model is not None:
        add_model_section(rep, model, fmu=fmu, validation=validation)
    return rep
