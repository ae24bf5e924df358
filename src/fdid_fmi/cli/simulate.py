"""``fdid simulate MODEL.json TRACE -o PRED.csv``: free-run prediction from the commands."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model import load_model
from ..simulate import simulate
from .mapping import add_trace_arguments, trace_from_args


def register(sub):
    p = sub.add_parser("simulate", help="free-run a model on a trace's commanded positions",
                       description="Simulate a model from the commanded positions of a trace and write "
                                   "t_s,<axis>_x_pred_mm,<axis>_e_pred_mm as CSV.")
    p.add_argument("model", help="model JSON written by fdid identify")
    p.add_argument("trace", help="trace with the commanded positions")
    p.add_argument("-o", "--output", default="prediction.csv", help="CSV to write")
    p.add_argument("--at-rest", action="store_true",
                   help="start at rest even if the record starts in motion")
    add_trace_arguments(p)
    p.set_defaults(func=run)


def write_prediction_csv(path, sim, axes):
    cols = [sim.t]
    header = ["t_s"]
    for ax in axes:
        cols += [sim.axes[ax]["position"], sim.axes[ax]["error"]]
        header += [f"{ax}_x_pred_mm", f"{ax}_e_pred_mm"]
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="",
               fmt="%.12g")
    return Path(path)


def run(args):
    model = load_model(args.model)
    trace = trace_from_args(args.trace, args)
    sim = simulate(model, trace, start_velocity={} if args.at_rest else None)
    write_prediction_csv(args.output, sim, model.axes)
    print(f"prediction of {len(sim.t)} samples for axes {model.axes} written to {args.output}")
    return 0
