"""``fdid plan``: from an NC program to predicted tracking and contour errors, and feeds that
keep them in tolerance.

    fdid plan part.nc --model model.json --tol 0.02 --optimize \\
        --report plan.html --json plan.json -o part_opt.nc

The axis limits are those the model recorded from its identification traces, unless
``--limits-from TRACE`` or ``--limits`` give others; an axis the twin does not model follows
its command (docs/plan-words.md: the words read and where the limits come from).

The program is interpolated at the model's Ts (exact stop at every block end, jerk-limited
S-curves within the axis limits; see :mod:`fdid_fmi.plan.interpolate`), or the controller's own
setpoints are taken from ``--commands TRACE``; the twin (``--model`` or ``--fmu``) predicts
the errors per block.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import InputError
from ..pipeline.argtypes import finite_float, fraction


def register(sub):
    p = sub.add_parser("plan", help="NC program -> predicted tracking/contour error per block -> feeds within --tol",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("program", help="ISO / RS-274 part program (.nc)")
    tw = p.add_mutually_exclusive_group(required=True)
    tw.add_argument("--model", help="identified model JSON (DriveModel)")
    tw.add_argument("--fmu", help="exported drive FMU (run through fmpy.simulate_fmu)")
    p.add_argument("--limits", action="append", default=[], metavar="[AXIS=]V,A,J",
                   help="axis limits: velocity [mm/s], acceleration [mm/s^2], jerk [mm/s^3]; without AXIS= for all axes "
                        "(default: those the model recorded from its identification traces)")
    p.add_argument("--limits-from", default=None, metavar="TRACE",
                   help="estimate the limits from a recorded trace of the same machine (default: the model's recorded limits)")
    p.add_argument("--commands", default=None, metavar="TRACE",
                   help="use the controller's interpolated setpoints (cmd channels of TRACE) instead of interpolating "
                        "(default: interpolate the program)")
    p.add_argument("--corner-angle", type=float, default=None, metavar="DEG",
                   help="no stop at junctions whose tangents differ by at most DEG (default: exact stop at every block end)")
    p.add_argument("--in-position", type=finite_float("--in-position"), default=None, metavar="MM",
                   help="after every rapid (G0) the next block waits until every axis's predicted tracking "
                        "error is within MM (default 0.01: SINUMERIK's fine exact-stop window, a Fanuc "
                        "in-position width); 0: no wait")
    p.add_argument("--tol", type=finite_float("--tol", positive=True), default=None, help="contour tolerance [mm]: blocks above it are flagged (default: none, nothing flagged)")
    p.add_argument("--optimize", action="store_true", help="find per-block feeds within --tol (needs --tol)")
    p.add_argument("--margin", type=fraction("--margin"), default=None,
                   help="the optimised feeds aim at tol x (1 - margin), room for the twin's error (default 0.02)")
    p.add_argument("-o", "--output", default=None, help="write the optimised NC program here (default: not written)")
    p.add_argument("--report", default=None, help="HTML report (default: not written)")
    p.add_argument("--json", default=None, help="JSON with every table and figure's data (default: not written)")
    p.add_argument("--csv", default=None, help="commanded and predicted positions, errors per sample (default: not written)")
    p.add_argument("--start", default="0,0,0", help="position before the first block, x,y,z [mm]")
    from ..pipeline.traces import add_trace_arguments
    add_trace_arguments(p)
    p.set_defaults(func=run)


def _ranged_trace(path, args):
    """A trace of --limits-from / --commands, cut to --range when one is given (one range)."""
    from ..pipeline.traces import single_range, trace_from_args
    return single_range(trace_from_args(path, args), "one --range for fdid plan's trace")


def _check_options(args):
    """Every option checked before any file is read, any work done or any line printed.

    Returns
    -------
    start : list of 3 floats, mm;  limits : dict axis -> AxisLimits from ``--limits``
    """
    from ..outputs import check_output, same_file
    from ..plan.interpolate import parse_limits
    outs = [o for o in (args.output, args.report, args.json, args.csv) if o]
    inputs = [i for i in (args.program, args.model or args.fmu, args.limits_from, args.commands) if i]
    for k, o in enumerate(outs):
        check_output(o, inputs=inputs)
        if any(same_file(o, other) for other in outs[:k]):
            raise InputError("two outputs name the same file", source=str(o))
    if args.optimize and args.tol is None:
        raise InputError("--optimize needs --tol (contour tolerance in mm)", column="--tol")
    if args.output and not args.optimize:
        raise InputError("-o writes the optimised program: add --optimize --tol TOL", column="-o")
    if args.margin is not None and not args.optimize:
        raise InputError("--margin is read by --optimize only: add --optimize --tol TOL", column="--margin")
    if args.commands:
        if args.optimize:
            raise InputError("--optimize re-interpolates the program: give --limits, not --commands",
                             column="--optimize")
        unused = [o for o, v in (("--limits", args.limits), ("--limits-from", args.limits_from),
                                 ("--corner-angle", args.corner_angle is not None),
                                 ("--in-position", args.in_position is not None)) if v]
        if unused:
            raise InputError(f"{unused[0]} shapes the interpolation, which --commands replaces by the "
                             f"trace's setpoints: leave one of them out", column=unused[0])
    if args.in_position is not None and not args.in_position >= 0:
        raise InputError(f"the in-position window must be >= 0 mm (0: no wait after a rapid), got "
                         f"{args.in_position!r}", column="--in-position")
    if not args.commands and args.corner_angle is not None and not 0 <= args.corner_angle <= 180:
        raise InputError(f"the angle between two blocks' tangents must be 0 to 180 deg, got "
                         f"{args.corner_angle!r}", column="--corner-angle")
    trace_opts = [o for o, v in (("--map", args.map), ("--unit", args.unit), ("--range", args.range),
                                 ("--layout", args.layout != "auto"), ("--axes", args.axes)) if v]
    if trace_opts and not (args.limits_from or args.commands):
        raise InputError(f"{trace_opts[0]} reads a trace: give --limits-from TRACE or --commands TRACE",
                         column=trace_opts[0])
    if trace_opts:
        from ..pipeline.traces import parse_mapping, parse_ranges, parse_units
        parse_mapping(args.map)
        parse_units(args.unit)
        parse_ranges(args.range)
    try:
        start = [float(v) for v in args.start.split(",")]
    except ValueError:
        start = []
    if len(start) != 3 or not all(math.isfinite(v) for v in start):
        raise InputError(f"'{args.start}' is not x,y,z: three finite numbers in mm", column="--start")
    lim = {}
    for text in args.limits:
        try:
            lim = parse_limits(text, lim)
        except InputError as exc:           # AxisLimits names 'limit v': say which option and text
            msg = str(exc).removeprefix(f"column '{exc.column}': ") if exc.column else str(exc)
            raise InputError(f"'{text}': {msg}" if text not in msg else msg, column="--limits") from None
    return start, lim


def run(args):
    import numpy as np
    from ..api import plan
    from ..labels import label
    from ..plan.predict import cutting_contour_max_um
    from ..plan.reporting import plan_report, words_summary

    start, given_limits = _check_options(args)
    ranged = {k: _ranged_trace(path, args) if path else None
              for k, path in (("limits_from", args.limits_from), ("commands", args.commands))}
    res = plan(args.model, args.program, fmu=args.fmu, tol_mm=args.tol, limits=given_limits,
               start=start, corner_angle_deg=args.corner_angle, in_position_mm=args.in_position,
               optimize=args.optimize, margin=args.margin, progress=True, **ranged)
    prog, ip, pr, fpl, model = res.program, res.interpolation, res.prediction, res.feed_plan, res.model
    fmu, axes, Ts, lim, origin = res.fmu, res.axes, res.Ts, res.limits, res.limit_sources
    # nothing is printed before here: every error the inputs or options can cause came first
    for note in res.notes:
        print(f"note: {note}")
    print(f"fdid plan: {args.program}: {len(prog.blocks)} blocks, axes moved {prog.axes_used}, "
          f"twin {'FMU ' + str(fmu) if fmu else 'model ' + args.model} (axes {axes}, Ts {Ts * 1e3:.4g} ms)")
    unmodelled = [a for a in prog.axes_used if a not in axes]
    if unmodelled:      # the contour error is measured in the model's axes only
        print(f"  warning: the program moves {unmodelled}, which the twin does not model: they follow their "
              f"commands ideally; their tracking errors, and contour errors out of the model's axes {axes}, "
              f"are not predicted")
    if lim is not None:
        for a in sorted(lim):
            if a in prog.axes_used or a in axes:
                print(f"  limits {a}: {lim[a].v:.4g} mm/s, {lim[a].a:.4g} mm/s^2, {lim[a].j:.4g} mm/s^3: "
                      f"{origin[a].split(' (')[0]}")
    read = words_summary(prog)
    if read:
        print(f"  words read: {read}")
    for r, text in prog.notes[:20]:
        print(f"  note: row {r}: {text}")
    for text in ip.info.get("notes", []):       # in-position waits that reached their cap
        print(f"  note: {text}")
    if len(prog.notes) > 20:
        print(f"  note: ... and {len(prog.notes) - 20} more")
    unread = [(r, w) for r, w in prog.ignored if w.startswith("not ")]
    if unread:              # lines after the end of the program: 'row N', as the errors name it
        print(f"  passed over: {', '.join(f'row {r}: {w}' for r, w in unread[:20])}"
              + (" ..." if len(unread) > 20 else ""))
    s = pr.summary
    print(f"  cycle time {s['cycle_time_s']:.3f} s; contour error RMS {s['contour_rms_um']:.2f} µm, "
          f"MAX {s['contour_max_um']:.2f} µm; "
          + "; ".join([f"{a}: tracking MAX {v['error_max_um']:.1f} µm" for a, v in s["axes"].items()]
                      + [f"{a}: not predicted" for a in s.get("not_predicted", [])]))
    print("\n| " + " | ".join(map(label, ("block", "line", "kind", "feed_mm_min", "duration_s", "contour_rms_um",
                                       "contour_max_um", "flag"))) + " |")
    print("|---:|---:|---|---:|---:|---:|---:|---|")
    for r in pr.blocks:
        feed = "rapid" if r["kind"] == "rapid" else "-" if r["kind"] == "dwell" else f"{r['feed_mm_min']:.0f}"
        print(f"| {r['block']} | {r['line']} | {r['kind']} | {feed} | {r['duration_s']:.3f} | "
              f"{r['contour_rms_um']:.2f} | {r['contour_max_um']:.2f} | {_flag(r, args.tol)} |")
    if fpl is not None:
        from ..plan.ncprogram import write_program
        cut, whole = cutting_contour_max_um(fpl.after), fpl.after.summary["contour_max_um"]
        # the tolerance judges the cutting blocks: a rapid's larger figure read as a missed tolerance
        print(f"\nfeed optimisation (tol {args.tol * 1e3:.3g} µm): cycle time {fpl.before.interp.cycle_time:.3f} s "
              f"(programmed) -> {fpl.after.interp.cycle_time:.3f} s (per-block feeds, contour MAX "
              f"{cut:.2f} µm on the cutting blocks"
              + (f", {whole:.2f} µm during rapids, not judged" if whole > cut else "") + "); "
              + (f"uniform override {100 * fpl.uniform_override:.1f} %: {fpl.uniform_cycle_time_s:.3f} s"
                 if fpl.uniform_override > 0 else "no uniform override meets the tolerance")
              + ("" if fpl.reachable else "; NOT every block reachable by the feed alone"))
        print("| " + " | ".join(map(label, ("block", "line", "feed_mm_min", "new_feed_mm_min", "contour_max_before_um",
                                           "contour_max_after_um", "time_before_s", "time_after_s"))) + " |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in fpl.rows:
            if r["kind"] == "rapid":
                continue
            print(f"| {r['block']} | {r['line']} | {r['feed_mm_min']:.0f} | {r['new_feed_mm_min']:.0f} | "
                  f"{r['contour_max_before_um']:.2f} | {r['contour_max_after_um']:.2f} | "
                  f"{r['time_before_s']:.3f} | {r['time_after_s']:.3f} |")
        if args.output:
            text = write_program(prog, fpl.new_feeds_mm_s(prog),
                                 header=f"feeds optimised by fdid plan for a contour tolerance of {args.tol:g} mm")
            _write_text(args.output, text, prog.encoding)     # a Latin-1 program stays Latin-1
            print(f"optimised program: {args.output}")
    if args.report or args.json:
        rep = plan_report(prog, pr, model=model, tol_mm=args.tol, feed_plan=fpl, fmu=fmu)
        if args.report:
            _write_text(args.report, rep.html())
            print(f"report: {args.report}")
        if args.json:
            _write_text(args.json, json.dumps(rep.to_dict(), indent=1))
    if args.csv:
        cols = ["t_s"] + [f"{a}_cmd_mm" for a in axes] + [f"{a}_pred_mm" for a in axes] + \
               [f"{a}_e_pred_mm" for a in axes] + ["contour_mm", "block"]
        data = np.column_stack([ip.t] + [ip.positions[a] for a in axes] + [pr.position[a] for a in axes]
                               + [pr.error[a] for a in axes] + [pr.contour, ip.block_of_sample + 1])
        import io
        buf = io.StringIO()
        # 17 digits: every float read back bit for bit (10 moved the commands by up to 0.1 um)
        np.savetxt(buf, data, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
        _write_text(args.csv, buf.getvalue())
    # exit 1 when the optimisation could not bring every block within the tolerance
    return 1 if (fpl is not None and not fpl.reachable) else 0


def _flag(row, tol_mm):
    """The table's flag: OVER, or OVER (dwell after) when only the dwell after the block (its
    settling) exceeds the tolerance."""
    if not row["flag"]:
        return ""
    return "OVER" if row["contour_max_um"] > tol_mm * 1e3 else "OVER (dwell after)"


def _write_text(path, text, encoding="utf-8"):
    """Write ``text`` atomically in ``encoding``, a :attr:`Program.encoding` (the program's own:
    UTF-16/32 with their byte-order mark, ``utf-8-sig`` with the UTF-8 one)."""
    from ..plan.ncprogram import encode_text
    data = encode_text(text, encoding)
    try:
        from ..outputs import atomic_write
        atomic_write(path, data)
    except ImportError:  # pragma: no cover
        Path(path).write_bytes(data)
