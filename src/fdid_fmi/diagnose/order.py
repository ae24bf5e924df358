"""Is the model's order too low? One more real pole, tried before an effect is named.

A residual that one more pole explains means the model's order is too low; it is not a dead time
or a mode, which are the effects a missing pole imitates best. :mod:`.loop` decides what the
refit below counts for (the note ``order_too_low``, a rival a dead time or mode must beat).

The refit: the new pole's frequency is scanned over a log grid from ``LOWEST_HZ`` to 0.4 / Ts,
with every other pole fixed (one LS projection per point, parabola-refined, as the Stribeck
velocity in :mod:`.friction`). The pole search then runs in the local windows around all the
poles, starting from the scan's best point (the search itself ends no worse than that start in
the LS objective; the engine then picks, by training free run, among minima within 5 % of the
best). The search is not a differential-evolution search of the new pole over the whole range with
the other poles in their local windows: held out, that is worse than the better of the model and
its same-order refit on 9 of 14 plant2 and virtual-drive runs, by up to 79 %: its few
generations do not converge in the larger space.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import augment as ag
from .base import scan_refine

LOWEST_HZ = 0.5
GRID = 9


def one_more_pole(recipe, train, maxiter=25):
    """The recipe refitted with one more real pole (module docstring).

    Parameters
    ----------
    recipe : :class:`.augment.Recipe` of the current model
    train : training traces carrying the model's free-run velocity
        (:func:`.augment.model_velocity_traces`)
    maxiter : DE iterations of the final local refit

    Returns
    -------
    DriveModel
    """
    Ts = train[0].Ts
    xs = np.linspace(np.log10(LOWEST_HZ), np.log10(0.4 / Ts), GRID)

    def objective(lx):
        try:
            m = ag.fit(ag.add_real_pole(recipe, 10 ** lx), train, search="locked", refine=False)
        except InputError:          # no feasible model with the pole there: not the best point
            return np.inf
        return m.metrics["objective_scaled_rms"]

    best, _ = scan_refine(objective, xs)
    return ag.fit(ag.add_real_pole(recipe, 10 ** best), train, search="local", maxiter=maxiter,
                  from_current=True)
