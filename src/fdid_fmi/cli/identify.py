"""``fdid identify``: trace -> model JSON (quasi-static, full-ls, pole-search, mimo).

The options, their checks and the identification: :mod:`fdid_fmi.pipeline.identify`, through
:func:`fdid_fmi.api.identify`."""
from __future__ import annotations

import math
import sys

import numpy as np

from ..errors import naming
from ..io.follow import follow_notes
from ..model import DriveModel, is_play
from ..outputs import check_output
from ..pipeline.identify import (add_identify_parser, check_arguments, check_data_range,
                                 nondefault_options, unidentified_notes)
from ..pipeline.traces import trace_from_args


def register(sub):
    p = add_identify_parser(sub)
    p.set_defaults(func=run)


def summary(model, trace=None):
    """Lines describing a model (and its free-run discrepancy on ``trace``)."""
    from ..metrics import measured_position, prediction_table
    from ..simulate import simulate
    lines = [f"method: {model.method}"]
    if isinstance(model, DriveModel):
        ident = model.identification
        blocks = ident.get("blocks", [ident])
        for b in blocks:
            if b.get("structure"):
                from ..identify import StructureChoice
                from ..identify.record import PoleSearchRecord
                rec = PoleSearchRecord.from_dict(b)
                if rec.structure_choice:
                    lines += StructureChoice.from_dict(rec.structure_choice).table()
                cp = ", ".join(f"{w:.3f} Hz / zeta {z:.4f}" for w, z in rec.complex_hz_zeta)
                rp = ", ".join(f"{p:.3f} Hz" for p in rec.real_hz)
                lines.append(f"poles: real [{rp}]  complex [{cp}]")
                if rec.v_tilde_mm_s:   # 3 decimals; below 0.1 mm/s 3 significant digits (never 0.000)
                    lines.append("v_tilde [mm/s]: " + ", ".join(
                        f"{a} {v:.3f}" if abs(v) >= 0.1 else f"{a} {v:.3g}" for a, v in rec.v_tilde_mm_s.items()))
                play = [s for s in rec.structure.inputs if is_play(s)]
                if play:
                    lines.append("play (presliding friction) half-width [mm]: " + ", ".join(
                        f"{s.axis} {s.params['width_mm']:g}" for s in play))
            elif "pole_constraints" in b:
                pc = b["pole_constraints"]
                lines.append(f"poles: p {pc['p_hz']:.3f} Hz, wn {pc['wn_hz']:.3f} Hz, zeta {pc['zeta']:.3f}"
                             f" (Eqn 4.9 {'satisfied' if pc['satisfied'] else 'violated'}"
                             f"{', constrained LS' if b.get('constrained') else ''})")
        lines.append(f"states: {model.n_states}, inputs: {[p.name for p in model.inputs]}, "
                     f"outputs: {[p.name for p in model.outputs]}")
        if model.limits:        # what fdid plan interpolates within by default
            lines.append("limits of the commands (v [mm/s], a [mm/s^2], j [mm/s^3]): " + "; ".join(
                f"{ax} {d['v_mm_s']:.4g}, {d['a_mm_s2']:.4g}, {d['j_mm_s3']:.4g}" for ax, d in model.limits.items()))
    else:
        for ax, g in model.gains.items():
            lines.append(f"{ax}: K_vel {g['K_vel']:.6g} s, K_acc {g['K_acc']:.6g} s^2, K_jerk {g['K_jerk']:.6g} s^3")
    if trace is not None:
        # over the --range pieces when given (each run from its own start, as simulate runs them),
        # not the whole record
        ranges = trace.meta.get("ranges")
        pieces = trace.select(ranges)
        sims = [simulate(model, tr) for tr in pieces]
        where = f", ranges {', '.join(f'{a:g}:{b:g}' for a, b in ranges)} s" if ranges else ""
        lines.append(f"free run on {trace.source}{where}:")
        lines.append(f"  {'axis':<5} {'e RMS um':>10} {'e MAX um':>10} {'pred-err RMS um':>16} "
                     f"{'pred-err MAX um':>16} {'% of RMS':>9}")
        for ax in model.axes:
            side = model.position_side(ax) if isinstance(model, DriveModel) else "motor"
            e = np.concatenate([tr.cmd(ax) - measured_position(tr, ax, side) for tr in pieces])
            tb = prediction_table(e, np.concatenate([s.axes[ax]["error"] for s in sims]))
            pct = tb["discrepancy_pct_of_rms"]     # undefined ('nan') when the measured error is 0
            pct = f"{pct:9.3f}" if math.isfinite(pct) else f"{'-':>9}"
            lines.append(f"  {ax + (' (tool)' if side == 'tool' else ''):<5} {tb['actual']['rms_um']:10.3f} {tb['actual']['max_um']:10.3f} "
                         f"{tb['discrepancy']['rms_um']:16.3f} {tb['discrepancy']['max_um']:16.3f} "
                         f"{pct}")
    return lines

def run(args):
    from ..api import identify
    check_output(args.output, inputs=[args.trace], what="model file")
    check_arguments(args)
    trace = trace_from_args(args.trace, args)
    check_data_range(trace, args.axis)
    for note in follow_notes(trace, args.axis):
        print(f"note: {args.trace}: {note}")
    for note in unidentified_notes(trace, args.axis):
        print(f"note: {note}")
    with naming(args.trace):
        model = identify(trace, args.method, axes=args.axis, progress=sys.stderr.isatty(), **nondefault_options(args))
    model.save(args.output)
    for line in summary(model, trace):
        print(line)
    print(f"model written to {args.output}")
    return 0

__all__ = ["register", "summary"]
