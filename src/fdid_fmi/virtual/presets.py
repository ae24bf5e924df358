"""Ready-made virtual machines for tests, examples and benchmarks.

Every preset returns a fresh :class:`~fdid_fmi.virtual.drive.MachineConfig`; change its fields
freely (``dataclasses.replace`` or attribute assignment). Masses in kg, gains in the units of
:class:`~fdid_fmi.virtual.drive.AxisConfig`.

=====================  =====================================================================
preset                 what it is
=====================  =====================================================================
deckel_maho_like       two axes, no feed-forward, Ts 0.6 ms, Kp 80 / 70 1/s: pole-dominated
                       tracking errors (K_vel = 1/Kp = 12.5 / 14.3 ms, e ~ 1.25 mm at 100
                       mm/s as the thesis's Deckel Maho 80P: K_vel = c2/a3 ~ 12.6 ms from its
                       Table 4-2), closed-loop poles ~9, 32, 39 Hz; Coulomb + viscous friction,
                       0.1 um encoder.
with_feedforward       the same machine with velocity and acceleration feed-forward (gain 1, exact
                       mass) and a Stribeck breakaway: small errors where friction transients at
                       reversals dominate.
flexible_y             deckel_maho_like with a two-mass Y axis: 20 kg tool side on a 25.8 Hz,
                       zeta 0.006 mode (motor side held); encoder on the motor, ``tool`` channel
                       on the tool side (thesis ch. 7 flexure).
coupled_xy             deckel_maho_like plus cross-axis coupling: force on Y = 0.1 N/(mm/s^2) x
                       X acceleration (a 100 kg coupling mass), force on X = 0.5 N/(mm/s) x Y
                       velocity.
emps_like              one rigid axis like the EMPS benchmark: M 95.11 kg, Fv 0.2035 N/(mm/s),
                       Fc 20.39 N, offset -3.16 N, P-P controller (Kp 160.18 1/s, Kv 8.557
                       N/(mm/s), no integral action), force limit 351.5 N (10 V x 35.15 N/V),
                       Ts 1 ms, 50 nm quantisation; ``cur`` is the controller output in V.
=====================  =====================================================================
"""
from __future__ import annotations

from .drive import AxisConfig, Coupling, MachineConfig

__all__ = ["deckel_maho_like", "with_feedforward", "flexible_y", "coupled_xy", "emps_like",
           "PRESETS"]


def _dm_axes():
    x = AxisConfig(name="x", Kp=80.0, Kv=150.0, Ti=0.015, tau_current=2e-4, mass=300.0,
                   viscous=0.2, coulomb=200.0, resolution=1e-4)
    y = AxisConfig(name="y", Kp=70.0, Kv=180.0, Ti=0.015, tau_current=2e-4, mass=400.0,
                   viscous=0.25, coulomb=250.0, resolution=1e-4)
    return x, y


def deckel_maho_like() -> MachineConfig:
    """Two-axis machine without feed-forward (thesis ch. 4 Deckel Maho 80P, TNC 430, 0.6 ms)."""
    x, y = _dm_axes()
    return MachineConfig(axes=[x, y], Ts=6e-4, name="deckel_maho_like")


def with_feedforward() -> MachineConfig:
    """deckel_maho_like with full velocity + acceleration feed-forward and Stribeck friction."""
    cfg = deckel_maho_like()
    for a in cfg.axes:
        a.vel_ff = 1.0
        a.acc_ff = 1.0
        a.stribeck = 0.4 * a.coulomb
        a.stribeck_velocity = 2.0
    cfg.name = "with_feedforward"
    return cfg


def flexible_y() -> MachineConfig:
    """deckel_maho_like whose Y axis carries a 25.8 Hz, zeta 0.006 tool-side mode (20 kg)."""
    cfg = deckel_maho_like()
    y = cfg.axes[1]
    y.tool_mass = 20.0
    y.mode_hz = 25.8
    y.mode_zeta = 0.006
    cfg.name = "flexible_y"
    return cfg


def coupled_xy() -> MachineConfig:
    """deckel_maho_like with acceleration (X -> Y) and velocity (Y -> X) cross coupling."""
    cfg = deckel_maho_like()
    cfg.couplings = [Coupling(source="x", target="y", kind="acc", gain=0.1),
                     Coupling(source="y", target="x", kind="vel", gain=0.5)]
    cfg.name = "coupled_xy"
    return cfg


def emps_like() -> MachineConfig:
    """One rigid axis with the EMPS benchmark's published physics and controller (Ts 1 ms)."""
    ax = AxisConfig(name="x", Kp=160.18, Kv=243.45 * 35.15 / 1000.0, Ti=float("inf"),
                    mass=95.11, viscous=0.2035, coulomb=20.39, force_offset=-3.16,
                    force_limit=10.0 * 35.15, kt=35.15, resolution=5e-5)
    return MachineConfig(axes=[ax], Ts=1e-3, name="emps_like")


PRESETS = {f.__name__: f for f in (deckel_maho_like, with_feedforward, flexible_y, coupled_xy,
                                    emps_like)}
