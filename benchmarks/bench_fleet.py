"""Fleet throughput: entries per minute against the number of local workers, and where the time goes.

Run:  .venv/bin/python benchmarks/bench_fleet.py [--machines 10] [--workers 2] [--no-diagnose]
          [--structure auto|rigid]
Writes benchmarks/results/bench_fleet.json and prints a markdown table.

A virtual fleet (``fdid_fmi.fleet.virtual``: ``--machines`` two-axis machines, half with
feed-forward, traces of 6 linear moves ~3 s at 1 ms) is run from scratch with a local process pool
of each worker count (a fresh output folder each time, so nothing is reused), then rerun once
unchanged (must do no work). Per entry the wall time of each stage (identify / export / validate /
diagnose) is read from the entries' results. Entries per minute = entries / wall time of the run,
including the pool's start-up. Worker CPU = user + system time of the pool's processes (they are
reaped when the pool shuts down): on a machine shared with other jobs the wall time depends on the
CPU share the pool gets, the CPU per entry does not; axes per CPU-hour = 3600 / worker CPU per entry.
``--structure auto`` (default) identifies as ``fdid identify`` does by default (structure chosen
from the data); ``rigid`` fixes the thesis's rigid-body structure.
"""
from __future__ import annotations

import argparse
import platform
import resource
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from publish import command, md_table, publish, publishable, report  # noqa: E402
from timing import timed  # noqa: E402

from fdid_fmi.fleet import run_fleet  # noqa: E402
from fdid_fmi.fleet.virtual import write_virtual_fleet  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "bench_fleet.json"
STAGES = ("identify_s", "export_s", "validate_s", "diagnose_s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--machines", type=int, default=10, help="two-axis machines (default 10: 20 axes)")
    ap.add_argument("--workers", default="2", help="worker counts to measure (default 2)")
    ap.add_argument("--structure", choices=("auto", "rigid"), default="auto",
                    help="identification structure of every entry (default auto: fdid identify's default)")
    ap.add_argument("--no-diagnose", action="store_true", help="leave diagnosis out")
    args = ap.parse_args(argv)
    counts = [int(w) for w in args.workers.split(",")]
    rows, split = [], {}
    with tempfile.TemporaryDirectory(prefix="bench_fleet_") as tmp:
        tmp = Path(tmp)
        extra = {"structure": "rigid"} if args.structure == "rigid" else None
        man = write_virtual_fleet(tmp / "data", n_machines=args.machines, nights=(1,),
                                  diagnose=not args.no_diagnose, extra_options=extra)[1]
        for w in counts:
            ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            wall, fr = timed(lambda: run_fleet(man, tmp / f"w{w}", workers=w, progress=False))
            ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (ru1.ru_utime + ru1.ru_stime) - (ru0.ru_utime + ru0.ru_stime)
            n = len(fr.entries)
            ok = [e for e in fr.entries if e.ok]
            t_rerun, again = timed(lambda: run_fleet(man, tmp / f"w{w}", workers=w, progress=False))
            tm = {s: float(np.mean([getattr(e.timings, s) for e in ok])) for s in STAGES + ("total_s",)}
            split[w] = tm
            rows.append({"workers": w, "entries": n, "failed": len(fr.failed), "wall_s": wall,
                         "worker_cpu_s": cpu, "cpu_s_per_entry": cpu / n,
                         "axes_per_cpu_hour": 3600.0 * n / cpu if cpu > 0 else None,
                         "entries_per_min": 60.0 * n / wall, "rerun_s": t_rerun,
                         "rerun_executed": len(again.executed), **{f"mean_{k}": v for k, v in tm.items()}})
    res = {"machine": platform.platform(), "python": platform.python_version(), "machines": args.machines,
           "structure": args.structure, "diagnose": not args.no_diagnose, "rows": rows,
           "note": "wall time of whole runs on a shared 2-core machine; per-stage times are means over "
                   "the entries (each entry's stages run one after the other in one worker)"}
    report(OUT, res, tables(res))
    if publishable(ap, args):
        publish("fleet", "Fleet throughput", tables(res), command("fleet"), res, notes=NOTES)
    return 0


NOTES = """A virtual fleet (`fdid_fmi.fleet.virtual`: two-axis machines, half with feed-forward,
traces of 6 linear moves of about 3 s at 1 ms), run from scratch by `fdid fleet run` on a local
pool, each entry identified (structure chosen from the data, as `fdid identify`), exported,
validated and diagnosed; then rerun unchanged (must do no work). Worker CPU: user + system time of
the pool's processes; axes per CPU-hour = 3600 / worker CPU per entry. Per-stage times are means
over the entries. The wall time depends on the CPU share the pool gets on a shared machine, the
CPU per entry does not."""


def tables(res):
    """The markdown table of a run's result."""
    return [f"{2 * res['machines']} axes, structure {res['structure']}, diagnosis "
            f"{'on' if res['diagnose'] else 'off'}:\n\n" + md_table(
                ["workers", "entries", "wall [s]", "entries/min", "worker CPU [s/entry]", "axes per CPU-hour",
                 "identify [s]", "export [s]", "validate [s]", "diagnose [s]", "entry total [s]",
                 "rerun [s] (entries run)"],
                [[r["workers"], r["entries"], f"{r['wall_s']:.1f}", f"{r['entries_per_min']:.1f}",
                  f"{r['cpu_s_per_entry']:.1f}", f"{r['axes_per_cpu_hour'] or float('nan'):.0f}",
                  f"{r['mean_identify_s']:.2f}", f"{r['mean_export_s']:.2f}", f"{r['mean_validate_s']:.2f}",
                  f"{r['mean_diagnose_s']:.2f}", f"{r['mean_total_s']:.2f}",
                  f"{r['rerun_s']:.2f} ({r['rerun_executed']})"] for r in res["rows"]])]


if __name__ == "__main__":
    raise SystemExit(main())
