"""Parameters of the second plant (units: mm, mm/s, N, kg, s) and presets.

The plant is an independent design, not a re-parameterisation of ``fdid_fmi.virtual``:
LuGre friction (bristle state, optional Stribeck), a position loop at Ts with a one-sample
computation delay around a velocity loop on the drive's own clock (250 us), a velocity estimate
from encoder differences through a first-order filter, a current loop as a continuous lag, a
unilateral spring-damper coupling with a dead zone, fixed-step integration (see :mod:`.plant`).
Force balance in these units: acceleration [mm/s^2] = 1000 * force [N] / mass [kg].
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace


@dataclass(frozen=True)
class Axis:
    """One feed axis: controller, current loop, mechanics, friction, disturbances, sensors.

    Controller (sampled at the plant's Ts)
    ---------------------------------------
    kv : 1/s, position-loop gain (v_ref = kv * (x_cmd - x_enc) + vff * v_cmd)
    kp_vel : N/(mm/s), velocity-loop proportional gain
    ti_vel : s, velocity-loop integral time (``math.inf``: P velocity loop)
    tau_vel : s, time constant of the first-order filter on the encoder-difference velocity
    vff, aff : velocity / acceleration feed-forward weights (0 = off, 1 = full); the
        acceleration feed-forward is aff * mass_estimate * a_cmd
    mass_estimate : kg, used by the acceleration feed-forward (default: the total mass)
    f_max : N, force-command saturation
    compute_delay : samples (0 or 1) between the sample a force is computed on and its output
    feedback_delay : samples of delay of the encoder value the controller uses

    Current loop (continuous)
    -------------------------
    current_hz, current_zeta : bandwidth (Hz) and damping of the force lag
    current_order : 1 (first-order lag, time constant 1/(2 pi current_hz)) or 2
    kt : N/A, force constant (only for the optional current channel)

    Mechanics
    ---------
    motor_mass, table_mass : kg (rotor and screw reflected to the table / table and workpiece)
    two_mass : False = one rigid body of motor_mass + table_mass
    lock_hz : Hz, table mode with the motor locked, sqrt(k / table_mass) / (2 pi)
    mode_zeta : damping ratio of that mode (coupling damper)
    backlash : mm, total dead zone of the coupling (two-mass only); the coupling cannot pull

    Friction (LuGre, one bristle state per body)
    ---------------------------------------------
    coulomb, static : N (static > coulomb adds the Stribeck effect)
    stribeck_velocity : mm/s, v_s in g(v) = Fc + (Fs - Fc) exp(-(v / v_s)^2)
    viscous : N/(mm/s), sigma_2
    bristle : mm, bristle deflection at the Coulomb level (sigma_0 = coulomb / bristle)
    bristle_zeta : damping of the bristle mode (sigma_1 = 2 zeta sqrt(sigma_0 m / 1000)),
        faded out with velocity: sigma_1(v) = sigma_1 exp(-(v / bristle_fade)^2)
    bristle_fade : mm/s
    table_share : fraction of coulomb / static / viscous acting on the table (two-mass)

    Disturbances and sensors
    ------------------------
    periodic_amplitude, periodic_period, periodic_phase : N, mm, rad; force on the motor body
        A sin(2 pi x_motor / period + phase) (ball-screw pitch)
    resolution : mm, encoder quantisation step (motor and tool side)
    noise : mm, standard deviation of the encoder noise added before quantisation
    record_delay : samples by which the recorded act/vel/tool lag the recorded command
    """

    name: str = "x"
    kv: float = 45.0
    kp_vel: float = 60.0
    ti_vel: float = 0.008
    tau_vel: float = 0.0004
    vff: float = 0.0
    aff: float = 0.0
    mass_estimate: float | None = None
    f_max: float = 6000.0
    compute_delay: int = 1
    feedback_delay: int = 0
    current_hz: float = 600.0
    current_zeta: float = 0.7
    current_order: int = 2
    kt: float = 20.0
    motor_mass: float = 50.0
    table_mass: float = 100.0
    two_mass: bool = False
    lock_hz: float = 150.0
    mode_zeta: float = 0.1
    backlash: float = 0.0
    coulomb: float = 40.0
    static: float = 40.0
    stribeck_velocity: float = 3.0
    viscous: float = 0.3
    bristle: float = 0.002
    bristle_zeta: float = 0.7
    bristle_fade: float = 1.0
    table_share: float = 0.6
    periodic_amplitude: float = 0.0
    periodic_period: float = 5.0
    periodic_phase: float = 0.0
    resolution: float = 1e-4
    noise: float = 1e-4
    record_delay: int = 0

    @property
    def mass(self):
        """Total moving mass, kg."""
        return self.motor_mass + self.table_mass

    def derived(self):
        """Derived quantities for the truth record (SI-like plant units)."""
        k = self.table_mass * (2 * math.pi * self.lock_hz) ** 2 / 1000.0          # N/mm
        free = math.sqrt(1000.0 * k * self.mass / (self.motor_mass * self.table_mass)) / (2 * math.pi)
        s0 = self.coulomb / self.bristle
        return {"mass_kg": self.mass, "coupling_stiffness_N_mm": k if self.two_mass else None,
                "free_free_mode_hz": free if self.two_mass else None,
                "sigma0_N_mm": s0, "velocity_loop_bandwidth_hz": 1000 * self.kp_vel / self.mass / (2 * math.pi),
                "following_error_per_velocity_s": (1.0 - self.vff) / self.kv if self.kv else None}

    def effects(self):
        """Names of the effects this axis has beyond a rigid LuGre axis."""
        out = []
        if self.static > self.coulomb:
            out.append("stribeck")
        if self.two_mass and self.backlash > 0:
            out.append("backlash")
        if self.two_mass:
            out.append("mode")
        if self.periodic_amplitude:
            out.append("periodic_position")
        if self.record_delay:
            out.append("delay")
        if self.feedback_delay:
            out.append("loop_delay")
        return out


@dataclass(frozen=True)
class Coupling:
    """Force on ``target`` = -gain_kg * (table acceleration of ``source``) / 1000, N."""

    source: str
    target: str
    gain_kg: float


@dataclass(frozen=True)
class Machine:
    """Axes sampled at one controller period.

    Ts : s, controller sample time (0.5 to 2 ms tested)
    axes : tuple of Axis
    couplings : tuple of Coupling (a source must not depend on its target)
    drive_period : s, clock of the velocity loop in the drive (Ts must be a multiple of it)
    integration_steps : fixed integration steps per drive period
    """

    Ts: float = 0.001
    axes: tuple = (Axis("x"), Axis("y"))
    couplings: tuple = field(default_factory=tuple)
    drive_period: float = 2.5e-4
    integration_steps: int = 1

    def axis(self, name):
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    def with_axis(self, name, **changes):
        """A copy with one axis's parameters changed."""
        return replace(self, axes=tuple(replace(a, **changes) if a.name == name else a for a in self.axes))

    def truth(self):
        return {"plant": "plant2", "Ts": self.Ts, "drive_period": self.drive_period,
                "integration_steps": self.integration_steps,
                "axes": {a.name: {**asdict(a), **a.derived(), "effects": a.effects()} for a in self.axes},
                "couplings": [asdict(c) for c in self.couplings]}


def rigid(Ts=0.001, **changes):
    """Two rigid axes without feed-forward (changes apply to both)."""
    return Machine(Ts=Ts, axes=(replace(Axis("x"), **changes), replace(Axis("y", motor_mass=40.0, table_mass=70.0,
                                                                               kp_vel=45.0, coulomb=30.0, static=30.0),
                                                                          **changes)))


def with_feedforward(Ts=0.0005, **changes):
    """Rigid axes with full velocity and 90 % acceleration feed-forward."""
    return rigid(Ts, vff=1.0, aff=0.9, **changes)


def flexible_y(Ts=0.001, lock_hz=38.0, mode_zeta=0.01, **changes):
    """Rigid X; two-mass Y: a heavy motor-side body (motor, screw, table: 100 kg) and a light
    tool-side body (20 kg) on a spring with the locked-motor mode ``lock_hz`` (free-free
    lock_hz sqrt(1.2)); softer Y loop gains."""
    m = rigid(Ts, **changes)
    return m.with_axis("y", two_mass=True, motor_mass=100.0, table_mass=20.0, lock_hz=lock_hz,
                       mode_zeta=mode_zeta, kv=30.0, kp_vel=45.0, ti_vel=0.012, table_share=0.3)
