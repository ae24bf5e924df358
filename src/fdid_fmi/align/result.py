"""Typed results of the alignment chain: each step's estimate with its uncertainty.

An :class:`AlignmentResult` holds the aligned :class:`~fdid_fmi.trace.Trace` and, per sensor,
a :class:`SensorAlignment` listing every step (:class:`Estimate`: value, 1-sigma uncertainty,
unit, method) and one line per thing that could not be estimated (``missing``).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from ..trace import Trace

__all__ = ["Estimate", "SensorAlignment", "AlignmentResult"]


def _plain(v):
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if np.isfinite(f) else None
    if isinstance(v, (np.integer,)):
        return int(v)
    return v


@dataclass(frozen=True)
class Estimate:
    """One estimated quantity of one alignment step.

    Attributes
    ----------
    step : str          ``timing``, ``orientation``, ``gravity_bias``, ``offset``, ``resample``
    name : str          e.g. ``time_offset``, ``clock_drift``, ``alpha``
    value : float or list
    uncertainty : float or list or None   1-sigma; None when not known (said in ``note``)
    unit : str          ``s``, ``ppm``, ``deg``, ``mm``, ``mm/s^2``, ``Hz``
    method : str        how it was estimated (thesis section / equation)
    note : str
    """

    step: str
    name: str
    value: object
    uncertainty: object
    unit: str
    method: str
    note: str = ""

    def to_dict(self):
        return {"step": self.step, "name": self.name, "value": _plain(self.value),
                "uncertainty": _plain(self.uncertainty), "unit": self.unit, "method": self.method,
                "note": self.note}

    def text(self, digits=4):
        def fmt(v):
            if isinstance(v, (list, tuple, np.ndarray)):
                return "(" + ", ".join(fmt(x) for x in v) + ")"
            if v is None or not np.isfinite(float(v)):     # as in to_dict (null): not known
                return "?"
            return f"{float(v):.{digits}g}"
        unc = _plain(self.uncertainty)
        u = "" if unc is None else f" ± {fmt(unc)}"
        return f"{fmt(self.value)}{u} {self.unit}"


@dataclass
class SensorAlignment:
    """Everything estimated for one sensor.

    Attributes
    ----------
    name, kind, source : str
    rate_hz : float                   nominal rate of the file
    estimates : list[Estimate]
    missing : list[str]               one line per quantity that could not be estimated
    mapping : (offset_s, scale)       controller time t = offset_s + scale * tau (sensor clock)
    rotation : (3, 3) list or None    sensor -> machine (accelerometer) / plate -> machine (KGM)
    constant : list or None           accelerometer gravity + bias, sensor frame, mm/s^2
    offset_mm : list or None          grid-encoder plate origin in machine coordinates
    axes_out : dict axis -> channel   what this sensor contributed to the trace
    """

    name: str
    kind: str
    source: str
    rate_hz: float
    estimates: list = field(default_factory=list)
    missing: list = field(default_factory=list)
    mapping: tuple = (0.0, 1.0)
    rotation: list | None = None
    direction: dict = field(default_factory=dict)
    constant: list | None = None
    offset_mm: list | None = None
    axes_out: dict = field(default_factory=dict)

    def get(self, name) -> Estimate:
        for e in self.estimates:
            if e.name == name:
                return e
        raise KeyError(f"sensor '{self.name}' has no estimate '{name}' "
                       f"(has {[e.name for e in self.estimates]})")

    def to_dict(self):
        return {"name": self.name, "kind": self.kind, "source": self.source, "rate_hz": self.rate_hz,
                "mapping": {"offset_s": _plain(self.mapping[0]), "scale": _plain(self.mapping[1])},
                "rotation": _plain(self.rotation), "direction": _plain(self.direction),
                "constant_mm_s2": _plain(self.constant), "offset_mm": _plain(self.offset_mm),
                "axes_out": dict(self.axes_out), "estimates": [e.to_dict() for e in self.estimates],
                "missing": list(self.missing)}


@dataclass
class AlignmentResult:
    """The aligned trace and what every step found.

    Attributes
    ----------
    trace : Trace              controller samples (cropped to the sensors' common overlap)
                               plus tool-side ``tool`` / ``acc`` channels with their roles
    sensors : list[SensorAlignment]
    window : (t0, t1)          controller-time range kept, s
    settings : dict            the parameters used (low-pass, windows, anti-alias cut-off)
    """

    trace: Trace
    sensors: list
    window: tuple
    settings: dict = field(default_factory=dict)

    @property
    def missing(self) -> list:
        return [m for s in self.sensors for m in s.missing]

    def sensor(self, name) -> SensorAlignment:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(f"no sensor '{name}' (sensors: {[s.name for s in self.sensors]})")

    def orientation(self) -> dict:
        """``{sensor name: 3x3 rotation}`` to reuse on another run of the same mounting."""
        return {s.name: np.array(s.rotation) for s in self.sensors
                if s.kind == "accelerometer" and s.rotation is not None}

    def to_dict(self):
        return {"format": "fdid-fmi alignment", "version": 1,
                "window_s": [_plain(self.window[0]), _plain(self.window[1])],
                "Ts": self.trace.Ts, "settings": _plain_dict(self.settings),
                "sensors": [s.to_dict() for s in self.sensors], "missing": self.missing}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=1)

    def table(self) -> str:
        """Markdown table: sensor, step, quantity, estimate ± 1 sigma, method."""
        rows = ["| sensor | step | quantity | estimate | method |", "|---|---|---|---|---|"]
        for s in self.sensors:
            for e in s.estimates:
                rows.append(f"| {s.name} | {e.step} | {e.name} | {e.text()} | {e.method} |")
        for m in self.missing:
            rows.append(f"| | missing | | {m} | |")
        return "\n".join(rows)


def _plain_dict(d):
    return {k: (_plain_dict(v) if isinstance(v, dict) else _plain(v)) for k, v in d.items()}
