"""Closing the loop on virtual-drive data (one undeclared effect at a time) and on EMPS.

For every scenario of ``fdid_fmi.diagnose.scenarios`` a SISO pole-search model is fitted on the
training trace, ``diagnose`` adds what the residual asks for, and the error table is reproduced
through exported FMUs. EMPS: model from DATA_EMPS (``qg`` only, no integral action); diagnosis on
DATA_EMPS_PULSES, first half fitted, second half held out. Prints the README table and writes one
HTML report per case. ``--default-path``: the virtual runs' models are ``fdid identify``'s default
(the structure chosen from the data, ``identify_auto``) and ``diagnose`` runs with its defaults,
as a user runs them (about 10 min on 2 cores instead of 3; EMPS as without it). ``--no-val``: no
held-out trace, as ``fdid diagnose --train`` alone (the training trace split at its standstill
nearest the middle; the "held-out" columns are its second part).

    .venv/bin/python examples/diagnose_scenarios.py [OUT_DIR] [--default-path] [--no-val]
"""
import argparse
import time
import warnings
from pathlib import Path

from fdid_fmi.diagnose import diagnose
from fdid_fmi.diagnose.reporting import diagnosis_report, fmu_check
from fdid_fmi.diagnose.limits import NoteKind
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario
from fdid_fmi.identify import identify_siso
from fdid_fmi.identify.choose_structure import identify_auto
from fdid_fmi.io import read_trace

_ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
_ap.add_argument("out", nargs="?", default="diagnose_out", help="folder for the reports and FMUs (default diagnose_out)")
_ap.add_argument("--default-path", action="store_true",
                 help="models by fdid identify's default structure choice, diagnose with its defaults")
_ap.add_argument("--no-val", action="store_true",
                 help="no held-out trace: the training trace split at its standstill nearest the middle")
_args = _ap.parse_args()
warnings.simplefilter("ignore")
out = Path(_args.out)
out.mkdir(parents=True, exist_ok=True)
SHOW = ("samples", "period_mm", "frequency_hz", "damping", "v_s_mm_s", "backlash_mm", "channel",
        "ratio_to_coulomb")


def params(e):
    return ", ".join(f"{k}={e[k]:.4g}" if isinstance(e[k], float) else f"{k}={e[k]}" for k in SHOW if k in e)


def row(name, d, fmu, t):
    eff = "; ".join(f"{e['kind']} ({params(e)})" for e in d.effects_added) or "none"
    notes = [n for n in d.notes if n.kind != NoteKind.NOT_OBSERVABLE]
    if notes:
        eff += "; note " + ", ".join(f"{n.kind.value} ({n.statistic:.3g})" for n in notes)
    cells = [name, eff]
    chans = list(d.before["val"])
    for tname in ("train", "val"):
        cells.append(" / ".join(f"{d.before[tname][c]['rms_um']:.3g} → {d.after[tname][c]['rms_um']:.3g}"
                                for c in chans))
    cells.append(" / ".join(f"{d.before['val'][c]['max_um']:.3g} → {d.after['val'][c]['max_um']:.3g}"
                            for c in chans))
    if fmu and "error" not in fmu:
        cells.append(f"{fmu['before']['val']['x']['rms_um']:.3g} → {fmu['after']['val']['x']['rms_um']:.3g}")
    else:
        cells.append(fmu.get("error", "–") if fmu else "–")
    cells.append(", ".join(chans))
    cells.append(f"{t:.0f} s")
    print("| " + " | ".join(cells) + " |", flush=True)


print("| data | effects added (fitted parameters) | train RMS before → after [µm] | held-out RMS "
      "before → after [µm] | held-out MAX before → after [µm] | FMU held-out RMS (x) [µm] | channels | time |")
print("|---|---|---|---|---|---|---|---|")
for name in ("clean", "clean_fast", "clean_xy", "stribeck", "backlash", "periodic", "delay", "mode",
             "coupling", "clean_p", "asymmetric"):
    t0 = time.perf_counter()
    tr, va = scenario(name)
    va = None if _args.no_val else va
    if _args.default_path:
        m = identify_auto(tr, "x", seed=0)
        d = diagnose(m, tr, va)
    else:
        m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
        d = diagnose(m, tr, va, maxiter=20)
    t = time.perf_counter() - t0
    fmu = fmu_check(d, out / f"fmu_{name}")
    diagnosis_report(d, title=f"Diagnosis: virtual drive, scenario '{name}'", fmu=fmu).write(out / f"{name}.html")
    row(name, d, fmu, t)

data = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "emps"
if data.is_dir():
    t0 = time.perf_counter()
    m = identify_siso(read_trace(data / "DATA_EMPS.mat"), integral_action=False, maxiter=30)
    d = diagnose(m, read_trace(data / "DATA_EMPS_PULSES.mat"), maxiter=20)
    t = time.perf_counter() - t0
    fmu = fmu_check(d, out / "fmu_emps")
    diagnosis_report(d, title="Diagnosis: EMPS model on DATA_EMPS_PULSES", fmu=fmu).write(out / "emps.html")
    row("EMPS pulses", d, fmu, t)
