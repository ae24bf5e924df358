"""Model accuracy and well-posedness on every validation trace of the README tables, for a
side-by-side comparison of two versions of the package.

Free-run discrepancy RMS in µm of the predicted tracking error (virtual drive; tool-side error for
the flexible axis) or position (EMPS, plant2) against the measurement, for the pole search, Full LS
and quasi-static. For every pole-search model and trace, the sensitivity of the free run to its
commands: each command sample moved by +-delta (random sign per sample, delta = 1e-12, 1e-9,
1e-6 mm), max |change of the predicted position| / delta ("gain"; the target is <= 100, with
1e-9 mm of slack at the smallest delta). Run this script with each version's Python, then compare:

    .venv/bin/python benchmarks/bench_accuracy.py --label new
    OTHER/.venv/bin/python benchmarks/bench_accuracy.py --label old    (the other version's venv)
    .venv/bin/python benchmarks/bench_accuracy.py --compare results/bench_accuracy_old.json \
        results/bench_accuracy_new.json

Writes benchmarks/results/bench_accuracy_<label>.json (single core: BLAS threads pinned to 1).
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from fdid_fmi.identify import (Bounds, identify_full_ls, identify_mimo, identify_quasi_static,  # noqa: E402
                               identify_siso, mimo_structure)
from fdid_fmi.metrics import rms  # noqa: E402
from fdid_fmi.model import load_model  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from fdid_fmi.trace import Channel, Trace  # noqa: E402
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine  # noqa: E402
from fdid_fmi.virtual import trajectories as tj  # noqa: E402
from publish import command, md_table, publish, publishable, report  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
EMPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "emps"
TESTS = Path(__file__).resolve().parents[1] / "tests"
DELTAS_MM = (1e-12, 1e-9, 1e-6)
GAINS = {}          # "case trace" -> [gain at each delta]
LINEAR_GAINS = {}   # the same with the friction switched off: the linear part's own gain


def perturbed(tr, axes, delta, seed=1):
    """``tr`` with every command sample of ``axes`` moved by +-delta mm (random sign)."""
    rng = np.random.default_rng(seed)
    ch = dict(tr.channels)
    for a in axes:
        c = tr.channels[tr.roles[a]["cmd"]]
        ch[c.name] = Channel(c.name, c.unit, c.data + delta * rng.choice([-1.0, 1.0], c.data.size))
    return Trace(t=tr.t, channels=ch, roles=tr.roles, source=tr.source, meta=dict(tr.meta),
                 jitter_tol=tr.jitter_tol)


def _gains(model, tr, params=None):
    base = simulate(model, tr, params=params)
    gains = []
    for d in DELTAS_MM:
        sim = simulate(model, perturbed(tr, model.axes, d), params=params)
        gains.append(max(float(np.max(np.abs(sim.axes[a]["position"] - base.axes[a]["position"])))
                         for a in model.axes) / d)
    return gains


def record_gains(key, model, tr):
    """max |position change| / delta of the free run of ``tr`` for each delta of DELTAS_MM, with
    the model's friction and without it."""
    GAINS[key] = _gains(model, tr)
    fric = {p.axis for p in model.inputs if p.kind == "friction"}
    LINEAR_GAINS[key] = _gains(model, tr, {f"{a}_friction_on": False for a in fric}) if fric else GAINS[key]


def _one(cfg, ax):
    return MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts)


def virtual_data(cfg, ax, n_moves=20):
    """The traces of benchmarks/checks/pole_search_virtual.py: 20 linear moves to train; a diamond,
    a circle and another move set to validate."""
    Ts = cfg.Ts
    one = _one(cfg, ax)
    train = simulate_machine(one, tj.linear_moves(n_moves=n_moves, axes=(ax,), Ts=Ts, seed=1), seed=1)
    vals = {"diamond": simulate_machine(cfg, tj.diamond(Ts=Ts), seed=2),
            "circle": simulate_machine(cfg, tj.circle(Ts=Ts), seed=3),
            "moves": simulate_machine(one, tj.linear_moves(n_moves=12, axes=(ax,), Ts=Ts, seed=7), seed=4)}
    return train, vals


def err_um(model, tr, ax):
    return 1e3 * rms(simulate(model, tr).axes[ax]["error"] - tr.error(ax))


def case_virtual(name, cfg, ax, pole_search):
    train, vals = virtual_data(cfg, ax)
    t0 = time.perf_counter()
    models = {"pole search": pole_search(train, ax), "Full LS": identify_full_ls(train, ax),
              "quasi-static": identify_quasi_static(train, [ax])}
    wall = time.perf_counter() - t0
    for v, tr in vals.items():
        record_gains(f"{name} {ax} {v}", models["pole search"], tr)
    return {f"{name} {ax} {v}": {k: err_um(m, tr, ax) for k, m in models.items()}
            for v, tr in vals.items()}, wall


def case_flexible():
    cfg = presets.flexible_y()
    nyq = 0.5 / cfg.Ts
    train = simulate_machine(_one(cfg, "y"), tj.linear_moves(n_moves=8, axes=("y",), Ts=cfg.Ts, seed=1),
                             seed=1)
    vals = {"circle": simulate_machine(cfg, tj.circle(Ts=cfg.Ts), seed=3),
            "diamond": simulate_machine(cfg, tj.diamond(Ts=cfg.Ts), seed=2)}
    bounds = Bounds(real_hz=[(0.02, nyq)], omega_hz=[(0.02, nyq), (20.0, 40.0)],
                    zeta=[(0.01, 4.0), (0.001, 0.5)])
    t0 = time.perf_counter()
    m = identify_mimo(train, mimo_structure(("y",), ("velocity", "tool_position"), 1, 2),
                      bounds=bounds, seed=0, maxiter=40)
    wall = time.perf_counter() - t0
    out = {}
    for v, tr in vals.items():
        pred = simulate(m, tr).axes["y"]["tool_position"]
        out[f"flexible y tool {v}"] = {"pole search": 1e3 * rms(pred - tr.get("y", "tool"))}
        record_gains(f"flexible y tool {v}", m, tr)
    return out, wall


def case_emps():
    from fdid_fmi.io import read_trace
    if not (EMPS / "DATA_EMPS.mat").is_file():
        return {}, 0.0
    train = read_trace(EMPS / "DATA_EMPS.mat")
    test = read_trace(EMPS / "DATA_EMPS_PULSES.mat").slice(0, 0.34)
    t0 = time.perf_counter()
    models = {"pole search": identify_siso(train, "x", integral_action=False),
              "Full LS": identify_full_ls(train, "x"), "quasi-static": identify_quasi_static(train)}
    wall = time.perf_counter() - t0
    out = {}
    for v, tr in (("train", train), ("pulses before 1st pulse", test)):
        out[f"EMPS position {v}"] = {k: 1e3 * rms(simulate(m, tr).axes["x"]["position"] - tr.act("x"))
                                     for k, m in models.items()}
        record_gains(f"EMPS position {v}", models["pole search"], tr)
    return out, wall


def case_plant2():
    """plant2's stored default-path models (tests/data) on their scenarios' traces: position."""
    sys.path.insert(0, str(TESTS))
    import plant2 as p2
    out = {}
    for scen in ("clean_rigid", "delay"):
        model = load_model(TESTS / "data" / f"plant2_{scen}_default_model.json")
        train, val, _ = p2.scenario(scen)
        for tr in train + val:
            key = f"plant2 {scen} {tr.meta['name']}"
            out[key] = {"pole search": 1e3 * rms(simulate(model, tr).axes["x"]["position"] - tr.act("x"))}
            record_gains(key, model, tr)
    return out, 0.0


def run():
    rows, walls = {}, {}
    no_ff = presets.deckel_maho_like()
    ff = presets.with_feedforward()
    for ax in ("x", "y"):
        r, walls[f"no feed-forward {ax}"] = case_virtual(
            "no feed-forward", no_ff, ax, lambda tr, a: identify_siso(tr, a, seed=0))
        rows.update(r)
        r, walls[f"feed-forward {ax}"] = case_virtual(
            "feed-forward", ff, ax,
            lambda tr, a: identify_mimo(tr, mimo_structure((a,), ("error",), n_real=2, n_complex=1), seed=0))
        rows.update(r)
    r, walls["flexible y"] = case_flexible()
    rows.update(r)
    r, walls["EMPS"] = case_emps()
    rows.update(r)
    r, _ = case_plant2()
    rows.update(r)
    return {"discrepancy_um": rows, "identification_wall_s": walls,
            "perturbation_gain": {"delta_mm": list(DELTAS_MM), "gain": dict(GAINS),
                                  "gain_without_friction": dict(LINEAR_GAINS)}}


def compare(old_file, new_file):
    old, new = (json.loads(Path(f).read_text()) for f in (old_file, new_file))
    print(f"| trace | model | {old.get('label', 'old')} [µm] | {new.get('label', 'new')} [µm] | ratio |")
    print("|---|---|---:|---:|---:|")
    for trace, d in new["discrepancy_um"].items():
        for model, v in d.items():
            o = old["discrepancy_um"].get(trace, {}).get(model)
            ratio = f"{v / o:.2f}" if o else "—"
            print(f"| {trace} | {model} | {o:.3f} | {v:.3f} | {ratio} |" if o is not None else
                  f"| {trace} | {model} | — | {v:.3f} | — |")
    og, ng = (d.get("perturbation_gain", {}).get("gain", {}) for d in (old, new))
    if ng:
        print()
        print("| trace | " + " | ".join(f"gain at {d:g} mm: {old.get('label', 'old')} / {new.get('label', 'new')}"
                                         for d in DELTAS_MM) + " |")
        print("|---|" + "---:|" * len(DELTAS_MM))
        for trace, g in ng.items():
            o = og.get(trace, [float("nan")] * len(g))
            print(f"| {trace} | " + " | ".join(f"{a:.3g} / {b:.3g}" for a, b in zip(o, g)) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", default="current")
    ap.add_argument("--out")
    ap.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    a = ap.parse_args()
    if a.compare:
        compare(*a.compare)
        return
    res = {"label": a.label, **run()}
    out = Path(a.out) if a.out else OUT / f"bench_accuracy_{a.label}.json"
    report(out, res, tables(res))
    if publishable(ap, a):
        publish("accuracy", "Accuracy and sensitivity to the commands", tables(res), command("accuracy"), res,
                notes=NOTES)


NOTES = """Free-run discrepancy RMS in µm: the model driven by the commands alone against the
measurement -- tracking error on the virtual drive (`fdid_fmi.virtual`; tool-side position on the
flexible Y axis), position on EMPS and plant2. Virtual drive: 20 linear moves per axis to train;
diamond, circle and 12 other moves to validate. Without feed-forward the pole search is the
thesis's rigid SISO model (`identify_siso`); with feed-forward two real poles and a complex pair
(`identify_mimo`, error output); flexible Y: 5th order with Table 7-3 bounds from tool-side position
and motor velocity. EMPS: trained on DATA_EMPS from `qg` and `qm`, validated on DATA_EMPS_PULSES
before its first force pulse (t ≤ 0.34 s). plant2 (`tests/plant2`): the stored default-path
models (`tests/data/plant2_*_default_model.json`), pole search only.

Sensitivity: every command sample moved by ±δ (random sign per sample); gain = max |change of the
predicted position| / δ, with the model's friction and with it switched off (the linear part
alone). A gain far larger at 1e-12 mm than at 1e-6 mm is a stick/slip decision that rounding
takes: feed an FMU the commands on the sample grid when runs are compared digit for digit."""

MODELS = ("pole search", "Full LS", "quasi-static")


def tables(res):
    """The markdown tables of a run's result: discrepancy per trace, then the sensitivity."""
    rows = []
    for trace, d in res["discrepancy_um"].items():
        ratio = (f"{d['pole search'] / d['Full LS']:.3f}×" if d.get("Full LS") else "")
        rows.append([trace] + [f"{d[k]:.3f}" if d.get(k) is not None else "" for k in MODELS] + [ratio])
    acc = md_table(["trace", *MODELS, "pole search / Full LS"], rows)
    g = res["perturbation_gain"]
    sens = md_table(["trace"] + [f"gain at δ = {d:g} mm" for d in g["delta_mm"]] + ["linear part alone"],
                    [[trace] + [f"{x:.3g}" for x in gains] + [f"{max(g['gain_without_friction'][trace]):.3g}"]
                     for trace, gains in g["gain"].items()])
    walls = md_table(["case", "identification wall [s]"],
                     [[k, f"{v:.1f}"] for k, v in res["identification_wall_s"].items() if v])
    return ["Free-run discrepancy RMS [µm]:\n\n" + acc, "Sensitivity to the commands:\n\n" + sens,
            "Identification time (pole search, Full LS and quasi-static together):\n\n" + walls]

if __name__ == "__main__":
    main()
