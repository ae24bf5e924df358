"""Diagnosis on the seeded plant family (``tests/family``): what it names against the truth.

For each case (``family.case(seed)``: a drawn one- or two-axis plant with zero to two undeclared
effects on axis x):

1. the default identification of ``fdid identify`` (``identify_auto``: the structure chosen from
   the data) on the case's training traces, axis x;
2. ``fdid diagnose``'s default diagnosis of that model on the first training trace, held out the
   first validation trace (a different move set);
3. against the recorded truth: per effect kind present, named or not and what was named instead
   (confusion); on clean cases, false alarms; the held-out RMS of the position residual before and
   after; the fitted parameter against the true one (period, v_s, dead time, frequency, lost
   motion, channel); the first round's statistic / threshold of every detector, and (in the JSON)
   every candidate of every round with its held-out gain and outcome; per kind the detection
   rate against the effect's visibility, its detectability bound (the smallest magnitude above
   which at least 90 % of the cases are named, in physical units and over the noise), the
   false-alarm rate, the wrong-effect rate and the confusion matrix (:func:`rates`). How visible
   each effect is: the RMS shift of the motor-encoder channel of the first training trace it
   causes (the case rebuilt without it, ``family.visibility``), over the encoder noise.

Writes benchmarks/results/bench_family_diagnosis.json (``--quick``: ..._quick.json; partial
results after every case) and its markdown tables beside it (.md), and prints them. BLAS pinned to
one thread.

    .venv/bin/python benchmarks/bench_family_diagnosis.py --quick
    .venv/bin/python benchmarks/bench_family_diagnosis.py [--cases N] [--split calibration|held-out|all]
        [--start SEED] [--seeds 3,5,8] [--maxiter N] [--identify-maxiter N] [--scale F] [--jobs N]
        [--below-trials N] [--out NAME.json]
    .venv/bin/python benchmarks/bench_family_diagnosis.py --print-only bench_family_diagnosis.json

``--quick``: 3 cases (unless ``--cases`` says otherwise), traces at 0.5 of their length,
identification with 8 generations (``--identify-maxiter``) and refits with 8 (``--maxiter``): a
smoke run, figures not comparable with full runs.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from family import KINDS, case, seeds, visibility  # noqa: E402
from family.cases import UNITS  # noqa: E402
from fdid_fmi.diagnose import diagnose  # noqa: E402
from fdid_fmi.diagnose.limits import NoteKind  # noqa: E402
from fdid_fmi.diagnose.reporting import candidate_table  # noqa: E402
from fdid_fmi.identify.choose_structure import identify_auto  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from publish import about, command, printed, publish, publishable  # noqa: E402
from timing import code_state  # noqa: E402

OUT = ROOT / "benchmarks" / "results"
OUT_DEFAULT = "bench_family_diagnosis.json"


def _err(exc):
    return f"{type(exc).__name__}: {exc}".splitlines()[0][:300]


def _scalars(d):
    return {k: v for k, v in d.items() if isinstance(v, (int, float, str, bool)) or v is None}


def parameter_error(kind, truth, named, machine):
    """The fitted parameter of a named effect against the truth: {name, true, fitted, rel_error}
    or None when the kind has no comparable parameter."""
    p = truth["params"]
    x = machine["axes"][0]
    if kind == "periodic_position":
        t, f, name = p["period_mm"], named.get("period_mm"), "period_mm"
    elif kind == "stribeck":
        t, f, name = p["v_s_mm_s"], named.get("v_s_mm_s"), "v_s_mm_s"
    elif kind == "delay":
        t, f, name = truth["magnitude"], named.get("samples"), "samples"
    elif kind == "mode":
        t, f, name = p["lock_hz"], named.get("frequency_hz", named.get("detected_hz")), "frequency_hz (locked)"
        if f is not None:       # the closed loop's mode lies between the locked and free-free values
            k = x["table_mass"] * (2 * math.pi * t) ** 2 / 1000.0
            ff = math.sqrt(1000.0 * k * (1 / x["motor_mass"] + 1 / x["table_mass"])) / (2 * math.pi)
            return {"name": name, "true": t, "free_free_hz": ff, "fitted": f, "rel_error": f / t - 1.0}
    elif kind == "backlash":
        t, f, name = truth["magnitude"], named.get("backlash_mm", named.get("width_mm")), "lost motion mm"
        if f is not None and named.get("width_mm") is not None and named.get("backlash_mm") is None:
            f = 2 * f           # a play law's half-width
    elif kind in ("coupling", "extra_input"):
        return {"name": "channel", "true": p["channel"], "fitted": named.get("channel"),
                "rel_error": 0.0 if named.get("channel") == p["channel"] else None}
    else:
        return None
    if f is None:
        return {"name": name, "true": t, "fitted": None, "rel_error": None}
    return {"name": name, "true": t, "fitted": f, "rel_error": float(f) / float(t) - 1.0}


def _free_run_um(model, trace, axis):
    """Free-run RMS (um) of the predicted minus the measured tracking error, or None when the
    simulator refuses the model on this trace."""
    try:
        e = simulate(model, trace).axes[axis]["error"] - trace.error(axis)
    except Exception as exc:     # reported, not fatal
        print(f"    simulate on {trace.meta.get('name')} failed: {_err(exc)}", flush=True)
        return None
    return float(np.sqrt(np.mean(e ** 2))) * 1e3


def first_round(d):
    """Per candidate label: the largest statistic / threshold of the first round."""
    out = {}
    for c in (d.rounds[0]["candidates"] if d.rounds else []):
        thr, st = c["threshold"], c["statistic"]
        r = st / thr if thr and np.isfinite(st) and np.isfinite(thr) else None
        key = c.get("label", c["kind"])
        if key not in out or (r is not None and (out[key]["ratio"] is None or r > out[key]["ratio"])):
            out[key] = {"statistic": st, "threshold": thr, "ratio": r, "detected": c["detected"]}
    return out


def run_case(seed, args):
    t0 = time.perf_counter()
    c = case(seed, scale=args.scale)
    ax = c.axis
    truth = c.truth()
    out = {"seed": seed, "split": c.split, "axis": ax, "Ts": c.machine.Ts, "n_axes": len(c.machine.axes),
           "truth": truth["effects"], "kinds": c.kinds, "samples_train": [t.n for t in c.train],
           "samples_val": c.val[0].n, "simulate_s": time.perf_counter() - t0,
           "controller": c.machine.axes[0].controller, "mass_kg": c.machine.axes[0].mass,
           "channels": sorted(c.train[0].channels), "visibility": visibility(c, args.scale)}
    vis = out["visibility"]
    print(f"\n[seed {seed}, {c.split}] {len(c.machine.axes)} axis/axes, Ts {c.machine.Ts * 1e3:g} ms, "
          f"{c.machine.axes[0].controller}, {c.machine.axes[0].mass:.0f} kg; truth: "
          + (", ".join(f"{e['kind']} {e['magnitude']:.4g} {e['unit']} ({vis[e['kind']]['noise_ratio']:.3g} x noise)"
                       for e in truth["effects"]) or "clean"), flush=True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t1 = time.perf_counter()
            model = identify_auto(c.train, ax, seed=0, maxiter=args.identify_maxiter, workers=args.jobs)
            out["identify_s"] = time.perf_counter() - t1
            ch = model.identification.get("structure_choice", {})
            out["structure"] = ch.get("chosen")
            print(f"  identified: {out['structure']} ({out['identify_s']:.0f} s)", flush=True)
            t2 = time.perf_counter()
            d = diagnose(model, c.train[0], c.val[0], maxiter=args.maxiter, workers=args.jobs,
                         below_trials=args.below_trials)
            out["diagnose_s"] = time.perf_counter() - t2
    except Exception as exc:
        out["error"] = _err(exc)
        traceback.print_exc()
        return out
    named = [_scalars(e) for e in d.effects_added]
    out["named"] = named
    out["suspected"] = [n.effect for n in d.notes if n.kind == NoteKind.SUSPECTED]
    out["notes"] = [n.kind.value for n in d.notes]
    out["val_before_um"] = {ch: v["rms_um"] for ch, v in d.before["val"].items()}
    out["val_after_um"] = {ch: v["rms_um"] for ch, v in d.after["val"].items()}
    out["first_round"] = first_round(d)
    out["candidates"] = [{k: v for k, v in c.items() if k != "note"} for c in candidate_table(d.rounds)]
    # the second validation trace (contour or long strokes), never seen by the diagnosis
    out["val2"] = {"name": c.val[1].meta["name"], "before_um": _free_run_um(model, c.val[1], ax),
                   "after_um": _free_run_um(d.final, c.val[1], ax)}
    kinds_named = [e["kind"] for e in named]
    out["params"] = {}
    for e in truth["effects"]:
        if e["kind"] in kinds_named:
            out["params"][e["kind"]] = parameter_error(e["kind"], e, named[kinds_named.index(e["kind"])],
                                                       truth["machine"])
    print(f"  named {kinds_named or 'nothing'} (diagnosis {out['diagnose_s']:.0f} s); held-out "
          + ", ".join(f"{ch} {out['val_before_um'][ch]:.3g} -> {out['val_after_um'][ch]:.3g} um"
                      for ch in out["val_before_um"]), flush=True)
    return out


def summarise(rows):
    """Per effect kind: cases, named, what else was named (confusion), parameter errors; clean
    cases: false alarms."""
    per = {k: {"cases": 0, "named": 0, "suspected": 0, "instead": Counter(), "rel_errors": [], "gains": [],
               "magnitudes": []} for k in KINDS}
    clean = {"cases": 0, "false_alarms": 0, "named": Counter(), "gains": []}
    for r in rows:
        if "error" in r:
            continue
        named = [e["kind"] for e in r["named"]]
        ch = r["axis"]
        b, a = r["val_before_um"].get(ch), r["val_after_um"].get(ch)
        gain = (1 - a / b) if b else None
        if not r["kinds"]:
            clean["cases"] += 1
            clean["false_alarms"] += bool(named)
            clean["named"].update(named)
            clean["gains"].append(gain)
            continue
        for e in r["truth"]:
            k = e["kind"]
            s = per[k]
            s["cases"] += 1
            s["magnitudes"].append((e["magnitude"], (r.get("visibility") or {}).get(k, {}).get("noise_ratio")))
            s["gains"].append(gain)
            if k in named:
                s["named"] += 1
                pe = r["params"].get(k)
                if pe and pe.get("rel_error") is not None:
                    s["rel_errors"].append(pe["rel_error"])
            elif k in r.get("suspected", []):
                s["suspected"] += 1
            s["instead"].update(n for n in named if n not in r["kinds"])
    return per, clean


# visibility bins (the effect's shift of the encoder channel over its noise) the detection rate is
# tabulated against; a bound needs at least MIN_ABOVE cases at or above it
VIS_BINS = (0.0, 1.0, 3.0, 10.0, 30.0, math.inf)
MIN_ABOVE = 3
DETECTED = 0.9


def detectability_bound(pairs, share=DETECTED, min_above=MIN_ABOVE):
    """The smallest magnitude above which at least ``share`` of the cases are named.

    Parameters
    ----------
    pairs : [(magnitude, named)] of one effect kind
    share, min_above : the bound is the smallest case magnitude m such that of the cases with
        magnitude >= m (at least ``min_above`` of them) at least ``share`` are named

    Returns
    -------
    float, or None ("not reached")
    """
    pts = sorted((float(m), bool(n)) for m, n in pairs if m is not None)
    for i, (m, _) in enumerate(pts):
        above = [n for _, n in pts[i:]]
        if len(above) >= min_above and sum(above) >= share * len(above):
            return m
    return None


def rates(rows):
    """Per kind: named against magnitude (physical units) and visibility bins, the detectability
    bound; over the cases: false-alarm rate (clean cases naming anything), wrong-effect rate (effect
    cases naming a kind they do not have) and the confusion matrix (true kind -> named kinds, or
    none)."""
    per = {k: [] for k in KINDS}
    confusion = {k: Counter() for k in KINDS}
    clean = effect = fa = wrong = 0
    for r in rows:
        if "error" in r:
            continue
        named = [e["kind"] for e in r["named"]]
        if not r["kinds"]:
            clean += 1
            fa += bool(named)
            continue
        effect += 1
        wrong += any(n not in r["kinds"] for n in named)
        for e in r["truth"]:
            k = e["kind"]
            vis = (r.get("visibility") or {}).get(k, {}).get("noise_ratio")
            per[k].append((e["magnitude"], vis, k in named))
            confusion[k].update(named or ["none"])
    out = {}
    for k, pts in per.items():
        bins = []
        for lo, hi in zip(VIS_BINS, VIS_BINS[1:]):
            sel = [n for _, v, n in pts if v is not None and lo <= v < hi]
            bins.append({"lo": lo, "hi": hi, "cases": len(sel), "named": sum(sel)})
        out[k] = {"cases": len(pts), "named": sum(n for *_, n in pts), "bins": bins,
                  "bound": detectability_bound([(m, n) for m, _, n in pts]),
                  "bound_noise_ratio": detectability_bound([(v, n) for _, v, n in pts]),
                  "unit": UNITS[k], "confusion": dict(confusion[k])}
    return {"per_kind": out, "clean_cases": clean, "false_alarms": fa,
            "false_alarm_rate": fa / clean if clean else None, "effect_cases": effect, "wrong_effect": wrong,
            "wrong_effect_rate": wrong / effect if effect else None}


def print_rates(rows):
    rt = rates(rows)
    print("\n### Detection against magnitude\n")
    print("Named / cases per visibility bin (the effect's RMS shift of the encoder channel over its noise); "
          f"bound: the smallest magnitude above which ≥ {DETECTED:.0%} of at least {MIN_ABOVE} cases are named.\n")
    heads = [f"{lo:g}–{hi:g}×" if np.isfinite(hi) else f"≥ {lo:g}×" for lo, hi in zip(VIS_BINS, VIS_BINS[1:])]
    print("| kind | named | " + " | ".join(heads) + " | bound (physical) | bound (× noise) | named as (confusion) |")
    print("|---|---:|" + "---:|" * len(heads) + "---:|---:|---|")
    for k, s in rt["per_kind"].items():
        cells = [f"{b['named']}/{b['cases']}" if b["cases"] else "" for b in s["bins"]]
        bound = "not reached" if s["bound"] is None else f"{s['bound']:.3g} {s['unit']}"
        bvis = "not reached" if s["bound_noise_ratio"] is None else f"{s['bound_noise_ratio']:.3g}"
        conf = ", ".join(f"{n} ×{c}" for n, c in sorted(s["confusion"].items())) or "—"
        print(f"| {k} | {s['named']}/{s['cases']} | " + " | ".join(cells) + f" | {bound} | {bvis} | {conf} |")
    fr, wr = rt["false_alarm_rate"], rt["wrong_effect_rate"]
    print(f"\nFalse alarms: {rt['false_alarms']} of {rt['clean_cases']} clean cases"
          + (f" ({fr:.0%})" if fr is not None else "") + f"; a wrong effect named in {rt['wrong_effect']} of "
          f"{rt['effect_cases']} effect cases" + (f" ({wr:.0%})" if wr is not None else ""))
    return rt


LIMITS = ("not checked", "statistic below its threshold, not tried", "tried below its threshold, not kept",
          "past its gate, not kept", "another kind kept instead")


def limit_of(r, kind):
    """Why an effect of a case was not named: the furthest any of its candidates got (one of
    ``LIMITS``), over every round; "another kind kept instead" when its candidates got no further
    than a trial and a kind the case does not have was named."""
    cs = [c for c in r.get("candidates", []) if c["kind"] == kind]
    wrong = any(e["kind"] not in r["kinds"] for e in r.get("named", []))
    if any(c.get("refitted") and not c.get("tried_below_threshold") for c in cs):
        why = LIMITS[3]
    elif any(c.get("tried_below_threshold") for c in cs):
        why = LIMITS[2]
    elif any(not c.get("not_checked") for c in cs):
        why = LIMITS[1]
    else:
        why = LIMITS[0]
    return LIMITS[4] if wrong and why in LIMITS[2:4] else why


def print_limits(rows):
    """Per kind: the effects not named, counted by what stopped them (:func:`limit_of`)."""
    tab = {k: Counter() for k in KINDS}
    for r in rows:
        if "error" in r:
            continue
        named = {e["kind"] for e in r.get("named", [])}
        for e in r["truth"]:
            if e["kind"] not in named:
                tab[e["kind"]][limit_of(r, e["kind"])] += 1
    print("\n### What stopped the effects not named\n")
    print("| kind | " + " | ".join(LIMITS) + " |")
    print("|---|" + "---:|" * len(LIMITS))
    for k, c in tab.items():
        if sum(c.values()):
            print(f"| {k} | " + " | ".join(str(c[x]) for x in LIMITS) + " |")
    return {k: dict(c) for k, c in tab.items()}


def missed(r):
    """Per true effect not named: what its detector's candidates came to (outcome, statistic /
    threshold, best held-out gain), from the candidate table of every round."""
    named = {e["kind"] for e in r.get("named", [])}
    out = {}
    for e in r["truth"]:
        k = e["kind"]
        if k in named:
            continue
        cs = [c for c in r.get("candidates", []) if c["kind"] == k]
        out[k] = [f"{c['label']} round {c['round']}: " + (
            f"{c['outcome']}{' (tried below its threshold)' if c.get('tried_below_threshold') else ''} "
            f"({c['statistic'] / c['threshold']:.2f}× threshold"
            + (f", held-out {c['best_gain_val']:+.1%}" if c.get("best_gain_val") is not None else "") + ")"
            if c["threshold"] and np.isfinite(c["statistic"]) and np.isfinite(c["threshold"])
            else f"gate closed (statistic {c['statistic']:.3g}, threshold {c['threshold']:.3g}"
                 + (f": {c['not_checked']}" if c.get("not_checked") else "") + ")")
            for c in cs] or ["no candidate of this kind"]
    return out


def _f(x, fmt="{:.3g}"):
    return "—" if x is None else fmt.format(x)


def print_tables(res):
    rows = res["cases"]
    print("\n### Family cases\n")
    print("| seed | split | axes | Ts [ms] | truth (magnitude) | structure | named (parameters) | "
          "held-out RMS x before → after [µm] | second validation trace [µm] | identify / diagnose [s] |")
    print("|---:|---|---:|---:|---|---|---|---|---|---|")
    for r in rows:
        vis = r.get("visibility") or {}
        truth = "; ".join(f"{e['kind']} {e['magnitude']:.3g} {e['unit']}"
                          + (f" ({vis[e['kind']]['noise_ratio']:.3g}× noise)" if e["kind"] in vis else "")
                          for e in r["truth"]) or "clean"
        if "error" in r:
            print(f"| {r['seed']} | {r['split']} | {r['n_axes']} | {r['Ts'] * 1e3:g} | {truth} | | error: {r['error']} | | | |")
            continue
        named = "; ".join(e["kind"] + " (" + ", ".join(
            f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in e.items()
            if k not in ("kind", "axis", "input", "output")) + ")" for e in r["named"]) or "none"
        if r.get("suspected"):
            named += " (suspected: " + ", ".join(r["suspected"]) + ")"
        if r.get("notes"):      # e.g. carried_lost_motion: a play in the chosen structure
            named += " (notes: " + ", ".join(sorted(set(r["notes"]))) + ")"
        ch = r["axis"]
        v2 = r.get("val2") or {}
        v2s = (f"{v2['name']}: {_f(v2.get('before_um'))} → {_f(v2.get('after_um'))}" if v2 else "—")
        print(f"| {r['seed']} | {r['split']} | {r['n_axes']} | {r['Ts'] * 1e3:g} | {truth} | {r.get('structure')} | "
              f"{named} | {r['val_before_um'][ch]:.3g} → {r['val_after_um'][ch]:.3g} | {v2s} | "
              f"{r['identify_s']:.0f} / {r['diagnose_s']:.0f} |")
    per, clean = summarise(rows)
    print("\n### Per effect kind\n")
    print("| kind | cases | named | suspected | named instead | parameter rel. error (median) | "
          "held-out gain of these cases, every kept effect (median) | magnitudes (shift of the encoder "
          "channel / its noise) |")
    print("|---|---:|---:|---:|---|---|---|---|")
    for k, s in per.items():
        if not s["cases"]:
            print(f"| {k} | 0 | | | | | | |")
            continue
        inst = ", ".join(f"{n} ×{c}" for n, c in s["instead"].items()) or "—"
        pe = f"{np.median(np.abs(s['rel_errors'])):.3f} (n={len(s['rel_errors'])})" if s["rel_errors"] else "—"
        g = [x for x in s["gains"] if x is not None]
        mags = ", ".join(f"{m:.3g} ({_f(rel)})" for m, rel in s["magnitudes"])
        print(f"| {k} | {s['cases']} | {s['named']} | {s['suspected']} | {inst} | {pe} | "
              f"{_f(float(np.median(g)) if g else None, '{:+.1%}')} | {mags} |")
    named = ", ".join(f"{n} ×{c}" for n, c in clean["named"].items()) or "—"
    print(f"\nClean cases: {clean['cases']}, false alarms {clean['false_alarms']} (named: {named})")
    print_rates(rows)
    print_limits(rows)
    lines = [(r["seed"], k, "; ".join(v)) for r in rows if "error" not in r for k, v in missed(r).items()]
    if lines:
        print("\n### Effects not named: what their candidates came to\n")
        print("| seed | effect | candidates (outcome, statistic / threshold, best held-out gain) |")
        print("|---:|---|---|")
        for seed, k, text in lines:
            print(f"| {seed} | {k} | {text} |")
    print("\n### First round: statistic / threshold per detector (≥ 1 passes the gate)\n")
    labels = sorted({lab for r in rows if "first_round" in r for lab in r["first_round"]})
    print("| seed | truth | " + " | ".join(labels) + " |")
    print("|---:|---|" + "---:|" * len(labels))
    for r in rows:
        if "first_round" not in r:
            continue
        fr = r["first_round"]
        print(f"| {r['seed']} | {', '.join(r['kinds']) or 'clean'} | "
              + " | ".join(_f((fr.get(lab) or {}).get("ratio"), "{:.2f}") for lab in labels) + " |")


def tables_text(res):
    """The markdown tables of :func:`print_tables` as one string."""
    return printed(print_tables, res)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=None, help="number of cases (default 8; --quick: 3)")
    ap.add_argument("--split", choices=("calibration", "held-out", "all"), default="held-out")
    ap.add_argument("--start", type=int, default=0, help="first seed considered")
    ap.add_argument("--seeds", default="", help="comma-separated seeds (overrides --cases/--split/--start)")
    ap.add_argument("--maxiter", type=int, default=None, help="DE iterations of each diagnosis refit (default 25)")
    ap.add_argument("--identify-maxiter", type=int, default=None,
                    help="DE iterations of the identification (default: identify_auto's)")
    ap.add_argument("--scale", type=float, default=1.0, help="trace length factor (family.case(scale=...))")
    ap.add_argument("--below-trials", type=int, default=0, help="candidates tried below their "
                    "thresholds per round (diagnose(below_trials=...); default 0, as diagnose)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of identification and diagnosis")
    ap.add_argument("--quick", action="store_true", help="3 cases, half-length traces, 8 generations "
                    "(identification and refits)")
    ap.add_argument("--out", default=OUT_DEFAULT, help="file name in benchmarks/results (--quick: "
                    "bench_family_diagnosis_quick.json)")
    ap.add_argument("--print-only", nargs="*", metavar="JSON", help="print the tables of earlier runs")
    args = ap.parse_args(argv)
    pub = publishable(ap, args)
    if args.print_only is not None:
        rows = []
        for f in args.print_only or [args.out]:
            rows += json.loads((OUT / f).read_text())["cases"]
        print_tables({"cases": rows})
        return
    if args.quick:
        args.out = "bench_family_diagnosis_quick.json" if args.out == OUT_DEFAULT else args.out
        args.cases = args.cases or 3
        args.scale = 0.5 if args.scale == 1.0 else args.scale
        args.maxiter = args.maxiter or 8
        args.identify_maxiter = args.identify_maxiter or 8
    args.maxiter = args.maxiter or 25
    args.cases = args.cases or 8
    todo = [int(s) for s in args.seeds.split(",") if s] or seeds(args.split, args.cases, args.start)
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / args.out
    res = {"code": code_state("src", "tests/family"), "settings": {k: v for k, v in vars(args).items() if k != "print_only"},
           "seeds": todo, "cases": []}
    t0 = time.perf_counter()

    def save():
        path.write_text(json.dumps(res, indent=1, default=float))

    for s in todo:
        res["cases"].append(run_case(s, args))
        save()
    res["wall_s"] = time.perf_counter() - t0
    per, clean = summarise(res["cases"])
    res["summary"] = {"per_kind": {k: {**v, "instead": dict(v["instead"])} for k, v in per.items()},
                      "clean": {**clean, "named": dict(clean["named"])}, "rates": rates(res["cases"])}
    save()
    text = tables_text(res)
    print(text)
    md = path.with_suffix(".md")
    md.write_text(text + "\n")
    print(f"\nwall time {res['wall_s']:.0f} s; JSON: {path}; tables: {md}")
    if pub:
        publish("family_diagnosis", "Diagnosis on the seeded plant family", [text], command("family_diagnosis"),
                res, state=res["code"], notes=about(__doc__))


if __name__ == "__main__":
    main()
