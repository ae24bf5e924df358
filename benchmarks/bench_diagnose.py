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
from timing import cpu_s  # noqa: E402  (benchmarks/timing.py, beside this script)

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
        rows.append({"scenario": name, "effects": [e["kind"] for e in one[3].effects_added],
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
    print(f"\n| scenario | effects | wall 1 / {args.workers} workers [s] | speed-up | CPU 1 / {args.workers} [s] | same |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scenario']} | {', '.join(r['effects']) or 'none'} | {r['wall_s_1']:.1f} / {r['wall_s_n']:.1f} "
              f"| {r['speedup']:.2f} | {r['cpu_s_1']:.1f} / {r['cpu_s_n']:.1f} | {'yes' if r['identical'] else 'NO'} |")
    print(f"| all | | {total['wall_s_1']:.1f} / {total['wall_s_n']:.1f} | {out['speedup']:.2f} "
          f"| {total['cpu_s_1']:.1f} / {total['cpu_s_n']:.1f} | {'yes' if ok else 'NO'} |")
    print(f"wrote {OUT}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
