"""The closed loop's lightly damped pole pairs, the truth a fitted mode is compared with.

The plant's mode parameters (``lock_hz``, the free-free frequency) are those of the open
mechanics; the identified models describe the closed loop (command -> measured position), whose
mode the position and velocity loops move and damp. Without friction, backlash, quantisation and
noise the plant is linear and time-invariant at the controller's sample rate (the drive clock
divides Ts), so an ARX model of high order fitted to a noise-free run gives its poles exactly up
to the order's truncation (orders 16-22 agree to 0.1 Hz on the scenarios' axes).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .params import Axis
from .plant import simulate_axis


def linear_axis(ax: Axis) -> Axis:
    """The axis without its nonlinear and random parts: friction, backlash, quantisation, noise."""
    return replace(ax, coulomb=0.0, static=0.0, backlash=0.0, resolution=1e-12, noise=0.0)


def closed_loop_pairs(ax: Axis, Ts, order=18, n=40000, f_range=(10.0, 200.0), output="motor"):
    """Complex pole pairs of the friction-free closed loop, command -> ``output`` position.

    Parameters
    ----------
    ax : Axis (friction, backlash, quantisation and noise are switched off here)
    Ts : float, s, the controller's sample time
    order : int, ARX order (denominator and numerator)
    n : int, samples of the random-walk command
    f_range : (lo, hi) Hz, natural frequencies kept
    output : ``motor`` (the encoder's body) or ``table``

    Returns
    -------
    list of (frequency_hz, zeta), lowest frequency first
    """
    lin = linear_axis(ax)
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.normal(0.0, 1e-3, n))
    u -= u[0]
    y = simulate_axis(lin, Ts, u, rng)[output]
    k = np.arange(order, n)
    phi = np.column_stack([-y[k - i] for i in range(1, order + 1)] + [u[k - i] for i in range(order + 1)])
    theta = np.linalg.lstsq(phi, y[order:], rcond=None)[0]
    s = np.log(np.roots(np.r_[1.0, theta[:order]]).astype(complex)) / Ts
    f, zeta = np.abs(s) / (2 * np.pi), -s.real / np.abs(s)
    keep = (s.imag > 0) & (f >= f_range[0]) & (f <= f_range[1])
    return sorted((float(a), float(b)) for a, b in zip(f[keep], zeta[keep]))
