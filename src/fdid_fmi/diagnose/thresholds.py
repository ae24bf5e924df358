"""The detectors' thresholds: one table, each entry with where its value comes from.

Every detector statistic (a candidate's ``label``: ``stribeck``, ``delay (early answer)``, ...)
is gated by the value in :data:`THRESHOLDS`. An entry records where its value comes from: the
false-alarm rate on clean cases it was set for and how many clean cases that rate was measured on
(None and 0 for a value set otherwise), and the command or rule that produced it. A gate only
orders and selects what is refitted; the held-out criterion of :mod:`.loop` decides what is kept.

Rule (:func:`quantile_threshold`): with N clean statistics and a stated rate q, at most
k = floor(q N) clean cases may pass. The threshold is the midpoint between the (k+1)-th largest
clean value, which must stay below, and the k-th largest, which may pass (k = 0: the largest clean
value times ``1 + TOP_MARGIN``). When the two order statistics tie, the threshold is just above
them: both stay below, and fewer than k pass. ``detected`` is
``statistic >= threshold`` (:class:`.base.Candidate`).

The shipped values were set between the clean and the effect runs of the virtual drive and
plant2. ``benchmarks/calibrate_thresholds.py`` computes the values for a stated rate instead:
from the clean cases of the calibration half of the plant family (``tests/family``, even seeds),
each rebuilt without its effects (``case(seed, without=KINDS)``), identified with
``identify_auto`` and run through every detector once, without refits of candidates;
``--skip-family --plants`` reads every statistic on plant2's and the virtual drive's scenarios
against the table.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..identify.choose_structure import PARSIMONY

# k = 0 (fewer than 1 / q clean cases): the largest clean value must stay below the threshold,
# and nothing above it is known; a small margin keeps that value itself from passing
TOP_MARGIN = 0.05


@dataclass(frozen=True)
class Threshold:
    """One detector statistic's gate.

    Attributes
    ----------
    value : the threshold (``detected`` is ``statistic >= value``)
    rate : false-alarm rate on clean cases it was set for (None: not set from clean cases)
    n_clean : clean cases the rate was measured on (0 when ``rate`` is None)
    source : the command that produced the value, or where it comes from
    statistic : what is compared with it
    """

    value: float
    rate: float | None
    n_clean: int
    source: str
    statistic: str


CALIBRATE = ".venv/bin/python benchmarks/calibrate_thresholds.py --cases 40"
PLANTS = "set between the virtual drive and plant2 (examples/diagnose_calibrate.py --effects --plant2)"

# keyed by Candidate.label; coupling and extra_input are the same statistic (R^2 of the residual
# on a filtered channel) and share one entry. The values set between the two plants are kept:
# at a 5 % false-alarm rate on 40 clean cases of the plant family (CALIBRATE, quick settings) the
# gates miss most effects of the virtual drive and plant2 and name fewer on the family
# (docs/decisions/diagnosis-gates.md)
THRESHOLDS = {
    "stribeck": Threshold(1.0, None, 0, PLANTS, "residual energy after motion starts / stops over the rest"),
    "asymmetric_friction": Threshold(4.0, None, 0, PLANTS,
                                     "|t| of the direction-independent mean residual over moves"),
    "backlash": Threshold(8.0, None, 0, PLANTS, "|t| of the direction-aligned tool-side offset over moves"),
    "mode": Threshold(0.27, None, 0, PLANTS, "fraction of the command band coherent with the residual"),
    "delay (early answer)": Threshold(2.3, None, 0, PLANTS,
                                      "early-answer chi-square without / with the best command shift"),
    "delay (refined free run)": Threshold(1.0 / (1.0 - PARSIMONY), None, 0, "the structure choice's parsimony margin",
                                          "refined free-run RMS without / with the best command shift"),
    "periodic_position": Threshold(15.0, None, 0, PLANTS, "peak of the position spectrum over its median"),
    "channel": Threshold(0.15, None, 0, PLANTS, "R^2 of the residual on the filtered channel"),
}

# candidate label -> table key, where they differ
KEY_OF = {"coupling": "channel", "extra_input": "channel"}


def key(label):
    """The :data:`THRESHOLDS` key of a candidate label."""
    return KEY_OF.get(label, label)


def threshold(label, settings=None):
    """The threshold of a candidate label; ``settings["thresholds"]`` ({key: value}) overrides the
    table (the calibration runs every detector with infinite thresholds, so that no candidate is
    built and every statistic is the one the gate would see)."""
    k = key(label)
    over = (settings or {}).get("thresholds") or {}
    return float(over[k]) if k in over else THRESHOLDS[k].value


def quantile_threshold(values, rate):
    """The threshold that lets at most ``floor(rate * N)`` of N clean statistics pass (module
    docstring's rule).

    Parameters
    ----------
    values : clean statistics (non-finite ones are left out)
    rate : stated false-alarm rate, 0 <= rate < 1

    Returns
    -------
    (threshold, k, n): the value, the clean cases allowed to pass, the finite values used; the
    threshold is nan when there are none
    """
    v = np.sort(np.asarray([x for x in values if x is not None and np.isfinite(x)], float))[::-1]
    n = v.size
    if n == 0:
        return float("nan"), 0, 0
    if not 0 <= rate < 1:
        raise ValueError(f"rate {rate} is not in [0, 1)")
    k = int(math.floor(rate * n + 1e-9))
    if k == 0:
        return float(v[0] * (1 + TOP_MARGIN)) if v[0] > 0 else float(v[0] + TOP_MARGIN), 0, n
    if v[k - 1] <= v[k]:        # a tie across the cut: both stay below, fewer than k pass
        return float(np.nextafter(v[k], np.inf)), k, n
    return float(0.5 * (v[k] + v[k - 1])), k, n
