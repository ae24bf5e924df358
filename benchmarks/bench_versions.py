"""Identification and diagnosis time of this checkout against another one, back to back.

The same workload runs in a fresh process per checkout (``--other`` names the other checkout's
Python, e.g. a clone at the previous release with its own venv), alternating, so both see the same
machine load; wall and CPU time (user + system of the child) are reported with their ratio.

Workload: the SISO pole search on the virtual Deckel-Maho-like X axis (20 linear moves, the
README's training set) and one diagnosis (the ``periodic`` scenario: detect, refit, keep).

    .venv/bin/python benchmarks/bench_versions.py --other ../base/.venv/bin/python [--repeat 2]

Writes benchmarks/results/bench_versions.json and prints a table.
"""
import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parent / "results" / "bench_versions.json"

WORK = r'''
import os, sys, time
for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[v] = "1"
task = sys.argv[1]
if task == "identify":
    from fdid_fmi.identify import identify_siso
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    tr = simulate_machine(MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts),
                          tj.linear_moves(n_moves=20, axes=("x",), Ts=cfg.Ts, seed=1), seed=1)
    t0 = time.perf_counter(); c0 = time.process_time()
    identify_siso(tr, "x", seed=0)
else:
    from fdid_fmi.diagnose.loop import diagnose
    from fdid_fmi.diagnose.scenarios import scenario
    from fdid_fmi.identify import identify_siso
    sc = scenario("periodic")
    train, val = sc[0], sc[1]
    m = identify_siso(train, "x", seed=0)
    t0 = time.perf_counter(); c0 = time.process_time()
    diagnose(m, train, val)
print(time.perf_counter() - t0, time.process_time() - c0)
'''


def run(python, task):
    """(wall s, cpu s) of the task body, measured inside the child."""
    res = subprocess.run([python, "-c", WORK, task], capture_output=True, text=True, timeout=3600,
                         env={**os.environ, "PYTHONWARNINGS": "ignore"})
    if res.returncode != 0:
        raise SystemExit(f"{python} {task} failed:\n{res.stderr[-2000:]}")
    wall, cpu = (float(x) for x in res.stdout.split()[-2:])
    return wall, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--other", default=None, help="the other checkout's Python")
    ap.add_argument("--repeat", type=int, default=1)
    a, _ = ap.parse_known_args()
    if a.other is None:
        print("bench_versions: nothing to compare with (give --other PATH/TO/OTHER/python)")
        return
    rows = []
    for task in ("identify", "diagnose"):
        best = {"this": (1e9, 1e9), "other": (1e9, 1e9)}
        for _ in range(a.repeat):
            for who, py in (("other", a.other), ("this", sys.executable)):
                w, c = run(py, task)
                best[who] = (min(best[who][0], w), min(best[who][1], c))
        rows.append({"task": task, "this_wall_s": best["this"][0], "this_cpu_s": best["this"][1],
                     "other_wall_s": best["other"][0], "other_cpu_s": best["other"][1]})
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"other": a.other, "rows": rows}, indent=2))
    print("| task | other: wall / CPU [s] | this: wall / CPU [s] | CPU ratio this/other |")
    print("|---|---:|---:|---:|")
    for r in rows:
        print(f"| {r['task']} | {r['other_wall_s']:.1f} / {r['other_cpu_s']:.1f} | "
              f"{r['this_wall_s']:.1f} / {r['this_cpu_s']:.1f} | {r['this_cpu_s'] / r['other_cpu_s']:.2f} |")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
