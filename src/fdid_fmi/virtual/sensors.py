"""Raw tool-side sensor files as separate acquisition systems write them, with KNOWN truth.

Thesis ch. 7.2: the motor encoders come from the CNC's oscilloscope (Ts 0.6 ms), a 2-D grid
encoder (KGM) from its own software (0.1 ms) and two 3-axis accelerometers from a third system
(0.488 ms), each with its own clock, start time and mounting. This module turns a virtual-drive
trace (:func:`fdid_fmi.virtual.simulate_machine`, e.g. preset ``flexible_y``) into such files:

* ``controller.csv`` - what the controller trace tool records: ``t_s``, ``<a>_cmd_mm``,
  ``<a>_mm`` (motor encoder), ``<a>_v_mm_s`` per axis. No tool-side channel.
* one CSV per accelerometer - ``t_s`` (its own clock, from 0), ``ax_<u>, ay_<u>, az_<u>``
  in the sensor frame: specific force f = R^T (a + g e_z) + bias + noise, where R (sensor ->
  machine) is Eqn 7.1, R = R_x(gamma) R_y(beta) R_z(alpha), and g e_z (9806.65 mm/s^2 up) is
  what a resting accelerometer reads.
* one CSV per grid encoder - ``t_s``, ``kgm_x_<u>, kgm_y_<u>``: the tool-side position in the
  grid plate's frame, p_kgm = R(theta)^T (p - o) + noise (plate turned by theta about z, its
  origin at o in machine coordinates).
* ``truth.json`` - every parameter above and the sample instants' mapping.

Clock model (both sensor kinds): the sensor clock reads tau = (1 + drift) (t - start) at
controller time t, i.e. it starts at controller time ``start_s`` (negative: before the controller
trace) and runs fast by ``drift_ppm``; the file's time column is k / rate_hz (nominal).

Tool-side truth between controller samples: an interpolating cubic spline through the exact
samples (tool position and acceleration of a two-mass axis; for a rigid axis the motor position
and the derivative of the spline through the exact motor velocity). The motion is band-limited
far below the controller's Nyquist frequency (moves ~ 20 Hz, mode 25.8 Hz, Nyquist 833 Hz), so
the spline is exact at the controller samples and accurate between them. Outside the controller
record the machine is at rest at its first / last position.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from ..errors import InputError
from ..trace import Trace
from ..units import UNITS, normalise_unit

__all__ = ["AccelerometerTruth", "GridEncoderTruth", "G_MM_S2", "euler_rotation", "ToolMotion",
           "tool_motion", "sample_accelerometer", "sample_grid_encoder", "write_controller_csv",
           "write_raw_run"]

G_MM_S2 = 9806.65  # standard gravity, mm/s^2
MACHINE_AXES = ("x", "y", "z")


def euler_rotation(alpha_deg, beta_deg, gamma_deg) -> Rotation:
    """Sensor -> machine rotation of thesis Eqn 7.1, R = R_x(gamma) R_y(beta) R_z(alpha).

    ``Rotation.from_euler("XYZ", [gamma, beta, alpha])`` (intrinsic X-Y-Z) is that product.
    """
    return Rotation.from_euler("XYZ", [gamma_deg, beta_deg, alpha_deg], degrees=True)


@dataclass
class AccelerometerTruth:
    """A 3-axis accelerometer on the tool side, with its mounting and clock errors.

    Attributes
    ----------
    name : str                 file stem and sensor name
    axes : tuple of str        machine axes whose tool-side motion the sensor rides on
    alpha_deg, beta_deg, gamma_deg : float
        Mounting rotation sensor -> machine (Eqn 7.1), deg.
    bias : (3,) float          sensor-frame offset, mm/s^2
    rate_hz : float            nominal sample rate
    start_s : float            controller time at which the sensor clock reads 0, s
    drift_ppm : float          sensor clock runs fast by this, 1e-6
    noise : float              white noise per sample and axis, mm/s^2 RMS
    unit : str                 unit written to the file (``m_s2``, ``g``, ``mm_s2``)
    tail_s : float             the record runs this long past the controller's end, s
    duration_s : float or None the record's length on the controller's clock, s (default: from
                               ``start_s`` to the controller's end + ``tail_s``)
    """

    name: str = "acc_tool"
    axes: tuple = ("x", "y")
    alpha_deg: float = 2.5
    beta_deg: float = -1.2
    gamma_deg: float = 0.8
    bias: tuple = (150.0, -200.0, 100.0)
    rate_hz: float = 5000.0
    start_s: float = -1.237
    drift_ppm: float = 60.0
    noise: float = 50.0
    unit: str = "m_s2"
    tail_s: float = 0.6
    duration_s: float | None = None

    @property
    def rotation(self) -> Rotation:
        return euler_rotation(self.alpha_deg, self.beta_deg, self.gamma_deg)


@dataclass
class GridEncoderTruth:
    """A 2-D grid encoder (KGM) measuring the tool-side x/y position.

    Attributes
    ----------
    name : str
    axes : tuple of str        the two machine axes of the plate, default (x, y)
    angle_deg : float          plate rotation about machine z (plate -> machine), deg
    offset_mm : (2,) float     plate origin in machine coordinates, mm
    rate_hz, start_s, drift_ppm, tail_s, duration_s : as :class:`AccelerometerTruth`
    noise : float              white noise per sample and axis, mm RMS
    unit : str                 ``um`` or ``mm``
    """

    name: str = "kgm"
    axes: tuple = ("x", "y")
    angle_deg: float = 0.35
    offset_mm: tuple = (12.345, -7.89)
    rate_hz: float = 1000.0
    start_s: float = -0.413
    drift_ppm: float = -40.0
    noise: float = 5e-5
    unit: str = "um"
    tail_s: float = 0.4
    duration_s: float | None = None


@dataclass
class ToolMotion:
    """Tool-side motion of every machine axis as functions of controller time (s).

    ``pos[a](t)`` in mm, ``acc[a](t)`` in mm/s^2; both hold the rest values outside
    [t0, t1] (position frozen, acceleration 0).
    """

    t0: float
    t1: float
    pos_splines: dict = field(default_factory=dict)
    acc_splines: dict = field(default_factory=dict)

    def pos(self, axis, t):
        t = np.asarray(t, dtype=float)
        if axis not in self.pos_splines:
            return np.zeros_like(t)
        return self.pos_splines[axis](np.clip(t, self.t0, self.t1))

    def acc(self, axis, t):
        t = np.asarray(t, dtype=float)
        if axis not in self.acc_splines:
            return np.zeros_like(t)
        inside = (t >= self.t0) & (t <= self.t1)
        return np.where(inside, self.acc_splines[axis](np.clip(t, self.t0, self.t1)), 0.0)


def tool_motion(trace: Trace) -> ToolMotion:
    """Spline the tool-side truth of a virtual-drive trace (see the module docstring).

    Two-mass axes use the ``tool`` and ``acc`` roles; rigid axes the exact motor position
    ``<a>_act_true`` and the derivative of the spline through ``<a>_vel_true``.
    """
    t = trace.t
    m = ToolMotion(float(t[0]), float(t[-1]))
    for a in trace.axes:
        if trace.has(a, "tool") and trace.has(a, "acc"):
            m.pos_splines[a] = CubicSpline(t, trace.get(a, "tool"))
            m.acc_splines[a] = CubicSpline(t, trace.get(a, "acc"))
        elif f"{a}_act_true" in trace.channels and f"{a}_vel_true" in trace.channels:
            m.pos_splines[a] = CubicSpline(t, trace.extra(f"{a}_act_true"))
            m.acc_splines[a] = CubicSpline(t, trace.extra(f"{a}_vel_true")).derivative()
        else:
            raise InputError(f"axis '{a}' has neither tool/acc roles nor the exact motor channels "
                             f"of a virtual-drive trace", source=trace.source, column=a)
    return m


def _clock(truth, t_ctrl_end, rng_unused=None):
    """Nominal sensor times tau_k = k / rate and their true controller times (s)."""
    length = truth.duration_s if truth.duration_s is not None else t_ctrl_end + truth.tail_s - truth.start_s
    if not length > 0:
        raise InputError(f"sensor '{truth.name}' would record nothing: it starts at {truth.start_s} s, "
                         f"after the controller's end {t_ctrl_end} s; give duration_s", column="start_s")
    span = length * (1 + truth.drift_ppm * 1e-6)
    n = int(np.floor(span * truth.rate_hz)) + 1
    tau = np.arange(n) / truth.rate_hz
    t_true = truth.start_s + tau / (1 + truth.drift_ppm * 1e-6)
    return tau, t_true


def sample_accelerometer(motion: ToolMotion, truth: AccelerometerTruth, seed=0):
    """Sensor-frame specific force at the sensor's own sample instants.

    Returns
    -------
    tau : (n,) s, the file's time column
    f : (n, 3) mm/s^2, f = R^T (a + g e_z) + bias + noise
    t_true : (n,) s, controller time of each sample
    """
    tau, t_true = _clock(truth, motion.t1)
    a = np.zeros((tau.size, 3))
    for i, ax in enumerate(MACHINE_AXES):
        if ax in truth.axes:
            a[:, i] = motion.acc(ax, t_true)
    a[:, 2] += G_MM_S2
    f = truth.rotation.inv().apply(a) + np.asarray(truth.bias, dtype=float)
    rng = np.random.default_rng(seed)
    f = f + rng.normal(0.0, truth.noise, f.shape) if truth.noise > 0 else f
    return tau, f, t_true


def sample_grid_encoder(motion: ToolMotion, truth: GridEncoderTruth, seed=0):
    """Grid-plate coordinates of the tool-side position at the encoder's sample instants.

    Returns
    -------
    tau : (n,) s;  p : (n, 2) mm, p = R(theta)^T (p_machine - o) + noise;  t_true : (n,) s
    """
    tau, t_true = _clock(truth, motion.t1)
    pm = np.column_stack([motion.pos(ax, t_true) for ax in truth.axes])
    pm = pm - np.asarray(truth.offset_mm, dtype=float)
    th = np.radians(truth.angle_deg)
    c, s = np.cos(th), np.sin(th)
    # R(theta)^T applied to row vectors
    p = np.column_stack([c * pm[:, 0] + s * pm[:, 1], -s * pm[:, 0] + c * pm[:, 1]])
    rng = np.random.default_rng(seed)
    if truth.noise > 0:
        p = p + rng.normal(0.0, truth.noise, p.shape)
    return tau, p, t_true


def _unit_factor(unit, quantity):
    u = normalise_unit(unit, column="unit")
    q, factor = UNITS[u]
    if q != quantity:
        raise InputError(f"unit '{unit}' is not a {quantity} unit", column="unit")
    return u, factor


def _write_csv(path, header, cols, fmt):
    from ..outputs import atomic_write
    data = np.column_stack(cols)
    lines = [",".join(header)]
    lines += [",".join(f.format(v) for f, v in zip(fmt, row)) for row in data.tolist()]
    atomic_write(path, "\n".join(lines) + "\n")
    return Path(path)


def write_controller_csv(trace: Trace, path):
    """What the controller's trace tool records: t, commanded and encoder position, velocity."""
    header, cols, fmt = ["t_s"], [trace.t], ["{:.7f}"]
    for a in trace.axes:
        header += [f"{a}_cmd_mm", f"{a}_mm", f"{a}_v_mm_s"]
        cols += [trace.cmd(a), trace.act(a), trace.get(a, "vel")]
        fmt += ["{:.9f}", "{:.9f}", "{:.6f}"]
    return _write_csv(path, header, cols, fmt)


def write_raw_run(trace: Trace, folder, accelerometers=(AccelerometerTruth(),),
                  grid_encoders=(GridEncoderTruth(),), seed=0):
    """Write one run as separate acquisition systems would: controller, accelerometer(s), KGM.

    Parameters
    ----------
    trace : Trace from :func:`fdid_fmi.virtual.simulate_machine` (its truth channels are used)
    folder : str or Path (created if missing)
    accelerometers, grid_encoders : sequences of :class:`AccelerometerTruth` /
        :class:`GridEncoderTruth`
    seed : int, seeds the sensor noise

    Returns
    -------
    dict with ``controller`` (Path), ``sensors`` {name: Path}, ``truth`` (dict, also written to
    ``truth.json``) and ``motion`` (:class:`ToolMotion`).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    motion = tool_motion(trace)
    out = {"controller": write_controller_csv(trace, folder / "controller.csv"), "sensors": {},
           "motion": motion}
    truth = {"controller": {"Ts": trace.Ts, "t0": float(trace.t[0]), "t1": float(trace.t[-1]),
                            "source": trace.source}, "accelerometers": {}, "grid_encoders": {}}
    for k, tr in enumerate(accelerometers):
        tau, f, _ = sample_accelerometer(motion, tr, seed=seed + 101 * (k + 1))
        u, fac = _unit_factor(tr.unit, "acceleration")
        names = [f"a{c}_{u}" for c in "xyz"]
        p = _write_csv(folder / f"{tr.name}.csv", ["t_s"] + names, [tau] + [f[:, i] / fac for i in range(3)],
                       ["{:.7f}"] + ["{:.7e}"] * 3)
        out["sensors"][tr.name] = p
        d = asdict(tr)
        d["rotation_matrix"] = tr.rotation.as_matrix().tolist()
        truth["accelerometers"][tr.name] = d
    for k, tr in enumerate(grid_encoders):
        tau, pk, _ = sample_grid_encoder(motion, tr, seed=seed + 211 * (k + 1))
        u, fac = _unit_factor(tr.unit, "position")
        names = [f"kgm_{c}_{u}" for c in "xy"]
        p = _write_csv(folder / f"{tr.name}.csv", ["t_s"] + names, [tau, pk[:, 0] / fac, pk[:, 1] / fac],
                       ["{:.7f}", "{:.6f}", "{:.6f}"])
        out["sensors"][tr.name] = p
        truth["grid_encoders"][tr.name] = asdict(tr)
    (folder / "truth.json").write_text(json.dumps(truth, indent=1, default=list))
    out["truth"] = truth
    return out
