"""``fdid demo``: the main job end to end on a generated (or given) trace.

virtual drive traces (or ``--trace FILE``) -> identify (pole search; Full LS and quasi-static as
baselines) -> FMI 2.0 co-simulation FMU -> validate through fmpy against the held-out trace and
the reference simulator -> report (HTML + JSON, with the identified model: poles, friction, Bode,
pole-zero map, FMU variables) in ``--out`` (default: ``out/demo/virtual`` or ``out/demo/emps``,
one folder per variant). The virtual variant also plans ``examples/pocket_corner.nc`` with the
identified model (``plan.html``: predicted contour error per block).
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from ..metrics import contour_error, rms_max_um
from ..errors import InputError
from ..model import DriveModel, jsonable
from ..outputs import atomic_write
from ..pipeline.argtypes import int_in


def register(sub):
    p = sub.add_parser("demo", help="identify -> FMU -> validate -> report, on generated or given data",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None,
                   help="folder for models, FMU, report (default: out/demo/virtual, out/demo/emps)")
    p.add_argument("--emps", action="store_true",
                   help="use the real EMPS data (../shared/data/emps) instead of the virtual drive")
    p.add_argument("--data", default=None, help="folder with DATA_EMPS.mat / DATA_EMPS_PULSES.mat (default: ../shared/data/emps)")
    # the search's seed (scipy / numpy legacy): 0 .. 2**32 - 1
    p.add_argument("--seed", type=int_in(0, 2 ** 32 - 1, "--seed"), default=0,
                   help="random seed of the generated traces and the search (default 0)")
    p.set_defaults(func=run)


def _virtual_case(seed):
    from ..virtual import MachineConfig, presets, simulate_machine
    from ..virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    train = {ax: simulate_machine(MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts),
                                  tj.linear_moves(n_moves=20, axes=(ax,), Ts=cfg.Ts, seed=1 + seed),
                                  seed=1 + seed)
             for ax in ("x", "y")}
    val = {"circle": simulate_machine(cfg, tj.circle(Ts=cfg.Ts), seed=3 + seed),
           "diamond": simulate_machine(cfg, tj.diamond(Ts=cfg.Ts), seed=2 + seed)}
    return "virtual Deckel-Maho-like two-axis machine (no feed-forward)", train, val, {}


def _default_emps_folder():
    """../shared/data/emps next to the source checkout, else ../shared/data/emps from the working
    directory (an installed package has no checkout around it)."""
    checkout = Path(__file__).resolve().parents[3]
    for folder in ((checkout / "pyproject.toml").is_file() and checkout.parent / "shared" / "data" / "emps",
                   Path("..") / "shared" / "data" / "emps"):
        if folder and folder.is_dir():
            return folder
    raise InputError("no EMPS data folder ../shared/data/emps here; give the folder with --data DIR",
                     source="--emps")


def _emps_case(folder):
    from ..api import read_trace
    folder = Path(folder)
    train = read_trace(folder / "DATA_EMPS.mat")
    # the PULSES record carries a force the qg-only model cannot know (see `fdid diagnose`)
    val = {"DATA_EMPS (training)": train, "DATA_EMPS_PULSES": read_trace(folder / "DATA_EMPS_PULSES.mat")}
    return "EMPS drive benchmark (real data)", {"x": train}, val, {"no_integral_action": True}


@contextlib.contextmanager
def staged_output(out):
    """Write a run's files into a fresh staging folder beside ``out`` and move them into ``out``
    only when the block ends without an exception: a failed or interrupted run leaves no empty or
    half-filled output folder behind.

    On failure the staging folder (created here) is removed, and so are ``out`` and those of its
    parent folders that this call created, if they are still empty; a folder that existed before
    (or that now holds anyone else's files) is never removed, and its files stay as they were.
    On success each file replaces its namesake in ``out`` with ``os.replace`` (atomic per file).

    Yields
    ------
    Path of the staging folder to write into.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("the demo's output folder exists and is not a folder", source=str(out))
    made = [d for d in (out, *out.parents) if not d.exists()]     # deepest first
    parent = out.parent if str(out.parent) else Path(".")
    stage = None
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name[:100]}.", suffix=".part", dir=parent))
        yield stage
        out.mkdir(exist_ok=True)
        for f in sorted(stage.iterdir()):
            os.replace(f, out / f.name)
        stage.rmdir()
    except BaseException:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        for d in made:
            try:
                d.rmdir()           # only an empty folder: never anyone's files
            except FileNotFoundError:
                continue            # not made (yet): e.g. out itself, made only on success
            except OSError:
                break
        raise


def run(args):
    out = Path(args.out) if args.out else Path("out/demo") / ("emps" if args.emps else "virtual")
    with staged_output(out) as work:
        return _run(args, out, work)


def _run(args, out, work):
    """The demo; files are written into ``work`` (see :func:`staged_output`), named as ``out``."""
    from ..api import export_fmu, identify, simulate, validate
    from ..report import Report, add_model_section, decimate

    t0 = time.perf_counter()
    if args.emps:
        data = Path(args.data) if args.data else _default_emps_folder()
        title, train, val, kw = _emps_case(data)
    else:
        title, train, val, kw = _virtual_case(args.seed)
    print(f"fdid demo: {title}")
    for ax, tr in train.items():
        print(f"  training trace for {ax}: {tr.n} samples, Ts = {tr.Ts * 1e3:.3g} ms")

    # ---- identify: pole search per axis, baselines
    models, baselines = [], {"full-ls": [], "quasi-static": []}
    for ax, tr in train.items():
        t1 = time.perf_counter()
        # what fdid identify does by default: the structure chosen from the data (EMPS: the
        # P-PD loop's structure, pinned by no_integral_action)
        m = identify(tr, "pole-search", axes=[ax], seed=args.seed, **kw)
        rec = m.records[0]
        chosen = (rec.structure_choice or {}).get("chosen", "rigid")
        poles = ", ".join([f"{p:.2f} Hz" for p in rec.real_hz]
                          + [f"{w:.2f} Hz / zeta {z:.3f}" for w, z in rec.complex_hz_zeta])
        print(f"  {ax}: pole search {time.perf_counter() - t1:.1f} s -> {chosen}: {poles}, "
              f"v_tilde {rec.v_tilde_mm_s[ax]:.3g} mm/s")
        models.append(m)
        baselines["full-ls"].append(identify(tr, "full-ls", axes=[ax]))
        baselines["quasi-static"].append(identify(tr, "quasi-static", axes=[ax]))
    model = models[0] if len(models) == 1 else DriveModel.combine(models, method="pole-search")
    model.save(work / "model.json")
    full_ls = (baselines["full-ls"][0] if len(models) == 1
               else DriveModel.combine(baselines["full-ls"], method="full-ls"))
    qs = baselines["quasi-static"]

    # ---- FMU + validation
    fmu = export_fmu(model, work / "drive.fmu").path
    print(f"  FMU: {out / fmu.name} ({fmu.stat().st_size / 1024:.1f} KiB)")
    rep = Report(f"fdid demo: {title}")
    rep.add_text(f"Identified with the pole search with LS projection (thesis ch. 4.3, 5) per axis, "
                 f"its structure chosen from the data as fdid identify does by default; "
                 f"exported as an FMI 2.0 co-simulation FMU (native C) and validated through fmpy on "
                 f"held-out traces. Model: {out / 'model.json'}; FMU: {out / fmu.name}.", heading="What was done")
    rows, summary = [], {"title": title, "validation": {}}
    vrs = {}
    for name, tr in val.items():
        vr = validate(fmu, tr, model=model)
        vr.fmu = str(out / fmu.name)      # the file as it will be named, not the staging copy
        vrs[name] = vr
        print(f"\n  validation on {name}: fmpy problems {len(vr.problems)}, max |FMU - reference| = "
              f"{vr.max_abs_diff_reference_mm:.3g} mm")
        print("  " + vr.table().replace("\n", "\n  "))
        summary["validation"][name] = vr.to_dict()
        sim_fl = simulate(full_ls, tr)
        for ax in model.axes:
            e = tr.error(ax)
            row = {"trace": name, "axis": ax, "error RMS [µm]": rms_max_um(e)["rms_um"],
                   "FMU RMS [µm]": vr.axes[ax]["rms_um"], "FMU MAX [µm]": vr.axes[ax]["max_um"],
                   "Full LS RMS [µm]": rms_max_um(sim_fl.axes[ax]["error"] - e)["rms_um"]}
            q = next(m for m in qs if ax in m.gains)
            row["quasi-static RMS [µm]"] = rms_max_um(simulate(q, tr).axes[ax]["error"] - e)["rms_um"]
            rows.append(row)
        _figures(rep, name, tr, model, simulate, decimate)
    rep.add_table("errors", rows, caption="Free-run tracking-error discrepancy (prediction - measured). "
                  "FMU: the exported FMU run through fmpy; baselines: the reference simulator.")
    rep.add_data("models", {"pole_search": model.identification, "metrics": model.metrics})
    add_model_section(rep, model, fmu=fmu, validation={
        "problems": [p for v in vrs.values() for p in v.problems],
        "max_abs_diff_reference_mm": max(v.max_abs_diff_reference_mm for v in vrs.values())})
    rep.write(work / "report.html")
    rep.write_json(work / "report.json")
    summary["table"] = rows
    # atomic, and strict JSON (a non-finite figure is null, not NaN)
    atomic_write(work / "summary.json", json.dumps(jsonable(summary), indent=1, allow_nan=False))
    print("\n| trace | axis | e RMS [µm] | FMU disc. RMS [µm] | FMU disc. MAX [µm] | Full LS [µm] | quasi-static [µm] |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['trace']} | {r['axis']} | {r['error RMS [µm]']:.1f} | {r['FMU RMS [µm]']:.3f} | "
              f"{r['FMU MAX [µm]']:.3f} | {r['Full LS RMS [µm]']:.3f} | {r['quasi-static RMS [µm]']:.3f} |")
    print(f"\nreport: {out / 'report.html'} (+ report.json, summary.json); total {time.perf_counter() - t0:.1f} s")
    if not args.emps:
        _plan_example(model, work, shown=out)
    bad = [n for n, v in summary["validation"].items() if v["problems"]]
    return 1 if bad else 0


# examples/pocket_corner.nc, carried here so that an installed package (no examples/ folder)
# plans it too (tests/test_readme_commands.py checks that the two are the same)
POCKET_CORNER_NC = """%
O0100 (fdid-fmi example: a pocket corner with lines and arcs in XY, metric, G94)
N10 G21 G90 G17 G94
N20 G0 X0 Y0 S8000 M3
N30 G1 X20 F3000
N40 G3 X40 Y0 R10
N50 G1 Y20 F2400
N60 G2 X20 Y20 I-10 J0
N70 G1 X0 Y0 F6000 (back to the start, 45 deg)
N80 M5
N90 M30
%
"""


def _plan_example(model, out, shown=None):
    """Plan the example program ``examples/pocket_corner.nc`` with the identified model; write
    ``plan.html`` into ``out`` (printed as in ``shown``, default ``out``)."""
    from ..api import plan
    from ..plan.ncprogram import parse_program
    from ..plan.reporting import plan_report
    nc = Path("examples/pocket_corner.nc")
    prog = parse_program(POCKET_CORNER_NC, source=str(nc))
    res = plan(model, prog, tol_mm=0.02, limits={a: (100.0, 2000.0, 1e5) for a in ("x", "y", "z")},
               in_position_mm=0)
    pr = res.prediction
    pr.interp.info.pop("limit_sources", None)       # the demo's own limits, said in the line below
    rep = plan_report(prog, pr, model=None, tol_mm=0.02)
    rep.write(out / "plan.html")
    s = pr.summary
    print(f"plan of {nc.name} (limits 100 mm/s, 2000 mm/s^2, 1e5 mm/s^3; tol 20 µm): cycle time "
          f"{s['cycle_time_s']:.3f} s, contour error MAX {s['contour_max_um']:.1f} µm, blocks over the "
          f"tolerance {s['flagged_blocks']}; {Path(shown or out) / 'plan.html'}")


def _figures(rep, name, tr, model, simulate, decimate):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sim = simulate(model, tr)
    axes = model.axes
    fig, axs = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    data = {"t_s": decimate(tr.t)}
    for ax in axes:
        e = tr.error(ax) * 1e3
        p = sim.axes[ax]["error"] * 1e3
        axs[0].plot(tr.t, e, label=f"{ax} measured")
        axs[0].plot(tr.t, p, "--", label=f"{ax} predicted")
        axs[1].plot(tr.t, p - e, label=ax)
        data[f"{ax}_e_um"] = decimate(e)
        data[f"{ax}_pred_minus_meas_um"] = decimate(p - e)
    axs[0].set_ylabel("tracking error [µm]")
    axs[1].set_ylabel("prediction - measured [µm]")
    axs[1].set_xlabel("t [s]")
    axs[0].legend(fontsize=8)
    axs[1].legend(fontsize=8)
    rep.add_figure(f"{name}_tracking", fig, data=data, caption=f"{name}: tracking error and discrepancy")
    if len(axes) == 2:
        a, b = axes
        cmd = np.column_stack([tr.cmd(a), tr.cmd(b)])
        ce_m = contour_error(cmd, np.column_stack([tr.act(a), tr.act(b)]))
        ce_p = contour_error(cmd, np.column_stack([sim.axes[a]["position"], sim.axes[b]["position"]]))
        fig, ax2 = plt.subplots(figsize=(10, 3.5))
        ax2.plot(tr.t, ce_m * 1e3, label="measured")
        ax2.plot(tr.t, ce_p * 1e3, "--", label="predicted")
        ax2.set_ylabel("contour error [µm]")
        ax2.set_xlabel("t [s]")
        ax2.legend(fontsize=8)
        rep.add_figure(f"{name}_contour", fig, data={"t_s": decimate(tr.t), "measured_um": decimate(ce_m * 1e3),
                                                     "predicted_um": decimate(ce_p * 1e3)},
                       caption=f"{name}: contour error (minimum distance to the commanded path)")
