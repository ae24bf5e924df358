"""The measured (or simulated) trace: a fixed sample time and named channels with units.

A ``Trace`` is what every reader returns and what every identifier takes. Channels
keep their unit; readers convert positions to mm (the CNC convention). Per-axis
*roles* say what a channel means for identification:

=========  ==============================================  ==========
role       meaning                                         unit
=========  ==============================================  ==========
``cmd``    commanded (reference) position x_r              mm / deg
``act``    measured position x (motor encoder)             mm / deg
``tool``   tool-side position (grid encoder, KGM)          mm / deg
``vel``    measured velocity                               mm/s
``acc``    measured (tool-side) acceleration               mm/s^2
``cur``    motor current / controller output               A, V, ...
=========  ==============================================  ==========

Channels with no role are kept as *extra* channels (e.g. EMPS ``pulses_N``).
Tracking error is e = x_cmd - x (thesis convention).
"""
from __future__ import annotations

import functools

import hashlib
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError

ROLES = ("cmd", "act", "tool", "vel", "acc", "cur")


@dataclass(frozen=True)
class Channel:
    """One named signal of a trace.

    Attributes
    ----------
    name : str
    unit : str (canonical spelling, see ``fdid_fmi.units``)
    data : ndarray, read-only float64, one value per sample
    """

    name: str
    unit: str
    data: np.ndarray

    def __post_init__(self):
        arr = np.array(self.data, dtype=float)  # always a private copy
        arr.setflags(write=False)
        object.__setattr__(self, "data", arr)

    @classmethod
    def adopt(cls, name, unit, data):
        """A channel over ``data`` itself, made read-only, without the private copy: for a
        float64 array its caller built and hands over (a reader's parsed column, which on a
        long trace is as large as the file). Anything else gets the copy."""
        if not (isinstance(data, np.ndarray) and data.dtype == np.float64 and data.base is None
                and data.ndim == 1 and data.flags.c_contiguous):
            return cls(name, unit, data)
        ch = cls.__new__(cls)
        data.setflags(write=False)
        for key, value in (("name", name), ("unit", unit), ("data", data)):
            object.__setattr__(ch, key, value)
        return ch


@dataclass
class Trace:
    """A fixed-sample-time record of named channels.

    Parameters
    ----------
    t : array_like, s
        Sample times, strictly increasing with a steady step.
    channels : dict[str, Channel] or list[Channel]
    roles : dict[str, dict[str, str]]
        ``roles[axis][role] = channel name``, e.g. ``{"x": {"cmd": "x_cmd_mm", "act": "x_mm"}}``.
    source : str
        Where it came from (file path or a description); used in error messages.
    meta : dict
        Free-form facts (controller gains, truth of a virtual drive, file hash...).
    jitter_tol : float
        Largest allowed relative deviation of a time step from the median step.
    """

    t: np.ndarray
    channels: dict
    roles: dict = field(default_factory=dict)
    source: str = "<memory>"
    meta: dict = field(default_factory=dict)
    jitter_tol: float = 0.05

    def __post_init__(self):
        if isinstance(self.channels, (list, tuple)):
            names = [c.name for c in self.channels]
            dup = next((nm for k, nm in enumerate(names) if nm in names[:k]), None)
            if dup is not None:         # the dict would keep the last one without a word
                raise InputError("two channels have this name", source=self.source, column=dup)
            self.channels = {c.name: c for c in self.channels}
        t = np.array(self.t, dtype=float)
        t.setflags(write=False)
        self.t = t
        self._check()

    # ------------------------------------------------------------------ checks
    def _check(self):
        src = self.source
        n = self.t.size
        if self.t.ndim != 1:
            raise InputError(f"time must be one column of numbers, got an array of shape {self.t.shape}",
                             source=src, column="time")
        if n < 2:
            raise InputError(f"a trace needs at least 2 samples, got {n}", source=src, column="time")
        bad = ~np.isfinite(self.t)
        if bad.any():
            raise InputError("time is not a finite number", source=src, column="time",
                             row=int(np.argmax(bad)) + 1)
        fault = time_grid_fault(self.t, self.jitter_tol)
        if fault is not None:
            kind, k = fault[0], fault[1]
            if kind == "order":
                raise InputError(f"time is not strictly increasing ({float(self.t[k]):.9g} then "
                                 f"{float(self.t[k + 1]):.9g})", source=src, column="time", row=k + 2)
            if kind == "jitter":
                raise InputError(
                    f"sample time is not steady: step {fault[2]:.6g} s against the median {fault[3]:.6g} s "
                    f"(tolerance {self.jitter_tol:.0%}); resample the trace first",
                    source=src, column="time", row=k + 2)
            raise InputError(f"the time stamps drift from a uniform grid (more than half a sample at "
                             f"t = {float(self.t[k]):.6g} s): more than one sample rate; resample the "
                             f"trace first", source=src, column="time", row=k + 1)
        for name, ch in self.channels.items():
            if ch.data.ndim != 1:
                raise InputError(f"must be one column of numbers, got an array of shape {ch.data.shape}",
                                 source=src, column=name)
            if ch.data.shape != (n,):
                raise InputError(f"has {ch.data.size} samples but time has {n}", source=src, column=name)
            nonfinite = ~np.isfinite(ch.data)
            if nonfinite.any():
                raise InputError("contains NaN or inf", source=src, column=name,
                                 row=int(np.argmax(nonfinite)) + 1)
        for axis, rmap in self.roles.items():
            for role, cname in rmap.items():
                if role not in ROLES:
                    raise InputError(f"unknown role '{role}' for axis '{axis}'; expected one of {ROLES}",
                                     source=src, column=cname)
                if cname not in self.channels:
                    raise InputError(f"role {axis}.{role} names a channel that is not in the trace "
                                     f"(channels: {sorted(self.channels)})", source=src, column=cname)

    # -------------------------------------------------------------- accessors
    @functools.cached_property
    def Ts(self) -> float:
        """Sample time in s: the nominal step the record was taken at (:func:`nominal_sample_time`),
        a clean decimal such as 0.0006 or 0.001 when the time column is within a quarter sample
        of that grid, else the mean step."""
        return nominal_sample_time(self.t)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def axes(self) -> list:
        return list(self.roles)

    def has(self, axis, role) -> bool:
        return role in self.roles.get(axis, {})

    def channel(self, axis, role) -> Channel:
        try:
            return self.channels[self.roles[axis][role]]
        except KeyError:
            have = {a: sorted(r) for a, r in self.roles.items()}
            raise InputError(f"needs the '{role}' channel of axis '{axis}', which is not mapped "
                             f"(mapped roles: {have})", source=self.source, column=f"{axis}.{role}")

    def get(self, axis, role) -> np.ndarray:
        """Data of a role channel (read-only view)."""
        return self.channel(axis, role).data

    def cmd(self, axis) -> np.ndarray:
        return self.get(axis, "cmd")

    def act(self, axis) -> np.ndarray:
        return self.get(axis, "act")

    def error(self, axis) -> np.ndarray:
        """Tracking error e = x_cmd - x (mm)."""
        return self.cmd(axis) - self.act(axis)

    def extra(self, name) -> np.ndarray:
        if name not in self.channels:
            raise InputError(f"no channel named '{name}' (channels: {sorted(self.channels)})",
                             source=self.source, column=name)
        return self.channels[name].data

    @property
    def extra_channels(self) -> list:
        used = {c for r in self.roles.values() for c in r.values()}
        return [c for c in self.channels if c not in used]

    def fingerprint(self) -> str:
        """sha256 of time and channel data (provenance of identified models)."""
        h = hashlib.sha256(self.t.tobytes())
        for name in sorted(self.channels):
            h.update(name.encode())
            h.update(self.channels[name].data.tobytes())
        return h.hexdigest()

    # ---------------------------------------------------------- derived traces
    def _with(self, t, channels, source_suffix):
        return Trace(t=t, channels=channels, roles={a: dict(r) for a, r in self.roles.items()},
                     source=self.source + source_suffix, meta=dict(self.meta), jitter_tol=self.jitter_tol)

    def slice(self, start=None, stop=None) -> "Trace":
        """Samples with ``start <= t <= stop`` (seconds) as a new Trace."""
        t0, t1 = self.t[0], self.t[-1]
        a = t0 if start is None else float(start)
        b = t1 if stop is None else float(stop)
        if not (a < b):
            raise InputError(f"range start {a} s must be before its end {b} s", source=self.source,
                             column="range")
        tol = 0.5 * self.Ts
        if a < t0 - tol or b > t1 + tol:
            raise InputError(f"range [{a}, {b}] s lies outside the data [{t0}, {t1}] s",
                             source=self.source, column="range")
        # a bound on a sample counts within float rounding: 1e-9 relative, but at most a
        # thousandth of a sample (1e-9 |t| alone is 1.7 s for time stamps in epoch seconds)
        ea, eb = (min(1e-9 * max(1.0, abs(v)), 1e-3 * self.Ts) for v in (a, b))
        m = (self.t >= a - ea) & (self.t <= b + eb)
        if m.sum() < 2:
            raise InputError(f"range [{a}, {b}] s holds fewer than 2 samples", source=self.source,
                             column="range")
        chans = {k: Channel(c.name, c.unit, c.data[m]) for k, c in self.channels.items()}
        out = self._with(self.t[m], chans, f"[{a:g}:{b:g}s]")
        # the same grid: a few samples cannot tell its step from a rounder one (1.05 ms -> 1 ms)
        out.__dict__["Ts"] = self.Ts
        return out

    def select(self, ranges) -> list:
        """Split into data ranges (the thesis GUI allows up to four).

        Parameters
        ----------
        ranges : sequence of (start_s, stop_s), or None for the whole trace

        Returns
        -------
        list[Trace]
        """
        if not ranges:
            return [self]
        return [self.slice(a, b) for a, b in ranges]

    def resample(self, Ts) -> "Trace":
        """Linear interpolation onto a uniform grid of step ``Ts`` (s)."""
        if not (np.isfinite(Ts) and Ts > 0):
            raise InputError(f"resample step must be a positive number of seconds, got {Ts!r}",
                             source=self.source, column="Ts")
        n = int(np.floor((self.t[-1] - self.t[0]) / Ts + 1e-9)) + 1
        t = self.t[0] + Ts * np.arange(n)
        chans = {k: Channel(c.name, c.unit, np.interp(t, self.t, c.data)) for k, c in self.channels.items()}
        return self._with(t, chans, f"@{Ts:g}s")

    @classmethod
    def from_arrays(cls, t, axes, extra=None, source="<arrays>", meta=None, units=None):
        """Build a trace from arrays.

        Parameters
        ----------
        t : array (s)
        axes : dict ``{axis: {role: array}}`` in canonical units (mm, mm/s, ...)
        extra : dict ``{name: array}`` of channels with no role
        units : dict ``{channel name: unit}`` for extra channels (default "1")
        """
        default_unit = {"cmd": "mm", "act": "mm", "tool": "mm", "vel": "mm_s", "acc": "mm_s2", "cur": "A"}
        channels, roles = {}, {}
        for axis, rmap in axes.items():
            roles[axis] = {}
            for role, data in rmap.items():
                name = f"{axis}_{role}"
                channels[name] = Channel(name, default_unit.get(role, "1"), data)
                roles[axis][role] = name
        for name, data in (extra or {}).items():
            channels[name] = Channel(name, (units or {}).get(name, "1"), data)
        return cls(t=t, channels=channels, roles=roles, source=source, meta=dict(meta or {}))


def time_grid_fault(t, jitter_tol):
    """The first fault of a time vector's grid, or None (one rule for :class:`Trace` and the file
    readers, which word their errors each their own way):

    * ``("order", k)``: t[k + 1] <= t[k];
    * ``("jitter", k, step, median)``: step k = t[k + 1] - t[k] deviates from the median step by
      more than ``jitter_tol`` of it;
    * ``("drift", k)``: stamp k is more than half a sample off the uniform grid (:func:`off_grid`).
    """
    dt = np.diff(t)
    bad = dt <= 0
    if bad.any():
        return "order", int(np.argmax(bad))
    ts = float(np.median(dt))
    dev = np.abs(dt - ts)
    jit = dev > jitter_tol * ts
    del dev
    if jit.any():
        k = int(np.argmax(jit))
        return "jitter", k, float(dt[k]), ts
    del dt, jit
    k = off_grid(t)
    return None if k is None else ("drift", k)


def off_grid(t, tol=0.5):
    """Index of the time stamp farthest from the uniform grid t0 + k (t[-1] - t[0]) / (n - 1) when
    it is more than ``tol`` samples away, else None. Each step may pass the jitter check while
    the stamps drift (two sample rates in one record): the simulators' uniform grid would then put
    samples at the wrong times."""
    t = np.asarray(t, float)
    ts = (t[-1] - t[0]) / (t.size - 1)
    dev = t - t[0]
    grid = np.arange(t.size, dtype=float)
    grid *= ts
    dev -= grid
    del grid
    np.abs(dev, out=dev)
    k = int(np.argmax(dev))
    return k if dev[k] > tol * ts else None


def nominal_sample_time(t, max_digits=9, tol=0.25):
    """The sample time a time column was recorded at, as the shortest clean decimal.

    A controller samples at a round period (0.6 ms, 1 ms, 125 us); the exported time column
    carries rounding (0.00059999999999998943 s) or a float32 clock (EMPS: steps of 0.99998 to
    1.00002 ms). The result is the decimal with the fewest significant digits (up to
    ``max_digits``) whose grid t0 + k Ts stays within ``tol`` samples of every recorded time;
    when none does (a real clock-rate error), the mean step (t[-1] - t[0]) / (n - 1).

    Parameters
    ----------
    t : (n,) strictly increasing times, s

    Returns
    -------
    float, s
    """
    t = np.asarray(t, float)
    k = np.arange(t.size)
    mean = float((t[-1] - t[0]) / (t.size - 1))
    for digits in range(1, max_digits + 1):
        c = float(f"{mean:.{digits}g}")
        if c > 0 and np.max(np.abs(t - t[0] - k * c)) <= tol * c:
            return c
    return mean
