"""``fdid diagnose MODEL.json --train TRACE [--val TRACE]``: find what the residual says the
model lacks, add it, and report the error before and after.

    fdid diagnose model.json --train run1.csv --val run2.csv --map t=t_s x.cmd=xc x.act=xm \\
        -o model_plus.json --report diagnosis.html --json diagnosis.json
    fdid diagnose emps.json --train DATA_EMPS_PULSES.mat          # split in two: fit / held out
"""
from __future__ import annotations

import json
import sys

from ..diagnose.augment import METHODS
from ..errors import InputError, naming
from ..model import DriveModel, load_model
from ..outputs import atomic_write, check_output, same_file
from ..pipeline.argtypes import fraction, int_in
from ..pipeline.traces import add_trace_arguments, single_range, trace_from_args


def register(sub):
    p = sub.add_parser("diagnose", help="find effects the model lacks, add them, report before/after",
                       description="Residual of the model's free run -> detectors (friction at reversals, "
                                   "mode, dead time, position-periodic force, coupling / unused channels) -> "
                                   "augment and refit -> keep only what lowers the held-out error.")
    p.add_argument("model", help="model JSON (pole-search or MIMO; one axis or the combined per-axis "
                                 "model of several) written by fdid identify")
    p.add_argument("--train", required=True, help="trace the effects are fitted on")
    p.add_argument("--val", default=None,
                   help="held-out trace the keep criterion is judged on (default: the training trace is "
                        "split at the standstill nearest its middle, or at its middle without one; the first part "
                        "is fitted, the second held out)")
    p.add_argument("--train-range", default=None, metavar="START:STOP", help="use this time range of --train [s] (default: all of it)")
    p.add_argument("--val-range", default=None, metavar="START:STOP", help="use this time range of --val [s] (default: all of it)")
    p.add_argument("-o", "--output", default=None, help="write the augmented model JSON here (default: not written)")
    p.add_argument("--report", default=None, help="write the HTML report here (default: not written)")
    p.add_argument("--json", default=None, help="write the JSON summary here (default: not written)")
    p.add_argument("--min-gain", type=fraction("--min-gain"), default=0.05,
                   help="keep an effect only if the held-out RMS falls by at least this fraction (0.05)")
    p.add_argument("--max-loss", type=fraction("--max-loss"), default=0.01,
                   help="... and no scored channel rises by more than this fraction (0.01)")
    p.add_argument("--max-steps", type=int_in(0, 100, "--max-steps"), default=4, help="at most this many effects added (per axis of a combined per-axis model)")
    p.add_argument("--search", choices=METHODS, default="de",
                   help="pole search of every refit: de (differential evolution, population 8 per "
                        "coordinate) or vp (variable projection: Gauss-Newton searches from the current "
                        "poles or a Sobol screen, as fdid identify's default; about half the CPU time, "
                        "and on some runs a different effect named); default de")
    p.add_argument("--maxiter", type=int_in(1, 100000, "--maxiter"), default=25,
                   help="iterations of each refit's pole search: vp: steps of each local search; de: "
                        "generations")
    p.add_argument("--jobs", type=int_in(1, 1024, "--jobs"), default=None,
                   help="processes running the independent refits side by side (default: one per core; "
                        "the result is the same for any number)")
    p.add_argument("--detectors", default=None,
                   help="comma list of detector families (friction, mode, delay, periodic, coupling; default: all)")
    p.add_argument("--exclude", nargs="+", action="extend", default=[], metavar="CHANNEL",
                   help="channels never to use as inputs")
    p.add_argument("--fmu", action="store_true",
                   help="also export both models as FMUs and reproduce the error table through them")
    add_trace_arguments(p)
    p.set_defaults(func=run)


def _ranged(trace, text, name):
    hint = "one data range per trace: --train-range / --val-range (or a single --range for both)"
    if trace.meta.get("ranges"):
        if text:
            raise InputError(f"give {hint}", column="--range")
        return single_range(trace, hint)
    if not text:
        return trace
    try:
        a, b = text.split(":")
        a = float(a) if a.strip() else None
        b = float(b) if b.strip() else None
    except ValueError:
        raise InputError(f"'{text}' is not START:STOP in seconds", column=name) from None
    return trace.slice(a, b)


def _check_outputs(args):
    """Every output path: writable, not an input, not two outputs on one file (before the work)."""
    inputs = [args.model, args.train] + ([args.val] if args.val else [])
    outs = [(args.output, "model file"), (args.report, "HTML report"), (args.json, "JSON summary")]
    outs = [(p, w) for p, w in outs if p]
    for k, (p, what) in enumerate(outs):
        check_output(p, inputs=inputs, what=what)
        for q, other in outs[:k]:
            if same_file(p, q):
                raise InputError(f"the {what} and the {other} are the same file", source=str(p))


def _refuse_in_sample_val(args, train_whole, val_whole, train, val):
    """Refuse a --val that is the --train data (the same file, or a copy: the same time and channel
    data) unless the two time ranges are disjoint: the held-out test would be in-sample."""
    if same_file(args.train, args.val):
        what = "the --val file is the --train file itself"
    elif train_whole.fingerprint() == val_whole.fingerprint():
        what = f"the --val file holds the same data as the --train file {args.train} (a copy?)"
    else:
        return
    if val.t[0] > train.t[-1] or train.t[0] > val.t[-1]:       # disjoint ranges: truly held out
        return
    raise InputError(f"{what}: the held-out error would be measured on the fitted data; give another "
                     "recording, disjoint --train-range / --val-range, or leave --val out (the training "
                     "trace is then split in a fitted and a held-out part)", source=args.val, column="--val")


def _refuse_unknown_exclude(exclude, traces):
    """Refuse an --exclude name that is a channel of none of the given traces (not ignored)."""
    have = sorted({c for tr in traces for c in tr.channels})
    for name in exclude:
        if name not in have:
            raise InputError(f"no channel '{name}' in the given trace(s); the channels are {have}",
                             column="--exclude")


def run(args):
    from ..api import diagnose
    from ..diagnose.reporting import diagnosis_report, fmt_params, fmu_check
    _check_outputs(args)
    if args.val_range and not args.val:     # it cuts only --val: not silently ignored
        raise InputError("--val-range cuts the --val trace, and no --val is given (without --val the held-out "
                         "part of --train is chosen by the split; use --train-range to cut --train)",
                         column="--val-range")
    if not 1 <= args.max_steps <= 20:
        raise InputError(f"--max-steps must be in 1 .. 20, got {args.max_steps}", column="--max-steps")
    if not 1 <= args.maxiter <= 10000:
        raise InputError(f"--maxiter must be in 1 .. 10000, got {args.maxiter}", column="--maxiter")
    from ..diagnose.augment import recipe_from_model
    from ..diagnose.loop import MIN_SAMPLES, split_blocks
    model = load_model(args.model)
    if not isinstance(model, DriveModel):
        raise InputError("diagnosis refits the model with the pole search and needs a pole-search or MIMO "
                         "model (fdid identify --method pole-search or mimo), not a quasi-static one",
                         source=args.model, column="identification")
    train_whole = trace_from_args(args.train, args)
    val_whole = trace_from_args(args.val, args) if args.val else None
    train = _ranged(train_whole, args.train_range, "--train-range")
    val = _ranged(val_whole, args.val_range, "--val-range") if args.val else None
    if val is not None:
        _refuse_in_sample_val(args, train_whole, val_whole, train, val)
    _refuse_unknown_exclude(args.exclude, [t for t in (train, val) if t is not None])
    for tr, what, need in ((train, "--train", MIN_SAMPLES * (1 if val is not None else 2)),
                           (val, "--val", MIN_SAMPLES)):
        if tr is not None and tr.n < need:
            raise InputError(f"has {tr.n} samples; diagnosis needs at least {need} "
                             f"({'fitted and held-out parts of ' if need > MIN_SAMPLES else ''}"
                             f"{MIN_SAMPLES} samples each)", source=tr.source, column=what)
    with naming(args.model):            # refuse a model (or block) that cannot be refitted, naming the file
        for block in split_blocks(model):
            recipe_from_model(block)
    # an empty list ("" or ",") is refused by diagnose(); it does not mean "every detector"
    dets = [d.strip() for d in args.detectors.split(",") if d.strip()] if args.detectors is not None else None
    diag = diagnose(model, train, val, detectors=dets, min_gain=args.min_gain, max_loss=args.max_loss,
                    max_steps=args.max_steps, maxiter=args.maxiter, exclude=args.exclude, jobs=args.jobs,
                    search=args.search,
                    progress=lambda m: print(f"  {m}", file=sys.stderr))
    fmu = fmu_check(diag) if args.fmu else None
    if diag.split:
        print(diag.split)
    for ax, d in (diag.axes or {"": diag}).items():     # what the final refit on the whole trace did
        if d.whole_refit:
            w = d.whole_refit
            print(f"  {'axis ' + ax + ': ' if ax else ''}refit of the augmented model on the whole trace "
                  + ("taken" if w["taken"] else f"not taken ({w.get('error') or w.get('implausible') or 'worse on some channel, or better on none'})")
                  + "".join(f", {ch} RMS {w['whole_before'][ch]['rms_um']:.4g} -> {w['whole_after'][ch]['rms_um']:.4g} um"
                            for ch in w.get("whole_before", {})))
    print(f"effects added: {[e['kind'] for e in diag.effects_added] or 'none'}")
    for e in diag.effects_added:    # what each is (a Stribeck term may have changed the friction law)
        print(f"  {e['kind']} on axis {e['axis']}: {fmt_params(e)}")
        if e.get("law") == "play":
            print(f"    the friction law of axis {e['axis']} is now the play of half-width "
                  f"{1e3 * e['width_mm']:g} um (presliding) in place of sat(v / v_tilde): the model and "
                  f"its FMU have no {e['axis']}_friction_level, {e['axis']}_v_tilde or "
                  f"{e['axis']}_friction_on parameter any more")
        if e.get("integral_action") is False:
            print(f"    the model of axis {e['axis']} has no integral action any more: its friction reaches "
                  f"the tracking error with a d.c. gain (a P loop), as the term needs")
    for ax, d in diag.axes.items():     # combined per-axis model: the findings of each block
        print(f"  axis {ax}: tried {', '.join(d.tried) or 'nothing'}; "
              f"kept {', '.join(e['kind'] for e in d.effects_added) or 'none'}")
    for tname in diag.before:
        for ch, b in diag.before[tname].items():
            a = diag.after[tname][ch]
            line = (f"  {tname:5s} {ch:8s} RMS {b['rms_um']:.4g} -> {a['rms_um']:.4g} um, "
                    f"MAX {b['max_um']:.4g} -> {a['max_um']:.4g} um")
            if fmu and "error" not in fmu and "." not in ch:
                line += (f"   (FMU: RMS {fmu['before'][tname][ch]['rms_um']:.4g} -> "
                         f"{fmu['after'][tname][ch]['rms_um']:.4g} um)")
            print(line)
    if fmu and "error" in fmu:
        print(f"  FMU check: {fmu['error']}")
    fmu_problems = [f"{label} model: {pr}" for label in ("before", "after")
                    for pr in (fmu or {}).get(label, {}).get("problems", [])]
    for pr in fmu_problems:     # as fdid validate says them: the FMU RMS alone reads as agreement
        print(f"  FMU check, {pr}")
    for note in diag.notes:
        print(f"note ({note.kind.value}): {note.text}")
    if args.output:
        diag.final.save(args.output)
        print(f"augmented model written to {args.output}")
    if args.json:
        d = diag.to_json()
        if fmu:
            d["fmu"] = fmu
        atomic_write(args.json, json.dumps(d, indent=1))
        print(f"JSON summary written to {args.json}")
    if args.report:
        html = diagnosis_report(diag, fmu=fmu, model_source=args.model)
        _write_report(html, args.report)
        print(f"report written to {args.report}")
    # as fdid validate: exit 1 when the FMU check found problems or could not be made
    return 1 if fmu and ("error" in fmu or fmu_problems) else 0


def _write_report(report, path):
    """Write a report atomically: render it into a temporary file beside ``path``, then move it."""
    from ..outputs import atomic_path
    with atomic_path(path) as tmp:
        report.write(tmp)
