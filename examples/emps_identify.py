"""EMPS (real data): every identifier trained on DATA_EMPS from qg and qm alone, validated on
DATA_EMPS_PULSES. Prints the free-run position error in µm (benchmarks/bench_emps.py measures
these models and more for docs/results/emps.md).

    .venv/bin/python examples/emps_identify.py [path/to/shared/data/emps]
"""
import argparse
import sys
import time
from pathlib import Path

from fdid_fmi.identify import identify_full_ls, identify_quasi_static, identify_siso
from fdid_fmi.io import read_trace
from fdid_fmi.metrics import rms_max_um
from fdid_fmi.errors import InputError
from fdid_fmi.simulate import simulate



def pole_search_line(identification):
    """The pole-search model's poles, v_tilde and friction refinement as one plain line (numbers
    formatted: the record holds numpy floats, whose repr is ``np.float64(...)``)."""
    real = ", ".join(f"{f:.3f}" for f in identification["real_hz"])
    cplx = ", ".join(f"{w:.3f} Hz / zeta {z:.4f}" for w, z in identification["complex_hz_zeta"])
    vt = ", ".join(f"{a} {v:.3f}" if abs(v) >= 0.1 else f"{a} {v:.3g}"
                   for a, v in identification["v_tilde_mm_s"].items())
    ch = identification["friction_refinement"]["chosen"]
    return (f"pole search: real [{real}] Hz  complex [{cplx}]  v_tilde [mm/s]: {vt}  refinement: "
            f"band {ch['band']:g}, {ch['iterations']} iterations, free-run objective "
            f"{ch['free_run_objective']:.4g}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default=Path(__file__).resolve().parents[2] / "shared" / "data" / "emps",
                    help="folder with DATA_EMPS.mat and DATA_EMPS_PULSES.mat (default ../shared/data/emps)")
    folder = Path(ap.parse_args(argv).folder)
    try:
        train = read_trace(folder / "DATA_EMPS.mat")
        test = read_trace(folder / "DATA_EMPS_PULSES.mat")
    except InputError as exc:
        sys.exit(f"emps_identify.py: error: {exc}")
    fits = {}
    for name, fn in (("pole search (SISO, no integral action)", lambda: identify_siso(train, "x", integral_action=False)),
                     ("Full LS (Eqn 4.7, constrained by Eqn 4.9)", lambda: identify_full_ls(train, "x")),
                     ("quasi-static (Eqn 3.5)", lambda: identify_quasi_static(train))):
        t0 = time.perf_counter()
        fits[name] = (fn(), time.perf_counter() - t0)
    print("| model | fit [s] | train RMS / MAX [µm] | test (pulses) RMS / MAX [µm] | test before 1st pulse RMS [µm] |")
    print("|---|---:|---:|---:|---:|")
    for name, (m, dt) in fits.items():
        cells = []
        for tr in (train, test, test.slice(0, 0.34)):
            d = rms_max_um(simulate(m, tr).axes["x"]["position"] - tr.act("x"))
            cells.append(d)
        print(f"| {name} | {dt:.1f} | {cells[0]['rms_um']:.2f} / {cells[0]['max_um']:.1f} | "
              f"{cells[1]['rms_um']:.1f} / {cells[1]['max_um']:.1f} | {cells[2]['rms_um']:.2f} |")
    m = fits["pole search (SISO, no integral action)"][0]
    print("\n" + pole_search_line(m.identification))


if __name__ == "__main__":
    main()
