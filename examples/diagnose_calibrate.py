"""Calibrate the diagnosis thresholds on clean virtual-drive data (and check them on a second plant).

Runs every detector once (no augmentation) on clean scenarios (gentle moves, fast moves, a softer
velocity loop, two uncoupled axes, a P loop without integral action) for several seeds and prints each detector's statistic with
its threshold. The thresholds in ``fdid_fmi.diagnose.*`` were set above the largest clean value
with margin; a statistic at or above its threshold only means the effect is *tried* -- the
held-out criterion decides whether it is kept.

    .venv/bin/python examples/diagnose_calibrate.py                 # virtual drive, 15 clean runs (~2 min)
    .venv/bin/python examples/diagnose_calibrate.py --effects       # + the 7 one-effect virtual runs
    .venv/bin/python examples/diagnose_calibrate.py --effects --plant2 [--json out.json]
                                                                    # + tests/plant2: 9 clean, 8 one-effect
    ... --default-path      every model by fdid identify's default (the structure chosen from the
                            data, ``identify_auto``) instead of the thesis's SISO pole search (slow:
                            about 30-120 s of CPU per run)

Besides the detectors, each run reports ``suspected (note)``: the statistic of the ``suspected``
note (``diagnose/limits.py``; :func:`fdid_fmi.diagnose.friction.concentration`, its reference the
larger of the moving and resting residual), against ``REVERSAL_SUSPECT``.

With ``--plant2`` a table gives, per detector, the largest clean value on each plant, the threshold
1.2 x that value (the rule of ``diagnose/base.py``) set on one plant and applied to the other
(false alarms on clean runs, hits on the runs with that effect), in both directions. The second
plant (``tests/plant2``: LuGre friction, its own loop and integrator) shares no code with
``fdid_fmi.virtual``; it is in the source tree, not the installed package.
"""
import argparse
import json
import os
import sys
import warnings
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

from fdid_fmi.diagnose import DETECTORS, friction  # noqa: E402
from fdid_fmi.diagnose import augment as ag  # noqa: E402
from fdid_fmi.diagnose.base import Context  # noqa: E402
from fdid_fmi.diagnose.residuals import residuals  # noqa: E402
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, _measured_only, scenario  # noqa: E402
from fdid_fmi.diagnose.limits import REVERSAL_SUSPECT  # noqa: E402
from fdid_fmi.identify import identify_siso  # noqa: E402
from fdid_fmi.identify.choose_structure import identify_auto  # noqa: E402

MARGIN = 1.2
VIRTUAL_CLEAN = ("clean", "clean_fast", "clean_soft", "clean_xy", "clean_p")
VIRTUAL_EFFECTS = {"stribeck": "stribeck", "backlash": "backlash", "periodic": "periodic_position",
                   "delay": "delay", "mode": "mode", "coupling": "coupling", "asymmetric": "asymmetric_friction"}


def statistics(m, tr):
    """{kind: (largest statistic, threshold)} of every detector on model m and trace tr."""
    ctx = Context(model=m, recipe=ag.recipe_from_model(m), train=ag.model_velocity_traces(m, [tr]),
                  res=[residuals(m, tr)], settings={"maxiter": 25})
    out = {}
    for mod in DETECTORS.values():
        for c in mod.detect(ctx):
            s = float(c.statistic) if np.isfinite(c.statistic) else float("nan")
            if c.label not in out or s > out[c.label][0]:
                out[c.label] = (s, float(c.threshold))
    out["suspected (note)"] = (max(friction.concentration(ctx.res, a, m.Ts) for a in m.axes), REVERSAL_SUSPECT)
    return out


def fit(tr, axis, integral_action=True, default_path=False):
    """The model a run's statistics are computed on: the thesis's SISO pole search, or with
    ``default_path`` fdid identify's default (the structure chosen from the data, one process)."""
    if default_path:
        return identify_auto(tr, axis, seed=0, workers=1)
    return identify_siso(tr, axis=axis, maxiter=30, seed=0, integral_action=integral_action)


def virtual_run(name, seeds, expected, motor_only=False, default_path=False):
    tr, _ = scenario(name, seeds=seeds)
    if motor_only:          # the tool-side channel dropped: what a motor encoder alone shows
        tr = _measured_only(tr, ("cmd", "act", "vel"))
    m = fit(tr, "x", INTEGRAL_ACTION.get(name, True), default_path)
    return {"plant": "virtual", "scenario": name + (" (motor only)" if motor_only else ""), "seed": seeds[0],
            "expected": expected, "stats": statistics(m, tr)}


def plant2_run(p2, name, seed, default_path=False):
    tr = p2.scenario(name, seed=seed)[0][0]
    m = fit(tr, p2.SCENARIOS[name][1], default_path=default_path)
    return {"plant": "plant2", "scenario": name, "seed": seed, "expected": p2.SCENARIOS[name][2],
            "stats": statistics(m, tr)}


def show(r):
    for kind, (s, thr) in r["stats"].items():
        print(f"{r['plant']:7s} {r['scenario']:16s} seed {r['seed']}  {kind:20s} {s:8.3f}  (threshold {thr:g})"
              + ("" if r["expected"] is None else f"  [effect: {r['expected']}]"), flush=True)


def transfer_table(runs):
    kinds = sorted({k for r in runs for k in r["stats"]})
    print(f"\nthreshold = {MARGIN} x largest clean statistic of the calibration plant\n")
    print("| detector | shipped | max clean virtual | max clean plant2 | cal. on | threshold | measured on | "
          "false alarms (clean) | hits (effect runs: statistic) |")
    print("|---|---:|---:|---:|---|---:|---|---|---|")
    for kind in kinds:
        shipped = next(r["stats"][kind][1] for r in runs if kind in r["stats"])
        mx = {}
        for plant in ("virtual", "plant2"):
            v = [r["stats"][kind][0] for r in runs if r["plant"] == plant and r["expected"] is None
                 and kind in r["stats"] and np.isfinite(r["stats"][kind][0])]
            mx[plant] = max(v) if v else None
        for cal, meas in (("virtual", "plant2"), ("plant2", "virtual")):
            if mx[cal] is None:
                continue
            t = MARGIN * mx[cal]
            clean = [r for r in runs if r["plant"] == meas and r["expected"] is None and kind in r["stats"]]
            fa = [f"{r['scenario']}/{r['seed']}" for r in clean if r["stats"][kind][0] >= t]
            eff = [r for r in runs if r["plant"] == meas and r["expected"] == kind.split(" (")[0] and kind in r["stats"]]
            hits = ", ".join(f"{r['scenario']}: {r['stats'][kind][0]:.3g}" + (" HIT" if r["stats"][kind][0] >= t else "")
                             for r in eff) or "—"
            f = lambda x: "—" if x is None else f"{x:.3g}"  # noqa: E731
            print(f"| {kind} | {shipped:g} | {f(mx['virtual'])} | {f(mx['plant2'])} | {cal} | {t:.3g} | {meas} | "
                  f"{len(fa)}/{len(clean)} {' '.join(fa)} | {hits} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--effects", action="store_true", help="also the one-effect virtual scenarios")
    ap.add_argument("--plant2", action="store_true", help="also tests/plant2 (clean seeds 0-2, effects seed 0)")
    ap.add_argument("--json", default="", help="write every run's statistics to this file")
    ap.add_argument("--default-path", action="store_true",
                    help="models by fdid identify's default structure choice instead of the thesis's pole search")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    runs = []
    for name in VIRTUAL_CLEAN:
        for seeds in ((1, 2), (3, 4), (5, 6)):
            runs.append(virtual_run(name, seeds, None, default_path=args.default_path))
            show(runs[-1])
    if args.effects:
        for name, kind in VIRTUAL_EFFECTS.items():
            runs.append(virtual_run(name, (1, 2), kind, default_path=args.default_path))
            show(runs[-1])
        for seeds in ((1, 2), (3, 4), (5, 6)):     # diagnose/limits.py: lost motion at the motor?
            runs.append(virtual_run("backlash", seeds, "backlash", motor_only=True, default_path=args.default_path))
            show(runs[-1])
    if args.plant2:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
        from plant2 import scenarios as p2
        for name in p2.CLEAN:
            for seed in (0, 1, 2):
                runs.append(plant2_run(p2, name, seed, args.default_path))
                show(runs[-1])
        for name, spec in p2.SCENARIOS.items():
            if spec[2] is not None:
                runs.append(plant2_run(p2, name, 0, args.default_path))
                show(runs[-1])
    print("\nlargest clean statistic per detector (virtual drive):")
    for kind in sorted({k for r in runs for k in r["stats"]}):
        vals = [(r["stats"][kind][0], r["scenario"], r["seed"]) for r in runs
                if r["plant"] == "virtual" and r["expected"] is None and kind in r["stats"]]
        if vals:
            worst = max(vals)
            thr = next(r["stats"][kind][1] for r in runs if kind in r["stats"])
            print(f"  {kind:20s} max {worst[0]:8.3f} ({worst[1]}, seed {worst[2]})   threshold {thr:g}   n = {len(vals)}")
    if args.plant2:
        transfer_table(runs)
    if args.json:
        Path(args.json).write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
