"""Watching for change: the new model of an axis against the last one, with evidence.

For one axis, :func:`compare_models` puts side by side

* **prediction error of the old model on the new traces** against the old model's error on its
  own traces, per measured channel (``motor``: the model's position vs the encoder; ``tool``:
  vs the tool-side channel, when the traces have one). A plant that changed is predicted worse
  by the model of the plant it was;
* **friction level**: the peak of the model's friction-to-tracking-error step response (µm per
  unit of the normalised Coulomb input d_nf, thesis Eqn 4.12-4.14: d0 s/P(s) for a loop with
  integral action). A step response compares models whatever their pole parameterisation;
* **friction band** v_tilde (mm/s) of the friction nonlinearity;
* **poles**: continuous poles sorted by magnitude, relative change of the magnitude of those in
  [``pole_min_hz``, ``pole_max_fraction``/Ts] (faster poles are beyond what a trace at Ts pins down);
* **added effects**: effect kinds diagnosis kept in the new model but not in the old one.

An axis is flagged when the old model predicts the new traces worse than its own, beyond the
thresholds (the test that does not depend on how an identification parameterises the plant: on
short traces two fits of the same plant can differ in friction level or fast poles by tens of
per cent and predict equally well), or when diagnosis added an effect the old model did not have
(``effects``). The parameter comparisons then name the change: ``friction`` (level or band), ``backlash`` (the grown residual is a
direction-dependent offset: r ~ b * direction, R^2 >= ``backlash_r2``, backlash ~ 2|b|),
``resonance`` (the grown residual has a spectral peak holding >= ``peak_fraction`` of its energy
above 3 Hz, or diagnosis added a mode), else ``dynamics``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..errors import InputError

__all__ = ["Thresholds", "ModelSignature", "ChangeReport", "model_signature", "friction_step_peak_um",
           "residual_signature", "compare_models"]


@dataclass(frozen=True)
class Thresholds:
    """Change thresholds (a manifest's ``[thresholds]`` table sets any of them).

    Attributes
    ----------
    error_ratio : float       old model's RMS error on the new traces > error_ratio x its RMS on its
                              own traces (per channel) ...
    error_floor_um : float    ... and larger by at least this many µm
    friction_rel : float      |friction step peak new / old - 1| above this
    v_tilde_factor : float    friction band changes by more than this factor (either way)
    pole_rel : float          a pole magnitude in the band changes by more than this fraction
    pole_min_hz : float       lower end of the compared pole band [Hz]
    pole_max_fraction : float upper end of the band = pole_max_fraction / Ts [Hz]
    effects : bool            flag effects diagnosis added that the old model did not have
    backlash_r2 : float       naming: direction term explains this share of the grown residual
    peak_fraction : float     naming: one spectral peak holds this share of its energy above 3 Hz
    """

    error_ratio: float = 2.0
    error_floor_um: float = 1.0
    friction_rel: float = 0.25
    v_tilde_factor: float = 30.0
    pole_rel: float = 0.5
    pole_min_hz: float = 2.0
    pole_max_fraction: float = 0.2
    effects: bool = True
    backlash_r2: float = 0.5
    peak_fraction: float = 0.2

    @classmethod
    def from_dict(cls, d, source="[thresholds]"):
        names = {f.name: f.type for f in fields(cls)}
        out = {}
        for k, v in (d or {}).items():
            if k not in names:
                raise InputError(f"unknown threshold '{k}'; expected one of {sorted(names)}", source=source,
                                 column=k)
            if k == "effects":
                if not isinstance(v, bool):
                    raise InputError(f"'effects' must be true or false, got {v!r}", source=source, column=k)
                out[k] = v
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v < 0:
                raise InputError(f"threshold '{k}' must be a non-negative number, got {v!r}", source=source,
                                 column=k)
            out[k] = float(v)
        return cls(**out)

    def to_dict(self):
        return asdict(self)


@dataclass
class ModelSignature:
    """What is compared of one model (JSON-able numbers only).

    Attributes
    ----------
    poles_hz : list of [re, im]   continuous poles / 2 pi [Hz], sorted by magnitude
    friction_peak_um : float or None   peak of the friction -> error step response [µm]
    v_tilde_mm_s : float or None
    effects : list of str         effect kinds added by diagnosis (``mode@30.1Hz`` style labels)
    Ts : float
    """

    poles_hz: list = field(default_factory=list)
    friction_peak_um: float | None = None
    v_tilde_mm_s: float | None = None
    effects: list = field(default_factory=list)
    Ts: float = 0.0


@dataclass
class ChangeReport:
    """Result of comparing a new model with the previous one of the same axis.

    Attributes
    ----------
    changed : bool
    kinds : list of str       named changes: friction, backlash, resonance, dynamics, effect
    summary : str             one line for the maintenance engineer
    evidence : list of str    every test that fired, with its numbers and threshold
    errors_um : dict          channel -> {"old_on_old", "old_on_new", "new_on_new"} RMS [µm]
    friction_rel : float or None
    v_tilde_factor : float or None
    pole_rel : list of float  relative change per compared pole
    new_effects : list of str
    estimates : dict          e.g. {"backlash_um": 19.6, "resonance_hz": 30.2}
    previous : str            where the old model came from
    """

    changed: bool = False
    kinds: list = field(default_factory=list)
    summary: str = "no change"
    evidence: list = field(default_factory=list)
    errors_um: dict = field(default_factory=dict)
    friction_rel: float | None = None
    v_tilde_factor: float | None = None
    pole_rel: list = field(default_factory=list)
    new_effects: list = field(default_factory=list)
    estimates: dict = field(default_factory=dict)
    previous: str = ""

    @classmethod
    def from_dict(cls, d):
        return cls(**d) if d is not None else None


# ----------------------------------------------------------------------------- model figures
def friction_step_peak_um(model, axis, seconds=0.5):
    """Peak |tracking error| [µm] of the model's response to a unit step of the axis's friction
    input (its linear part; ``level`` included). None when the model has no friction input."""
    j = next((i for i, p in enumerate(model.inputs) if p.kind == "friction" and p.axis == axis), None)
    o = next((i for i, p in enumerate(model.outputs) if p.kind == "error" and p.axis == axis), None)
    if o is None:
        o = next((i for i, p in enumerate(model.outputs) if p.kind == "position" and p.axis == axis), None)
    if j is None or o is None:
        return None
    level = float(model.inputs[j].params.get("level", 1.0))
    A, b, c, d = model.A, model.B[:, j], model.C[o], model.D[o, j]
    x = np.zeros(model.n_states)
    peak = abs(d)
    for _ in range(max(1, int(round(seconds / model.Ts)))):
        x = A @ x + b
        peak = max(peak, abs(c @ x + d))
    return float(peak * level * 1e3)


def _effect_label(e):
    kind = str(e.get("kind", "effect"))
    if kind == "mode" and e.get("frequency_hz"):
        return f"mode@{float(e['frequency_hz']):.1f}Hz"
    if kind in ("coupling", "extra_input") and e.get("channel"):
        return f"{kind}:{e['channel']}"
    return kind


def model_signature(model, axis) -> ModelSignature:
    """The numbers :func:`compare_models` compares, from a DriveModel (one axis)."""
    poles = sorted((complex(p) for p in model.poles), key=lambda p: (abs(p), p.imag))
    poles = [[float(p.real / (2 * np.pi)), float(p.imag / (2 * np.pi))] for p in poles if p.imag >= 0]
    fr = next((p for p in model.inputs if p.kind == "friction" and p.axis == axis), None)
    return ModelSignature(poles_hz=poles, friction_peak_um=friction_step_peak_um(model, axis),
                          v_tilde_mm_s=float(fr.params["v_tilde"]) if fr is not None else None,
                          effects=[_effect_label(e) for e in model.effects if e.get("axis", axis) == axis],
                          Ts=float(model.Ts))


# ----------------------------------------------------------------------------- residual analysis
def direction_of_motion(cmd):
    """+1 / -1: the direction of the last commanded motion, held through stops (0 before the
    first move)."""
    d = np.sign(np.diff(np.asarray(cmd, float), prepend=cmd[0]))
    idx = np.where(d != 0, np.arange(d.size), 0)
    np.maximum.accumulate(idx, out=idx)
    out = d[idx]
    out[: np.argmax(d != 0) if np.any(d != 0) else d.size] = 0.0
    return out


def residual_signature(residual, cmd, Ts):
    """Shape of a residual (measured - predicted position, mm): backlash-like or resonant?

    Returns
    -------
    dict  ``direction_r2`` (share of variance explained by b * direction + c), ``backlash_um``
          (2|b|), ``peak_hz`` (largest spectral peak above 3 Hz), ``peak_fraction`` (share of
          the energy above 3 Hz within +-10 % of it)
    """
    r = np.asarray(residual, float)
    r = r - r.mean()
    dirn = direction_of_motion(cmd)
    X = np.column_stack([dirn, np.ones_like(dirn)])
    coef, *_ = np.linalg.lstsq(X, r, rcond=None)
    fit = X @ coef
    var = float(r @ r)
    r2 = float(1 - np.sum((r - fit) ** 2) / var) if var > 0 else 0.0
    rr = r - fit                                 # what the direction term leaves
    spec = np.abs(np.fft.rfft(rr * np.hanning(rr.size))) ** 2
    f = np.fft.rfftfreq(rr.size, Ts)
    band = f >= 3.0
    if not band.any() or spec[band].sum() <= 0:
        return {"direction_r2": r2, "backlash_um": float(2 * abs(coef[0]) * 1e3), "peak_hz": None,
                "peak_fraction": 0.0}
    k = np.argmax(np.where(band, spec, -1))
    near = band & (np.abs(f - f[k]) <= 0.1 * f[k] + 2 * (f[1] - f[0]))
    return {"direction_r2": r2, "backlash_um": float(2 * abs(coef[0]) * 1e3), "peak_hz": float(f[k]),
            "peak_fraction": float(spec[near].sum() / spec[band].sum())}


# ----------------------------------------------------------------------------- comparison
def compare_models(old_sig: ModelSignature, new_sig: ModelSignature, errors_um: dict, residuals: dict,
                   thresholds: Thresholds, previous="") -> ChangeReport:
    """Compare an axis's new model with its previous one.

    Parameters
    ----------
    old_sig, new_sig : ModelSignature
    errors_um : dict channel -> {"old_on_old", "old_on_new", "new_on_new"} RMS [µm]
    residuals : dict channel -> (residual mm, cmd mm, Ts): the old model's residual on the new
        traces (for naming what grew)
    thresholds : Thresholds

    Returns
    -------
    ChangeReport
    """
    th = thresholds
    rep = ChangeReport(errors_um={k: dict(v) for k, v in errors_um.items()}, previous=str(previous))
    ev, kinds = rep.evidence, []
    grown = []
    for ch, e in errors_um.items():
        oo, on = e.get("old_on_old"), e.get("old_on_new")
        if oo is None or on is None:
            continue
        if on > th.error_ratio * oo and on - oo > th.error_floor_um:
            grown.append(ch)
            ev.append(f"{ch}: old model's error on the new traces {on:.3g} µm RMS vs {oo:.3g} µm on its own "
                      f"({on / oo if oo > 0 else float('inf'):.2g}x > {th.error_ratio:g}x and +{on - oo:.3g} µm "
                      f"> {th.error_floor_um:g} µm); the new model: {e.get('new_on_new', float('nan')):.3g} µm")
    named = []                     # parameter changes beyond their thresholds (name a change)
    fp_o, fp_n = old_sig.friction_peak_um, new_sig.friction_peak_um
    if fp_o and fp_n:
        rep.friction_rel = fp_n / fp_o - 1.0
        if abs(rep.friction_rel) > th.friction_rel:
            named.append(("friction", f"friction level {'up' if rep.friction_rel > 0 else 'down'} "
                          f"{abs(rep.friction_rel):.0%}: step-response peak {fp_o:.3g} -> {fp_n:.3g} µm "
                          f"(threshold {th.friction_rel:.0%})"))
    vt_o, vt_n = old_sig.v_tilde_mm_s, new_sig.v_tilde_mm_s
    if vt_o and vt_n:
        rep.v_tilde_factor = vt_n / vt_o
        if max(rep.v_tilde_factor, 1 / rep.v_tilde_factor) > th.v_tilde_factor:
            named.append(("friction", f"friction band v_tilde {vt_o:.3g} -> {vt_n:.3g} mm/s "
                          f"(x{rep.v_tilde_factor:.3g}; threshold x{th.v_tilde_factor:g})"))
    hi = th.pole_max_fraction / new_sig.Ts if new_sig.Ts else np.inf
    po = sorted(float(np.hypot(*p)) for p in old_sig.poles_hz)
    pn = sorted(float(np.hypot(*p)) for p in new_sig.poles_hz)
    moved = []
    for a in po:                   # each old pole in the band against the nearest new one
        if th.pole_min_hz <= a <= hi and pn:
            b = min(pn, key=lambda x: abs(x - a))
            rel = abs(b - a) / a
            rep.pole_rel.append(float(rel))
            if rel > th.pole_rel:
                moved.append((a, b))
    if moved:
        named.append(("dynamics", "poles moved: " + ", ".join(f"{a:.3g} -> {b:.3g} Hz" for a, b in moved)
                      + f" (threshold {th.pole_rel:.0%} in [{th.pole_min_hz:g}, {hi:.3g}] Hz)"))
    old_kinds = {x.split("@")[0] for x in old_sig.effects}
    rep.new_effects = [e for e in new_sig.effects if e.split("@")[0] not in old_kinds]
    if rep.new_effects and th.effects:
        ev.append(f"diagnosis added {rep.new_effects} (previous model: {old_sig.effects or 'none'})")
        for e in rep.new_effects:
            k = {"mode": "resonance", "backlash": "backlash", "stribeck": "friction",
                 "asymmetric_friction": "friction"}.get(e.split("@")[0].split(":")[0], "effect")
            kinds.append(k)
            if k == "resonance" and "@" in e:
                rep.estimates.setdefault("resonance_hz", float(e.split("@")[1].rstrip("Hz")))
    if grown:
        # the prediction got worse: name the change from the parameters that moved ...
        # (friction acts where the model predicts: its change names a change only when that
        # channel -- the motor side, or the tool side of a tool-side model -- got worse)
        primary = "motor" if "motor" in errors_um else "tool"
        for k, line in named:
            if k == "friction" and primary in grown:
                kinds.append(k)
                ev.append(line)
            else:
                ev.append(line + f" -- not used to name the change ({primary} side within the thresholds)"
                          if k == "friction" else line)
        # ... and from the shape of what grew: the tool side only when the motor side did not
        # grow with it (else the motor explains it), the model's own side only when the
        # friction level did not move (else friction explains it)
        for ch in grown:
            if ch not in residuals or (ch == "tool" and "motor" in grown):
                continue
            if ch == primary and "friction" in kinds:
                continue               # the friction change explains what grew there
            sig = residual_signature(*residuals[ch])
            if sig["direction_r2"] >= th.backlash_r2 and "friction" not in kinds:
                kinds.append("backlash")
                rep.estimates["backlash_um"] = sig["backlash_um"]
                ev.append(f"{ch} residual is a direction-dependent offset (R^2 {sig['direction_r2']:.2f} >= "
                          f"{th.backlash_r2:g}): lost motion ~ {sig['backlash_um']:.3g} µm")
            elif sig["peak_hz"] and sig["peak_fraction"] >= th.peak_fraction:
                kinds.append("resonance")
                rep.estimates["resonance_hz"] = sig["peak_hz"]
                ev.append(f"{ch} residual has a spectral peak at {sig['peak_hz']:.3g} Hz holding "
                          f"{sig['peak_fraction']:.0%} of its energy above 3 Hz (>= {th.peak_fraction:.0%})")
        if not kinds:
            kinds.append("dynamics")
    else:
        for _, line in named:
            ev.append(line + " -- not flagged: the old model still predicts the new traces within "
                      "the error thresholds")
    rep.kinds = list(dict.fromkeys(kinds))
    rep.changed = bool(rep.kinds)
    rep.summary = _summary(rep) if rep.changed else "no change beyond the thresholds"
    return rep


def _summary(rep):
    parts = []
    for k in rep.kinds:
        if k == "friction" and rep.friction_rel is not None:
            parts.append(f"friction level {'up' if rep.friction_rel > 0 else 'down'} {abs(rep.friction_rel):.0%}")
        elif k == "friction":
            parts.append(f"friction band x{rep.v_tilde_factor:.3g}")
        elif k == "backlash":
            b = rep.estimates.get("backlash_um")
            parts.append(f"backlash / lost motion ~{b:.0f} µm" if b else "backlash")
        elif k == "resonance":
            f = rep.estimates.get("resonance_hz")
            parts.append(f"new resonance ~{f:.0f} Hz" if f else "new resonance")
        elif k == "dynamics":
            parts.append("dynamics changed (poles / prediction error)")
        else:
            parts.append(f"new effect(s) {rep.new_effects}")
    return "; ".join(parts)
