"""Identification speed and accuracy: wall time against samples and model order, the
batched regressor engine against a straightforward DE over scipy filters, and accuracy against
Full LS. Single core (BLAS threads pinned to 1). Writes benchmarks/results/bench_identify.json
and prints markdown tables.

    .venv/bin/python benchmarks/bench_identify.py [--quick]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy import optimize, signal  # noqa: E402

from fdid_fmi.identify import identify_full_ls, identify_mimo, identify_siso, mimo_structure  # noqa: E402
from fdid_fmi.identify import regressors as rg  # noqa: E402
from fdid_fmi.metrics import rms  # noqa: E402
from fdid_fmi.signals import measured_velocity  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine  # noqa: E402
from fdid_fmi.virtual import trajectories as tj  # noqa: E402
from timing import timed  # noqa: E402  (benchmarks/timing.py)

OUT = Path(__file__).resolve().parent / "results"


def training(n_samples, seed=1):
    """A one-axis Deckel-Maho-like trace of about n_samples (linear moves, no feed-forward)."""
    cfg = presets.deckel_maho_like()
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    moves = 2
    while True:
        path = tj.linear_moves(n_moves=moves, axes=("x",), Ts=cfg.Ts, seed=seed)
        if path.n >= n_samples:
            break
        moves = int(moves * 1.5) + 1
    tr = simulate_machine(one, path, seed=seed)
    return tr.slice(0, tr.t[0] + (n_samples - 1) * tr.Ts)


def naive_siso(tr, seed=0, maxiter=None):
    """The straightforward implementation the issue measured: scipy DE, every candidate filters
    each regressor through its own bilinear transfer function (lfilter), then lstsq."""
    Ts = tr.Ts
    xr, e = tr.cmd("x"), tr.error("x")
    v = measured_velocity(tr.act("x"), Ts, 1, "backward")
    nyq = 0.5 / Ts
    lo = np.array([np.log10(0.1), np.log10(0.5), 0.05, np.log10(1e-4 * np.max(np.abs(v)))])
    hi = np.array([np.log10(0.95 * nyq), np.log10(0.95 * nyq), 2.0, np.log10(0.3 * np.max(np.abs(v)))])

    def obj(x):
        a = rg.characteristic_polynomial([10 ** x[0]], [(10 ** x[1], x[2])])
        d = np.clip(v / 10 ** x[3], -1, 1)
        cols = []
        for power, sig in ((3, xr), (2, xr), (1, xr), (1, d)):
            num = np.zeros(4)
            num[3 - power] = 1.0
            b, ad = signal.bilinear(num, a, fs=1 / Ts)
            cols.append(signal.lfilter(b, ad, sig - sig[0]))
        M = np.column_stack(cols)
        th = np.linalg.lstsq(M, e, rcond=None)[0]
        return rms(e - M @ th)

    dim = 4
    return optimize.differential_evolution(obj, list(zip(lo, hi)), seed=seed, popsize=8,
                                           maxiter=maxiter or (40 + 10 * dim), tol=1e-7, init="sobol",
                                           polish=False, updating="deferred")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer sizes (a smoke run)")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    res = {"single_core": True, "siso_vs_samples": [], "order": [], "speedup": {}, "accuracy": []}

    sizes = [1000, 12000] if args.quick else [1000, 3000, 12000, 30000, 100000]
    for n in sizes:
        tr = training(n)
        t_search, m = timed(lambda: identify_siso(tr, "x", seed=0, refine=False))
        t_full, _ = timed(lambda: identify_siso(tr, "x", seed=0))
        res["siso_vs_samples"].append({"samples": tr.n, "search_s": t_search, "search_and_refine_s": t_full,
                                       "nfev": m.identification["search"]["nfev"]})

    tr = training(12000)
    for nr, nc in ((1, 1), (2, 1), (1, 2), (2, 2)):
        st = mimo_structure(("x",), ("error",), nr, nc)
        t, m = timed(lambda: identify_mimo(tr, st, seed=0, refine=False))
        res["order"].append({"order": nr + 2 * nc, "n_real": nr, "n_complex": nc, "search_s": t,
                             "nfev": m.identification["search"]["nfev"]})

    t_fast, m_fast = timed(lambda: identify_siso(tr, "x", seed=0, refine=False))
    t_naive, r_naive = timed(lambda: naive_siso(tr, seed=0))
    res["speedup"] = {"samples": tr.n, "engine_s": t_fast, "straightforward_s": t_naive,
                      "ratio": t_naive / t_fast, "engine_nfev": m_fast.identification["search"]["nfev"],
                      "straightforward_nfev": int(r_naive.nfev)}

    cfg = presets.deckel_maho_like()
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    vals = {"diamond": simulate_machine(cfg, tj.diamond(Ts=cfg.Ts), seed=2),
            "circle": simulate_machine(cfg, tj.circle(Ts=cfg.Ts), seed=3),
            "moves": simulate_machine(one, tj.linear_moves(n_moves=12, axes=("x",), Ts=cfg.Ts, seed=7), seed=4)}
    train = simulate_machine(one, tj.linear_moves(n_moves=20, axes=("x",), Ts=cfg.Ts, seed=1), seed=1)
    ps = identify_siso(train, "x", seed=0)
    fl = identify_full_ls(train, "x")
    for name, v in vals.items():
        e = v.error("x")
        d_ps = rms(simulate(ps, v).axes["x"]["error"] - e)
        d_fl = rms(simulate(fl, v).axes["x"]["error"] - e)
        res["accuracy"].append({"trace": name, "error_rms_um": rms(e) * 1e3, "pole_search_um": d_ps * 1e3,
                                "full_ls_um": d_fl * 1e3, "pole_search_pct_of_rms": 100 * d_ps / rms(e),
                                "ratio_to_full_ls": d_ps / d_fl})

    (OUT / "bench_identify.json").write_text(json.dumps(res, indent=1))
    print("\n### SISO pole search (poles + v_tilde searched), one core\n")
    print("| samples | search [s] | search + friction refinement [s] | evaluations |\n|---:|---:|---:|---:|")
    for r in res["siso_vs_samples"]:
        print(f"| {r['samples']} | {r['search_s']:.2f} | {r['search_and_refine_s']:.2f} | {r['nfev']} |")
    print("\n### Model order (12k samples, search only)\n")
    print("| order | real | complex | search [s] | evaluations |\n|---:|---:|---:|---:|---:|")
    for r in res["order"]:
        print(f"| {r['order']} | {r['n_real']} | {r['n_complex']} | {r['search_s']:.2f} | {r['nfev']} |")
    s = res["speedup"]
    print(f"\n### Engine against a straightforward DE over scipy filters ({s['samples']} samples)\n")
    print("| implementation | time [s] | evaluations | ms / evaluation |\n|---|---:|---:|---:|")
    print(f"| batched all-pole filter + FIR regressors | {s['engine_s']:.2f} | {s['engine_nfev']} | "
          f"{1e3 * s['engine_s'] / s['engine_nfev']:.3f} |")
    print(f"| one bilinear lfilter per regressor + lstsq | {s['straightforward_s']:.2f} | "
          f"{s['straightforward_nfev']} | {1e3 * s['straightforward_s'] / s['straightforward_nfev']:.3f} |")
    print(f"\nspeed-up: {s['ratio']:.1f}x (same run, same machine)")
    print("\n### Accuracy on unseen trajectories (virtual Deckel-Maho-like X axis, no feed-forward)\n")
    print("| trace | e RMS [µm] | pole search [µm] | % of RMS | Full LS [µm] | ratio |\n|---|---:|---:|---:|---:|---:|")
    for r in res["accuracy"]:
        print(f"| {r['trace']} | {r['error_rms_um']:.1f} | {r['pole_search_um']:.3f} | "
              f"{r['pole_search_pct_of_rms']:.3f} | {r['full_ls_um']:.3f} | {r['ratio_to_full_ls']:.3f} |")
    print(f"\nJSON: {OUT / 'bench_identify.json'}")


if __name__ == "__main__":
    main()
