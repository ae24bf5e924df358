"""Write the example traces in examples/ with the virtual feed drive (reproducible: fixed seeds).

    .venv/bin/python examples/make_example_traces.py

* ``virtual_xy_moves.csv``: the Deckel-Maho-like two-axis machine (no feed-forward, Ts 0.6 ms),
  varying-distance linear moves, one axis at a time (thesis ch. 4 identification trajectory);
* ``virtual_circle.csv``: the same machine on a 20 mm circle at 100 mm/s (held-out trace).

Columns ``t_s, x_cmd_mm, x_mm, y_cmd_mm, y_mm`` (commanded and measured positions), read by
every ``fdid`` command without ``--map``.
"""
import argparse
from pathlib import Path

import numpy as np

from fdid_fmi.virtual import presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj

HERE = Path(__file__).resolve().parent


def write(trace, path):
    cols = [trace.t]
    for a in ("x", "y"):
        cols += [trace.cmd(a), trace.act(a)]
    np.savetxt(path, np.column_stack(cols), delimiter=",", fmt="%.8g",
               header="t_s,x_cmd_mm,x_mm,y_cmd_mm,y_mm", comments="")
    print(f"{path.name}: {trace.n} samples")


def main():
    argparse.ArgumentParser(description="Write examples/virtual_xy_moves.csv and examples/virtual_circle.csv "
                            "(overwritten) with the virtual feed drive.").parse_args()
    cfg = presets.deckel_maho_like()
    write(simulate_machine(cfg, tj.linear_moves(n_moves=12, axes=("x", "y"), Ts=cfg.Ts, seed=5), seed=5),
          HERE / "virtual_xy_moves.csv")
    write(simulate_machine(cfg, tj.circle(Ts=cfg.Ts), seed=6), HERE / "virtual_circle.csv")


if __name__ == "__main__":
    main()
