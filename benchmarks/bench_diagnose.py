"""Diagnosis wall time with its independent refits in one process and in worker processes, side by
side (``diagnose(workers=N)``, ``fdid diagnose --jobs N``; docs/method.md, section 6).

Virtual-drive scenarios (``fdid_fmi.diagnose.scenarios``: one undeclared effect each, a held-out
trace), the thesis path's model (``identify_siso``, seed 0, 30 generations), each diagnosed with
``maxiter`` 20 (as ``examples/diagnose_scenarios.py``) once with one worker and once with
``--workers``, one after the other in this process; BLAS single-threaded in both. Every pair must
give the same diagnosis (its JSON summary without the wall time, and the final model's matrices):
a difference is reported and the script exits with status 1.

    .venv/bin/python benchmarks/bench_diagnose.py [--workers N] [--scenarios a,b,...]

Writes benchmarks/results/bench_diagnose.json and prints a table: wall time and CPU time (this
process and its finished workers) per run, the speed-up and the CPU overhead.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fdid_fmi.diagnose import diagnose  # noqa: E402
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario  # noqa: E402
from fdid_fmi.identify import identify_siso  # noqa: E402
from publish import command, md_table, publish, publishable  # noqa: E402  (benchmarks/, beside this script)
from timing import cpu_s  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "bench_diagnose.json"
SCENARIOS = ("clean", "stribeck", "periodic", "delay", "mode", "coupling")


def run(model, tr, va, workers):
    t0, c0 = time.perf_counter(), cpu_s()
    d = diagnose(model, tr, va, maxiter=20, workers=workers)
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    summary = d.to_json()
    summary.pop("wall_time_s")
    return wall, cpu, json.dumps(summary, sort_keys=True), d


def same(a, b):
    return a[2] == b[2] and all(np.array_equal(getattr(a[3].final, k), getattr(b[3].final, k)) for k in "ABCD")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = ap.parse_args(argv)
    rows, ok = [], True
    for name in args.scenarios.split(","):
        tr, va = scenario(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
            one, many = run(m, tr, va, 1), run(m, tr, va, args.workers)
        summary = json.loads(one[2])
        rows.append({"scenario": name, "effects": [e["kind"] for e in one[3].effects_added],
                     "before": summary["before"], "after": summary["after"],
                     "wall_s_1": one[0], "cpu_s_1": one[1], "wall_s_n": many[0], "cpu_s_n": many[1],
                     "speedup": one[0] / many[0], "cpu_ratio": many[1] / one[1], "identical": same(one, many)})
        ok &= rows[-1]["identical"]
        print(f"{name}: {one[0]:.1f} s -> {many[0]:.1f} s, identical: {rows[-1]['identical']}", flush=True)
    total = {k: sum(r[k] for r in rows) for k in ("wall_s_1", "wall_s_n", "cpu_s_1", "cpu_s_n")}
    out = {"workers": args.workers, "cpu_count": os.cpu_count(), "rows": rows, "total": total,
           "speedup": total["wall_s_1"] / total["wall_s_n"], "cpu_ratio": total["cpu_s_n"] / total["cpu_s_1"]}
    OUT.parent.mkdir(exist_ok=True)
    tmp = OUT.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(out, indent=1))
    tmp.replace(OUT)
    print()
    for t in tables(out):
        print(t + "\n")
    print(f"wrote {OUT}")
    if publishable(ap, args):
        publish("diagnose", "Diagnosis on the virtual drive: what it names, one and two workers", tables(out),
                command("diagnose"), out, notes=NOTES)
    return 0 if ok else 1


NOTES = """Virtual-drive scenarios (`fdid_fmi.diagnose.scenarios`: one undeclared effect each, a
separate held-out trace), the thesis path's rigid model (`identify_siso`, seed 0, 30 generations),
each diagnosed (`diagnose(maxiter=20)`) once with one worker and once with two, one after the
other, BLAS on one thread. RMS of the position residual (µm) per trace and axis before → after the
diagnosis; every pair of runs must give the same diagnosis."""


def _rms(before, after):
    """'trace axis: before → after' for every trace and axis of a diagnosis summary."""
    return "; ".join(f"{tr} {ax}: {b['rms_um']:.3f} → {after[tr][ax]['rms_um']:.3f}"
                     for tr, axes in before.items() for ax, b in axes.items() if b.get("rms_um") is not None)


def tables(out):
    """The markdown tables of a run's result."""
    w, rows, total = out["workers"], out["rows"], out["total"]
    named = md_table(["scenario", "effects named", "RMS before → after [µm]"],
                     [[r["scenario"], ", ".join(r["effects"]) or "none", _rms(r["before"], r["after"])] for r in rows],
                     ["l", "l", "l"])
    speed = md_table(["scenario", f"wall 1 / {w} workers [s]", "speed-up", f"CPU 1 / {w} [s]", "same diagnosis"],
                     [[r["scenario"], f"{r['wall_s_1']:.1f} / {r['wall_s_n']:.1f}", f"{r['speedup']:.2f}",
                       f"{r['cpu_s_1']:.1f} / {r['cpu_s_n']:.1f}", "yes" if r["identical"] else "NO"] for r in rows]
                     + [["all", f"{total['wall_s_1']:.1f} / {total['wall_s_n']:.1f}", f"{out['speedup']:.2f}",
                         f"{total['cpu_s_1']:.1f} / {total['cpu_s_n']:.1f}",
                         "yes" if all(r["identical"] for r in rows) else "NO"]])
    return ["What the diagnosis names:\n\n" + named, "Time with one and two worker processes:\n\n" + speed]


if __name__ == "__main__":
    sys.exit(main())
