"""Accuracy of the alignment chain against the virtual drive's truth, over random mountings and
clocks (not a unit test; tests/test_align_virtual.py checks one case per acceptance item).

Run:  .venv/bin/python benchmarks/bench_align.py [--seeds N] [--modes M]
Per seed: a calibration run of the ``flexible_y`` machine (X and Y moved one at a time, 16 moves,
~9 s) written as controller / accelerometer (5 kHz) / KGM (1 kHz) files with random mounting
angles, biases, start delays and clock drifts, then aligned with fdid_fmi.align.align. For the
first M seeds also a Y-only identification run (20 moves) aligned with the calibration's
orientation, and the tool-side mode identified from the aligned acceleration and from the
perfectly aligned simulated trace (5th order, Table 7-3 bounds, double integrator, 2nd-order
d.c.-gain constraint). Writes benchmarks/results/bench_align.json and prints the worst errors.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from fdid_fmi.align import align, read_accelerometer, read_grid_encoder
from fdid_fmi.identify import Bounds, identify_mimo, mimo_structure
from fdid_fmi.io import read_trace
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fdid_fmi.virtual.sensors import AccelerometerTruth, GridEncoderTruth, write_raw_run

OUT = Path(__file__).resolve().parent / "results" / "bench_align.json"
CFG = presets.flexible_y()
TS = CFG.Ts


def truths(seed):
    r = np.random.default_rng(1000 + seed)
    acc = AccelerometerTruth(alpha_deg=r.uniform(-10, 10), beta_deg=r.uniform(-7, 7),
                             gamma_deg=r.uniform(-3, 3), bias=tuple(r.uniform(-300, 300, 3)),
                             start_s=r.uniform(-4, -0.5), drift_ppm=r.uniform(-100, 100))
    kgm = GridEncoderTruth(angle_deg=r.uniform(-1, 1), offset_mm=tuple(r.uniform(-50, 50, 2)),
                           start_s=r.uniform(-3, -0.2), drift_ppm=r.uniform(-100, 100))
    return acc, kgm


def run_align(run, **kw):
    return align(read_trace(run["controller"]),
                 [read_accelerometer(run["sensors"]["acc_tool"], axes=("x", "y")),
                  read_grid_encoder(run["sensors"]["kgm"])], **kw)


def errors(run, res, acc, kgm):
    s, k = res.sensor("acc_tool"), res.sensor("kgm")
    m, T = run["motion"], res.trace
    out = {"offset_acc_samples": abs(s.get("time_offset").value - acc.start_s) / TS,
           "offset_kgm_samples": abs(k.get("time_offset").value - kgm.start_s) / TS,
           "drift_acc_ppm": abs(s.get("clock_drift").value - acc.drift_ppm),
           "drift_kgm_ppm": abs(k.get("clock_drift").value - kgm.drift_ppm),
           "kgm_angle_deg": abs(k.get("angle").value - kgm.angle_deg),
           "kgm_origin_um": 1e3 * float(np.max(np.abs(np.array(k.get("origin").value) - kgm.offset_mm))),
           "tool_pos_rms_um": 1e3 * max(float(np.sqrt(np.mean((T.get(a, "tool") - m.pos(a, T.t)) ** 2)))
                                        for a in T.axes if T.has(a, "tool")),
           "acc_rms_over_noise": max(float(np.sqrt(np.mean((T.get(a, "acc") - m.acc(a, T.t)) ** 2)))
                                     for a in T.axes if T.has(a, "acc"))
                                 / (acc.noise * np.sqrt(res.settings["aa_cutoff_hz"] / (0.5 * acc.rate_hz)))}
    if s.rotation is not None and "alpha" in [e.name for e in s.estimates]:
        out["angle_deg"] = max(abs(s.get(n).value - getattr(acc, f"{n}_deg")) for n in ("alpha", "beta", "gamma"))
        out["bias_mm_s2"] = float(np.max(np.abs(np.array(s.get("bias").value) - acc.bias)))
    out["missing"] = res.missing
    return out


def mode_of(trace):
    nyq = 0.5 / TS
    b = Bounds(real_hz=[(0.02, nyq)], omega_hz=[(0.02, nyq), (20.0, 40.0)], zeta=[(0.01, 4.0), (0.001, 0.5)])
    st = mimo_structure(("y",), ("acceleration",), 1, 2, integrators={"acceleration": 2},
                        dc_gain={"acceleration": (2, 1.0)})
    m = identify_mimo(trace, st, bounds=b, seed=0, maxiter=40)
    return [p for p in m.identification["complex_hz_zeta"] if 20 <= p[0] <= 40][0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--modes", type=int, default=2)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.seeds):
            acc, kgm = truths(seed)
            sim = simulate_machine(CFG, tj.linear_moves(n_moves=16, axes=("x", "y"), Ts=TS, seed=seed + 3),
                                   seed=seed)
            run = write_raw_run(sim, Path(tmp) / f"cal{seed}", [acc], [kgm], seed=seed)
            t0 = time.process_time()
            cal = run_align(run)
            row = {"seed": seed, "align_cpu_s": time.process_time() - t0, "calibration": errors(run, cal, acc, kgm)}
            if seed < args.modes:
                one = MachineConfig(axes=[CFG.axis("y")], Ts=TS)
                ysim = simulate_machine(one, tj.linear_moves(n_moves=20, axes=("y",), Ts=TS, seed=seed + 1),
                                        seed=seed + 1)
                acc2 = dataclasses.replace(acc, start_s=acc.start_s - 0.7, drift_ppm=acc.drift_ppm + 15,
                                           bias=tuple(np.array(acc.bias) * 0.8))
                kgm2 = dataclasses.replace(kgm, start_s=kgm.start_s - 0.3)
                yr = write_raw_run(ysim, Path(tmp) / f"y{seed}", [acc2], [kgm2], seed=seed + 50)
                yres = run_align(yr, orientation=cal)
                row["yrun"] = errors(yr, yres, acc2, kgm2)
                fa, za = mode_of(yres.trace)
                fp, zp = mode_of(ysim)
                tm = ysim.meta["truth"]["linear"]["continuous"]["modes"]["y"]
                row["mode"] = {"aligned_hz": fa, "aligned_zeta": za, "perfect_hz": fp, "perfect_zeta": zp,
                               "truth_hz": tm["hz"], "truth_zeta": tm["zeta"],
                               "aligned_err_pct": 100 * abs(fa / tm["hz"] - 1),
                               "aligned_vs_perfect_pct": 100 * abs(fa / fp - 1)}
            rows.append(row)
            print(json.dumps(row, default=float))
    keys = [k for k in rows[0]["calibration"] if k != "missing"]
    worst = {k: max(r["calibration"][k] for r in rows if k in r["calibration"]) for k in keys}
    ywor = {k: max(r["yrun"][k] for r in rows if "yrun" in r and k in r["yrun"]) for k in keys
            if any("yrun" in r and k in r["yrun"] for r in rows)}
    modes = [r["mode"] for r in rows if "mode" in r]
    print("\nworst over", len(rows), "calibration runs:")
    for k, v in worst.items():
        print(f"  {k:22s} {v:.4g}   (y run: {ywor.get(k, float('nan')):.4g})")
    for md in modes:
        print(f"  mode: aligned {md['aligned_hz']:.3f} Hz / {md['aligned_zeta']:.4f}, perfect "
              f"{md['perfect_hz']:.3f} / {md['perfect_zeta']:.4f}, truth {md['truth_hz']:.3f} / "
              f"{md['truth_zeta']:.4f} (closed loop)")
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps({"rows": rows, "worst_calibration": worst, "worst_yrun": ywor}, indent=1,
                              default=float))
    print(f"written {OUT}")


if __name__ == "__main__":
    main()
