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

    .venv/bin/python benchmarks/bench_diagnose.py [--workers N] [--scenarios a,b,...] [--search S]
    .venv/bin/python benchmarks/bench_diagnose.py --other /path/to/old/.venv/bin/python [--search S]
        [--other-search S] [--workers N] [--scenarios a,b,...] [--out NAME.json]

``--other PYTHON``: this version against another version's interpreter (its installed fdid_fmi)
instead of one worker against many: each scenario is identified and diagnosed with ``--workers``
once per version, in a fresh subprocess, the versions alternating which runs first; the table
gives per scenario and version the diagnosis's wall and CPU seconds, what it named and the held-out
RMS before and after, with the CPU ratio new / old. ``--search S`` / ``--other-search S`` pass
``search=S`` to ``diagnose`` of this / the other run (for code that has that option). Writes
benchmarks/results/bench_diagnose_other.json unless ``--out`` says otherwise.

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
from timing import child_json, code_state, cpu_s  # noqa: E402

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


def run(model, tr, va, workers, search=None):
    t0, c0 = time.perf_counter(), cpu_s()
    d = diagnose(model, tr, va, maxiter=20, workers=workers, **({"search": search} if search else {}))
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


def child(name, workers, search):
    """Identify and diagnose one scenario with ``workers``; print one JSON line."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m, tr, va = case(name)
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
        if name == "emps" and not (EMPS / "DATA_EMPS.mat").is_file():
            print("emps: no EMPS data in ../shared/data/emps, skipped")
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m, tr, va = case(name)
            one, many = run(m, tr, va, 1, args.search), run(m, tr, va, args.workers, args.search)
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
