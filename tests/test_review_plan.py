"""Review of fdid_fmi.plan against hand-derived truths: the geometry the parser reads, the v/a/j
limits, end points and cycle time of the interpolation, and the contour error of a circle traced
by drives whose response is known in closed form."""
import math

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel, Port
from fdid_fmi.plan.interpolate import AxisLimits, interpolate
from fdid_fmi.plan.ncprogram import parse_program
from fdid_fmi.plan.predict import predict

EPS = np.finfo(float).eps


def _within_limits(P, limits, Ts):
    """Largest |n-th finite difference| / Ts^n over its limit, per axis and n = 1, 2, 3, after
    subtracting the rounding of an n-th difference of these positions (2^n eps max|P| / Ts^n:
    each of the 2^n-weighted terms carries one rounding of size eps max|P|)."""
    worst = 0.0
    for i, a in enumerate("xyz"):
        lim = limits[a]
        for n, bound in ((1, lim.v), (2, lim.a), (3, lim.j)):
            d = np.abs(np.diff(P[:, i], n=n)).max() / Ts ** n
            rounding = 2 ** n * EPS * np.abs(P).max() / Ts ** n
            worst = max(worst, (d - rounding) / bound)
    return worst


def _P(ip):
    return np.column_stack([ip.positions[a] for a in "xyz"])


def _tangent_line_arc(phi_deg, R=10.0, L=20.0, F=6000):
    """A line at phi, a tangent counter-clockwise quarter arc and a tangent line (G-code)."""
    phi = math.radians(phi_deg)
    u = np.array([math.cos(phi), math.sin(phi)])
    nrm = np.array([-u[1], u[0]])
    p1 = L * u
    c = p1 + R * nrm
    a1 = math.atan2(-nrm[1], -nrm[0]) + math.pi / 2
    p2 = c + R * np.array([math.cos(a1), math.sin(a1)])
    p3 = p2 + L * np.array([-math.sin(a1), math.cos(a1)])
    return (f"G1 X{p1[0]:.6f} Y{p1[1]:.6f} F{F}\nG3 X{p2[0]:.6f} Y{p2[1]:.6f} I{R * nrm[0]:.6f} "
            f"J{R * nrm[1]:.6f}\nG1 X{p3[0]:.6f} Y{p3[1]:.6f}\n")


LIM = {a: AxisLimits(100.0, 2000.0, 5e4) for a in "xyz"}


@pytest.mark.parametrize("text, corner, Ts", [
    ("G1 X10 F6000\nX20 Y0.524\nX30 Y1.5\n", 10.0, 1e-3),                   # 3 deg kinks
    ("G1 F6000 X10\n" + "\n".join(f"X{10 * math.cos(2 * math.pi * k / 90):.4f} "
                                  f"Y{10 * math.sin(2 * math.pi * k / 90):.4f}" for k in range(1, 46)),
     10.0, 1e-3),                                                              # a polygon "circle"
    (_tangent_line_arc(45.0), 1.0, 5e-4),                                      # diagonal tangents
])
def test_lookahead_keeps_every_axis_limit(text, corner, Ts):
    """With --corner-angle the sampled commands stay within v/a/j of every axis as without it.
    (Before: the kink and curvature-jump terms were capped at half the limits but added to a
    tangential jerk of up to the whole limit: the 3 deg kinks had 1.04 j, the polygon 1.3 j,
    the 45 deg line-arc tangent 1.05 j.)"""
    p = parse_program(text)
    ip = interpolate(p, LIM, Ts, corner_angle_deg=corner)
    assert _within_limits(_P(ip), LIM, Ts) <= 1.0
    assert np.abs(_P(ip)[-1] - p.blocks[-1].end).max() < 1e-12


def test_lookahead_still_carries_velocity_through_diagonal_tangents():
    p = parse_program(_tangent_line_arc(45.0))
    Ts = 5e-4
    ip = interpolate(p, LIM, Ts, corner_angle_deg=1.0)
    vj = ip.info["junction_velocity_mm_s"]
    assert vj[0] > 1.0 and vj[1] > 1.0                 # no exact stop at the tangent junctions
    P = _P(ip)
    for k in (0, 1):                                   # the sampled path speed there is not zero
        k1 = ip.spans[k][1]
        v = np.linalg.norm(np.diff(P[k1 - 1:k1 + 2], axis=0), axis=1) / Ts
        assert v.min() > 0.5 * vj[k]
