"""Detector thresholds from a stated false-alarm rate on clean cases of the calibration half.

For each of the first ``--cases`` calibration seeds of the plant family (``tests/family``, even
seeds), the case is rebuilt without its effects (``case(seed, without=KINDS)``: the same plant,
paths and noise), identified with the default path (``identify_auto``, axis x) and run through
every detector once, as the first round of ``diagnose`` runs them (the same ``Context``), with
every threshold set to infinity: no candidate is built or refitted, and every statistic is the
one a gate would compare (the asymmetric-friction statistic includes its P-loop twin's). A
candidate the detector could not check (``not_checked``) or a channel skipped as a loop signal
gives no value.

Per statistic (:data:`fdid_fmi.diagnose.thresholds.THRESHOLDS` key) the threshold is
:func:`fdid_fmi.diagnose.thresholds.quantile_threshold` of the clean values at ``--rate``: at most
floor(rate N) of the N clean values pass. Writes benchmarks/results/calibrate_thresholds.json
(every case's statistics, partial after every case) and prints the table beside the values in
the table now; the values go into ``thresholds.THRESHOLDS`` by hand, with the command.

    .venv/bin/python benchmarks/calibrate_thresholds.py [--cases N] [--start SEED] [--rate 0.05]
        [--scale F] [--identify-maxiter N] [--maxiter N] [--jobs N] [--out NAME.json]
    .venv/bin/python benchmarks/calibrate_thresholds.py --print-only calibrate_thresholds.json [...]
    .venv/bin/python benchmarks/calibrate_thresholds.py --skip-family --plants [--print-only ...]

``--plants``: every statistic, thresholds infinite, on the scenarios of plant2 (seed 0) and of the
virtual drive, on their default-path models, against the calibrated thresholds (which of their
effects would fall below; which clean scenario would pass): calibrate_thresholds_plants.json.

BLAS pinned to one thread.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from family import KINDS, case, seeds  # noqa: E402
from fdid_fmi.diagnose import augment as ag  # noqa: E402
from fdid_fmi.diagnose.base import Context  # noqa: E402
from fdid_fmi.diagnose.loop import DETECTORS  # noqa: E402
from fdid_fmi.diagnose.refits import Refits  # noqa: E402
from fdid_fmi.diagnose.residuals import residuals  # noqa: E402
from fdid_fmi.diagnose.thresholds import THRESHOLDS, key, quantile_threshold  # noqa: E402
from fdid_fmi.diagnose.whiteness import structured_share  # noqa: E402
from fdid_fmi.identify.choose_structure import identify_auto  # noqa: E402
from timing import code_state  # noqa: E402

OUT = ROOT / "benchmarks" / "results"
OUT_DEFAULT = "calibrate_thresholds.json"


def clean_statistics(model, train, maxiter, refits, max_delay=6):
    """{table key: [values]} of every detector's first-round statistic on ``train`` (one Trace),
    thresholds infinite (module docstring). A key may hold several values (one per channel)."""
    settings = {"maxiter": maxiter, "exclude": [], "max_delay": max_delay, "min_gain": 0.05,
                "max_loss": 0.01, "thresholds": dict.fromkeys(THRESHOLDS, float("inf"))}
    ctx = Context(model=model, recipe=ag.recipe_from_model(model), train=ag.model_velocity_traces(model, [train]),
                  res=[residuals(model, train)], settings=settings, refits=refits)
    out = {}
    for nm, mod in DETECTORS.items():
        for c in mod.detect(ctx):
            if c.not_checked or not np.isfinite(c.statistic):
                continue
            if c.evidence.get("follows_command_r2", 0.0) > 0.9:     # skipped as a loop signal
                continue
            out.setdefault(key(c.label), []).append(float(c.statistic))
    return out


def run_case(seed, args, refits):
    t0 = time.perf_counter()
    c = case(seed, without=KINDS, scale=args.scale)
    row = {"seed": seed, "n_axes": len(c.machine.axes), "Ts": c.machine.Ts, "channels": sorted(c.train[0].channels)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = identify_auto(c.train, c.axis, seed=0, maxiter=args.identify_maxiter, workers=args.jobs)
            row["structure"] = m.identification.get("structure_choice", {}).get("chosen")
            row["identify_s"] = time.perf_counter() - t0
            row["stats"] = clean_statistics(m, c.train[0], args.maxiter, refits)
            # what the loop's below-threshold trials read (loop.UNEXPLAINED_SHARE), on clean models
            row["structured_share"] = {nm: max(structured_share(v) for v in residuals(m, tr).channels().values())
                                       for nm, tr in (("train", c.train[0]), ("val", c.val[0]))}
    except Exception as exc:
        row["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
        traceback.print_exc()
    row["wall_s"] = time.perf_counter() - t0
    return row


def plant_runs(args, refits, save=lambda runs: None):
    """Every detector's statistic (thresholds infinite) on the scenarios of plant2 (seed 0) and of
    the virtual drive, each on its default-path model (``identify_auto``, what ``fdid identify``
    fits, with the calibration's iterations): [{plant, scenario, expected kind or None, stats}]."""
    from bench_plant2 import VIRTUAL_CLEAN, VIRTUAL_EFFECTS
    from fdid_fmi.diagnose.scenarios import scenario as vscenario
    from plant2 import scenarios as p2
    todo = [("plant2", n) for n in p2.SCENARIOS] + [("virtual", n) for n in VIRTUAL_CLEAN + tuple(VIRTUAL_EFFECTS)]
    if args.plant_scenarios:
        todo = [pn for pn in todo if f"{pn[0]}:{pn[1]}" in args.plant_scenarios.split(",")]
    out = []
    for plant, name in todo:
        t0 = time.perf_counter()
        if plant == "plant2":
            train, _, truth = p2.scenario(name)
            tr, ax, expected = train[0], truth["axis"], truth["effect"]
        else:
            tr, _ = vscenario(name)
            ax, expected = "x", VIRTUAL_EFFECTS.get(name)
        row = {"plant": plant, "scenario": name, "expected": expected}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = identify_auto(tr, ax, seed=0, maxiter=args.identify_maxiter, workers=args.jobs)
                row["structure"] = m.identification.get("structure_choice", {}).get("chosen")
                row["stats"] = clean_statistics(m, tr, args.plant_maxiter, refits)
        except Exception as exc:
            row["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
            traceback.print_exc()
        row["wall_s"] = time.perf_counter() - t0
        print(f"[{plant} {name}] {row.get('structure') or row.get('error')} ({row['wall_s']:.0f} s)", flush=True)
        out.append(row)
        save(out)           # partial results survive an interrupted run
    return out


def print_plants(runs, tab):
    """Per plant scenario: its effect's statistic over the calibrated threshold and the one now;
    clean scenarios: the largest ratio of any statistic."""
    print("\n| plant | scenario | effect | statistic | value | / threshold now | / calibrated | passes calibrated |")
    print("|---|---|---|---|---:|---:|---:|---|")
    for r in runs:
        st = r.get("stats") or {}
        if r["expected"] is None:
            ratios = {k: max(v) / tab[k]["threshold"] for k, v in st.items() if v and k in tab}
            k = max(ratios, key=ratios.get) if ratios else None
            if k:
                print(f"| {r['plant']} | {r['scenario']} | clean | {k} (largest) | {max(st[k]):.3g} | "
                      f"{max(st[k]) / THRESHOLDS[k].value:.2f} | {ratios[k]:.2f} | "
                      f"{'FALSE ALARM' if ratios[k] >= 1 else 'no'} |")
            continue
        keys = [k for k in tab if k.split(" (")[0] == key(r["expected"]) or
                (r["expected"] in ("coupling", "extra_input") and k == "channel")]
        for k in keys:
            v = max(st.get(k) or [float("nan")])
            print(f"| {r['plant']} | {r['scenario']} | {r['expected']} | {k} | {v:.3g} | "
                  f"{v / THRESHOLDS[k].value:.2f} | {v / tab[k]['threshold']:.2f} | "
                  f"{'yes' if v >= tab[k]['threshold'] else 'BELOW'} |")


def table(rows, rate):
    """Per table key: the calibrated threshold, k, N, the largest clean values, the value now."""
    out = {}
    for k, th in THRESHOLDS.items():
        vals = [v for r in rows for v in (r.get("stats") or {}).get(k, [])]
        thr, allowed, n = quantile_threshold(vals, rate)
        out[k] = {"threshold": thr, "rate": rate, "allowed": allowed, "n_clean": n,
                  "n_cases": sum(bool((r.get("stats") or {}).get(k)) for r in rows),
                  "largest": sorted(vals, reverse=True)[:4], "median": float(np.median(vals)) if vals else None,
                  "current": th.value,
                  "current_false_alarms": sum(v >= th.value for v in vals)}
    return out


def print_table(tab):
    print("\n| statistic | threshold now | clean ≥ it | calibrated | rate | N values (cases) | k | "
          "largest clean values | median |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---:|")
    for k, t in tab.items():
        big = ", ".join(f"{v:.3g}" for v in t["largest"])
        med = "—" if t["median"] is None else f"{t['median']:.3g}"
        print(f"| {k} | {t['current']:.4g} | {t['current_false_alarms']} | {t['threshold']:.4g} | "
              f"{t['rate']:.0%} | {t['n_clean']} ({t['n_cases']}) | {t['allowed']} | {big} | {med} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=40, help="clean calibration cases (default 40)")
    ap.add_argument("--start", type=int, default=0, help="first seed considered")
    ap.add_argument("--rate", type=float, default=0.05, help="false-alarm rate on clean cases (default 0.05)")
    ap.add_argument("--scale", type=float, default=0.5, help="trace length factor (default 0.5, as "
                    "bench_family_diagnosis --quick)")
    ap.add_argument("--identify-maxiter", type=int, default=8, help="DE iterations of the identification "
                    "(default 8, as bench_family_diagnosis --quick)")
    ap.add_argument("--maxiter", type=int, default=8, help="iterations of the detectors' own refits "
                    "(delay shifts, P-loop twin; default 8, as bench_family_diagnosis --quick)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--out", default=OUT_DEFAULT, help="file name in benchmarks/results")
    ap.add_argument("--print-only", nargs="*", metavar="JSON", help="the table of earlier runs (merged)")
    ap.add_argument("--plants", action="store_true", help="also every statistic on plant2's and the virtual "
                    "drive's scenarios (default-path models) against the calibrated thresholds")
    ap.add_argument("--plant-maxiter", type=int, default=8, help="iterations of the detectors' own refits "
                    "on the plants' scenarios (default 8, as the calibration's)")
    ap.add_argument("--plants-out", default="calibrate_thresholds_plants.json", help="file name of "
                    "--plants' results in benchmarks/results")
    ap.add_argument("--plant-scenarios", default="", help="comma-separated plant:scenario (e.g. "
                    "plant2:delay,virtual:mode; default every one)")
    ap.add_argument("--skip-family", action="store_true", help="no family cases: the calibration table "
                    "of --print-only's files (or --out's), and --plants against it")
    args = ap.parse_args(argv)
    if args.print_only is not None or args.skip_family:
        rows, rate, plants = [], args.rate, []
        for f in args.print_only or [args.out]:
            part = json.loads((OUT / f).read_text())
            have = {r["seed"] for r in rows}
            rows += [r for r in part.get("cases", []) if r["seed"] not in have]
            plants = part.get("plants") or plants
        print(f"{len(rows)} clean cases")
        tab = table(rows, rate)
        print_table(tab)
        if args.plants and args.skip_family:
            t0 = time.perf_counter()
            path = OUT / args.plants_out
            code = code_state("src")

            def save(runs):
                path.write_text(json.dumps({"code": code, "plants": runs, "wall_s": time.perf_counter() - t0},
                                           indent=1, default=float))

            with Refits(args.jobs) as refits:
                plants = plant_runs(args, refits, save)
            print(f"JSON: {path}")
        if plants:
            print_plants(plants, tab)
        return
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / args.out
    todo = seeds("calibration", args.cases, args.start)
    res = {"code": code_state("src", "tests/family"), "settings": {k: v for k, v in vars(args).items()
                                                                   if k != "print_only"},
           "seeds": todo, "cases": []}
    t0 = time.perf_counter()
    with Refits(args.jobs) as refits:
        for s in todo:
            row = run_case(s, args, refits)
            res["cases"].append(row)
            path.write_text(json.dumps(res, indent=1, default=float))
            print(f"[seed {s}] {row.get('structure') or row.get('error')} ({row['wall_s']:.0f} s) "
                  f"structured share {row.get('structured_share')}: "
                  + ", ".join(f"{k} {max(v):.3g}" for k, v in (row.get("stats") or {}).items()), flush=True)
    res["wall_s"] = time.perf_counter() - t0
    res["table"] = table(res["cases"], args.rate)
    path.write_text(json.dumps(res, indent=1, default=float))
    print_table(res["table"])
    print(f"\nwall time {res['wall_s']:.0f} s; JSON: {path}")


if __name__ == "__main__":
    main()
