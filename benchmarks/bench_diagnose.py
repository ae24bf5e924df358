"""Diagnosis wall time with its independent refits in one process and in worker processes, side by
side (``diagnose(workers=N)``, ``fdid diagnose --jobs N``; docs/method.md, section 6).

Virtual-drive scenarios (``fdid_fmi.diagnose.scenarios``: one undeclared effect each, a held-out
trace), the thesis path's model (``identify_siso``, seed 0, 30 generations), each diagnosed with
``maxiter`` 20 (as ``examples/diagnose_scenarios.py``) once with one worker and once with
``--workers``, one after the other in this process; BLAS single-threaded in both. Every pair must
give the same diagnosis (its JSON summary without the wall time, and the final model's matrices):
a difference is reported and the script exits with status 1.

    .venv/bin/python benchmarks/bench_diagnose.py [--workers N] [--scenarios a,b,...]
    .venv/bin/python benchmarks/bench_diagnose.py --other /path/to/old/.venv/bin/python [--search S]
        [--other-search S] [--workers N] [--scenarios a,b,...] [--out NAME.json]

``--other PYTHON``: this version against another version's interpreter (its installed fdid_fmi)
instead of one worker against many: each scenario is identified and diagnosed with ``--workers``
once per version, in a fresh subprocess, the versions alternating which runs first; the table
gives per scenario and version the diagnosis's wall and CPU seconds, what it named and the held-out
RMS before and after, with the CPU ratio new / old. ``--search S`` / ``--other-search S`` pass
``search=S`` to ``diagnose`` of this / the other run (for code that has that option). Writes
benchmarks/results/bench_diagnose_other.json unless ``--out`` says otherwise.

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
from timing import child_json, code_state, cpu_s  # noqa: E402  (benchmarks/timing.py, beside this script)

OUT = Path(__file__).resolve().parent / "results" / "bench_diagnose.json"
SCENARIOS = ("clean", "stribeck", "periodic", "delay", "mode", "coupling")


def run(model, tr, va, workers, search=None):
    t0, c0 = time.perf_counter(), cpu_s()
    d = diagnose(model, tr, va, maxiter=20, workers=workers, **({"search": search} if search else {}))
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    summary = d.to_json()
    summary.pop("wall_time_s")
    return wall, cpu, json.dumps(summary, sort_keys=True), d


def same(a, b):
    return a[2] == b[2] and all(np.array_equal(getattr(a[3].final, k), getattr(b[3].final, k)) for k in "ABCD")


def child(name, workers, search):
    """Identify and diagnose one scenario with ``workers``; print one JSON line."""
    tr, va = scenario(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
        wall, cpu, _, d = run(m, tr, va, workers, search)
    print(json.dumps({"scenario": name, "wall_s": wall, "cpu_s": cpu,
                      "effects": [e["kind"] for e in d.effects_added],
                      "notes": [f"{n.kind.value}: {n.effect}" for n in d.notes],
                      "before_val": d.before["val"], "after_val": d.after["val"]}, default=float))


def side_by_side(args):
    """The scenarios diagnosed by this and the other version (module docstring); exit status 0."""
    runs = {"new": (sys.executable, args.search), "old": (args.other or sys.executable, args.other_search)}
    res = {"runs": {k: f"{p}{' search=' + s if s else ''}" for k, (p, s) in runs.items()}, "code": code_state(),
           "workers": args.workers, "cpu_count": os.cpu_count(), "scenarios": {}}
    out = OUT.parent / (args.out or "bench_diagnose_other.json")
    for i, name in enumerate(args.scenarios.split(",")):
        res["scenarios"][name] = {}
        for key in (["old", "new"] if i % 2 == 0 else ["new", "old"]):     # alternate which runs first
            python, search = runs[key]
            r = child_json(python, Path(__file__).resolve(), ["--child", name, "--workers", str(args.workers)]
                           + (["--search", search] if search else []))
            res["scenarios"][name][key] = r
            print(f"[{name}] {key}: " + (f"FAILED {r['error']}" if "error" in r else
                                         f"{r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} CPU-s, {r['effects']}"), flush=True)
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps(res, indent=1))
    print("\n".join(f"- {k}: {v}" for k, v in res["runs"].items()))
    print("\n| scenario | run | wall s | CPU s | named | held-out RMS before → after [µm] | CPU new / old |")
    print("|---|---|---:|---:|---|---|---:|")
    tot = {"old": [0.0, 0.0], "new": [0.0, 0.0]}
    for name, rr in res["scenarios"].items():
        for key in ("old", "new"):
            r = rr[key]
            if "error" in r:
                print(f"| {name} | {key} | | | FAILED: {r['error']} | | |")
                continue
            tot[key][0] += r["wall_s"]
            tot[key][1] += r["cpu_s"]
            chans = " ".join(f"{ch}: {r['before_val'][ch]['rms_um']:.3g} → {r['after_val'][ch]['rms_um']:.3g}"
                             for ch in r["before_val"])
            o = rr["old"]
            ratio = f"{r['cpu_s'] / o['cpu_s']:.2f}" if key == "new" and "error" not in o and o["cpu_s"] else ""
            print(f"| {name} | {key} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | {', '.join(r['effects']) or 'none'} "
                  f"| {chans} | {ratio} |")
    for key in ("old", "new"):
        ratio = f"{tot['new'][1] / tot['old'][1]:.2f}" if key == "new" and tot["old"][1] else ""
        print(f"| all | {key} | {tot[key][0]:.1f} | {tot[key][1]:.1f} | | | {ratio} |")
    print(f"wrote {out}")
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--search", default=None, help="search= passed to this run's diagnose")
    ap.add_argument("--other", default=None, metavar="PYTHON",
                    help="another version's python: its diagnoses side by side with this one's")
    ap.add_argument("--other-search", default=None, help="search= passed to the other run's diagnose")
    ap.add_argument("--out", default=None, help="file name in benchmarks/results (side-by-side run)")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child, args.workers, args.search)
        return 0
    if args.other or args.other_search:
        return side_by_side(args)
    rows, ok = [], True
    for name in args.scenarios.split(","):
        tr, va = scenario(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
            one, many = run(m, tr, va, 1, args.search), run(m, tr, va, args.workers, args.search)
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
