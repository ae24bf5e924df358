"""What every detector returns: a :class:`Candidate` (evidence, estimated parameters, the
augmented recipe to refit), and the :class:`Context` the detectors read.

Evidence is one statistic compared with a threshold (:mod:`.thresholds`: one table, each value
set from a stated false-alarm rate on clean cases of the plant family's calibration half). A gate
only decides which effects are tried first: the held-out criterion of :mod:`.loop` decides what
is kept, and when the held-out residual is structured the strongest candidates below their gates
are tried as well.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .refits import Refits


@dataclass
class Candidate:
    """An effect a detector proposes.

    Attributes
    ----------
    kind : effect kind (``stribeck``, ``asymmetric_friction``, ``backlash``, ``mode``, ``delay``,
           ``periodic_position``, ``coupling``, ``extra_input``)
    axis : axis it belongs to
    statistic, threshold : evidence; ``detected = statistic >= threshold``
    statistic_name : which statistic, where a kind has more than one (``delay``: ``early answer``,
           ``refined free run``); ``label`` names the candidate's statistic in calibration tables
    params : estimated parameters (e.g. ``frequency_hz``, ``samples``, ``period_mm``, ``channel``)
    recipe : augmented :class:`~.augment.Recipe` to refit (None when not detected)
    search : refit search of the engine for this effect (``local`` or ``wide``)
    from_current : the refit (and its reference's) starts from the current poles, as the
           detector's own refit that found the effect did
    evidence : further numbers for the report
    plot : data for a figure of the evidence (dict of arrays), optional
    reference : Recipe, optional -- what the effect must beat besides the current model (e.g. a
           tool-side output without the backlash feature: the output alone is not backlash)
    not_checked : why the detector could not test for the effect on these data ('' when it
           could); such a candidate is never detected, and the diagnosis reports it as a note
           (``not_checked``, :mod:`.limits`) instead of "nothing found"
    prepare : callable without arguments, optional -- builds ``recipe`` (and ``reference``, and
           the parameters a refit needs, e.g. a Stribeck velocity's scan) as a detected candidate
           gets them; the loop calls it for a candidate below its threshold that it tries all the
           same (:data:`.loop.UNEXPLAINED_SHARE`). None: nothing could be tried
    """

    kind: str
    axis: str
    statistic: float
    threshold: float
    params: dict = field(default_factory=dict)
    recipe: object = None
    search: str = "local"
    from_current: bool = False
    statistic_name: str = ""
    evidence: dict = field(default_factory=dict)
    plot: dict = field(default_factory=dict)
    note: str = ""
    reference: object = None
    not_checked: str = ""
    prepare: object = field(default=None, repr=False, compare=False)

    @property
    def label(self):
        return f"{self.kind} ({self.statistic_name})" if self.statistic_name else self.kind

    @property
    def detected(self):
        return bool(not self.not_checked and np.isfinite(self.statistic) and self.statistic >= self.threshold)

    def summary(self):
        d = {"kind": self.kind, "label": self.label, "axis": self.axis, "statistic": float(self.statistic),
             "threshold": float(self.threshold), "detected": self.detected,
             "params": self.params, "evidence": self.evidence, "note": self.note}
        if self.not_checked:
            d["not_checked"] = self.not_checked
        return d


@dataclass
class Context:
    """Inputs of the detectors.

    model : current DriveModel; recipe : its Recipe; train : list of training traces whose
    ``vel`` role is the model's free-run velocity (for refits); res : Residuals of the model on
    each training trace; settings : dict (``maxiter``, ``exclude`` channels, ``max_delay``);
    refits : :class:`.refits.Refits`, where independent refits run (default: in this process)
    """

    model: object
    recipe: object
    train: list
    res: list
    settings: dict = field(default_factory=dict)
    refits: Refits = field(default_factory=Refits)

    @property
    def Ts(self):
        return self.model.Ts


def command_velocity(cmd, Ts):
    """Commanded velocity (mm/s), central differences."""
    return np.gradient(np.asarray(cmd, float), Ts)


def motion_events(cmd, Ts, frac=0.02):
    """Starts, stops and reversals of the commanded motion.

    Returns
    -------
    list of (k, kind, direction): kind ``start`` (from rest or a reversal: direction of the new
    motion) or ``stop`` (direction of the motion that ended); |v_cmd| > frac * max|v_cmd| is moving.
    """
    v = command_velocity(cmd, Ts)
    vmax = float(np.max(np.abs(v))) if v.size else 0.0
    if vmax <= 0:
        return []
    s = np.where(np.abs(v) > frac * vmax, np.sign(v), 0.0)
    ev = []
    for k in np.flatnonzero(np.diff(s) != 0) + 1:
        if s[k - 1] != 0:
            ev.append((int(k), "stop", float(s[k - 1])))
        if s[k] != 0:
            ev.append((int(k), "start", float(s[k])))
    return ev


def scan_refine(f, xs, map=map):
    """Minimise f over the grid xs, then a parabola through the best point and its neighbours
    (when all three are finite). ``map``: how f is evaluated over the grid (e.g.
    :meth:`.refits.Refits.map`, which needs a picklable f)."""
    vals = np.array(list(map(f, xs)))
    k = int(np.argmin(vals))
    best = float(xs[k])
    if 0 < k < len(xs) - 1 and np.all(np.isfinite(vals[k - 1:k + 2])):   # inf: an infeasible point
        x0, x1, x2 = xs[k - 1], xs[k], xs[k + 1]
        y0, y1, y2 = vals[k - 1], vals[k], vals[k + 1]
        den = (x0 - x1) * (x0 - x2) * (x1 - x2)
        A = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
        B = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den
        if A > 0:
            xv = -B / (2 * A)
            if x0 < xv < x2:
                best = float(xv)
    return best, vals


# a mode is a resonance: its pair's peak |H| / H(0) = 1 / (2 zeta sqrt(1 - zeta^2)) is at least
# 3 dB (sqrt 2) for zeta <= sin(22.5 deg). A mode multiplies every numerator by a quadratic
# (augment._times_quadratic), so a heavily damped pair with those zeros is a Pade approximant of
# a dead time: the virtual drive's 3-sample delay was fitted as 190 Hz, zeta 0.47, on the thesis
# model (true modes: 0.06 there; plant2 0.17-0.22, its delay 0.40; README)
MODE_MAX_DAMPING = float(np.sin(np.pi / 8))


def implausible(effect):
    """Reason a fitted effect is physically implausible, or '' (checked before keeping it)."""
    if effect.get("kind") == "stribeck" and not effect.get("ratio_to_coulomb", 1.0) > 0:
        return "the fitted breakaway excess is not positive (not a Stribeck effect)"
    if effect.get("kind") == "mode" and not effect.get("damping", 0.1) <= MODE_MAX_DAMPING:
        return (f"the fitted pair is not lightly damped (damping {effect.get('damping', float('nan')):.2f} "
                f"> {MODE_MAX_DAMPING:.3f}: no resonance peak of 3 dB); a dead time or loop dynamics "
                "the structure lacks, not a mode")
    return ""
