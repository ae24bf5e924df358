"""Parameters of a family plant (units: mm, mm/s, N, kg, s, Hz) and how a seed draws them.

A plant is drawn the way a machine is built and commissioned:

* mechanics: table (tool-side) mass 20-500 kg (log-uniform); motor and screw inertia J with a
  screw lead p reflected to the table as m_motor = J (2 pi / p)^2 (J grows with the table mass,
  lead 5-40 mm); friction from the mass (Coulomb 0.5-2 % of the weight plus a seal share), a
  viscous part, the law ``coulomb`` (stiff bristles: a Coulomb-plus-viscous map with sticking) or
  ``lugre`` (soft, damped bristles: presliding of a few um);
* current loop: a first-order lag of bandwidth 300-2000 Hz; the force limit 2.5-5 times the force
  of the path's largest acceleration plus friction;
* controller: ``p-pi`` (position P, velocity PI; 80 % of plants) or ``pid`` (position PID on the
  force), tuned from the loop's small delays T_sum = tau_c + (compute delay + 1/2) Ts + tau_vf +
  Ts / 2: velocity-loop bandwidth w_v = (0.6 .. 1) / (2 T_sum), kp_vel = m_est w_v / 1000,
  ti_vel = (4 .. 8) / w_v, position gain kv = w_v / (3 .. 6) (PID: the triple pole w_p = w_v / (1.5
  .. 3)); the mass estimate m_est is off by up to +-10 %; velocity (and, with it, acceleration)
  feed-forward on a third of the plants;
* sensors: encoder resolution 0.01-1 um (log-uniform), noise 0.3-2 quantisation steps (at least
  5 nm), a velocity channel, a current channel and a tool-side encoder on some plants.

Undeclared effects (:class:`Effect`) change these parameters (see :mod:`family.cases`).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field


@dataclass(frozen=True)
class AxisPlant:
    """One feed axis.

    Controller
    ----------
    controller : ``p-pi`` or ``pid``
    kv : 1/s, position gain (p-pi)
    kp_vel : N/(mm/s), velocity-loop gain; ti_vel : s, its integral time (p-pi)
    kp_pid : N/mm, ki_pid : N/(mm s), kd_pid : N/(mm/s) (pid)
    tau_vf : s, first-order filter of the encoder-difference velocity
    vff, aff : velocity and acceleration feed-forward weights (0 off, 1 full)
    m_est : kg, the mass the acceleration feed-forward and the tuning assume
    f_max : N, force (current) limit; kt : N/A, force constant
    compute_delay : samples between a controller output's computation and its application

    Current loop and mechanics
    --------------------------
    current_hz : Hz, bandwidth of the current loop (first-order lag)
    motor_mass : kg, rotor and screw reflected to the table; table_mass : kg, table and workpiece
    inertia_kgm2 : kg m^2 and lead_mm : mm, from which motor_mass was reflected
    two_mass : bool, a drive-train spring between motor side and table (else one rigid body)
    lock_hz : Hz, table mode with the motor held, sqrt(k / table_mass) / (2 pi); mode_zeta : damping
    backlash_mm : mm, total dead zone of the drive-train spring

    Friction (bristle model per body)
    ---------------------------------
    friction_law : ``coulomb`` (stiff bristles) or ``lugre``
    coulomb, static : N (static > coulomb: a Stribeck breakaway); stribeck_velocity : mm/s
    viscous : N/(mm/s); bristle_mm : mm, deflection at the breakaway level; bristle_zeta,
    bristle_fade (mm/s): micro-damping and its fade with velocity; table_share : fraction of the
    friction on the table (two-mass)

    Disturbances and sensors
    ------------------------
    periodic_amplitude : N, periodic_period : mm, periodic_phase : rad, force on the motor side
    A sin(2 pi x1 / period + phase)
    resolution_mm, noise_mm : encoder quantisation step and noise standard deviation
    vel_channel, cur_channel, tool_channel : which measured channels the trace carries
    record_delay : samples by which every measured channel lags the recorded command
    """

    name: str = "x"
    controller: str = "p-pi"
    kv: float = 40.0
    kp_vel: float = 30.0
    ti_vel: float = 0.01
    kp_pid: float = 0.0
    ki_pid: float = 0.0
    kd_pid: float = 0.0
    tau_vf: float = 0.0
    vff: float = 0.0
    aff: float = 0.0
    m_est: float = 100.0
    f_max: float = 3000.0
    kt: float = 2.0
    compute_delay: int = 1
    current_hz: float = 800.0
    motor_mass: float = 40.0
    table_mass: float = 60.0
    inertia_kgm2: float = 0.0
    lead_mm: float = 10.0
    two_mass: bool = False
    lock_hz: float = 300.0
    mode_zeta: float = 0.1
    backlash_mm: float = 0.0
    friction_law: str = "coulomb"
    coulomb: float = 20.0
    static: float = 20.0
    stribeck_velocity: float = 2.0
    viscous: float = 0.1
    bristle_mm: float = 5e-4
    bristle_zeta: float = 0.5
    bristle_fade: float = 1.0
    table_share: float = 0.6
    periodic_amplitude: float = 0.0
    periodic_period: float = 5.0
    periodic_phase: float = 0.0
    resolution_mm: float = 1e-4
    noise_mm: float = 1e-4
    vel_channel: bool = True
    cur_channel: bool = False
    tool_channel: bool = False
    record_delay: int = 0

    @property
    def mass(self):
        """Total moving mass, kg."""
        return self.motor_mass + self.table_mass

    def spring_N_mm(self):
        """Drive-train stiffness k = table_mass (2 pi lock_hz)^2 / 1000, N/mm."""
        return self.table_mass * (2 * math.pi * self.lock_hz) ** 2 / 1000.0

    def free_free_hz(self):
        """Mode of the two bodies on the spring with the motor free, Hz."""
        k = self.spring_N_mm()
        return math.sqrt(1000.0 * k * (1 / self.motor_mass + 1 / self.table_mass)) / (2 * math.pi)

    def velocity_bandwidth_hz(self):
        """Velocity-loop crossover kp_vel / m_est (p-pi) or the PID's triple pole, Hz."""
        if self.controller == "pid":
            return (self.kd_pid * 1000.0 / self.m_est / 3.0) / (2 * math.pi)
        return self.kp_vel * 1000.0 / self.m_est / (2 * math.pi)


@dataclass(frozen=True)
class Machine:
    """One or two axes at one controller sample time.

    Ts : s; axes : tuple of AxisPlant (the first is the axis of interest)
    coupling_kg : kg, force on the first axis = -coupling_kg (tool-side acceleration of the second
        axis) / 1000 N (a cross inertia; 0 without)
    disturbance_rms : N, RMS of a measured external force on the first axis (0: none)
    disturbance_channel : name of the extra channel that records it (also recorded, without any
        effect on the plant, when ``decoy_channel``)
    decoy_channel : bool, the trace carries a measured channel that does not act on the plant
    """

    Ts: float = 0.001
    axes: tuple = (AxisPlant(),)
    coupling_kg: float = 0.0
    disturbance_rms: float = 0.0
    disturbance_channel: str = "x_load_N"
    decoy_channel: bool = False

    def to_dict(self):
        return asdict(self)


@dataclass(frozen=True)
class Effect:
    """An undeclared effect of a case.

    kind : as ``fdid diagnose`` names it: ``stribeck``, ``backlash``, ``periodic_position``,
        ``delay``, ``mode``, ``coupling``, ``extra_input``
    magnitude : float, its size in ``unit`` (stribeck: breakaway excess F_s - F_c, N; backlash:
        total lost motion, mm; periodic_position: amplitude, N; delay: samples; mode: tool-side
        mass, kg; coupling: cross inertia, kg; extra_input: RMS of the measured force, N)
    unit : str
    axis : the axis it acts on
    params : dict, its other true parameters (v_s_mm_s, period_mm, frequency_hz, ...)
    relative : float, the magnitude relative to the scale it was drawn on (log-uniform)
    """

    kind: str
    magnitude: float
    unit: str
    axis: str = "x"
    params: dict = field(default_factory=dict)
    relative: float = float("nan")


def loguniform(rng, lo, hi):
    """A draw log-uniform in [lo, hi]."""
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_axis(rng, name, Ts, acc_max):
    """A clean axis drawn from the family's ranges (module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
    name : axis name
    Ts : s
    acc_max : mm/s^2, the largest path acceleration it must follow (sets the force limit)
    """
    table = loguniform(rng, 20.0, 500.0)
    lead = float(rng.choice([5.0, 10.0, 16.0, 20.0, 25.0, 32.0, 40.0]))
    J = loguniform(rng, 0.3, 3.0) * 1e-3 * (table / 100.0) ** 0.7         # kg m^2
    motor = J * (2 * math.pi / (lead * 1e-3)) ** 2
    motor = min(max(motor, 0.15 * table), 1.5 * table)                    # a plausible inertia match
    mass = motor + table
    weight = 9.81 * mass
    coulomb = weight * loguniform(rng, 0.005, 0.02) + loguniform(rng, 5.0, 40.0)
    law = "lugre" if rng.uniform() < 0.4 else "coulomb"
    bristle = loguniform(rng, 1e-3, 4e-3) if law == "lugre" else loguniform(rng, 2e-4, 6e-4)
    current_hz = loguniform(rng, 300.0, 2000.0)
    controller = "pid" if rng.uniform() < 0.2 else "p-pi"
    compute_delay = int(rng.integers(0, 2))
    tau_vf = float(rng.uniform(0.0, 1.5)) * Ts
    T_sum = 1 / (2 * math.pi * current_hz) + (compute_delay + 0.5) * Ts + tau_vf + 0.5 * Ts
    w_v = rng.uniform(0.6, 1.0) / (2 * T_sum)
    m_est = mass * rng.uniform(0.9, 1.1)
    ff = rng.uniform() < 0.33
    kw = {}
    if controller == "pid":
        w_p = w_v / rng.uniform(1.5, 3.0)
        kw = dict(kp_pid=3 * m_est * w_p ** 2 / 1000.0, ki_pid=m_est * w_p ** 3 / 1000.0,
                  kd_pid=3 * m_est * w_p / 1000.0, kv=0.0, kp_vel=0.0, ti_vel=math.inf)
    else:
        kw = dict(kv=w_v / rng.uniform(3.0, 6.0), kp_vel=m_est * w_v / 1000.0, ti_vel=rng.uniform(4.0, 8.0) / w_v)
    f_max = rng.uniform(2.5, 5.0) * (mass * acc_max / 1000.0 + coulomb)
    resolution = loguniform(rng, 1e-5, 1e-3)
    noise = max(5e-6, resolution * rng.uniform(0.3, 2.0))
    return AxisPlant(
        name=name, controller=controller, tau_vf=tau_vf, vff=1.0 if ff else 0.0,
        aff=float(rng.uniform(0.7, 1.0)) if ff else 0.0, m_est=m_est, f_max=f_max,
        kt=loguniform(rng, 0.5, 10.0) * (mass / 100.0) ** 0.5, compute_delay=compute_delay,
        current_hz=current_hz, motor_mass=motor, table_mass=table, inertia_kgm2=J, lead_mm=lead,
        lock_hz=loguniform(rng, 250.0, 450.0), mode_zeta=rng.uniform(0.08, 0.2),
        friction_law=law, coulomb=coulomb, static=coulomb, stribeck_velocity=1.0,
        viscous=loguniform(rng, 0.002, 0.02) * mass / 10.0, bristle_mm=bristle,
        bristle_zeta=rng.uniform(0.3, 0.8) if law == "lugre" else 0.3,
        bristle_fade=loguniform(rng, 0.3, 3.0), table_share=rng.uniform(0.5, 0.8),
        periodic_phase=float(rng.uniform(0, 2 * math.pi)), resolution_mm=resolution, noise_mm=noise,
        vel_channel=bool(rng.uniform() < 0.7), cur_channel=bool(rng.uniform() < 0.5),
        tool_channel=bool(rng.uniform() < 0.25), **kw)
