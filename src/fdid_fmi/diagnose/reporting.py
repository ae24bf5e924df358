"""HTML / JSON report of a diagnosis (built on :class:`fdid_fmi.report.Report`), and the same
before/after numbers reproduced through exported FMUs.

Per kept effect: its name and fitted parameters, the residual before and after on the training
and held-out traces (figures), the evidence figure of its detector, and the RMS/MAX table. Then
every candidate of every round (statistic, threshold, held-out gain, kept or why not:
:func:`candidate_table`, also the JSON summary's ``candidates``), the
whiteness / cross-correlation tests of what is left, and the FMU table when FMUs were checked.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from ..report import Report, decimate


def fmu_check(diag, workdir=None, fmi_version=2):
    """Export the given and the final model as FMUs and validate both on both traces.

    Returns
    -------
    dict ``{"before"|"after": {"train"|"val": {axis: {"rms_um", "max_um"}}, "max_abs_diff_reference_mm":
    float, "problems": [...], "fmu": file name}}``, or ``{"error": message}`` when FMU export / fmpy
    are not available. ``workdir``: where the FMUs are written (kept); default a temporary folder,
    removed before returning.
    """
    if workdir is None:     # a temporary folder, removed after: none is left per run
        with tempfile.TemporaryDirectory(prefix="fdid_diagnose_") as wd:
            return _fmu_check(diag, Path(wd), fmi_version)
    wd = Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    return _fmu_check(diag, wd, fmi_version)


def _fmu_check(diag, wd, fmi_version):
    try:
        from ..fmu import export_fmu, validate_fmu
    except ImportError as exc:  # pragma: no cover - depends on the FMU package
        return {"error": f"FMU support not available: {exc}"}
    out = {}
    for label, model in (("before", diag.model), ("after", diag.final)):
        try:
            path = export_fmu(model, wd / f"model_{label}.fmu", fmi_version=fmi_version)
        except Exception as exc:   # report, do not hide: the model table stands without it
            return {"error": f"FMU export of the {label} model failed: {exc}"}
        d = {"fmu": path.name, "max_abs_diff_reference_mm": 0.0}
        for tname, tr in (("train", diag.train), ("val", diag.val)):
            res = validate_fmu(path, tr, model=model)
            d[tname] = res.axes
            d["max_abs_diff_reference_mm"] = max(d["max_abs_diff_reference_mm"], res.max_abs_diff_reference_mm)
            d.setdefault("problems", []).extend(res.problems)
        out[label] = d
    return out


def fmt_params(e):
    """An effect's fitted parameters as ``name=value, ...`` (what the report and the console show)."""
    skip = {"kind", "axis", "input", "inputs", "output"}
    parts = []
    for k, v in e.items():
        if k in skip:
            continue
        parts.append(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}")
    return ", ".join(parts)


def error_rows(before, after, fmu=None, traces=None):
    """Rows of the before/after table: per trace and channel the free-run discrepancy (measured -
    predicted) RMS / MAX before and after, beside the measured tracking error of that channel
    (commanded minus measured position, motor or tool side) when ``traces`` ({trace label:
    Trace}) are given, and the FMU's discrepancy when ``fmu`` (:func:`fmu_check`) is. Keys as
    :data:`fdid_fmi.labels.LABELS` labels them."""
    rows = []
    for tname in before:
        for ch in before[tname]:
            r = {"trace": tname, "channel": ch}
            measured = _measured_error(traces.get(tname), ch) if traces else None
            if measured is not None:
                r["measured_rms_um"], r["measured_max_um"] = measured["rms_um"], measured["max_um"]
            r.update({"rms_before_um": before[tname][ch]["rms_um"], "rms_after_um": after[tname][ch]["rms_um"],
                      "max_before_um": before[tname][ch]["max_um"], "max_after_um": after[tname][ch]["max_um"]})
            b = before[tname][ch]["rms_um"]
            r["rms_change"] = f"{100 * (after[tname][ch]['rms_um'] / b - 1):+.1f} %" if b > 0 else "–"
            if fmu and "error" not in fmu and "." not in ch:
                fb = fmu["before"].get(tname, {}).get(ch)
                fa = fmu["after"].get(tname, {}).get(ch)
                if fb and fa:
                    r["fmu_rms_before_um"], r["fmu_rms_after_um"] = fb["rms_um"], fa["rms_um"]
                    r["fmu_max_before_um"], r["fmu_max_after_um"] = fb["max_um"], fa["max_um"]
            rows.append(r)
    return rows


def _measured_error(trace, channel):
    """{"rms_um", "max_um"} of the measured tracking error of a residual channel ("x": commanded
    minus measured position, "x.tool": minus the tool-side position), or None."""
    from ..metrics import rms_max_um
    axis, _, side = channel.partition(".")
    role = "tool" if side == "tool" else "act"
    if trace is None or not (trace.has(axis, "cmd") and trace.has(axis, role)):
        return None
    return rms_max_um(np.asarray(trace.cmd(axis), float) - np.asarray(trace.get(axis, role), float))


def _residual_figure(step_label, rb, ra):
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    chans = list(rb["train"].channels())
    fig, axs = plt.subplots(len(chans), 2, figsize=(11, 2.6 * len(chans)), squeeze=False)
    data = {}
    for i, ch in enumerate(chans):
        for j, tname in enumerate(("train", "val")):
            t = decimate(rb[tname].t)
            b = decimate(rb[tname].channels()[ch]) * 1e3
            a = decimate(ra[tname].channels()[ch]) * 1e3
            ax = axs[i][j]
            ax.plot(t, b, lw=0.6, color="tab:red", label="before")
            ax.plot(t, a, lw=0.6, color="tab:blue", label="after")
            ax.set_title(f"{tname} · {ch}", fontsize=9)
            ax.set_ylabel("residual [µm]")
            ax.grid(alpha=0.3)
            data[f"{tname}.{ch}"] = {"t_s": t, "before_um": b, "after_um": a}
        axs[i][0].legend(fontsize=8, loc="upper right")
    for j in range(2):
        axs[-1][j].set_xlabel("t [s]")
    fig.suptitle(step_label, fontsize=10)
    fig.tight_layout()
    return fig, data


def _one_legend(ax, ax2):
    """Both axes' curves of a twin-axis figure in one legend."""
    ax.legend(*(a + b for a, b in zip(ax.get_legend_handles_labels(), ax2.get_legend_handles_labels())),
              fontsize=8, loc="best")


def _evidence_figure(cand):
    import matplotlib.pyplot as plt
    p = cand.get("plot") or {}
    kind = cand["kind"]
    if not p:
        return None, None
    fig, ax = plt.subplots(figsize=(8, 3))
    if kind == "mode":
        f, H, bg, coh = (np.asarray(p[k]) for k in ("f_hz", "H", "background", "coherence"))
        ax.semilogy(f, H, lw=0.8, label="|residual / commanded acceleration|")
        ax.semilogy(f, bg, lw=0.8, ls="--", label="running median")
        ax2 = ax.twinx()
        ax2.plot(f, coh, color="tab:green", lw=0.6, label="coherence")
        ax2.set_ylim(0, 1)
        ax2.set_ylabel("coherence [-]")
        ax.set_xlabel("f [Hz]")
        ax.set_ylabel("|H| [s²] (mm per mm/s²)")    # residual (mm) over commanded acceleration
        _one_legend(ax, ax2)
    elif kind == "periodic_position":
        lam, P, bg = (np.asarray(p[k]) for k in ("wavelength_mm", "power", "background"))
        ax.loglog(lam, P, lw=0.8, label="residual power over position")
        ax.loglog(lam, bg, lw=0.8, ls="--", label="running median")
        ax.set_xlabel("wavelength [mm]")
        ax.set_ylabel("power [mm²]")        # |FFT of the residual|² / samples (periodic.position_spectrum)
    elif kind == "delay":
        ax.semilogy(np.asarray(p["shift"]), np.asarray(p["objective"]), "o-",
                    label="chi-square of the residual's early answer")
        ax.set_xlabel("command shift [samples]")
        ax.set_ylabel("chi-square [-] (training)")
        if "refined_free_run_um" in p:
            ax2 = ax.twinx()
            ax2.plot(np.asarray(p["shift"]), np.asarray(p["refined_free_run_um"]), "s--", color="tab:orange",
                     label="free-run RMS, refined refits")
            ax2.set_ylabel("free-run RMS [µm] (training)")
            _one_legend(ax, ax2)
    else:
        plt.close(fig)
        return None, None
    if ax.get_legend() is None:
        ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig, p


def diagnosis_report(diag, title=None, fmu=None, model_source=""):
    """:class:`~fdid_fmi.report.Report` of a :class:`~.loop.Diagnosis` (optionally with the
    :func:`fmu_check` result)."""
    rep = Report(title or "Closing the loop: diagnosis", meta={
        "model": model_source or diag.model.provenance.get("software", ""),
        "training trace": diag.train.source, "held-out trace": diag.val.source,
        "wall time": f"{diag.wall_time_s:.1f} s"})
    s = diag.settings
    eff = diag.effects_added
    summary = ("Effects added: " + ("; ".join(f"{e['kind']} ({fmt_params(e)})" for e in eff)
                                    if eff else "none (no candidate met the keep criterion)") + ".")
    rep.add_text(summary, heading="Summary")
    for note in diag.notes:     # what the data cannot show or only suggest (limits.py)
        rep.add_text(f"Note ({note.kind.value.replace('_', ' ')}): {note.text}.")
    if diag.axes:       # combined per-axis model: what each axis's block showed
        rep.add_table("per_axis", per_axis_rows(diag),
                      caption="combined per-axis model: every block diagnosed on its own axis")
    rep.add_text(
        f"Residual = measured - free-run prediction. An effect is kept only if the held-out RMS of some "
        f"scored channel falls by at least {100 * s['min_gain']:.0f} % (against the better of the current "
        f"model and the same refit without the effect; without a held-out trace, in the first round, "
        f"against that refit alone) and no channel rises by more than "
        f"{100 * s['max_loss']:.0f} %. {diag.split}")
    traces = {"train": diag.train, "val": diag.val}
    rep.add_table("errors", error_rows(diag.before, diag.after, fmu, traces),
                  caption="the measured tracking error, and beside it the twin's discrepancy (measured - "
                          "free-run prediction) before (given model) and after (every kept effect)")
    if fmu:
        if "error" in fmu:
            rep.add_text(f"FMU check: {fmu['error']}")
        else:
            rep.add_text("FMU check: both models exported as FMI 2.0 co-simulation FMUs and run through "
                         "fmpy on the same traces; largest |FMU - reference simulator| = "
                         f"{max(fmu['before']['max_abs_diff_reference_mm'], fmu['after']['max_abs_diff_reference_mm']):.3g} mm.")
    for i, (st, owner, k) in enumerate(_steps(diag), 1):
        e = st.effect
        rep.add_heading(f"Step {i}: {e['kind']} on axis {e['axis']}")
        rep.add_text(f"Fitted parameters: {fmt_params(e)}")
        rep.add_table(f"step{i}_errors", error_rows(st.before, st.after, traces=traces),
                      caption=f"the twin's discrepancy before / after step {i}, beside the measured tracking error")
        fig, data = _residual_figure(f"step {i}: {e['kind']}", st.residual_before, st.residual_after)
        rep.add_figure(f"step{i}_residual", fig, data, caption="residual before (red) and after (blue)")
        plot = _round_plot(owner, k, e["kind"], e["axis"])
        if plot:
            f2, d2 = _evidence_figure({"kind": e["kind"], "plot": plot})
            if f2 is not None:
                rep.add_figure(f"step{i}_evidence", f2, d2, caption=f"evidence of the {e['kind']} detector")
    rep.add_heading("Candidates, round by round")
    table = candidate_table(diag.rounds)
    for rnd in diag.rounds:
        rows = []
        for c in table:
            if (c["round"], c.get("block")) != (rnd["round"], rnd.get("axis")):
                continue
            gv = c["gain_val"] or {}
            rows.append({"round": c["round"], "kind": c["label"], "axis": c["axis"],
                         "statistic": c["statistic"], "threshold": c["threshold"],
                         "tried": ("not checked" if c["not_checked"] else "yes" if c["detected"] else "no"),
                         "held-out gain": ", ".join(f"{k}: {100 * v:+.1f} %" for k, v in gv.items()) or "–",
                         "kept": "yes" if c["kept"] else ("implausible: " + c["implausible"]
                                                          if c["implausible"] else "no"),
                         "note": c["note"] + (f" (not checked: {c['not_checked']})" if c["not_checked"] else "")})
        rep.add_table(f"{rnd['axis']}_round{rnd['round']}" if "axis" in rnd else f"round{rnd['round']}",
                      rows, caption=f"axis {rnd['axis']}" if "axis" in rnd else "")
    rep.add_heading("What is left: whiteness and input cross-correlation")
    rows = []
    for label, tests in (("before", diag.tests_before), ("after", diag.tests_after)):
        for tname, axes in tests.items():
            for a, t in axes.items():
                rows.append({"model": label, "trace": tname, "axis": a, "99 % band": t["band"],
                             "acf lags outside": f"{100 * t['acf_outside']:.0f} %", "max |acf|": t["acf_max"],
                             "xcf(v_cmd) lags outside": f"{100 * t['xcf_outside']:.0f} %",
                             "max |xcf|": t["xcf_max"]})
    rep.add_table("whiteness", rows, caption="autocorrelation of the residual (lags 1-50) and its "
                                             "cross-correlation with the commanded velocity (lags -50..50)")
    rep.add_data("diagnosis", diag.to_json())
    if fmu:
        rep.add_data("fmu", fmu)
    from ..report import add_model_section
    add_model_section(rep, diag.final, heading="The model after diagnosis")
    return rep


def candidate_table(rounds):
    """Every candidate of every round, with its evidence and what its refit did: one flat list
    (the JSON summary's ``candidates`` and the report's per-round tables).

    Parameters
    ----------
    rounds : ``Diagnosis.rounds`` (each ``{"round", "candidates", "trials"}``, and ``"axis"``
        for the rounds of a combined model's block)

    Returns
    -------
    list of dict, per candidate: ``round``, ``block`` (the block's axis of a combined model, else
    None), ``kind``, ``label`` (kind and statistic), ``axis``, ``statistic``, ``threshold``,
    ``detected`` (statistic >= threshold), ``not_checked`` (why the detector could not test, or
    ''), ``tried_below_threshold`` (not detected, and tried all the same because the held-out
    residual was structured: :data:`.loop.UNEXPLAINED_SHARE`; its outcome is its trial's),
    ``refitted`` (a trial refit was made), ``gain_train``, ``gain_val`` (fractions of RMS
    reduction per scored channel against the trial's reference, or None), ``best_gain_val``
    (the largest of ``gain_val``, or None), ``criterion_met``, ``kept``, ``implausible`` (reason,
    or ''), ``error`` (of a failed refit, or ''), ``outcome`` (one phrase: ``below threshold``,
    ``not checked``, ``not refitted``, ``refit failed``, ``implausible``, ``held-out gain too
    small``, ``another candidate kept``, ``kept``), ``params``, ``note``.
    """
    out = []
    for rnd in rounds:
        kept_any = any(t.get("kept") for t in rnd.get("trials", []))
        for c in rnd["candidates"]:
            label = c.get("label", c["kind"])
            trial = next((t for t in rnd.get("trials", []) if (t.get("label", t["kind"]), t.get("axis"), t["params"])
                          == (label, c["axis"], c["params"])), None)
            t = trial or {}
            gv = t.get("gain_val")
            if c.get("not_checked"):
                outcome = "not checked"
            elif not c["detected"] and trial is None:
                outcome = "below threshold"
            elif trial is None:
                outcome = "not refitted"
            elif t.get("error"):
                outcome = "refit failed"
            elif t.get("kept"):
                outcome = "kept"
            elif t.get("implausible"):
                outcome = "implausible"
            elif t.get("criterion_met") and kept_any:
                outcome = "another candidate kept"
            else:
                outcome = "held-out gain too small"
            out.append({"round": rnd["round"], "block": rnd.get("axis"), "kind": c["kind"], "label": label,
                        "axis": c["axis"], "statistic": c["statistic"], "threshold": c["threshold"],
                        "detected": bool(c["detected"]), "not_checked": c.get("not_checked", ""),
                        "tried_below_threshold": bool(t.get("below_threshold")),
                        "refitted": trial is not None and not t.get("error"),
                        "gain_train": t.get("gain_train"), "gain_val": gv,
                        "best_gain_val": max(gv.values()) if gv else None,
                        "criterion_met": bool(t.get("criterion_met", False)), "kept": bool(t.get("kept", False)),
                        "implausible": t.get("implausible") or "", "error": t.get("error", ""),
                        "outcome": outcome, "params": c["params"], "note": c.get("note", "")})
    return out


def per_axis_rows(diag):
    """One row per axis of a combined model's diagnosis: the candidates tried (those past their
    detector's gate), kept effects and the held-out RMS of the axis's channels before and after."""
    rows = []
    for a, d in diag.axes.items():
        kept = [e["kind"] for e in d.effects_added]
        val_b, val_a = d.before.get("val", {}), d.after.get("val", {})
        rows.append({"axis": a, "tried": ", ".join(d.tried) or "nothing",
                     "kept": ", ".join(kept) or "none",
                     "held-out discrepancy RMS before -> after [µm]": "; ".join(f"{ch}: {val_b[ch]['rms_um']:.4g} -> "
                                                    f"{val_a[ch]['rms_um']:.4g}" for ch in val_b)})
    return rows


def _steps(diag):
    """(step, diagnosis that owns its rounds, 1-based step number there) of every kept effect."""
    for owner in (diag.axes.values() if diag.axes else [diag]):
        for k, st in enumerate(owner.steps, 1):
            yield st, owner, k


def _round_plot(diag, i, kind, axis):
    for rnd in diag.rounds:
        if rnd["round"] == i:
            return rnd.get("plots", {}).get(f"{kind}|{axis}")
    return None
