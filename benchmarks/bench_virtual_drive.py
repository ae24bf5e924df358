"""Speed of the virtual feed drive (not a unit test).

Run:  .venv/bin/python benchmarks/bench_virtual_drive.py [--quick]
Writes benchmarks/results/bench_virtual_drive.json and prints a table of samples/s.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from timing import timed  # benchmarks/timing.py

from fdid_fmi.virtual import (MachineConfig, PRESETS, circle, linear_moves, linear_truth,
                              simulate_machine)

OUT = Path(__file__).resolve().parent / "results" / "bench_virtual_drive.json"


def linearised(cfg):
    for a in cfg.axes:
        a.coulomb, a.coulomb_neg, a.stribeck = 0.0, None, 0.0
        a.resolution, a.force_offset = 0.0, 0.0
    return cfg


def one_axis(cfg):
    return MachineConfig([cfg.axes[0]], Ts=cfg.Ts, n_sub=cfg.n_sub, name=cfg.name + "_x")


def cmd_for(cfg, n, seed=0):
    """A pseudo-random move sequence of at least n samples, cut to n."""
    moves = max(4, int(n * cfg.Ts / 0.6))
    tr = linear_moves(n_moves=moves, axes=tuple(cfg.axis_names), v=100, acc=2000, jerk=1e5,
                      Ts=cfg.Ts, seed=seed)
    while tr.n < n:
        moves *= 2
        tr = linear_moves(n_moves=moves, axes=tuple(cfg.axis_names), v=100, acc=2000, jerk=1e5,
                          Ts=cfg.Ts, seed=seed)
    return {a: tr[a][:n] for a in cfg.axis_names}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 100k-sample cases")
    args = ap.parse_args()
    cases = [
        ("emps_like (1 axis, friction)", lambda: PRESETS["emps_like"](), 12000),
        ("deckel_maho_like X only, linear", lambda: linearised(one_axis(PRESETS["deckel_maho_like"]())), 12000),
        ("deckel_maho_like X only, friction", lambda: one_axis(PRESETS["deckel_maho_like"]()), 12000),
        ("with_feedforward X only (Stribeck)", lambda: one_axis(PRESETS["with_feedforward"]()), 12000),
        ("deckel_maho_like X+Y, friction", lambda: PRESETS["deckel_maho_like"](), 12000),
        ("flexible_y X+Y (two-mass Y)", lambda: PRESETS["flexible_y"](), 12000),
        ("coupled_xy X+Y", lambda: PRESETS["coupled_xy"](), 12000),
    ]
    if not args.quick:
        cases += [("emps_like (1 axis, friction)", lambda: PRESETS["emps_like"](), 100000),
                  ("flexible_y X+Y (two-mass Y)", lambda: PRESETS["flexible_y"](), 100000)]
    rows = []
    for name, make, n in cases:
        cfg = make()
        cmd = cmd_for(cfg, n)
        sim_s, out = timed(lambda: simulate_machine(cfg, cmd, truth=False), 3 if n <= 12000 else 1)
        truth_s, _ = timed(lambda: linear_truth(cfg), 3)
        steps = out.meta["truth"]["steps"]
        rows.append(dict(case=name, samples=n, axes=len(cfg.axes), Ts=cfg.Ts, sim_s=sim_s,
                         samples_per_s=n / sim_s, truth_s=truth_s, split_samples=steps["split_into_sub_steps"],
                         n_sub=cfg.n_sub))
    t0 = time.perf_counter()
    tr = circle(radius=20, v=100, acc=2000, jerk=1e5, Ts=1e-3, turns=20)
    traj_s = time.perf_counter() - t0
    result = {"python": platform.python_version(), "machine": platform.machine(),
              "processor": platform.processor(), "numpy": np.__version__, "rows": rows,
              "trajectory": {"case": "circle 20 turns", "samples": tr.n, "seconds": traj_s}}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(result, indent=2))
    print(f"{'case':40s} {'N':>7s} {'axes':>4s} {'sim s':>7s} {'samples/s':>10s} {'truth s':>7s} {'split':>6s}")
    for r in rows:
        print(f"{r['case']:40s} {r['samples']:7d} {r['axes']:4d} {r['sim_s']:7.3f} {r['samples_per_s']:10.0f} "
              f"{r['truth_s']:7.3f} {r['split_samples']:6d}")
    print(f"trajectory: circle, {tr.n} samples in {traj_s:.3f} s")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
