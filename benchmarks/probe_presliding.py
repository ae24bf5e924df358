"""Probe (not a feature): would a position-based friction input find plant2's tool-side mode?

The model's friction input is the thesis's sat(v / v_tilde) (Eqn 4.10): a function of velocity,
without memory. Plant2's LuGre friction moves through presliding, a function of travel since the
last reversal, and holds its force at rest. This probe adds one input to the default MIMO
structure of plant2's flexible Y axis (error and tool position fitted): the play (backlash)
operator of the measured motor position with half-width b,

    h_k = min(max(h_(k-1), x_k - b), x_k + b),   p_k = (x_k - h_k) / b  in [-1, 1],

as an external input (``fdid identify --external``). It is an oracle: the held-out traces are
simulated with p from their measured position too, where a model would have to compute it from
its own. A feature built into the kernel, the C FMU and the identification (b searched like
v_tilde) would be the product; this only measures whether it is worth building.

Run: ``.venv/bin/python benchmarks/probe_presliding.py`` (about 3 min on 2 cores); writes
``benchmarks/results/probe_presliding.json`` and prints a table.
"""
import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fdid_fmi.identify.choose_structure import Candidate, free_run_rms  # noqa: E402
from fdid_fmi.identify.pole_search import identify_mimo  # noqa: E402
from fdid_fmi.identify.record import PoleSearchRecord  # noqa: E402
from fdid_fmi.identify.structure import mimo_structure  # noqa: E402
from fdid_fmi.metrics import rms  # noqa: E402
from fdid_fmi.simulate import simulate  # noqa: E402
from fdid_fmi.trace import Channel, Trace  # noqa: E402
from plant2 import scenarios as p2  # noqa: E402

AXIS, OUTPUTS, FORM = "y", ("error", "tool_position"), "quadratic"
WIDTHS_MM = (None, 0.0015, 0.003, 0.006)          # None: the default structure, no play input
CANDIDATES = (Candidate("r1c2", 1, 2), Candidate("r1c2-noI", 1, 2, False), Candidate("r2c2-noI", 2, 2, False))


def with_play(tr, b):
    """``tr`` with channel ``play`` = (x - h) / b of its measured motor position x."""
    x = np.asarray(tr.act(AXIS), float)
    h = np.empty_like(x)
    h[0] = x[0]
    for k in range(1, x.size):
        h[k] = min(max(h[k - 1], x[k] - b), x[k] + b)
    chans = dict(tr.channels)
    chans["play"] = Channel("play", "1", (x - h) / b)
    return Trace(t=tr.t, channels=chans, roles={a: dict(r) for a, r in tr.roles.items()}, source=tr.source,
                 meta=dict(tr.meta))


def fit(cand, b, train, vals):
    """The candidate's default MIMO structure, with the play input of half-width b (mm) if given."""
    st = mimo_structure((AXIS,), OUTPUTS, n_real=cand.n_real, n_complex=cand.n_complex,
                        integral_action=cand.integral_action, externals=() if b is None else ("play",),
                        same_sample=FORM)
    if b is not None:
        train, vals = with_play(train, b), [with_play(v, b) for v in vals]
    t0 = time.perf_counter()
    m = identify_mimo([train], st, bounds=cand.bounds(train.Ts), seed=0)
    rec = PoleSearchRecord.from_dict(m.identification)
    row = {"structure": cand.label, "b_um": None if b is None else b * 1e3, "wall_s": time.perf_counter() - t0,
           "train_free_run_um": free_run_rms(m, [train], AXIS, OUTPUTS) * 1e3,
           "complex_hz_zeta": rec.complex_hz_zeta, "held_out_um": {}}
    for v in vals:
        s = simulate(m, v).axes[AXIS]
        row["held_out_um"][v.meta["name"]] = {"motor": rms(s["error"] - v.error(AXIS)) * 1e3,
                                              "tool": rms(s["tool_position"] - v.get(AXIS, "tool")) * 1e3 if "tool_position" in s else None}
    return row


def main():
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()
    warnings.simplefilter("ignore")
    train, vals, truth = p2.scenario("flexible_y")
    rows = [fit(c, b, train[0], vals) for b in WIDTHS_MM for c in CANDIDATES]
    out = ROOT / "benchmarks" / "results" / "probe_presliding.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"scenario": "flexible_y", "closed_loop_pair": "37.21 Hz, zeta 0.092",
                               "rows": rows}, indent=1))
    print("| play b [µm] | structure | training free run [µm] | pairs [Hz, ζ] | held out motor / tool [µm] "
          "(circle, diamond, reversals) |\n|---|---|---:|---|---|")
    for r in rows:
        pairs = "; ".join(f"{w:.2f}, {z:.3f}" for w, z in r["complex_hz_zeta"])
        ho = " / ".join(", ".join(f"{d[k]:.2f}" for d in r["held_out_um"].values()) for k in ("motor", "tool"))
        b = "none" if r["b_um"] is None else f"{r['b_um']:g}"
        print(f"| {b} | {r['structure']} | {r['train_free_run_um']:.3f} | {pairs} | {ho} |")
    print(f"\nJSON: {out}")


if __name__ == "__main__":
    main()
