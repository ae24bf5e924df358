"""Calibrate the diagnosis thresholds on clean virtual-drive data.

Runs every detector once (no augmentation) on clean scenarios (gentle moves, fast moves, a softer
velocity loop, two uncoupled axes, a P loop without integral action) for several seeds and prints each detector's statistic with
its threshold. The thresholds in ``fdid_fmi.diagnose.*`` were set above the largest clean value
with margin; a statistic at or above its threshold only means the effect is *tried* -- the
held-out criterion decides whether it is kept.

    .venv/bin/python examples/diagnose_calibrate.py
"""
import warnings

import numpy as np

from fdid_fmi.diagnose import DETECTORS
from fdid_fmi.diagnose import augment as ag
from fdid_fmi.diagnose.base import Context
from fdid_fmi.diagnose.residuals import residuals
from fdid_fmi.diagnose.scenarios import INTEGRAL_ACTION, scenario
from fdid_fmi.identify import identify_siso

warnings.simplefilter("ignore")
rows = {}
for name in ("clean", "clean_fast", "clean_soft", "clean_xy", "clean_p"):
    for seeds in ((1, 2), (3, 4), (5, 6)):
        tr, _ = scenario(name, seeds=seeds)
        m = identify_siso(tr, axis="x", maxiter=30, integral_action=INTEGRAL_ACTION.get(name, True))
        ctx = Context(model=m, recipe=ag.recipe_from_model(m), train=ag.model_velocity_traces(m, [tr]),
                      res=[residuals(m, tr)], settings={"maxiter": 25})
        for fam, mod in DETECTORS.items():
            for c in mod.detect(ctx):
                rows.setdefault((c.kind, c.threshold), []).append((name, seeds[0], c.statistic))
                print(f"{name:10s} seed {seeds[0]}  {c.kind:20s} {c.statistic:8.3f}  (threshold {c.threshold:g})",
                      flush=True)
print("\nlargest clean statistic per detector:")
for (kind, thr), vals in rows.items():
    worst = max(vals, key=lambda v: v[2])
    print(f"  {kind:20s} max {worst[2]:8.3f} ({worst[0]}, seed {worst[1]})   threshold {thr:g}   "
          f"n = {len(vals)}")
