"""Time and accuracy of the default identification (``fdid identify``: ``identify_auto``) on fixed
training traces, for a side-by-side comparison of two versions (or two search settings).

Traces (axis x, seed 0, two worker processes):

- ``virtual ff``: the virtual drive with feed-forward (``presets.with_feedforward()``), 20 linear
  moves to train; diamond, circle and 12 other moves to validate (``bench_accuracy.virtual_data``);
- ``virtual no-ff``: the same on the drive without feed-forward (``presets.deckel_maho_like()``);
- ``plant2 clean_rigid``, ``plant2 stribeck``: the scenario's training trace; its circle, diamond
  and reversals to validate (``tests/plant2``).

Every (trace, version) runs ``identify_auto(train, axis, seed=0, workers=2)`` in a fresh
subprocess; the versions alternate trace by trace. Per run: wall s and CPU s of the
identification (this process and its worker processes, ``resource.getrusage``), the chosen
structure, the free-run RMS (um) of predicted minus measured tracking error on the training trace
and on each validation trace. Then the ratios new / old.

    .venv/bin/python benchmarks/bench_default_identify.py [--quick] [--search S]
        [--other PYTHON] [--other-search S] [--old-from JSON] [--traces a,b] [--out NAME.json]

``--other PYTHON`` runs the same workload with another version's interpreter (e.g.
/path/to/old/.venv/bin/python); ``--search S`` / ``--other-search S`` pass ``search=S`` to
``identify_auto`` of this / the other run (for code that has that option; with ``--other-search``
alone the other run uses this interpreter); ``--old-from JSON`` takes the old runs from a stored
result instead (its ``new`` runs). ``--quick``: the feed-forward virtual trace only
(about 3 minutes). Writes benchmarks/results/bench_default_identify.json and prints a markdown table.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from publish import command, publish, publishable  # noqa: E402  (benchmarks/, beside this script)
from timing import child_json, code_state, cpu_s  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
OUT = HERE / "results"
TRACES = ("virtual ff", "virtual no-ff", "plant2 clean_rigid", "plant2 stribeck")
AXIS = "x"


# ------------------------------------------------------------------ child: one identification
def _data(name):
    """(train trace, {validation name: trace}) of one benchmark trace."""
    if name.startswith("virtual"):
        sys.path.insert(0, str(HERE))
        from bench_accuracy import virtual_data
        from fdid_fmi.virtual import presets
        cfg = presets.with_feedforward() if name == "virtual ff" else presets.deckel_maho_like()
        train, vals = virtual_data(cfg, AXIS)
        return train, vals
    sys.path.insert(0, str(ROOT / "tests"))
    from plant2 import scenarios as p2
    train, vals, truth = p2.scenario(name.split()[1])
    assert truth["axis"] == AXIS, truth["axis"]
    return train[0], {v.meta["name"]: v for v in vals}


def child(name, search):
    """Identify one trace with the default path; print one JSON line."""
    import warnings

    from fdid_fmi import __version__
    from fdid_fmi.identify.choose_structure import identify_auto
    from fdid_fmi.metrics import rms
    from fdid_fmi.simulate import simulate
    train, vals = _data(name)
    kw = {"search": search} if search else {}
    cpu0, t0 = cpu_s(), time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = identify_auto(train, AXIS, seed=0, workers=2, **kw)
    wall, cpu = time.perf_counter() - t0, cpu_s() - cpu0
    choice = model.identification["structure_choice"]

    def err_um(tr):
        return 1e3 * float(rms(simulate(model, tr).axes[AXIS]["error"] - tr.error(AXIS)))

    print(json.dumps({"trace": name, "version": __version__, "search": search, "wall_s": wall, "cpu_s": cpu,
                      "chosen": f"{choice['chosen']} {choice['same_sample']}", "fits": len(choice["candidates"]),
                      "train_um": err_um(train), "val_um": {k: err_um(v) for k, v in vals.items()},
                      "samples": train.n}))


# ------------------------------------------------------------------ parent
def run_one(python, name, search):
    r = child_json(python, Path(__file__).resolve(), ["--child", name] + (["--search", search] if search else []))
    return {"trace": name, **r} if "error" in r else r


def _ratio(a, b):
    return a / b if a is not None and b else None


def table(res):
    """Markdown lines: one row per trace and run, ratios new / old where there is an old run."""
    both = "old" in res["runs"]
    lines = ["| trace | run | chosen | wall s | CPU s | train µm | validation µm |"
             + (" ratio CPU | ratio train | ratio validation |" if both else ""),
             "|---|---|---|---:|---:|---:|---|" + ("---:|---:|---|" if both else "")]
    for name, runs in res["traces"].items():
        new, old = runs.get("new"), runs.get("old")
        for key in ("old", "new"):
            r = runs.get(key)
            if r is None:
                continue
            if "error" in r:
                lines.append(f"| {name} | {res['runs'][key]} | FAILED: {r['error']} |  |  |  |  |"
                             + ("  |  |  |" if both else ""))
                continue
            vals = ", ".join(f"{k} {v:.3f}" for k, v in r["val_um"].items())
            rat = ["", "", ""]
            if key == "new" and old and "error" not in old and "error" not in new:
                rat = [f"{_ratio(new['cpu_s'], old['cpu_s']):.3f}", f"{_ratio(new['train_um'], old['train_um']):.3f}",
                       ", ".join(f"{k} {_ratio(v, old['val_um'].get(k)):.3f}" for k, v in new["val_um"].items())]
            lines.append(f"| {name} | {res['runs'][key]} | {r['chosen']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | "
                         f"{r['train_um']:.3f} | {vals} |" + (" " + " | ".join(rat) + " |" if both else ""))
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="the feed-forward virtual trace only")
    ap.add_argument("--traces", help=f"comma-separated subset of: {', '.join(TRACES)}")
    ap.add_argument("--search", default=None, help="search= passed to this run's identify_auto")
    ap.add_argument("--other", default=None, help="another version's python to run the same workload")
    ap.add_argument("--other-search", default=None, help="search= passed to the other run's identify_auto")
    ap.add_argument("--old-from", default=None, metavar="JSON",
                    help="take the old runs from this file's new runs instead of running them")
    ap.add_argument("--out", default="bench_default_identify.json")
    a = ap.parse_args()
    if a.child:
        child(a.child, a.search)
        return
    names = ["virtual ff"] if a.quick else (a.traces.split(",") if a.traces else list(TRACES))
    for n in names:
        if n not in TRACES:
            ap.error(f"unknown trace {n!r}; choose from {TRACES}")
    runs = {"new": (sys.executable, a.search)}
    if a.other or a.other_search:
        runs["old"] = (a.other or sys.executable, a.other_search)
    res = {"runs": {k: f"{p}{' search=' + s if s else ''}" for k, (p, s) in runs.items()},
           "code": code_state(), "axis": AXIS, "seed": 0, "workers": 2, "traces": {}}
    stored = None
    if a.old_from:
        stored = json.loads((OUT / a.old_from if not Path(a.old_from).is_file() else Path(a.old_from)).read_text())
        res["runs"]["old"] = f"{stored['runs']['new']} (stored: {a.old_from})"
    order = list(runs)
    for i, name in enumerate(names):
        res["traces"][name] = {}
        for key in (order if i % 2 == 0 else order[::-1]):     # alternate which version runs first
            python, search = runs[key]
            r = run_one(python, name, search)
            res["traces"][name][key] = r
            print(f"[{name}] {key}: " + (f"FAILED {r['error']}" if "error" in r else
                                         f"{r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} CPU-s, {r['chosen']}, "
                                         f"train {r['train_um']:.3f} um"), flush=True)
        if stored is not None and name in stored["traces"]:
            res["traces"][name]["old"] = stored["traces"][name]["new"]
    out = OUT / a.out
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    print()
    print("\n".join(f"- {k}: {v}" for k, v in res["runs"].items()))
    print("\n".join(table(res)))
    print(f"written {out}")
    if publishable(ap, a):
        shown = dict(res, runs={"new": "default"})
        publish("default_identify", "Default identification: time and accuracy", ["\n".join(table(shown))],
                command("default_identify"), res, state=res["code"], notes=NOTES)


NOTES = """`identify_auto` (what `fdid identify` runs by default: the structure chosen from the data,
variable-projection search), axis x, seed 0, two worker processes, each trace in a fresh process;
wall and CPU s of the identification (the process and its workers). Traces: the virtual drive with
and without feed-forward (20 linear moves to train; diamond, circle and 12 other moves to
validate) and the plant2 scenarios clean_rigid and stribeck (their circle, diamond and reversals to
validate). Free-run RMS of predicted minus measured tracking error, µm. `--other PYTHON` or
`--other-search de` adds a second run per trace and the ratios (written to benchmarks/results/
only)."""

if __name__ == "__main__":
    main()
