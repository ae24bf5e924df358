"""``fdid validate X.fmu TRACE``: FMU vs reference simulator vs measurement."""
from __future__ import annotations

import json

from ..pipeline.argtypes import finite_float
from ..pipeline.traces import add_trace_arguments, trace_from_args


def register(sub):
    p = sub.add_parser(
        "validate", help="check an FMU: fmpy validation, reference simulator, measured trace",
        description="Validate an FMU the way co-simulation masters run it: fmpy's model-description "
                    "checks; the FMU run by fmpy.simulate_fmu with an input table of the trace's "
                    "commanded positions (step = the model's Ts), rows aligned by time, against the "
                    "in-process prediction (target <= 1e-9 mm; a non-finite output is a problem); "
                    "and its tracking-error (and two-axis contour-error) discrepancy to the "
                    "measurement in µm. Exit code 1 when a problem is found.")
    p.add_argument("fmu", help="the FMU to check")
    p.add_argument("trace", help="measured trace (commanded and actual positions)")
    p.add_argument("--model", default=None,
                   help="reference model JSON (default: resources/model.json inside the FMU)")
    p.add_argument("--json", default=None, metavar="OUT.json", help="write the results as JSON (default: not written)")
    p.add_argument("--tolerance", type=finite_float("--tolerance", positive=True), default=1e-9,
                   help="largest accepted |FMU - reference| in mm (default 1e-9)")
    add_trace_arguments(p)
    p.set_defaults(func=run)


def run(args):
    from ..api import validate
    from ..outputs import atomic_write, check_output
    if args.json:
        check_output(args.json, inputs=[p for p in (args.fmu, args.trace, args.model) if p], suffix=".json")
    trace = trace_from_args(args.trace, args)
    pieces = trace.select(trace.meta.get("ranges"))
    results = [validate(args.fmu, t, model=args.model, tolerance_mm=args.tolerance) for t in pieces]
    for k, r in enumerate(results):
        if len(results) > 1:
            print(f"## range {k + 1}: {pieces[k].t[0]:g} .. {pieces[k].t[-1]:g} s")
        print(r.table())
        print()
    if args.json:
        data = results_json(results)
        # what was validated: which FMU, trace and reference
        data["inputs"] = {"fmu": str(args.fmu), "trace": str(args.trace), "ranges_s": trace.meta.get("ranges"),
                          "model": str(args.model) if args.model else "the model.json inside the FMU"}
        atomic_write(args.json, json.dumps(data, indent=1, allow_nan=False))
        print(f"results written to {args.json}")
    return 0 if all(r.ok for r in results) else 1


def results_json(results):
    """JSON data of the validation of one range (its result) or several: every problem, the
    worst FMU-vs-reference difference (null when a range's is not a finite number: max() lets a
    NaN of a later range pass, and an inf would be written as the non-JSON token Infinity), ok, and
    each range's result."""
    import numpy as np

    from ..model import jsonable
    if len(results) == 1:
        return results[0].to_dict()
    worst = [r.max_abs_diff_reference_mm for r in results]
    return jsonable({"problems": [p for r in results for p in r.problems],
                     "max_abs_diff_reference_mm": max(worst) if np.all(np.isfinite(worst)) else None,
                     "ok": all(r.ok for r in results),
                     "ranges": [r.to_dict() for r in results]})
