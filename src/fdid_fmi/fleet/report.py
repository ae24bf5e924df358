"""The fleet report: one JSON table (``fleet.json``) and one self-contained HTML page (``fleet.html``).

The HTML opens with what a maintenance engineer needs in the morning: how many axes were done,
which failed and why (one line each), which changed since the previous run, named (friction,
backlash, resonance, dynamics) with the evidence and the thresholds; then the table of every axis
(FMU discrepancy to the measurement, FMU vs reference simulator, model error, friction level,
effects diagnosis added, wall time).
"""
from __future__ import annotations

import json
from pathlib import Path

from ..outputs import atomic_write

__all__ = ["summary_lines", "write_fleet_report", "fleet_report_html"]


def summary_lines(fr):
    """Plain-text summary of a :class:`~.runner.FleetResult`."""
    n = len(fr.entries)
    ok = sum(e.ok for e in fr.entries)
    nv = len(fr.validation_failed)
    lines = [f"fleet: {n} axes, {ok} done, {len(fr.failed)} failed"
             f"{f' ({nv} of them: FMU validation)' if nv else ''}; {len(fr.executed)} run now, "
             f"{len(fr.skipped)} unchanged since the last run (reused); {fr.wall_s:.1f} s on {fr.executor}"]
    if fr.previous:
        if fr.previous_version and fr.previous_version != fr.version:
            lines.append(f"note: the previous run was made with software {fr.previous_version}, this one with "
                         f"{fr.version}: a change of the software can show as a change of the plant")
        ch = fr.changed
        lines.append(f"compared with {fr.previous}: {len(ch)} axis/axes changed beyond the thresholds")
        for e in ch:
            lines.append(f"  CHANGED {e.key}: {e.change.summary}")
            for ev in e.change.evidence:
                lines.append(f"      - {ev}")
        new = [e.key for e in fr.entries if e.ok and e.change is None]
        if new:
            lines.append(f"  no previous model for: {', '.join(new)}")
    for e in fr.failed:
        what = "VALIDATION FAILED" if e.status == "validation_failed" else "FAILED"
        lines.append(f"  {what} {e.key}: {e.error}")
    # the readers' notes (a unit assumed or doubtful: a time in ms under t_s makes a model 1000x
    # off without an error) reached only fleet.json / fleet.html; one line per axis here
    noted = [e for e in fr.entries if e.notes]
    if noted:
        lines.append(f"trace notes on {len(noted)} axis/axes (how a trace was read where that may be wrong; "
                     f"check before trusting the figures):")
        for e in noted[:MAX_NOTED_AXES]:
            more = f" (+{len(e.notes) - 1} more note(s) in fleet.html)" if len(e.notes) > 1 else ""
            lines.append(f"  NOTE {e.key}: {_short(e.notes[0])}{more}")
        if len(noted) > MAX_NOTED_AXES:
            lines.append(f"  ... and {len(noted) - MAX_NOTED_AXES} more axes with notes: see fleet.html")
    return lines


MAX_NOTED_AXES = 20     # axes with trace notes listed in the summary (all are in fleet.html)
MAX_NOTE = 400          # characters of a note in the summary


def _short(text):
    return text if len(text) <= MAX_NOTE else text[:MAX_NOTE - 3] + "..."


def _fmt(v):
    if v is None:
        return "–"
    if isinstance(v, float):
        return "not computed" if v != v else f"{v:.3g}"      # NaN: runner._worst's "not computed"
    if isinstance(v, list):
        return ", ".join(map(str, v)) or "–"
    return str(v)


def fleet_report_html(fr):
    """The HTML page (a :class:`fdid_fmi.report.Report`)."""
    from ..report import Report
    from .runner import table_rows
    rep = Report(f"Fleet report: {Path(fr.manifest).name}",
                 meta={"executor": fr.executor, "started (UTC)": fr.started_utc, "wall time [s]": f"{fr.wall_s:.1f}",
                       "fdid-fmi": fr.version, "previous": fr.previous or "none"})
    rep.add_text("\n\n".join(summary_lines(fr)), heading="Summary")
    if fr.previous:
        rows = [{"axis": e.key, "change": e.change.summary, "evidence": " | ".join(e.change.evidence)}
                for e in fr.changed]
        if rows:
            rep.add_table("changed", rows, caption="Axes whose plant changed since the previous run, with the "
                          "evidence (thresholds below).")
        else:
            rep.add_text("No axis changed beyond the thresholds.", heading="Changed axes")
        rep.add_table("thresholds", [{"threshold": k, "value": v} for k, v in fr.thresholds.to_dict().items()],
                      caption="Change thresholds (fdid_fmi.fleet.compare.Thresholds; the manifest's "
                              "[thresholds] table sets them).")
    if fr.failed:
        rep.add_table("failed", [{"axis": e.key, "status": e.status, "reason": e.error} for e in fr.failed],
                      caption="Entries that did not complete (the others did); validation_failed: every "
                              "stage ran, but the FMU's validation found problems (its outputs are kept).")
    rows = table_rows(fr)
    noted = [{"axis": f"{r['machine']}/{r['axis']}", "note": n} for r in rows for n in r["notes"]]
    if noted:
        rep.add_table("trace_notes", noted, caption="How the traces were read where that may be wrong (units "
                      "assumed or doubtful): check them before trusting the axis's figures.")
    rep.add_table("axes", [{k: _fmt(v) for k, v in r.items() if k != "notes"} for r in rows],
                  caption="Every axis: FMU tracking-error discrepancy to the measurement (µm, worst held-out "
                          "trace), FMU vs reference simulator (mm), model free-run position error (µm), "
                          "friction step-response peak (µm), effects diagnosis kept, wall time (s).")
    tm = [e.timings for e in fr.entries if e.ok and e.key in fr.executed and not e.reused_build]
    if tm:
        stages = ("identify_s", "export_s", "validate_s", "diagnose_s", "compare_s", "total_s")
        rep.add_table("timings", [{"stage": s, "mean [s]": sum(getattr(t, s) for t in tm) / len(tm),
                                   "sum [s]": sum(getattr(t, s) for t in tm)} for s in stages],
                      caption=f"Per-entry wall time over the {len(tm)} entries run now.")
    return rep


def write_fleet_report(fr, out):
    """Write ``out/fleet.json`` and ``out/fleet.html`` atomically; returns their paths."""
    from ..model import jsonable
    out = Path(out)
    # non-finite figures (a diverged FMU's inf, a figure not computed) are null: NaN / Infinity
    # are not JSON
    j = atomic_write(out / "fleet.json", json.dumps(jsonable(fr.to_dict()), indent=1, allow_nan=False))
    h = atomic_write(out / "fleet.html", fleet_report_html(fr).html())
    return j, h
