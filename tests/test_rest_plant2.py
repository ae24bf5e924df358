"""At rest, the twin settles as the plant does: no creep unless the data show it.

The independent plant (tests/plant2: LuGre friction with presliding, a velocity PI loop) is not at
rest when its command stops: its true motor position settles by ~0.4 µm over the next seconds
(75-94 nm/s over the first 5 s on the three move sets below, 0.1-3 nm/s after that). The twin
identified from its training moves (the pole search, rigid structure, as in
benchmarks/checks/pole_search_virtual.py; stored) settles alike. Measured: 89 / 69 / 99 nm/s against the plant's
91 / 75 / 94 nm/s, the positions after 5 s 0.01-0.03 µm apart. On the virtual drive, whose
stiction holds the axis, the twins' drift is the other half of this comparison (docs/decisions/rest-behaviour.md).
"""
from pathlib import Path

import numpy as np

from fdid_fmi.model import load_model
from fdid_fmi.simulate import simulate
from fdid_fmi.virtual import trajectories as tj

import plant2 as p2
from plant2.plant import simulate_axis
from plant2.scenarios import SCENARIOS


def test_twin_settles_like_the_plant_after_a_stop():
    _, _, truth = p2.scenario("clean_rigid")
    name = truth["axis"]
    # the pole search (seed 0, default search) on the training moves: tests/data/make_fitted_models.py
    model = load_model(Path(__file__).parent / "data" / "plant2_clean_rigid_siso_model.json")
    machine = SCENARIOS["clean_rigid"][0]()
    Ts, n = machine.Ts, int(5 / machine.Ts)
    for seed in (5, 6, 7):
        mv = tj.linear_moves(n_moves=3, axes=(name,), Ts=Ts, seed=seed)[name]
        cmd = np.concatenate([mv, np.full(n, mv[-1])])
        plant = simulate_axis(machine.axis(name), Ts, cmd, np.random.default_rng(seed),
                              drive_period=machine.drive_period)["motor"][mv.size:]
        twin = simulate(model, {name: cmd}, Ts=Ts).axes[name]["position"][mv.size:]
        drift_plant = abs(plant[-1] - plant[0]) / 5 * 1e6          # nm/s
        drift_twin = abs(twin[-1] - twin[0]) / 5 * 1e6
        assert drift_plant > 10.0, seed                               # the plant really settles
        assert 0.5 < drift_twin / drift_plant < 2.0, (seed, drift_twin, drift_plant)
