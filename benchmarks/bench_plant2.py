"""Identification and diagnosis on a second, independently written plant.

The plant (``tests/plant2``: LuGre friction, drive-clock velocity loop, continuous current loop,
fixed-step RK4 with an exact bristle update, jerk-filter paths) shares no code with
``fdid_fmi.virtual``. On every scenario of ``plant2.scenarios``:

1. identification with the public API -- every candidate of the automatic structure choice
   (``choose_structure.fit_structures``; the one ``keep`` keeps is the default of ``fdid
   identify``), Full LS and quasi-static -- each simulated (``fdid_fmi.simulate.simulate``) on the
   three validation traces (circle, diamond, reversals): free-run RMS of the predicted minus
   measured tracking error, its ratio to the better of Full LS / quasi-static, and the default's
   ratio to the best candidate (the exhaustive search);
2. ``fdid_fmi.diagnose.diagnose`` (held-out: the reversals trace) on a model of the training trace:
   which effect is named against the truth. ``--diagnose-base thesis`` (default): the thesis's
   rigid pole-search model (``identify_siso``), the effects' own detection problem;
   ``--diagnose-base default``: what a user runs, ``fdid identify`` then ``fdid diagnose`` with
   their defaults (``identify_auto``, the structure chosen from the data, and ``diagnose``'s
   default settings);
3. threshold transfer in both directions: every detector's statistic (as a multiple of its
   shipped threshold) on clean and one-effect data of both plants (virtual: the scenarios of
   ``fdid_fmi.diagnose.scenarios``); each plant's thresholds recalibrated as 1.2 x its largest
   clean value and applied to the other plant (false alarms on clean runs, hits on effect runs).

Writes benchmarks/results/bench_plant2.json and prints markdown tables. BLAS pinned to one thread;
the structure choice (identification, and the default diagnosis base) fits its candidates in two
processes.

    .venv/bin/python benchmarks/bench_plant2.py [--quick] [--scenarios a,b] [--skip-identification]
        [--skip-diagnose] [--skip-calibration] [--diagnose-base thesis|default] [--jobs N] [--out NAME.json]
    .venv/bin/python benchmarks/bench_plant2.py --print-only bench_plant2.json bench_plant2_diagnosis.json
    .venv/bin/python benchmarks/bench_plant2.py --skip-identification --diagnose-base default \
        --other /path/to/old/.venv/bin/python [--search S] [--other-search S] [--jobs N]

``--other PYTHON``: the diagnoses side by side with another version's interpreter (its installed
fdid_fmi; this script and the plant2 scenarios are this tree's): every scenario's diagnosis runs
in a fresh subprocess per version, the versions alternating which runs first, and a table gives
per scenario and version the diagnosis's wall and CPU seconds (its worker processes included),
what it named and the held-out RMS before and after, with the CPU ratio new / old. ``--search S``
/ ``--other-search S`` pass ``search=S`` to ``diagnose`` of this / the other run (for code that
has that option; with ``--other-search`` alone the other run uses this interpreter). Both
versions diagnose the same base model: the first run of a scenario identifies it (this tree's
script with that version's package) and writes it to a temporary folder, the second reads it.
Identification and calibration are not run then; the other version's diagnoses are written
under ``diagnosis_other``.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fdid_fmi.diagnose import DETECTORS, diagnose  # noqa: E402
from fdid_fmi.diagnose import augment as ag  # noqa: E402
from fdid_fmi.diagnose.base import Context  # noqa: E402
from fdid_fmi.diagnose.limits import NoteKind  # noqa: E402
from fdid_fmi.diagnose.residuals import residuals  # noqa: E402
from fdid_fmi.identify import (identify_full_ls, identify_quasi_static, identify_siso)  # noqa: E402
from fdid_fmi.identify.choose_structure import (StructureChoice, fit_options, fit_structures, free_run_rms,  # noqa: E402
                                                identify_auto, keep, scored_outputs)
from fdid_fmi.metrics import rms  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from plant2 import scenarios as p2  # noqa: E402
from plant2.linear import closed_loop_pairs  # noqa: E402
from publish import about, command, printed, publish, publishable  # noqa: E402
from timing import child_json, code_state, cpu_s, timed  # noqa: E402  (benchmarks/timing.py)

OUT = ROOT / "benchmarks" / "results"
MARGIN = 1.2
VIRTUAL_CLEAN = ("clean", "clean_fast", "clean_soft", "clean_xy", "clean_p")
VIRTUAL_EFFECTS = {"stribeck": "stribeck", "backlash": "backlash", "periodic": "periodic_position",
                   "delay": "delay", "mode": "mode", "coupling": "coupling", "asymmetric": "asymmetric_friction"}
DIAG_SETTINGS = {"min_gain": 0.05, "max_loss": 0.01, "max_steps": 4, "maxiter": 25, "exclude": [],
                 "max_delay": 6, "detectors": list(DETECTORS)}


def _err(exc):
    return f"{type(exc).__name__}: {exc}".splitlines()[0][:300]


def _val_rms(model, vals, axis):
    """Free-run RMS (um) of predicted minus measured tracking error on each validation trace."""
    out = {}
    for v in vals:
        try:
            out[v.meta["name"]] = rms(simulate(model, v).axes[axis]["error"] - v.error(axis)) * 1e3
        except Exception as exc:  # a model the simulator refuses is reported, not fatal
            out[v.meta["name"]] = None
            print(f"    simulate failed: {_err(exc)}", flush=True)
    return out


def _fit(label, fn, vals, axis):
    try:
        t, m = timed(fn)
    except Exception as exc:
        print(f"  {label}: FAILED {_err(exc)}", flush=True)
        return {"error": _err(exc)}, None
    r = _val_rms(m, vals, axis)
    print(f"  {label}: {t:.1f} s  " + "  ".join(f"{k} {v:.3f}" if v is not None else f"{k} -" for k, v in r.items()),
          flush=True)
    return {"wall_s": t, "val_rms_um": r}, m


def identification(name):
    train, vals, truth = p2.scenario(name)
    ax = truth["axis"]
    tr = train[0]
    res = {"scenario": name, "axis": ax, "Ts": truth["Ts"], "effect": truth["effect"],
           "samples_train": tr.n, "e_rms_um": {v.meta["name"]: rms(v.error(ax)) * 1e3 for v in vals},
           "methods": {}, "structures": {}}
    print(f"\n[{name}] axis {ax}, Ts {truth['Ts'] * 1e3:g} ms, {tr.n} training samples", flush=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res["methods"]["full_ls"], _ = _fit("Full LS", lambda: identify_full_ls(tr, ax), vals, ax)
        res["methods"]["quasi_static"], _ = _fit("quasi-static", lambda: identify_quasi_static(tr, axes=[ax]),
                                                 vals, ax)
        # the default of `fdid identify` (identify_auto): every candidate structure is fitted
        # (fit_structures) and the choice rule picks one; the exhaustive search over the same
        # candidates is their validation RMS
        opts = fit_options([tr], ax, None, 0, None, "de", "backward", 1)
        t, (chosen, results, probes) = timed(lambda: keep(*fit_structures(tr, ax, seed=0, workers=2), [tr], ax,
                                                          opts, workers=2))
        outputs = scored_outputs([tr], ax)
        res["structure_choice_wall_s"] = t
        print(f"  structure choice: {t:.0f} s, chosen {chosen.label} {chosen.same_sample}", flush=True)
        for r, m in results + probes:
            key = f"{r.label} {r.same_sample}"
            entry = {"train_free_run_um": r.free_run_rms_mm * 1e3, "parameters": r.parameters,
                     "on_bound": r.on_bound, "real_hz": r.real_hz, "complex_hz_zeta": r.complex_hz_zeta}
            entry["val_rms_um"] = _val_rms(m, vals, ax) if m is not None else {}
            if outputs != ["error"]:    # the choice's own score: error and tool side, one RMS
                entry["val_scored_um"] = {v.meta["name"]: free_run_rms(m, [v], ax, outputs) * 1e3
                                          for v in vals} if m is not None else {}
            res["structures"][key] = entry
            if r is chosen:
                res["methods"]["pole_search"] = dict(entry, chosen=key)
    # ratios to the better baseline, best structure by mean validation RMS
    names = list(res["e_rms_um"])

    def v(d, k):
        return (d.get("val_rms_um") or {}).get(k)

    base = {}
    for k in names:
        b = [x for x in (v(res["methods"]["full_ls"], k), v(res["methods"]["quasi_static"], k)) if x is not None]
        base[k] = min(b) if b else None
    res["baseline_um"] = base
    cands = {"default": res["methods"]["pole_search"], **res["structures"]}
    ok = {key: d for key, d in cands.items() if all(v(d, k) is not None for k in names)}
    best = min(ok, key=lambda key: np.mean([v(ok[key], k) for k in names])) if ok else None
    res["best_structure"] = best
    res["ratio_default"] = {k: (v(cands["default"], k) / base[k] if v(cands["default"], k) and base[k] else None)
                            for k in names}
    res["ratio_best"] = {k: (v(ok[best], k) / base[k] if best and base[k] else None) for k in names}
    res["ratio_default_to_best"] = {k: (v(cands["default"], k) / v(ok[best], k) if best and v(cands["default"], k)
                                        else None) for k in names}
    if "val_scored_um" in cands["default"]:     # the best by the score the choice uses (tool side too)
        sc = {key: d["val_scored_um"] for key, d in res["structures"].items()
              if len(d.get("val_scored_um") or {}) == len(names)}
        best_s = min(sc, key=lambda key: np.mean(list(sc[key].values())))
        res["best_structure_scored"] = best_s
        res["ratio_default_to_best_scored"] = {k: cands["default"]["val_scored_um"][k] / sc[best_s][k]
                                               for k in names}
    return res


def _max_by_kind(summaries):
    """Largest statistic / threshold ratio per effect kind (per statistic, where a kind has two:
    ``delay (early answer)``) among candidate summaries."""
    out = {}
    for c in summaries:
        thr = c["threshold"]
        r = c["statistic"] / thr if thr and np.isfinite(c["statistic"]) else float("nan")
        key = c.get("label", c["kind"])     # a kind with two statistics (delay) keeps both
        if key not in out or (np.isfinite(r) and not r <= out[key]["ratio"]):
            out[key] = {"ratio": r, "statistic": c["statistic"], "threshold": thr}
    return out


def detector_statistics(model, tr):
    ctx = Context(model=model, recipe=ag.recipe_from_model(model), train=ag.model_velocity_traces(model, [tr]),
                  res=[residuals(model, tr)], settings=dict(DIAG_SETTINGS))
    cands = []
    for mod in DETECTORS.values():
        cands.extend(c.summary() for c in mod.detect(ctx))
    return _max_by_kind(cands)


def base_model(tr, ax, base, path=None):
    """The model diagnosed, the options ``diagnose`` gets, and the chosen structure's poles.
    ``path``: a model file to read when it exists, else where the identified model is written
    (the side-by-side run's versions diagnose the same model)."""
    from fdid_fmi.model import load_model
    if path and Path(path).is_file():
        m = load_model(path)
    else:
        m = identify_siso(tr, ax, maxiter=30, seed=0) if base == "thesis" else identify_auto(tr, ax, seed=0, workers=2)
        if path:
            m.save(path)
    if base == "thesis":
        return m, {"maxiter": 20}, {}
    choice = StructureChoice.from_dict(m.identification["structure_choice"])
    c = next(c for c in choice.candidates if c.chosen)
    return m, {}, {"structure": f"{c.label} {c.same_sample}", "complex_hz_zeta": c.complex_hz_zeta,
                   "real_hz": c.real_hz}


def diagnosis(name, base="thesis", no_val=False, jobs=1, search=None, model_path=None):
    train, vals, truth = p2.scenario(name)
    ax = truth["axis"]
    tr = train[0]
    # held out: the reversals trace, or (no_val, as `fdid diagnose --train` alone) the training
    # trace's part after its standstill nearest the middle
    va = None if no_val else next(v for v in vals if v.meta["name"] == "reversals")
    print(f"\n[diagnose {name}] truth: {truth['effect']} {truth['effect_params']}", flush=True)
    out = {"scenario": name, "axis": ax, "truth": truth["effect"], "truth_params": truth["effect_params"]}
    if truth["effect"] == "mode":       # what a fitted mode is compared with: the closed loop's pair
        machine = p2.SCENARIOS[name][0]()
        out["closed_loop_pairs"] = closed_loop_pairs(machine.axis(ax), machine.Ts)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m, options, out["model"] = base_model(tr, ax, base, model_path)
            if search:
                options["search"] = search
            c0 = cpu_s()
            t, d = timed(lambda: diagnose(m, tr, va, workers=jobs, **options))
            out["cpu_s"] = cpu_s() - c0     # with the worker processes (shut down when it returns)
    except Exception as exc:
        out["error"] = _err(exc)
        traceback.print_exc()
        return out
    out["wall_s"] = t
    out["split"] = d.split
    out["named"] = [{k: v for k, v in e.items() if isinstance(v, (int, float, str, bool)) or v is None}
                    for e in d.effects_added]
    out["before_val"] = d.before["val"]
    out["after_val"] = d.after["val"]
    out["first_round"] = _max_by_kind(d.rounds[0]["candidates"]) if d.rounds else {}
    kinds = [e["kind"] for e in d.effects_added]
    out["suspected"] = [n.effect for n in d.notes if n.kind == NoteKind.SUSPECTED]
    out["order_too_low"] = [round(n.statistic, 4) for n in d.notes if n.kind == NoteKind.ORDER_TOO_LOW]
    out["carried_lost_motion_um"] = [round(n.statistic * 1e3, 2) for n in d.notes if n.kind == NoteKind.CARRIED]
    out["order_check"] = d.rounds[0].get("order_check") if d.rounds else None
    # an effect the data cannot identify counts when the diagnosis says it is suspected
    # (a lost motion the model carries, as a note, counts for backlash)
    noted = out["suspected"] + ["backlash"] * bool(out["carried_lost_motion_um"])
    out["correct"] = (kinds == [] and not noted if truth["effect"] is None
                      else truth["effect"] in kinds + noted)
    print(f"  named {kinds}  ({t:.0f} s)", flush=True)
    return out


def calibration(quick, plant2_diag):
    """Detector statistics on clean and effect runs of both plants (ratios to shipped thresholds)."""
    from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario as vscenario
    runs = []   # {plant, scenario, seed, expected, stats}
    seeds_p2 = (0, 1) if quick else (0, 1, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in p2.CLEAN:
            for s in seeds_p2:
                tr = p2.scenario(name, seed=s)[0][0]
                ax = p2.SCENARIOS[name][1]
                m = identify_siso(tr, ax, maxiter=30, seed=0)
                runs.append({"plant": "plant2", "scenario": name, "seed": s, "expected": None,
                             "stats": detector_statistics(m, tr)})
                print(f"  plant2 clean {name} seed {s}", flush=True)
        for d in plant2_diag:
            if d.get("truth") is not None and "first_round" in d:
                runs.append({"plant": "plant2", "scenario": d["scenario"], "seed": 0, "expected": d["truth"],
                             "stats": d["first_round"]})
        vseeds = ((1, 2),) if quick else ((1, 2), (3, 4))
        for name in VIRTUAL_CLEAN:
            for sd in vseeds:
                tr, _ = vscenario(name, seeds=sd)
                m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
                runs.append({"plant": "virtual", "scenario": name, "seed": sd[0], "expected": None,
                             "stats": detector_statistics(m, tr)})
                print(f"  virtual clean {name} seed {sd[0]}", flush=True)
        for name, kind in VIRTUAL_EFFECTS.items():
            tr, _ = vscenario(name)
            m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
            runs.append({"plant": "virtual", "scenario": name, "seed": 1, "expected": kind,
                         "stats": detector_statistics(m, tr)})
            print(f"  virtual effect {name}", flush=True)
    kinds = sorted({k for r in runs for k in r["stats"]})
    table = []
    for kind in kinds:
        row = {"kind": kind}
        for plant in ("virtual", "plant2"):
            clean = [r["stats"][kind]["ratio"] for r in runs if r["plant"] == plant and r["expected"] is None
                     and kind in r["stats"] and np.isfinite(r["stats"][kind]["ratio"])]
            row[f"max_clean_{plant}"] = max(clean) if clean else None
            row[f"n_clean_{plant}"] = len(clean)
        for cal, meas in (("virtual", "plant2"), ("plant2", "virtual")):
            thr = {"shipped": 1.0,
                   "recalibrated": MARGIN * row[f"max_clean_{cal}"] if row[f"max_clean_{cal}"] else None}
            for tname, t in thr.items():
                if t is None:
                    continue
                fa = [r["scenario"] for r in runs if r["plant"] == meas and r["expected"] is None
                      and kind in r["stats"] and r["stats"][kind]["ratio"] >= t]
                eff = [r for r in runs if r["plant"] == meas and r["expected"] == kind.split(" (")[0]]
                hits = [r["scenario"] for r in eff if kind in r["stats"] and r["stats"][kind]["ratio"] >= t]
                row[f"{cal}->{meas}:{tname}"] = {"threshold_ratio": t, "false_alarms": fa,
                                                 "n_clean": row[f"n_clean_{meas}"], "hits": hits,
                                                 "n_effect": len(eff),
                                                 "effect_ratios": {r["scenario"]: r["stats"].get(kind, {}).get("ratio")
                                                                   for r in eff}}
        table.append(row)
    return {"runs": runs, "table": table, "margin": MARGIN}


def _f(x, fmt="{:.3f}"):
    return "—" if x is None else fmt.format(x)


def mode_in_model(d, tolerance=0.03):
    """Relative frequency error of the model's pair nearest the closed loop's mode pair, when
    the diagnosed model's chosen structure carries one within ``tolerance`` (3 %)."""
    pairs, truth = (d.get("model") or {}).get("complex_hz_zeta"), d.get("closed_loop_pairs")
    if d.get("truth") != "mode" or not pairs or not truth:
        return None
    err = min(abs(f / truth[0][0] - 1.0) for f, _ in pairs)
    return err if err <= tolerance else None


def _verdict(d):
    if d["correct"]:
        return "yes"
    err = mode_in_model(d)
    return "no" if err is None else f"yes (a pair of the chosen structure, {100 * err:.1f} % off)"


def print_tables(res):
    print("\n### Identification on plant2: free-run RMS of the tracking-error prediction [µm]\n")
    print("| scenario | Ts [ms] | trace | e RMS | pole search (default) | chosen | best structure | best | Full LS | "
          "quasi-static | default / better baseline | best / better baseline | default / best |")
    print("|---|---:|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|")
    for r in res["identification"]:
        ps = r["methods"]["pole_search"].get("val_rms_um", {})
        fl = r["methods"]["full_ls"].get("val_rms_um", {})
        qs = r["methods"]["quasi_static"].get("val_rms_um", {})
        b = r["best_structure"]
        bd = ({"default": r["methods"]["pole_search"], **r["structures"]}.get(b) or {}).get("val_rms_um", {})
        for k in r["e_rms_um"]:
            chosen = r["methods"]["pole_search"].get("chosen", "rigid")
            print(f"| {r['scenario']} | {r['Ts'] * 1e3:g} | {k} | {r['e_rms_um'][k]:.1f} | {_f(ps.get(k))} | {chosen} | "
                  f"{b} | {_f(bd.get(k))} | {_f(fl.get(k))} | {_f(qs.get(k))} | {_f(r['ratio_default'].get(k))} | "
                  f"{_f(r['ratio_best'].get(k))} | {_f((r.get('ratio_default_to_best') or {}).get(k))} |")
    for r in res["identification"]:
        if r.get("ratio_default_to_best_scored"):   # the choice scored error and tool side
            print(f"\n{r['scenario']}, scored as the choice scores (error and tool side): best "
                  f"{r['best_structure_scored']}, default / best "
                  + ", ".join(f"{k} {x:.2f}" for k, x in r["ratio_default_to_best_scored"].items()))
    if res.get("diagnosis"):
        # a row diagnosed on fdid identify's default model records that model (merged files may mix bases)
        bases = {"fdid identify's default model (structure chosen)" if d.get("model")
                 else "thesis's rigid pole-search model" for d in res["diagnosis"] if "error" not in d}
        print(f"\n### Diagnosis on plant2 ({' / '.join(sorted(bases))}; held out: the reversals trace)\n")
        print("| scenario | truth | named (parameters) | held-out RMS before → after [µm] | right? |")
        print("|---|---|---|---|---|")
        for d in res["diagnosis"]:
            if "error" in d:
                print(f"| {d['scenario']} | {d['truth']} | error: {d['error']} | | no |")
                continue
            named = "; ".join(e["kind"] + " (" + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                                           for k, v in e.items() if k != "kind") + ")"
                              for e in d["named"]) or "none"
            if d.get("suspected"):
                named += " (suspected, not identifiable: " + ", ".join(d["suspected"]) + ")"
            if d.get("carried_lost_motion_um"):
                named += f" (note: the model carries a lost motion of {d['carried_lost_motion_um'][0]:.1f} µm)"
            if d.get("order_too_low"):
                named += f" (order too low: one more real pole {100 * d['order_too_low'][0]:.1f} % better)"
            chans = " ".join(f"{ch}: {d['before_val'][ch]['rms_um']:.3g} → {d['after_val'][ch]['rms_um']:.3g}"
                             for ch in d["before_val"])
            cl = "".join(f" (closed-loop pair {f:.2f} Hz, ζ {z:.3f})" for f, z in d.get("closed_loop_pairs", [])[:1])
            if d.get("model"):
                named = (f"model {d['model']['structure']}, pairs "
                         + (", ".join(f"{f:.1f} Hz ζ {z:.3f}" for f, z in d["model"]["complex_hz_zeta"]) or "none")
                         + f"; named: {named}")
            print(f"| {d['scenario']} | {d['truth'] or 'none'} {d['truth_params'] or ''}{cl} | {named} | {chans} | "
                  f"{_verdict(d)} |")
    if res.get("calibration"):
        c = res["calibration"]
        print(f"\n### Detector thresholds across plants (statistic / shipped threshold; recalibrated = "
              f"{c['margin']} x largest clean value on the calibration plant)\n")
        print("| detector | max clean virtual | max clean plant2 | virtual → plant2 shipped: false alarms, hits | "
              "virtual → plant2 recal. | plant2 → virtual recal. |")
        print("|---|---:|---:|---|---|---|")

        def cell(row, key):
            x = row.get(key)
            if not x:
                return "—"
            fa = f"{len(x['false_alarms'])}/{x['n_clean']} FA"
            hits = f"{len(x['hits'])}/{x['n_effect']} hit" if x["n_effect"] else "no effect run"
            return f"thr {x['threshold_ratio']:.2f}: {fa}, {hits}"

        for row in c["table"]:
            print(f"| {row['kind']} | {_f(row['max_clean_virtual'], '{:.2f}')} | {_f(row['max_clean_plant2'], '{:.2f}')} | "
                  f"{cell(row, 'virtual->plant2:shipped')} | {cell(row, 'virtual->plant2:recalibrated')} | "
                  f"{cell(row, 'plant2->virtual:recalibrated')} |")


def _named(d):
    """What a diagnosis named, in words (kinds, suspected effects, notes)."""
    words = ", ".join(e["kind"] for e in d["named"]) or "none"
    if d.get("suspected"):
        words += " (suspected: " + ", ".join(d["suspected"]) + ")"
    if d.get("carried_lost_motion_um"):
        words += " (carried lost motion)"
    return words


def side_by_side(res):
    """Markdown lines: per scenario the other (old) and this (new) version's diagnosis."""
    lines = ["| scenario | truth | run | wall s | CPU s | named | held-out RMS before → after [µm] | right? | "
             "CPU new / old |", "|---|---|---|---:|---:|---|---|---|---:|"]
    old = {d["scenario"]: d for d in res.get("diagnosis_other", [])}
    tot = {"old": [0.0, 0.0], "new": [0.0, 0.0]}
    for new in res["diagnosis"]:
        for key, d in (("old", old.get(new["scenario"])), ("new", new)):
            if d is None:
                continue
            if "error" in d:
                lines.append(f"| {d['scenario']} | {d.get('truth') or 'none'} | {key} | | | error: {d['error']} | | no | |")
                continue
            tot[key][0] += d["wall_s"]
            tot[key][1] += d["cpu_s"]
            chans = " ".join(f"{ch}: {d['before_val'][ch]['rms_um']:.3g} → {d['after_val'][ch]['rms_um']:.3g}"
                             for ch in d["before_val"])
            o = old.get(d["scenario"])
            ratio = (f"{d['cpu_s'] / o['cpu_s']:.2f}" if key == "new" and o and "error" not in o and o["cpu_s"]
                     else "")
            lines.append(f"| {d['scenario']} | {d.get('truth') or 'none'} | {key} | {d['wall_s']:.1f} | "
                         f"{d['cpu_s']:.1f} | {_named(d)} | {chans} | {_verdict(d)} | {ratio} |")
    if tot["old"][1]:
        lines.append(f"| all | | old | {tot['old'][0]:.1f} | {tot['old'][1]:.1f} | | | | |")
    lines.append(f"| all | | new | {tot['new'][0]:.1f} | {tot['new'][1]:.1f} | | | | "
                 + (f"{tot['new'][1] / tot['old'][1]:.2f}" if tot["old"][1] else "") + " |")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer calibration seeds")
    ap.add_argument("--scenarios", default="", help="comma-separated subset of plant2 scenarios")
    ap.add_argument("--skip-identification", action="store_true")
    ap.add_argument("--skip-diagnose", action="store_true")
    ap.add_argument("--skip-calibration", action="store_true")
    ap.add_argument("--diagnose-base", choices=("thesis", "default"), default="thesis",
                    help="model diagnosed: the thesis's rigid pole search, or fdid identify's default")
    ap.add_argument("--no-val", action="store_true",
                    help="diagnose without a held-out trace (the training trace split at its standstill)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="processes of each diagnosis's refits (diagnose(workers=N)); the same diagnosis "
                         "for any number, to the last bit when BLAS runs one thread (OPENBLAS_NUM_THREADS=1)")
    ap.add_argument("--search", default=None, help="search= passed to this run's diagnose")
    ap.add_argument("--other", default=None, metavar="PYTHON",
                    help="another version's python: its diagnoses side by side with this one's")
    ap.add_argument("--other-search", default=None, help="search= passed to the other run's diagnose")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--base-model", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default="bench_plant2.json", help="file name in benchmarks/results")
    ap.add_argument("--print-only", nargs="*", metavar="JSON",
                    help="print the tables of earlier runs (files in benchmarks/results, merged in order)")
    args = ap.parse_args()
    pub = publishable(ap, args)
    if args.print_only is not None:
        merged = {}
        for f in args.print_only or ["bench_plant2.json"]:
            part = json.loads((OUT / f).read_text())
            for k, val in part.items():
                if isinstance(val, list) and isinstance(merged.get(k), list):
                    have = {r.get("scenario") for r in merged[k] if isinstance(r, dict)}
                    merged[k] += [r for r in val if not (isinstance(r, dict) and r.get("scenario") in have)]
                elif val or k not in merged:
                    merged[k] = val
        print_tables(merged)
        return
    if args.child:      # one diagnosis, as a JSON line (the side-by-side run's subprocess)
        print(json.dumps(diagnosis(args.child, args.diagnose_base, args.no_val, args.jobs, args.search,
                                   args.base_model), default=float))
        return
    names = [s for s in args.scenarios.split(",") if s] or list(p2.SCENARIOS)
    OUT.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    # identification and the default diagnosis base (identify_auto) use two worker processes
    res = {"single_core": args.skip_identification and args.diagnose_base == "thesis", "quick": args.quick,
           "scenarios": names, "code": code_state(),
           "diagnose_base": args.diagnose_base, "no_val": args.no_val, "jobs": args.jobs,
           "blas_threads_env": os.environ.get("OPENBLAS_NUM_THREADS"), "identification": [], "diagnosis": []}
    print(f"code: {res['code']}", flush=True)
    path = OUT / args.out

    def save():                                   # partial results survive an interrupted run
        path.write_text(json.dumps(res, indent=1, default=float))

    if args.other or args.other_search:
        runs = {"new": (sys.executable, args.search), "old": (args.other or sys.executable, args.other_search)}
        res["runs"] = {k: f"{p}{' search=' + s if s else ''}" for k, (p, s) in runs.items()}
        res["diagnosis_other"] = []
        flags = ["--diagnose-base", args.diagnose_base, "--jobs", str(args.jobs)] + ["--no-val"] * args.no_val
        shared = Path(tempfile.mkdtemp(prefix="bench-plant2-"))     # the base models both versions diagnose
        for i, name in enumerate(names):
            for key in (["old", "new"] if i % 2 == 0 else ["new", "old"]):     # alternate which runs first
                python, search = runs[key]
                d = child_json(python, Path(__file__).resolve(),
                               ["--child", name, *flags, "--base-model", str(shared / f"{name}.json")]
                               + (["--search", search] if search else []))
                d.setdefault("scenario", name)
                (res["diagnosis"] if key == "new" else res["diagnosis_other"]).append(d)
                print(f"[{name}] {key}: " + (f"FAILED {d['error']}" if "error" in d else
                                             f"{d['wall_s']:.1f} s wall, {d['cpu_s']:.1f} CPU-s, {_named(d)}"),
                      flush=True)
                save()
        res["wall_s"] = time.perf_counter() - t0
        save()
        print("\n".join(f"- {k}: {v}" for k, v in res["runs"].items()))
        print("\n".join(side_by_side(res)))
        print(f"\nwall time {res['wall_s']:.0f} s; JSON: {path}")
        return
    for name in ([] if args.skip_identification else names):
        res["identification"].append(identification(name))
        save()
    if not args.skip_diagnose:
        for name in names:
            res["diagnosis"].append(diagnosis(name, args.diagnose_base, args.no_val, args.jobs))
            save()
    # the thresholds were calibrated on the thesis models: their transfer is measured on those
    if not args.skip_calibration and not args.skip_diagnose and args.diagnose_base == "thesis":
        print("\n[calibration]", flush=True)
        res["calibration"] = calibration(args.quick, res["diagnosis"])
    res["wall_s"] = time.perf_counter() - t0
    save()
    text = printed(print_tables, res)
    print(text)
    print(f"\nwall time {res['wall_s']:.0f} s; JSON: {path}")
    if pub:
        publish("plant2", "Identification and diagnosis on plant2", [text], command("plant2"), res,
                state=res["code"], notes=about(__doc__))


if __name__ == "__main__":
    main()
