"""Speed and size of the exported FMUs (not a unit test).

Run:  .venv/bin/python benchmarks/bench_fmu.py [--quick]
Writes benchmarks/results/bench_fmu.json and prints a markdown table.

For each model (the identified EMPS pole-search model when ../shared/data is present, and the
hand-built coupled two-axis model of the tests) it measures steps per second of
- the C FMU driven by a C host (tests/c_host/host.c: dlopen, setReal/getReal/doStep per step),
- the C FMU through fmpy's FMU2Slave (Python loop, one setReal/getReal/doStep per step),
- the C FMU through fmpy with one doStep of 1000 samples (the internal loop alone),
- the pythonfmu FMU of the same model through fmpy,
- the numpy reference simulator,
and the size of each FMU file.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import fmu_support as fs  # noqa: E402
from fmu_support.host import build_host, run_host  # noqa: E402

from fdid_fmi.fmu import export_fmu  # noqa: E402
from fdid_fmi.fmu.build import compiler_available  # noqa: E402
from fdid_fmi.fmu.validate import FmuRunner  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "bench_fmu.json"


def models():
    out = {"coupled 2-axis (hand-built)": fs.coupled_model()}
    data = ROOT.parent / "shared" / "data" / "emps" / "DATA_EMPS.mat"
    if data.is_file():
        from fdid_fmi.identify import identify_siso
        from fdid_fmi.io import read_trace
        out = {"EMPS SISO (pole search)": identify_siso(read_trace(data), "x", integral_action=False,
                                                        seed=0), **out}
    return out


def fmpy_rate(fmu, cmds, Ts, n, outs, block=1):
    r = FmuRunner(fmu)
    try:
        f = r.fmu
        in_vr = [r.vr(f"{a}_x_cmd") for a in cmds]
        out_vr = [r.vr(o) for o in outs]
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.setReal(in_vr, [c[0] for c in cmds.values()])
        f.exitInitializationMode()
        U = np.column_stack(list(cmds.values()))
        t0 = time.perf_counter()
        k = 0
        while k < n:
            f.setReal(in_vr, list(U[k]))
            f.getReal(out_vr)
            f.doStep(k * Ts, block * Ts)
            k += block
        dt = time.perf_counter() - t0
        f.terminate()
        return k / dt
    finally:
        r.close()


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer steps")
    args = ap.parse_args(argv)
    n_c, n_py = (200_000, 5_000) if args.quick else (2_000_000, 30_000)
    tmp = Path(tempfile.mkdtemp(prefix="bench_fmu_"))
    host = build_host(tmp)
    rows = []
    for name, m in models().items():
        ident = "bench_" + str(len(rows))
        rng = np.random.default_rng(0)
        cmds = {a: fs.smooth_moves(n_py, rng, start=5.0 + i) for i, a in enumerate(m.axes)}
        outs = [f"{a}_{k}" for a in m.axes for k in ("x", "e", "v")]
        fmu = export_fmu(m, tmp / f"{ident}.fmu", model_identifier=ident)
        sizes = {"c_fmi2_linux64_kib": fmu.stat().st_size / 1024}
        if compiler_available("win64"):
            f2 = export_fmu(m, tmp / f"{ident}w.fmu", platforms=("linux64", "win64"), model_identifier=ident)
            sizes["c_fmi2_linux64_win64_kib"] = f2.stat().st_size / 1024
        f3 = export_fmu(m, tmp / f"{ident}3.fmu", fmi_version=3, model_identifier=ident)
        sizes["c_fmi3_linux64_kib"] = f3.stat().st_size / 1024
        pyfmu = export_fmu(m, tmp / f"{ident}py.fmu", backend="python", model_identifier=ident)
        sizes["pythonfmu_kib"] = pyfmu.stat().st_size / 1024
        # C host: repeat the command record up to n_c steps
        reps = int(np.ceil(n_c / n_py))
        long = {f"{a}_x_cmd": np.tile(c, reps)[:n_c] for a, c in cmds.items()}
        proc, _ = run_host(host, fmu, long, outs, m.Ts, mode="bench")
        if proc.returncode != 0:
            raise RuntimeError(proc.stderr)
        c_rate = float(proc.stdout.split()[1])
        rates = {
            "c_host": c_rate,
            "fmpy": fmpy_rate(fmu, cmds, m.Ts, n_py, outs),
            "fmpy_block1000": fmpy_rate(fmu, {a: np.tile(c, 20) for a, c in cmds.items()}, m.Ts,
                                        20 * n_py, outs, block=1000),
            "pythonfmu_fmpy": fmpy_rate(pyfmu, {a: c[: n_py // 5] for a, c in cmds.items()}, m.Ts,
                                        n_py // 5, outs),
        }
        t0 = time.perf_counter()
        simulate(m, cmds, Ts=m.Ts)
        rates["numpy_reference"] = n_py / (time.perf_counter() - t0)
        rows.append({"model": name, "states": m.n_states, "inputs": len(m.inputs),
                     "outputs": len(m.outputs), "steps_per_second": rates, "fmu_size": sizes})
    result = {"machine": platform.platform(), "python": platform.python_version(), "rows": rows,
              "notes": "steps/s: one setReal + getReal + doStep(Ts) per step unless noted; "
                       "fmpy_block1000 = doStep over 1000 internal steps per call"}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(result, indent=1))
    print("| model | states | C host | fmpy | fmpy, 1000-step doStep | pythonfmu (fmpy) | numpy reference "
          "| FMU size C FMI2 (linux64 / +win64) | C FMI3 | pythonfmu |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        s, z = r["steps_per_second"], r["fmu_size"]
        both = f"{z['c_fmi2_linux64_kib']:.0f} / {z.get('c_fmi2_linux64_win64_kib', float('nan')):.0f} KiB"
        print(f"| {r['model']} | {r['states']} | {s['c_host']:.3g} | {s['fmpy']:.3g} | "
              f"{s['fmpy_block1000']:.3g} | {s['pythonfmu_fmpy']:.3g} | {s['numpy_reference']:.3g} | "
              f"{both} | {z['c_fmi3_linux64_kib']:.0f} KiB | {z['pythonfmu_kib']:.0f} KiB |")
    print(f"\nsteps per second; results in {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
