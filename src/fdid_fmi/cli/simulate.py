"""``fdid simulate MODEL.json TRACE -o PRED.csv``: free-run prediction from the commands."""
from __future__ import annotations

import contextlib
import io
import sys

import numpy as np

from ..errors import InputError, naming
from ..model import load_model
from ..outputs import atomic_write, check_output
from ..simulate import simulate
from ..pipeline.traces import add_trace_arguments, trace_from_args


def register(sub):
    p = sub.add_parser("simulate", help="free-run a model on a trace's commanded positions",
                       description="Simulate a model from the commanded positions of a trace and write "
                                   "t_s,<axis>_x_pred_mm,<axis>_e_pred_mm as CSV.")
    p.add_argument("model", help="model JSON written by fdid identify")
    p.add_argument("trace", help="trace with the commanded positions")
    p.add_argument("-o", "--output", default="prediction.csv",
                   help="CSV to write (default: prediction.csv; an existing file is replaced; - for "
                        "standard output)")
    p.add_argument("--at-rest", action="store_true",
                   help="start at rest even if the record starts in motion")
    add_trace_arguments(p)
    p.set_defaults(func=run)


def _time_digits(t):
    """Significant digits that keep time stamps a sample apart distinct (12 at least: the
    values' precision; 17 at most): a record on an epoch clock (1.7e9 s at 0.6 ms) needs 17,
    and with 12 it would be written with duplicate time stamps that no reader accepts."""
    t = np.asarray(t, float)
    span = float(np.max(np.abs(t))) if t.size > 1 else 0.0
    Ts = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if not (span > 0 and Ts > 0):
        return 12
    return int(min(17, max(12, np.ceil(np.log10(span)) - np.floor(np.log10(Ts)) + 4)))


def write_prediction_csv(path, sim, axes):
    """Write ``t_s,<axis>_x_pred_mm,<axis>_e_pred_mm`` rows of one or several simulations
    (``sim`` a result or a list of results, e.g. one per ``--range``) atomically; ``path`` ``-``:
    to standard output.

    Raises InputError when a predicted value is not finite (nothing is written then)."""
    sims = sim if isinstance(sim, (list, tuple)) else [sim]
    header = ["t_s"] + [f"{ax}_{q}_pred_mm" for ax in axes for q in ("x", "e")]
    blocks = []
    for r in sims:
        cols = [r.t]
        for ax in axes:
            cols += [r.axes[ax]["position"], r.axes[ax]["error"]]
        blocks.append(np.column_stack(cols))
    data = np.vstack(blocks)
    bad = ~np.isfinite(data)
    if bad.any():
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(f"the prediction is not finite from row {i + 2} on; nothing written",
                         source=str(path), column=header[j], row=i + 2)
    buf = io.StringIO()
    fmt = [f"%.{_time_digits(sims[0].t)}g"] + ["%.12g"] * (len(header) - 1)
    np.savetxt(buf, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    if str(path) == "-":
        sys.stdout.write(buf.getvalue())
        return path
    return atomic_write(path, buf.getvalue())


def run(args):
    to_stdout = args.output == "-"
    if not to_stdout:
        check_output(args.output, inputs=[args.model, args.trace], what="prediction CSV")
    # with the CSV on standard output, everything else goes to standard error
    say = sys.stderr if to_stdout else sys.stdout
    model = load_model(args.model)
    with contextlib.redirect_stdout(say):       # the reader's notes
        trace = trace_from_args(args.trace, args)
    pieces = trace.select(trace.meta.get("ranges"))
    with naming(args.trace):
        sims = [simulate(model, t, start_velocity={} if args.at_rest else None) for t in pieces]
    write_prediction_csv(args.output, sims, model.axes)
    n = sum(len(r.t) for r in sims)
    what = f" in {len(sims)} ranges" if len(sims) > 1 else ""
    print(f"prediction of {n} samples{what} for axes {model.axes} written to "
          f"{'standard output' if to_stdout else args.output}", file=say)
    return 0
