"""The planner's workflow end to end on the virtual Deckel-Maho-like machine.

    .venv/bin/python benchmarks/bench_plan.py [--tol 0.02]

1. identify a pole-search model of each axis from linear moves (as `fdid demo`);
2. for each example program (examples/*.nc): interpolate (100 mm/s, 2000 mm/s^2, 1e5 mm/s^3),
   predict the contour error per block with the model and with its FMU (fmpy.simulate_fmu), and
   compare with the virtual drive itself on the same commanded positions (RMS and MAX per block);
3. optimise the feeds of examples/pocket_corner.nc for --tol and check the result on the virtual
   drive; cycle times: programmed, per-block feeds, one uniform override.
Writes benchmarks/results/bench_plan.json and prints the tables.
"""
import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from publish import command, md_table, publish, publishable
from timing import timed

from fdid_fmi.identify import identify_siso
from fdid_fmi.fmu import export_fmu
from fdid_fmi.model import DriveModel
from fdid_fmi.plan import read_program
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.optimize import optimize_feeds
from fdid_fmi.plan.predict import predict, signed_contour_error
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj

ROOT = Path(__file__).resolve().parents[1]
LIMITS = {a: AxisLimits(100.0, 2000.0, 1e5) for a in "xyz"}


def virtual_contour(cfg, ip):
    tr = simulate_machine(cfg, {a: ip.positions[a] for a in ("x", "y")}, seed=1)
    return signed_contour_error(np.column_stack([ip.positions["x"], ip.positions["y"]]),
                                np.column_stack([tr.act("x"), tr.act("y")]))


def per_block(ip, c):
    out = []
    for b in range(len(ip.spans)):
        sel = ip.block_of_sample == b
        out.append((float(np.sqrt(np.mean(c[sel] ** 2))) * 1e3, float(np.abs(c[sel]).max()) * 1e3)
                   if sel.any() else (0.0, 0.0))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tol", type=float, default=0.02)
    args = ap.parse_args()
    cfg = presets.deckel_maho_like()
    ms = []
    for ax in ("x", "y"):
        tr = simulate_machine(MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts),
                              tj.linear_moves(n_moves=20, axes=(ax,), Ts=cfg.Ts, seed=1), seed=1)
        ms.append(identify_siso(tr, ax, seed=0))
    model = DriveModel.combine(ms, method="pole-search")
    tmp = Path(tempfile.mkdtemp(prefix="bench_plan_"))
    fmu = export_fmu(model, tmp / "drive.fmu")
    results = {"tol_mm": args.tol, "programs": {}}
    print("| program | block | line | kind | virtual RMS / MAX [µm] | model RMS / MAX [µm] | FMU RMS / MAX [µm] | worst deviation [%] |")
    print("|---|---:|---:|---|---:|---:|---:|---:|")
    for nc in sorted((ROOT / "examples").glob("*.nc")):
        prog = read_program(nc)
        ip = interpolate(prog, LIMITS, model.Ts)
        t_model, pm = timed(lambda: predict(ip, model=model, program=prog))
        t_fmu, pf = timed(lambda: predict(ip, fmu=fmu, program=prog))
        tv = per_block(ip, virtual_contour(cfg, ip))
        bm, bf = per_block(ip, pm.contour), per_block(ip, pf.contour)
        rows = []
        for b, v, m, f in zip(prog.blocks, tv, bm, bf):
            dev = max((abs(m[i] - v[i]) / v[i] * 100 if v[i] > 5 else 0.0) for i in (0, 1))
            devf = max((abs(f[i] - v[i]) / v[i] * 100 if v[i] > 5 else 0.0) for i in (0, 1))
            rows.append({"block": b.index + 1, "line": b.line, "kind": b.kind, "virtual": v, "model": m,
                         "fmu": f, "deviation_pct": dev, "deviation_fmu_pct": devf})
            print(f"| {nc.name} | {b.index + 1} | {b.line} | {b.kind} | {v[0]:.2f} / {v[1]:.2f} | {m[0]:.2f} / {m[1]:.2f} | "
                  f"{f[0]:.2f} / {f[1]:.2f} | {max(dev, devf):.1f} |")
        results["programs"][nc.name] = {"blocks": rows, "cycle_time_s": ip.cycle_time, "samples": ip.n,
                                        "predict_model_s": t_model, "predict_fmu_s": t_fmu}
    prog = read_program(ROOT / "examples" / "pocket_corner.nc")
    t_opt, fpl = timed(lambda: optimize_feeds(prog, LIMITS, model.Ts, args.tol, model=model, progress=True))
    ip2 = interpolate(prog, LIMITS, model.Ts, overrides=fpl.overrides)
    virt_after = float(np.abs(virtual_contour(cfg, ip2)).max()) * 1e3
    print(f"\nfeed optimisation of pocket_corner.nc, tol {args.tol * 1e3:g} µm ({t_opt:.1f} s, {fpl.iterations} twin runs)")
    print("| block | line | feed [mm/min] | first pass [mm/min] | new feed [mm/min] | contour MAX before / after [µm] | time before / after [s] |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for r in fpl.rows:
        print(f"| {r['block']} | {r['line']} | {r['feed_mm_min']:.0f} | {r['first_pass_mm_min']:.0f} | "
              f"{r['new_feed_mm_min']:.0f} | {r['contour_max_before_um']:.2f} / {r['contour_max_after_um']:.2f} | "
              f"{r['time_before_s']:.3f} / {r['time_after_s']:.3f} |")
    print(f"cycle time: programmed {fpl.before.interp.cycle_time:.3f} s (contour MAX "
          f"{fpl.before.summary['contour_max_um']:.1f} µm), per-block feeds {fpl.after.interp.cycle_time:.3f} s "
          f"(twin {fpl.after.summary['contour_max_um']:.2f} µm, virtual drive {virt_after:.2f} µm), uniform override "
          f"{100 * fpl.uniform_override:.1f} %: {fpl.uniform_cycle_time_s:.3f} s ({fpl.uniform_max_contour_um:.2f} µm)")
    results["optimisation"] = {"rows": fpl.rows, "cycle_programmed_s": fpl.before.interp.cycle_time,
                               "cycle_optimised_s": fpl.after.interp.cycle_time,
                               "cycle_uniform_s": fpl.uniform_cycle_time_s, "uniform_override": fpl.uniform_override,
                               "max_after_model_um": fpl.after.summary["contour_max_um"],
                               "max_after_virtual_um": virt_after, "wall_s": t_opt, "reachable": fpl.reachable}
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    (out / "bench_plan.json").write_text(json.dumps(results, indent=1, default=float))
    if publishable(ap, args):
        publish("plan", "Planning: predicted contour error per NC block", tables(results), command("plan"),
                results, notes=NOTES)


NOTES = """The virtual Deckel-Maho-like machine; a rigid pole-search model per axis identified from 20
linear moves (`identify_siso`, seed 0) and its FMU. Each example program (`examples/*.nc`) is
interpolated with 100 mm/s, 2000 mm/s², 1e5 mm/s³ per axis; the contour error per block predicted
by the model and by its FMU (`fmpy.simulate_fmu`) is compared with the virtual drive run on the
same commanded positions (RMS / MAX per block in µm; deviation: the larger relative difference of
RMS and MAX, on blocks above 5 µm). Then the feeds of `examples/pocket_corner.nc` are optimised
for the tolerance (`fdid plan --optimize`) and the result checked on the virtual drive."""


def tables(results):
    """The markdown tables of a run's result: per block, then the feed optimisation."""
    rows = [[prog, b["block"], b["line"], b["kind"], *(f"{b[k][0]:.2f} / {b[k][1]:.2f}" for k in ("virtual", "model", "fmu")),
             f"{max(b['deviation_pct'], b['deviation_fmu_pct']):.1f}"]
            for prog, p in results["programs"].items() for b in p["blocks"]]
    blocks = md_table(["program", "block", "line", "kind", "virtual drive RMS / MAX", "model RMS / MAX",
                       "FMU RMS / MAX", "deviation [%]"], rows, ["l", "r", "r", "l", "r", "r", "r", "r"])
    o = results["optimisation"]
    feeds = md_table(["block", "line", "feed [mm/min]", "new feed [mm/min]", "contour MAX before / after [µm]",
                      "time before / after [s]"],
                     [[r["block"], r["line"], f"{r['feed_mm_min']:.0f}", f"{r['new_feed_mm_min']:.0f}",
                       f"{r['contour_max_before_um']:.2f} / {r['contour_max_after_um']:.2f}",
                       f"{r['time_before_s']:.3f} / {r['time_after_s']:.3f}"] for r in o["rows"]], ["r"] * 6)
    cycle = md_table(["feeds", "cycle time [s]", "contour MAX [µm]"],
                     [["programmed", f"{o['cycle_programmed_s']:.3f}", ""],
                      ["per-block feeds", f"{o['cycle_optimised_s']:.3f}",
                       f"{o['max_after_model_um']:.1f} on the twin, {o['max_after_virtual_um']:.1f} on the virtual drive"],
                      [f"one uniform override ({100 * o['uniform_override']:.1f} %)", f"{o['cycle_uniform_s']:.3f}", ""]],
                     ["l", "r", "l"])
    return ["Contour error per block, µm:\n\n" + blocks,
            f"Feed optimisation of pocket_corner.nc for {results['tol_mm'] * 1e3:g} µm:\n\n" + feeds, cycle]


if __name__ == "__main__":
    main()
