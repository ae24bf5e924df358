"""The user's path on the bundled data: ``fdid demo`` (virtual two-axis machine without
feed-forward: identify with the structure chosen from the data, Full LS and quasi-static as
baselines, export the FMU, validate it through fmpy on unseen traces) and ``fdid identify`` on the
tutorial's two-axis example, each a fresh ``fdid`` process, timed.

    .venv/bin/python benchmarks/bench_demo.py [--skip-identify]

Writes benchmarks/results/bench_demo.json and prints the tables; without options also
docs/results/demo.md (the README's accuracy and FMU rows are made from it).
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from publish import command, md_table, publish, publishable, report  # noqa: E402
from timing import code_state  # noqa: E402

OUT = HERE / "results" / "bench_demo.json"
FDID = Path(sys.executable).with_name("fdid")
EXAMPLE = HERE.parent / "examples" / "virtual_xy_moves.csv"


def run_timed(args, cwd):
    """Run ``fdid ARGS``; its wall s and CPU s (the process and its workers)."""
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([str(FDID), *args], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode:
        sys.exit(f"bench_demo.py: fdid {' '.join(args)} failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    return {"command": "fdid " + " ".join(args), "wall_s": wall, "cpu_s": cpu}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--skip-identify", action="store_true", help="the demo alone (no fdid identify timings)")
    a = ap.parse_args(argv)
    state = code_state()
    with tempfile.TemporaryDirectory(prefix="bench_demo_") as tmp:
        tmp = Path(tmp)
        runs = [run_timed(["demo", "--out", str(tmp / "demo")], tmp)]
        summary = json.loads((tmp / "demo" / "summary.json").read_text())
        if not a.skip_identify:
            runs.append(run_timed(["identify", str(EXAMPLE), "-o", str(tmp / "m.json")], tmp))
            runs.append(run_timed(["identify", str(EXAMPLE), "-o", str(tmp / "r.json"), "--structure", "rigid"],
                                  tmp))
    for r in runs:       # the command as a user types it, without this run's temporary folder
        r["command"] = r["command"].replace(f" --out {tmp}/demo", "").replace(str(tmp) + "/", "") \
            .replace(str(HERE.parent) + "/", "")
    res = {"table": summary["table"],
           "fmu_max_abs_diff_mm": {n: v["max_abs_diff_reference_mm"] for n, v in summary["validation"].items()},
           "fmu_problems": {n: v["problems"] for n, v in summary["validation"].items()},
           "runs": runs}
    report(OUT, res, tables(res))
    if publishable(ap, a):
        publish("demo", "The demo: accuracy, FMU against the model, time", tables(res), command("demo"), res,
                state=state, notes=NOTES)


NOTES = """`fdid demo` (as `./run.sh demo`): the virtual Deckel-Maho-like two-axis machine without
feed-forward; per axis a pole-search model with the structure chosen from the data (what `fdid
identify` does by default), trained on 20 linear moves, and the Full LS and quasi-static baselines;
validated on a circle and a diamond it has not seen. Free-run discrepancy of the predicted tracking
error against the measured one, RMS in µm. The FMU column: the exported FMU run by
`fmpy.simulate_fmu`, fed every sample; max |FMU − model|: the FMU against the in-process model
(`fdid validate --model`, target ≤ 1e-9 mm)."""


def tables(res):
    """The markdown tables of a run's result."""
    rows = [[r["trace"], r["axis"], f"{r['error RMS [µm]']:.1f}",
             f"{r['FMU RMS [µm]']:.3f} / {r['FMU MAX [µm]']:.3f}", f"{r['Full LS RMS [µm]']:.3f}",
             f"{r['quasi-static RMS [µm]']:.1f}", f"{res['fmu_max_abs_diff_mm'][r['trace']]:.2g}"]
            for r in res["table"]]
    acc = md_table(["trace", "axis", "tracking error RMS", "pole search, FMU: RMS / MAX", "Full LS", "quasi-static",
                    "max \\|FMU − model\\| [mm]"], rows, ["l", "l", "r", "r", "r", "r", "r"])
    speed = md_table(["command", "wall [s]", "CPU [s]"],
                     [[f"`{r['command']}`", f"{r['wall_s']:.1f}", f"{r['cpu_s']:.1f}"] for r in res["runs"]])
    return ["Free-run discrepancy, µm:\n\n" + acc,
            "Time of each command, a fresh process, BLAS on one thread per process (the structure "
            "choice fits its candidates in two worker processes):\n\n" + speed]


if __name__ == "__main__":
    main()
