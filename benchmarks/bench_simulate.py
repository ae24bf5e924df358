"""Reference simulation speed: the compiled core against the pure-Python step.

The free run of a DriveModel is ``fmu_templates/fdid_core.c`` built into the package
(``fdid_fmi._kernel``); a numpy/Python loop runs 0.1-0.2 M samples/s. That Python loop is kept
as the test oracle (``tests/sim_oracle.py``), so both are timed side by side
in one run, on the same models and commands (single core, BLAS threads pinned to 1):

- a 3rd-order axis with friction (the thesis's rigid-body model, hand-built, causal);
- an identified causal pole-search axis (virtual drive, no feed-forward);
- the two-axis coupled model with two friction inputs.

The compiled core is timed as best of 3 after one warm-up run (the first run of a process also
pays the operating system's page faults of its fresh output arrays, 20-25 % on 2 M samples;
identification and fleets call it many times).

    .venv/bin/python benchmarks/bench_simulate.py [--quick]

Writes benchmarks/results/bench_simulate.json and prints a table (samples/s; target for the
compiled core: >= 10 M samples/s on the 3rd-order axis).
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))          # the oracle and the hand-built models

import fmu_support as fs  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from sim_oracle import oracle_simulate  # noqa: E402
from publish import command, md_table, publish, publishable, report  # noqa: E402
from timing import timed  # noqa: E402

OUT = HERE / "results" / "bench_simulate.json"


def identified_axis():
    from fdid_fmi.identify import identify_siso
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    tr = simulate_machine(one, tj.linear_moves(n_moves=8, axes=("x",), Ts=cfg.Ts, seed=1), seed=1)
    return identify_siso(tr, "x", seed=0, maxiter=20)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    n_fast, n_slow = (200_000, 5_000) if a.quick else (2_000_000, 20_000)
    cases = [("3rd-order axis + friction (hand-built)", fs.siso_model()),
             ("identified pole-search axis (virtual, no FF)", identified_axis()),
             ("coupled X/Y, 2 friction inputs", fs.coupled_model())]
    rows = []
    for name, m in cases:
        rng = np.random.default_rng(0)
        cmd_fast = {ax: fs.smooth_moves(n_fast, rng, start=1.0 + i) for i, ax in enumerate(m.axes)}
        cmd_slow = {ax: c[:n_slow] for ax, c in cmd_fast.items()}
        simulate(m, cmd_fast, Ts=m.Ts)      # warm-up: the first run also page-faults its fresh arrays
        t_c, res = timed(lambda: simulate(m, cmd_fast, Ts=m.Ts), 3)
        t_py, ref = timed(lambda: oracle_simulate(m, cmd_slow, Ts=m.Ts), 1)
        c_c, _ = timed(lambda: simulate(m, cmd_fast, Ts=m.Ts), 3, clock=time.process_time)
        c_py, _ = timed(lambda: oracle_simulate(m, cmd_slow, Ts=m.Ts), 1, clock=time.process_time)
        same = bool(np.array_equal(res.y[:n_slow], ref.y))
        rows.append(dict(case=name, states=m.n_states, compiled_samples=n_fast, compiled_s=t_c,
                         compiled_samples_per_s=n_fast / t_c, python_samples=n_slow, python_s=t_py,
                         python_samples_per_s=n_slow / t_py, speedup=(n_fast / t_c) / (n_slow / t_py),
                         compiled_cpu_samples_per_s=n_fast / c_c, python_cpu_samples_per_s=n_slow / c_py,
                         identical_outputs=same))
    res = {"rows": rows, "quick": a.quick}
    report(OUT, res, tables(res))
    if publishable(ap, a):
        publish("simulate", "Simulation speed", tables(res), command("simulate"), res,
                notes="Samples per second of the free run through `fdid_fmi.simulate.simulate` (the compiled "
                      "core, best of 3 after a warm-up) against the pure-Python loop kept as the test oracle, "
                      "on the same models and commands, one core (BLAS on one thread); outputs written for "
                      "every sample. Times depend on what else runs on the machine.")


def tables(res):
    """The markdown table of a run's result."""
    return [md_table(
        ["model", "states", "compiled core: wall / CPU [samples/s]", "Python loop: wall / CPU [samples/s]",
         "ratio (wall)", "same doubles"],
        [[r["case"], r["states"], f"{r['compiled_samples_per_s'] / 1e6:.1f} M / "
          f"{r['compiled_cpu_samples_per_s'] / 1e6:.1f} M", f"{r['python_samples_per_s'] / 1e3:.0f} k / "
          f"{r['python_cpu_samples_per_s'] / 1e3:.0f} k", f"{r['speedup']:.0f}×",
          "yes" if r["identical_outputs"] else "no"] for r in res["rows"]],
        ["l", "r", "r", "r", "r", "l"])]

if __name__ == "__main__":
    main()
