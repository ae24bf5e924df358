"""Writes tests/data/xy_twin_model.json: the two-axis (X, Y) twin the program tests plan with.

The virtual Deckel-Maho-like machine (fdid_fmi.virtual.presets) runs six random jerk-limited moves
per axis; each axis is identified by the SISO pole search (seed 0) and the two are combined. The
model records the feed, acceleration and jerk of those traces (``limits``). Run from the project
root: ``.venv/bin/python tests/data/make_xy_twin_model.py`` (about a minute).
"""
from pathlib import Path

from fdid_fmi.identify import identify_siso
from fdid_fmi.model import DriveModel
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj

cfg = presets.deckel_maho_like()
models = []
for ax in ("x", "y"):
    tr = simulate_machine(MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts),
                          tj.linear_moves(n_moves=6, axes=(ax,), Ts=cfg.Ts, seed=1), seed=1)
    models.append(identify_siso(tr, ax, seed=0))
model = DriveModel.combine(models, method="pole-search")
out = Path(__file__).with_name("xy_twin_model.json")
model.save(out)
print(out, model.axes, model.Ts, model.limits)
