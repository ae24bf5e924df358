"""At rest: how far the twin moves in the 5 s after a stop, against how far the plant itself does
(no creep unless the data show it; docs/decisions/rest-behaviour.md).

Two plants that share no code: the virtual drive (``fdid_fmi.virtual``; stiction holds its axis,
the measured encoder of 0.1 µm is what it shows) and plant2 (``tests/plant2``; LuGre friction
with presliding, whose true motor position settles for seconds after a stop). On each, twins are
identified from the training moves as in docs/results/accuracy.md (seed 0): the rigid SISO
pole search without feed-forward, two real poles and a complex pair with it. Each twin and its
plant then run the same commands: three linear moves (seeds 5, 6, 7), then 5 s at rest.

    .venv/bin/python benchmarks/bench_rest.py

Writes benchmarks/results/bench_rest.json and prints a table: the drift over the 5 s in nm/s
(|x(5 s) - x(0)| / 5 s) of the twin and of the plant, and the twin's end position minus the
plant's, relative to where each stopped, in µm.
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

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import plant2 as p2  # noqa: E402
from publish import about, command, md_table, publish  # noqa: E402
from plant2.plant import simulate_axis  # noqa: E402
from plant2.scenarios import SCENARIOS  # noqa: E402

from fdid_fmi.identify import identify_mimo, identify_siso, mimo_structure  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine  # noqa: E402
from fdid_fmi.virtual import trajectories as tj  # noqa: E402

OUT = HERE / "results" / "bench_rest.json"
SEEDS = (5, 6, 7)
REST_S = 5.0


def identify(train, ax, feedforward):
    if feedforward:
        return identify_mimo(train, mimo_structure((ax,), ("error",), n_real=2, n_complex=1), seed=0)
    return identify_siso(train, ax, seed=0)


def rest_command(ax, Ts, seed):
    mv = tj.linear_moves(n_moves=3, axes=(ax,), Ts=Ts, seed=seed)[ax]
    return mv.size, np.concatenate([mv, np.full(int(REST_S / Ts), mv[-1])])


def drift(x):
    """(nm/s over the rest, displacement in µm) of a position record that starts at the stop."""
    d = float(x[-1] - x[0])
    return abs(d) / REST_S * 1e6, d * 1e3


def virtual_case(ax, feedforward):
    cfg = presets.with_feedforward() if feedforward else presets.deckel_maho_like()
    one = MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts)
    train = simulate_machine(one, tj.linear_moves(n_moves=20, axes=(ax,), Ts=cfg.Ts, seed=1), seed=1)
    model = identify(train, ax, feedforward)

    def plant(cmd, seed):
        return simulate_machine(one, {ax: cmd}, seed=seed, truth=False).act(ax)
    return model, cfg.Ts, plant


def plant2_case(name, feedforward):
    train, _, truth = p2.scenario(name)
    ax = truth["axis"]
    model = identify(train[0], ax, feedforward)
    machine = SCENARIOS[name][0]()

    def plant(cmd, seed):
        return simulate_axis(machine.axis(ax), machine.Ts, cmd, np.random.default_rng(seed),
                             drive_period=machine.drive_period)["motor"]
    return model, machine.Ts, plant, ax


def measure(label, model, Ts, plant, ax):
    rows = []
    for seed in SEEDS:
        k, cmd = rest_command(ax, Ts, seed)
        twin = simulate(model, {ax: cmd}, Ts=Ts).axes[ax]["position"][k:]
        real = plant(cmd, seed)[k:]
        (vt, dt), (vp, dp) = drift(twin), drift(real)
        rows.append({"seed": seed, "twin_nm_s": vt, "plant_nm_s": vp, "end_difference_um": dt - dp})
    print(f"| {label} | " + " / ".join(f"{r['twin_nm_s']:.1f}" for r in rows) + " | "
          + " / ".join(f"{r['plant_nm_s']:.1f}" for r in rows) + " | "
          + " / ".join(f"{r['end_difference_um']:+.3f}" for r in rows) + " |", flush=True)
    return {"case": label, "axis": ax, "Ts": Ts, "rows": rows}


def main():
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    print("| plant, twin | twin drift [nm/s] | plant drift [nm/s] | twin - plant after 5 s [µm] |")
    print("|---|---|---|---|")
    cases = []
    for ax in ("x", "y"):
        for ff in (False, True):
            model, Ts, plant = virtual_case(ax, ff)
            label = f"virtual {ax}, {'FF, r2c1' if ff else 'no FF, rigid'}"
            cases.append(measure(label, model, Ts, plant, ax))
    for name, ff in (("clean_rigid", False), ("clean_rigid_2ms", False), ("clean_ff", True)):
        model, Ts, plant, ax = plant2_case(name, ff)
        cases.append(measure(f"plant2 {name}, {'r2c1' if ff else 'rigid'}", model, Ts, plant, ax))
    res = {"rest_s": REST_S, "seeds": SEEDS, "cases": cases, "wall_s": time.perf_counter() - t0}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=2))
    print(f"wrote {OUT} ({time.perf_counter() - t0:.0f} s)")
    publish("rest", "At rest: twin against plant after a stop", tables(res), command("rest"), res,
            notes=about(__doc__))


def tables(res):
    """The markdown table of a run's result."""
    return [md_table(["plant, twin", "twin drift [nm/s]", "plant drift [nm/s]", "twin − plant after 5 s [µm]"],
                     [[c["case"], " / ".join(f"{r['twin_nm_s']:.1f}" for r in c["rows"]),
                       " / ".join(f"{r['plant_nm_s']:.1f}" for r in c["rows"]),
                       " / ".join(f"{r['end_difference_um']:+.3f}" for r in c["rows"])] for c in res["cases"]],
                     ["l", "r", "r", "r"])]


if __name__ == "__main__":
    main()
