"""Diagnosis on the virtual drive and EMPS: what it names, the error before and after, the FMUs of
both models, and its wall time with its independent refits in one process and in worker processes
(``diagnose(workers=N)``, ``fdid diagnose --jobs N``; docs/method.md, section 6).

Virtual-drive scenarios (``fdid_fmi.diagnose.scenarios``: one undeclared effect each, a separate
held-out trace) with the thesis path's model (``identify_siso``, seed 0, 30 generations); EMPS: the
model of DATA_EMPS (``qg`` only, no integral action) diagnosed on DATA_EMPS_PULSES, its first part
fitted, the second held out. Each diagnosed with ``maxiter`` 20 once with one worker and once
with ``--workers``, one after the other in this process; BLAS single-threaded in both. Every pair
must give the same diagnosis (its JSON summary without the wall time, and the final model's
matrices): a difference is reported and the script exits with status 1. The model before and
after is exported as an FMU and run through fmpy on the held-out trace (``fmu_check``).

    .venv/bin/python benchmarks/bench_diagnose.py [--workers N] [--scenarios a,b,...]

Writes benchmarks/results/bench_diagnose.json and prints the tables: effects named with their
fitted parameters, RMS before and after, wall time and CPU time (this process and its finished
workers) per run, the speed-up and the CPU overhead.
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
from fdid_fmi.diagnose.limits import NoteKind  # noqa: E402
from fdid_fmi.diagnose.reporting import fmu_check  # noqa: E402
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario  # noqa: E402
from fdid_fmi.identify import identify_siso  # noqa: E402
from fdid_fmi.io import read_trace  # noqa: E402
from publish import command, md_table, publish, publishable  # noqa: E402  (benchmarks/, beside this script)
from timing import cpu_s  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "bench_diagnose.json"
EMPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "emps"
SCENARIOS = ("clean", "clean_fast", "clean_xy", "stribeck", "backlash", "periodic", "delay", "mode", "coupling",
             "clean_p", "asymmetric", "emps")
SHOW = ("samples", "period_mm", "frequency_hz", "damping", "v_s_mm_s", "backlash_mm", "channel",
        "ratio_to_coulomb")


def case(name):
    """(model, training trace, held-out trace or None) of a scenario; ``emps``: the EMPS data."""
    if name == "emps":
        m = identify_siso(read_trace(EMPS / "DATA_EMPS.mat"), integral_action=False, maxiter=30)
        return m, read_trace(EMPS / "DATA_EMPS_PULSES.mat"), None
    tr, va = scenario(name)
    return identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True)), tr, va


def run(model, tr, va, workers):
    t0, c0 = time.perf_counter(), cpu_s()
    d = diagnose(model, tr, va, maxiter=20, workers=workers)
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    summary = d.to_json()
    summary.pop("wall_time_s")
    return wall, cpu, json.dumps(summary, sort_keys=True), d


def same(a, b):
    return a[2] == b[2] and all(np.array_equal(getattr(a[3].final, k), getattr(b[3].final, k)) for k in "ABCD")


def effects_text(d):
    """The effects added with their fitted parameters, and the notes, as one cell."""
    def params(e):
        return ", ".join(f"{k}={e[k]:.4g}" if isinstance(e[k], float) else f"{k}={e[k]}" for k in SHOW if k in e)
    eff = "; ".join(f"{e['kind']} ({params(e)})" for e in d.effects_added) or "none"
    notes = [n for n in d.notes if n.kind != NoteKind.NOT_OBSERVABLE]
    if notes:
        eff += "; note " + ", ".join(f"{n.kind.value} ({n.statistic:.3g})" for n in notes)
    return eff


def change(d, trace, key="rms_um"):
    """'before → after' per channel of one trace of a diagnosis."""
    return " / ".join(f"{d.before[trace][c][key]:.3g} → {d.after[trace][c][key]:.3g}" for c in d.before["val"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = ap.parse_args(argv)
    rows, ok = [], True
    for name in args.scenarios.split(","):
        if name == "emps" and not (EMPS / "DATA_EMPS.mat").is_file():
            print("emps: no EMPS data in ../shared/data/emps, skipped")
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m, tr, va = case(name)
            one, many = run(m, tr, va, 1), run(m, tr, va, args.workers)
            fmu = fmu_check(many[3])
        d = one[3]
        rows.append({"scenario": name, "effects": [e["kind"] for e in d.effects_added],
                     "effects_text": effects_text(d), "channels": list(d.before["val"]),
                     "train_rms": change(d, "train"), "val_rms": change(d, "val"), "val_max": change(d, "val", "max_um"),
                     "fmu_val_rms": (fmu["error"] if "error" in fmu else
                                     f"{fmu['before']['val']['x']['rms_um']:.3g} → {fmu['after']['val']['x']['rms_um']:.3g}"),
                     "held_out": "separate trace" if va is not None else "second part of the training trace",
                     "wall_s_1": one[0], "cpu_s_1": one[1], "wall_s_n": many[0], "cpu_s_n": many[1],
                     "speedup": one[0] / many[0], "cpu_ratio": many[1] / one[1], "identical": same(one, many)})
        ok &= rows[-1]["identical"]
        print(f"{name}: {rows[-1]['effects_text']}; {one[0]:.1f} s -> {many[0]:.1f} s, identical: "
              f"{rows[-1]['identical']}", flush=True)
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
        publish("diagnose", "Diagnosis on the virtual drive and EMPS", tables(out), command("diagnose"), out,
                notes=NOTES)
    return 0 if ok else 1


NOTES = __doc__.split("\n\n")[1] + """

Residual of the position per channel (x; x / tool side where the tool is recorded), µm, before →
after the diagnosis; on EMPS the held-out part is the second part of DATA_EMPS_PULSES."""


def tables(out):
    """The markdown tables of a run's result."""
    w, rows, total = out["workers"], out["rows"], out["total"]
    named = md_table(["data", "effects added (fitted parameters)", "train RMS", "held-out RMS", "held-out MAX",
                      "FMU held-out RMS (x)", "channels"],
                     [[r["scenario"], r["effects_text"], r["train_rms"], r["val_rms"], r["val_max"], r["fmu_val_rms"],
                       ", ".join(r["channels"])] for r in rows], ["l"] * 7)
    speed = md_table(["data", f"wall 1 / {w} workers [s]", "speed-up", f"CPU 1 / {w} [s]", "same diagnosis"],
                     [[r["scenario"], f"{r['wall_s_1']:.1f} / {r['wall_s_n']:.1f}", f"{r['speedup']:.2f}",
                       f"{r['cpu_s_1']:.1f} / {r['cpu_s_n']:.1f}", "yes" if r["identical"] else "NO"] for r in rows]
                     + [["all", f"{total['wall_s_1']:.1f} / {total['wall_s_n']:.1f}", f"{out['speedup']:.2f}",
                         f"{total['cpu_s_1']:.1f} / {total['cpu_s_n']:.1f}",
                         "yes" if all(r["identical"] for r in rows) else "NO"]])
    return ["What the diagnosis names:\n\n" + named, "Time with one and two worker processes:\n\n" + speed]


if __name__ == "__main__":
    sys.exit(main())
