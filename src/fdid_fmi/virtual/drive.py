"""Configuration, plant assembly and linearised closed-loop truth of the virtual feed drive.

Per axis (all positions mm, velocities mm/s, forces N, masses kg):

* **Controller**, sampled at Ts: P position loop (Kp, 1/s) with optional velocity
  feed-forward, PI velocity loop (Kv, N/(mm/s); Ti, s) on the backward-difference velocity of
  the measured position, optional acceleration feed-forward (gain x mass, N per mm/s^2), a force
  (current) limit with conditional-integration anti-windup. The feed-forward derivatives are
  centred differences of the command (one sample of look-ahead, as a CNC interpolator has):
  ``rd_k = (r_{k+1} - r_{k-1}) / 2Ts``, ``rdd_k = (r_{k+1} - 2 r_k + r_{k-1}) / Ts^2``.
  The controller output is held (ZOH) until the next sample.
* **Current loop**: first-order lag F' = (u - F) / tau_current (tau 0: none).
* **Mechanics**: rigid (one mass ``mass``) or two-mass (motor side ``mass``, tool side
  ``tool_mass`` on a spring k = m_t w^2 and damper c = 2 zeta m_t w, w = 2 pi ``mode_hz``: the
  tool-side mode with the motor side held, which a stiff position loop approximates; the
  closed-loop flexible pole is reported in the truth). Encoder on the motor side.
* **Cross-axis coupling**: force on a target axis = gain x (position | velocity | acceleration)
  of a source axis's motor side (N/mm, N/(mm/s), N/(mm/s^2)); all linear, part of the plant.

Nonlinear effects (friction, backlash, periodic force, limits, quantisation, noise) are simulated
in :mod:`fdid_fmi.virtual.machine`; the *linear truth* here leaves them out (viscous damping is
linear and stays in).

Linearised closed-loop truth (:func:`linear_truth`), two versions:

``continuous``  the controller treated as continuous (P-PI with ideal derivatives, no ZOH, no
                sample delays): closed-loop poles, G_er(s) = e/x_r = 1 - G_track(s) (thesis
                Eqn 3.1) as num/den per (output axis, command axis), and its Taylor
                coefficients at s = 0 (Eqn 3.2): K_vel, K_acc, K_jerk.
``sampled``     the exact discrete closed loop the simulator runs (ZOH plant over Ts, backward
                difference velocity, centred feed-forward, in-loop delays): poles z and their
                s-plane equivalents log(z)/Ts, and the same Taylor coefficients of
                G_er(e^{s Ts}); its state space (input r_{k+1}) for ``scipy.signal.dlsim``.

Without feed-forward, K_vel = 1/Kp in both exactly; the sampled loop's K_acc is shifted by
-K_vel Ts/2 (the ZOH's half sample), i.e. by Kp Ts/2 relative: 2.4% for deckel_maho_like
(Kp 80 1/s, Ts 0.6 ms), and lsim of the continuous G_er reproduces the simulated error to
0.6% (deckel_maho_like) / 1.7% (emps_like, Kp 160 1/s, Ts 1 ms) of its peak. With feed-forward
the residual errors (a few um) are themselves sampling effects, and only the ``sampled`` truth
describes them (its K_acc even has the other sign): use it there.
Taylor coefficients are computed by Cauchy's integral on a circle |s| = rho well inside the
nearest pole (64-point FFT), so any analytic G(s) (delays included) is handled exactly.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import linalg, signal

from ..errors import InputError

__all__ = ["AxisConfig", "Coupling", "MachineConfig", "linear_truth", "Plant", "build_plant",
           "taylor_coefficients", "sampled_closed_loop"]


# ----------------------------------------------------------------------------- config
@dataclass
class AxisConfig:
    """One feed-drive axis of the virtual machine (units in brackets).

    Controller: ``Kp`` [1/s] position gain; ``Kv`` [N/(mm/s)] velocity gain; ``Ti`` [s]
    integral time; ``vel_ff`` [-] velocity feed-forward gain (0 off, 1 full); ``acc_ff`` [-]
    acceleration feed-forward gain times ``ff_mass`` [kg] (default: total moving mass);
    ``tau_current`` [s] current-loop lag (0: none); ``force_limit`` [N]; ``kt`` [N/A] force
    constant (the ``cur`` channel is force / kt).

    Mechanics: ``mass`` [kg] (motor side, or the whole axis when rigid); ``viscous``
    [N/(mm/s)]; two-mass when ``tool_mass`` [kg] and ``mode_hz`` [Hz] are given, with
    ``mode_zeta`` [-].

    Friction (on ``friction_side``, "motor" or "tool"): ``coulomb`` [N] (positive direction),
    ``coulomb_neg`` [N] (negative direction; None = symmetric), ``stribeck`` [N] breakaway
    excess over Coulomb with ``stribeck_velocity`` [mm/s]: |F| = Fc + Fs exp(-(v/vs)^2).

    Other effects: ``backlash`` [mm] lost motion between motor and tool side (two-mass: dead
    zone of the spring; rigid: kinematic play seen on the tool channel); ``periodic_amplitude``
    [N], ``periodic_period`` [mm], ``periodic_phase`` [rad]: F = A sin(2 pi x / period + phase)
    on the motor side (ball-screw pitch, cogging); ``force_offset`` [N] constant force on the
    motor side (gravity, cable drag; left out of the linear truth); ``delay`` [samples] in-loop measurement
    delay; ``record_delay`` [samples] delay of the recorded act/vel channels only (data
    acquisition offset); ``resolution`` [mm] encoder quantisation (0: none); ``noise_std``
    [mm] measurement noise (before quantisation).
    """

    name: str = "x"
    # controller
    Kp: float = 60.0
    Kv: float = 100.0
    Ti: float = 0.01
    vel_ff: float = 0.0
    acc_ff: float = 0.0
    ff_mass: float | None = None
    tau_current: float = 0.0
    force_limit: float = float("inf")
    kt: float = 1.0
    # mechanics
    mass: float = 100.0
    viscous: float = 0.0
    tool_mass: float | None = None
    mode_hz: float | None = None
    mode_zeta: float = 0.01
    # friction
    coulomb: float = 0.0
    coulomb_neg: float | None = None
    stribeck: float = 0.0
    stribeck_velocity: float = 1.0
    friction_side: str = "motor"
    # other effects
    backlash: float = 0.0
    periodic_amplitude: float = 0.0
    periodic_period: float = 5.0
    periodic_phase: float = 0.0
    force_offset: float = 0.0
    delay: int = 0
    record_delay: int = 0
    resolution: float = 0.0
    noise_std: float = 0.0

    # ------------------------------------------------------------------ derived
    @property
    def two_mass(self) -> bool:
        return self.tool_mass is not None and self.mode_hz is not None

    @property
    def total_mass(self) -> float:
        return self.mass + (self.tool_mass if self.two_mass else 0.0)

    @property
    def has_friction(self) -> bool:
        return self.coulomb > 0 or (self.coulomb_neg or 0.0) > 0 or self.stribeck > 0

    def effects(self) -> list:
        """Names of the effects switched on (beyond the linear P-PI drive)."""
        on = []
        if self.vel_ff:
            on.append("velocity_feedforward")
        if self.acc_ff:
            on.append("acceleration_feedforward")
        if self.tau_current > 0:
            on.append("current_lag")
        if np.isfinite(self.force_limit):
            on.append("force_limit")
        if self.viscous:
            on.append("viscous_friction")
        if self.two_mass:
            on.append("two_mass")
        if self.coulomb > 0 or (self.coulomb_neg or 0) > 0:
            on.append("coulomb_friction")
        if self.coulomb_neg is not None and self.coulomb_neg != self.coulomb:
            on.append("asymmetric_coulomb")
        if self.stribeck > 0:
            on.append("stribeck")
        if self.backlash > 0:
            on.append("backlash")
        if self.periodic_amplitude:
            on.append("periodic_force")
        if self.force_offset:
            on.append("force_offset")
        if not np.isfinite(self.Ti):
            on.append("no_integral_action")
        if self.delay:
            on.append("measurement_delay")
        if self.record_delay:
            on.append("record_delay")
        if self.resolution > 0:
            on.append("quantisation")
        if self.noise_std > 0:
            on.append("noise")
        return on

    def validate(self):
        """Raise InputError naming the first bad parameter."""
        col = f"axis {self.name!r}"

        def pos(name, strict=True):
            v = getattr(self, name)
            ok = v is not None and np.isfinite(v) and (v > 0 if strict else v >= 0)
            if not ok:
                raise InputError(f"{name} must be {'> 0' if strict else '>= 0'} and finite, got {v!r}",
                                 column=f"{col}.{name}")

        for n in ("Kp", "Kv", "mass", "kt", "stribeck_velocity", "periodic_period"):
            pos(n)
        if not (self.Ti > 0):
            raise InputError(f"Ti must be > 0 (inf: no integral action), got {self.Ti!r}",
                             column=f"{col}.Ti")
        if not np.isfinite(self.force_offset):
            raise InputError(f"force_offset must be finite, got {self.force_offset!r}",
                             column=f"{col}.force_offset")
        for n in ("viscous", "tau_current", "coulomb", "stribeck", "backlash", "resolution",
                  "noise_std", "mode_zeta"):
            pos(n, strict=False)
        if not (self.force_limit > 0):
            raise InputError(f"force_limit must be > 0 (inf for none), got {self.force_limit!r}",
                             column=f"{col}.force_limit")
        if self.coulomb_neg is not None:
            pos("coulomb_neg", strict=False)
        for n in ("delay", "record_delay"):
            v = getattr(self, n)
            if int(v) != v or v < 0:
                raise InputError(f"{n} must be a whole number of samples >= 0, got {v!r}",
                                 column=f"{col}.{n}")
        if (self.tool_mass is None) != (self.mode_hz is None):
            raise InputError("a two-mass axis needs both tool_mass and mode_hz (or neither)",
                             column=f"{col}.tool_mass")
        if self.two_mass:
            pos("tool_mass")
            pos("mode_hz")
        if self.friction_side not in ("motor", "tool"):
            raise InputError(f"friction_side must be 'motor' or 'tool', got {self.friction_side!r}",
                             column=f"{col}.friction_side")
        if self.friction_side == "tool" and not self.two_mass:
            raise InputError("friction_side 'tool' needs a two-mass axis", column=f"{col}.friction_side")
        if self.ff_mass is not None:
            pos("ff_mass")
        return self


@dataclass
class Coupling:
    """Cross-axis coupling: force on ``target`` = ``gain`` x ``kind`` of ``source``'s motor side.

    kind: "pos" (gain N/mm), "vel" (N/(mm/s)) or "acc" (N/(mm/s^2), i.e. a coupling mass/1000).
    """

    source: str
    target: str
    kind: str = "acc"
    gain: float = 0.0


@dataclass
class MachineConfig:
    """A virtual machine: axes, couplings and the controller sample time.

    Attributes
    ----------
    axes : list[AxisConfig]
    Ts : float, s
    couplings : list[Coupling]
    n_sub : int   sub-steps per sample used where the friction / backlash is non-smooth
    adaptive : bool   take whole samples where that is exact (sliding, stuck); False: every
                  sample with a nonlinear force is split into n_sub sub-steps
    name : str
    """

    axes: list
    Ts: float = 1e-3
    couplings: list = field(default_factory=list)
    n_sub: int = 8
    adaptive: bool = True
    name: str = "virtual"

    def axis(self, name) -> AxisConfig:
        for a in self.axes:
            if a.name == name:
                return a
        raise InputError(f"no axis named {name!r} (axes: {[a.name for a in self.axes]})", column="axis")

    @property
    def axis_names(self) -> list:
        return [a.name for a in self.axes]

    def validate(self):
        if not self.axes:
            raise InputError("a machine needs at least one axis", column="axes")
        names = self.axis_names
        if len(set(names)) != len(names):
            raise InputError(f"axis names must be unique, got {names}", column="axes")
        if not (np.isfinite(self.Ts) and self.Ts > 0):
            raise InputError(f"Ts must be a positive number of seconds, got {self.Ts!r}", column="Ts")
        if int(self.n_sub) != self.n_sub or self.n_sub < 1:
            raise InputError(f"n_sub must be a positive integer, got {self.n_sub!r}", column="n_sub")
        for a in self.axes:
            a.validate()
        for c in self.couplings:
            if c.source not in names or c.target not in names or c.source == c.target:
                raise InputError(f"coupling {c.source!r} -> {c.target!r} must join two different axes "
                                 f"of {names}", column="couplings")
            if c.kind not in ("pos", "vel", "acc"):
                raise InputError(f"coupling kind must be 'pos', 'vel' or 'acc', got {c.kind!r}",
                                 column="couplings")
        return self

    def to_dict(self) -> dict:
        return {"name": self.name, "Ts": self.Ts, "n_sub": int(self.n_sub),
                "adaptive": bool(self.adaptive),
                "axes": [_jsonable(asdict(a)) for a in self.axes],
                "couplings": [asdict(c) for c in self.couplings]}


def _jsonable(d):
    out = {}
    for k, v in d.items():
        if isinstance(v, float) and not np.isfinite(v):
            out[k] = "inf" if v > 0 else "-inf"
        else:
            out[k] = v
    return out


# ----------------------------------------------------------------------------- plant
@dataclass
class Plant:
    """Continuous linear plant of the whole machine: z' = A z + Bu u + Bw w.

    z = [q (dof positions, mm), q' (mm/s), F (lagged motor forces, N)]; u: force commands
    (one per axis, N); w: extra forces per dof (friction, backlash correction, periodic), N.
    Index maps: ``motor[a]`` / ``tool[a]`` dof of axis a (tool is None when rigid);
    ``lag[a]`` index of the force state in z (None without current lag).
    """

    A: np.ndarray
    Bu: np.ndarray
    Bw: np.ndarray
    n_dof: int
    motor: dict
    tool: dict
    lag: dict
    axes: list
    spring: dict  # axis -> (k N/mm, c N/(mm/s)) for two-mass axes

    @property
    def nz(self):
        return self.A.shape[0]

    def pos(self, dof):
        return dof

    def vel(self, dof):
        return self.n_dof + dof

    def force_rows(self):
        """Rows giving dof accelerations: q'' = Aq z + Bqu u + Bqw w."""
        r = slice(self.n_dof, 2 * self.n_dof)
        return self.A[r], self.Bu[r], self.Bw[r]


def build_plant(cfg: MachineConfig) -> Plant:
    """Assemble the machine's continuous linear plant (mass matrix form, then solved)."""
    names = cfg.axis_names
    motor, tool, lag, spring = {}, {}, {}, {}
    nd = 0
    for a in cfg.axes:
        motor[a.name] = nd
        nd += 1
        if a.two_mass:
            tool[a.name] = nd
            nd += 1
        else:
            tool[a.name] = None
    nl = 0
    for a in cfg.axes:
        if a.tau_current > 0:
            lag[a.name] = 2 * nd + nl
            nl += 1
        else:
            lag[a.name] = None
    na = len(names)
    Mass = np.zeros((nd, nd))
    K = np.zeros((nd, nd))
    D = np.zeros((nd, nd))
    P = np.zeros((nd, nl))      # lagged force -> dof
    Bdir = np.zeros((nd, na))   # direct force command -> dof
    for i, a in enumerate(cfg.axes):
        m = motor[a.name]
        Mass[m, m] = a.mass / 1000.0  # kg -> N/(mm/s^2)
        fr = tool[a.name] if (a.two_mass and a.friction_side == "tool") else m
        D[fr, fr] += a.viscous
        if a.two_mass:
            t = tool[a.name]
            mt = a.tool_mass / 1000.0
            w = 2 * np.pi * a.mode_hz
            k, c = mt * w * w, 2 * a.mode_zeta * mt * w
            spring[a.name] = (k, c)
            Mass[t, t] = mt
            for (p, q, s) in ((m, m, 1), (t, t, 1), (m, t, -1), (t, m, -1)):
                K[p, q] += s * k
                D[p, q] += s * c
        if lag[a.name] is not None:
            P[m, lag[a.name] - 2 * nd] = 1.0
        else:
            Bdir[m, i] = 1.0
    for c in cfg.couplings:
        s, t = motor[c.source], motor[c.target]
        if c.kind == "pos":
            K[t, s] -= c.gain
        elif c.kind == "vel":
            D[t, s] -= c.gain
        else:
            Mass[t, s] -= c.gain
    Mi = np.linalg.inv(Mass)
    nz = 2 * nd + nl
    A = np.zeros((nz, nz))
    Bu = np.zeros((nz, na))
    Bw = np.zeros((nz, nd))
    A[:nd, nd:2 * nd] = np.eye(nd)
    A[nd:2 * nd, :nd] = -Mi @ K
    A[nd:2 * nd, nd:2 * nd] = -Mi @ D
    A[nd:2 * nd, 2 * nd:] = Mi @ P
    Bu[nd:2 * nd] = Mi @ Bdir
    Bw[nd:2 * nd] = Mi
    for i, a in enumerate(cfg.axes):
        if lag[a.name] is not None:
            j = lag[a.name]
            A[j, j] = -1.0 / a.tau_current
            Bu[j, i] = 1.0 / a.tau_current
    return Plant(A, Bu, Bw, nd, motor, tool, lag, names, spring)


def zoh(A, B, h):
    """Exact zero-order-hold discretisation over h seconds: (Ad, Bd)."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A * h
    M[:n, n:] = B * h
    E = linalg.expm(M)
    return E[:n, :n], E[:n, n:]


# ----------------------------------------------------------------------------- truth helpers
def taylor_coefficients(G, rho, n_terms=4, n_points=64):
    """Taylor coefficients c_0..c_{n_terms-1} of an analytic G(s) at s = 0.

    Cauchy's integral on the circle |s| = rho (trapezoidal rule = FFT), exact to the aliasing
    term (rho / R)^n_points, R the distance to the nearest singularity.

    Parameters
    ----------
    G : callable, complex ndarray -> complex ndarray (vectorised)
    rho : float, radius (rad/s), well inside the nearest pole
    """
    th = 2 * np.pi * np.arange(n_points) / n_points
    s = rho * np.exp(1j * th)
    g = np.asarray(G(s), dtype=complex)
    c = np.fft.fft(g) / n_points
    return [float(np.real(c[k]) / rho ** k) for k in range(n_terms)]


def _pole_info(p):
    p = complex(p)
    w = abs(p)
    return {"re": p.real, "im": p.imag, "hz": w / (2 * np.pi),
            "zeta": (-p.real / w) if w > 0 else 1.0}


def _controller_params(a: AxisConfig):
    mff = a.total_mass if a.ff_mass is None else a.ff_mass
    return a.Kp, a.Kv, a.Ti, a.vel_ff, a.acc_ff * mff / 1000.0  # acc ff in N per mm/s^2


def _integrators(cfg):
    """Axis index -> position among the integral states (axes with finite Ti only)."""
    out, n = {}, 0
    for i, a in enumerate(cfg.axes):
        if np.isfinite(a.Ti):
            out[i] = n
            n += 1
    return out


def _continuous_closed_loop(cfg: MachineConfig, plant: Plant):
    """Closed loop with the controller treated as continuous.

    State X = [z, I] (I: integral of the velocity error, mm; axes with finite Ti), inputs
    [r, r', r''] per axis. Returns (A, B0, B1, B2), B_k the input matrix of the k-th command
    derivative.
    """
    na, nz = len(cfg.axes), plant.nz
    ints = _integrators(cfg)
    n = nz + len(ints)
    A = np.zeros((n, n))
    B0, B1, B2 = (np.zeros((n, na)) for _ in range(3))
    A[:nz, :nz] = plant.A
    for i, a in enumerate(cfg.axes):
        Kp, Kv, Ti, kvff, kaff = _controller_params(a)
        m = plant.motor[a.name]
        # eps = Kp (r - x) + kvff r' - v
        eps = np.zeros(n)
        eps[plant.pos(m)] = -Kp
        eps[plant.vel(m)] = -1.0
        e_r, e_rd = Kp, kvff
        # u = Kv (eps + I / Ti) + kaff r''
        urow = Kv * eps
        if i in ints:
            j = nz + ints[i]
            A[j] += eps          # I' = eps
            B0[j, i] += e_r
            B1[j, i] += e_rd
            urow[j] += Kv / Ti
        A[:nz] += np.outer(plant.Bu[:, i], urow)
        B0[:nz, i] += plant.Bu[:, i] * Kv * e_r
        B1[:nz, i] += plant.Bu[:, i] * Kv * e_rd
        B2[:nz, i] += plant.Bu[:, i] * kaff
    return A, B0, B1, B2


def _structural_keep(A, B, c):
    """States structurally reachable from the inputs B and observable at the output row c.

    Removes exactly the states that cannot take part in the transfer function (e.g. the other
    axes of an uncoupled machine), so the num/den come out without cancelled pole-zero pairs.
    """
    G = A != 0
    reach = np.any(B != 0, axis=1)
    while True:
        new = reach | np.any(G[:, reach], axis=1)
        if (new == reach).all():
            break
        reach = new
    obs = c != 0
    while True:
        new = obs | np.any(G[obs, :], axis=0)
        if (new == obs).all():
            break
        obs = new
    return np.flatnonzero(reach & obs)


def _polyadd(a, b):
    n = max(len(a), len(b))
    return np.pad(a, (n - len(a), 0)) + np.pad(b, (n - len(b), 0))


def _trim(p, tol=1e-12):
    p = np.asarray(p, dtype=float)
    scale = np.max(np.abs(p)) if p.size else 0.0
    k = 0
    while k < p.size - 1 and abs(p[k]) <= tol * scale:
        k += 1
    return p[k:]


def sampled_closed_loop(cfg: MachineConfig, plant: Plant | None = None):
    """The exact discrete closed loop run by the simulator (all nonlinear effects off).

    Input w_k = r_{k+1} per axis (the controller's one-sample look-ahead). Outputs, per axis in
    order: measured error r_k - y_k (y: measured motor position, in-loop delay included),
    motor position x_k, tool position (motor position when rigid). Record delays are not in it.

    Returns
    -------
    (Ad, Bd, Cd, Dd), out_names
    """
    plant = plant or build_plant(cfg)
    Ts = cfg.Ts
    na, nz = len(cfg.axes), plant.nz
    Phi, Gam = zoh(plant.A, plant.Bu, Ts)
    dl = [int(a.delay) for a in cfg.axes]
    # state layout
    ints = _integrators(cfg)
    iI = nz
    iy = iI + len(ints)
    ir = iy + na
    irm = ir + na
    ibuf = irm + na
    boff = np.concatenate(([0], np.cumsum(dl))).astype(int)
    nX = ibuf + int(boff[-1])
    nU = na
    W = nX  # column offset of the input in a row over [X; w]

    def unit(j):
        r = np.zeros(nX + nU)
        r[j] = 1.0
        return r

    Anew = np.zeros((nX, nX + nU))
    Cout, names = [], []
    urows = []
    yrows = []
    for i, a in enumerate(cfg.axes):
        Kp, Kv, Ti, kvff, kaff = _controller_params(a)
        m = plant.motor[a.name]
        xrow = unit(plant.pos(m))
        y = unit(ibuf + boff[i] + dl[i] - 1) if dl[i] > 0 else xrow
        yrows.append(y)
        e = unit(ir + i) - y
        vm = (y - unit(iy + i)) / Ts
        rd = (unit(W + i) - unit(irm + i)) / (2 * Ts)
        rdd = (unit(W + i) - 2 * unit(ir + i) + unit(irm + i)) / Ts ** 2
        eps = Kp * e + kvff * rd - vm
        u = Kv * eps + kaff * rdd
        if i in ints:
            Inew = unit(iI + ints[i]) + Ts * eps
            u = u + Kv * Inew / Ti
            Anew[iI + ints[i]] = Inew
        urows.append(u)
        Anew[iy + i] = y
        Anew[ir + i] = unit(W + i)
        Anew[irm + i] = unit(ir + i)
        if dl[i] > 0:
            Anew[ibuf + boff[i]] = xrow
            for j in range(1, dl[i]):
                Anew[ibuf + boff[i] + j] = unit(ibuf + boff[i] + j - 1)
        t = plant.tool[a.name]
        trow = unit(plant.pos(t)) if t is not None else xrow
        Cout += [e, xrow, trow]
        names += [f"{a.name}_err", f"{a.name}_pos", f"{a.name}_tool"]
    U = np.array(urows)  # (na, nX + nU)
    Zrows = np.zeros((nz, nX + nU))
    Zrows[:, :nz] = Phi
    Zrows += Gam @ U
    Anew[:nz] = Zrows
    Cout = np.array(Cout)
    return (Anew[:, :nX], Anew[:, nX:], Cout[:, :nX], Cout[:, nX:]), names


# ----------------------------------------------------------------------------- truth
def linear_truth(cfg: MachineConfig) -> dict:
    """Linearised closed-loop truth of a virtual machine (friction and nonlinearities off).

    Returns
    -------
    dict with keys
        ``assumptions`` (str), ``continuous`` and ``sampled`` (see module docstring). Both hold
        ``K[out_axis][cmd_axis] = {"K_vel", "K_acc", "K_jerk"}`` (s, s^2, s^3) of the
        *recorded* motor-side error e = cmd - act (delays included), ``K_tool`` (same for the
        tool-side error, two-mass axes) and ``poles`` (list of {re, im, hz, zeta}).
        ``continuous`` also has ``G_er[out][cmd] = {"num", "den"}`` (descending powers of s,
        delay-free), ``G_er_tool`` (two-mass), ``state_space`` (A, B0, B1, B2, C) and ``modes``
        (closed-loop flexible pole per two-mass axis). ``sampled`` has ``poles_z``,
        ``state_space`` (Ad, Bd, Cd, Dd with input r_{k+1}) and ``outputs``.
    """
    cfg.validate()
    plant = build_plant(cfg)
    names = cfg.axis_names
    na = len(names)
    Ts = cfg.Ts
    Acl, B0, B1, B2 = _continuous_closed_loop(cfg, plant)
    n = Acl.shape[0]
    poles = np.linalg.eigvals(Acl)
    rho = 0.25 * np.min(np.abs(poles[np.abs(poles) > 1e-9])) if np.any(np.abs(poles) > 1e-9) else 1.0
    Cx = np.zeros((na, n))
    Ct = np.zeros((na, n))
    for i, a in enumerate(cfg.axes):
        Cx[i, plant.pos(plant.motor[a.name])] = 1.0
        t = plant.tool[a.name]
        Ct[i, plant.pos(t if t is not None else plant.motor[a.name])] = 1.0
    loop_delay = any(a.delay for a in cfg.axes)

    def G_cont(s, C, j, i, rec_delay):
        """e_j / r_i at complex points s (continuous controller; delays as e^{-s tau}).

        ``rec_delay`` (samples) delays the position before it is subtracted: the recorded
        motor position is the measurement, delayed in the loop and again by the recording."""
        out = np.empty(s.size, dtype=complex)
        dij = 1.0 if i == j else 0.0
        for k, sk in enumerate(s):
            if loop_delay:
                y = _cont_delay_response(cfg, plant, sk, C, j, i)
            else:
                X = np.linalg.solve(sk * np.eye(n) - Acl, B0[:, i] + sk * B1[:, i] + sk * sk * B2[:, i])
                y = C[j] @ X
            out[k] = dij - y * np.exp(-sk * rec_delay * Ts)
        return out

    cont = {"poles": [_pole_info(p) for p in sorted(poles, key=lambda p: (abs(p), p.imag))],
            "G_er": {}, "K": {}, "K_tool": {}, "G_er_tool": {},
            "state_space": {"A": Acl.tolist(), "B0": B0.tolist(), "B1": B1.tolist(),
                            "B2": B2.tolist(), "C_motor": Cx.tolist(), "C_tool": Ct.tolist(),
                            "inputs": "B0 r + B1 r' + B2 r'' per axis", "state": "[plant z, I]"},
            "approximate_delay": bool(loop_delay)}
    for j, aj in enumerate(cfg.axes):
        for key, C in (("G_er", Cx), ("G_er_tool", Ct)):
            if key == "G_er_tool" and not aj.two_mass:
                continue
            cont[key][aj.name] = {}
            for i, ai in enumerate(cfg.axes):
                Bin = np.column_stack((B0[:, i], B1[:, i], B2[:, i]))
                keep = _structural_keep(Acl, Bin, C[j])
                if keep.size == 0:  # no path from this command to this output
                    cont[key][aj.name][ai.name] = {"num": [1.0 if i == j else 0.0], "den": [1.0]}
                    continue
                Ak = Acl[np.ix_(keep, keep)]
                nums = []
                for Bk in (B0, B1, B2):
                    num, den = signal.ss2tf(Ak, Bk[keep, i:i + 1], C[j:j + 1, keep], np.zeros((1, 1)))
                    nums.append(np.atleast_1d(np.squeeze(num)))
                num = _polyadd(_polyadd(nums[0], np.r_[nums[1], 0.0]), np.r_[nums[2], 0.0, 0.0])
                num_e = _polyadd((den if i == j else np.zeros(1)), -num)
                if abs(num_e[-1]) < 1e-10 * abs(den[-1]):
                    num_e[-1] = 0.0  # G_er(0) = 0 up to rounding (integral/type-1 loop)
                cont[key][aj.name][ai.name] = {"num": _trim(num_e).tolist(), "den": np.asarray(den).tolist()}
        cont["K"][aj.name] = {}
        if aj.two_mass:
            cont["K_tool"][aj.name] = {}
        for i, ai in enumerate(cfg.axes):
            c = taylor_coefficients(lambda s: G_cont(s, Cx, j, i, aj.record_delay + aj.delay), rho)
            cont["K"][aj.name][ai.name] = {"K_vel": c[1], "K_acc": c[2], "K_jerk": c[3], "G0": c[0]}
            if aj.two_mass:
                c = taylor_coefficients(lambda s: G_cont(s, Ct, j, i, 0), rho)
                cont["K_tool"][aj.name][ai.name] = {"K_vel": c[1], "K_acc": c[2], "K_jerk": c[3], "G0": c[0]}
    modes = {}
    for a in cfg.axes:
        if a.two_mass:
            w0 = 2 * np.pi * a.mode_hz
            cand = [p for p in poles if p.imag > 0]
            best = min(cand, key=lambda p: abs(abs(p) - w0))
            modes[a.name] = _pole_info(best)
            modes[a.name]["open_loop_hz"] = a.mode_hz
            modes[a.name]["open_loop_zeta"] = a.mode_zeta
    cont["modes"] = modes

    # ------------------------------------------------------------- sampled (exact) truth
    (Ad, Bd, Cd, Dd), outs = sampled_closed_loop(cfg, plant)
    zp = np.linalg.eigvals(Ad).astype(complex)
    nzero = int(np.sum(np.abs(zp) < 1e-9))
    sp = [np.log(z) / Ts for z in zp if abs(z) >= 1e-9]
    nX = Ad.shape[0]

    def G_samp(s, row, i, rec_delay):
        out = np.empty(s.size, dtype=complex)
        for k, sk in enumerate(s):
            z = np.exp(sk * Ts)
            X = np.linalg.solve(z * np.eye(nX) - Ad, Bd[:, i])
            g = (Cd[row] @ X + Dd[row, i]) * z  # input is r_{k+1}
            out[k] = g
        return out

    samp = {"poles_z": [[float(z.real), float(z.imag)] for z in zp],
            "n_poles_at_origin": nzero,
            "poles": [_pole_info(p) for p in sorted(sp, key=lambda p: (abs(p), p.imag))],
            "K": {}, "K_tool": {},
            "state_space": {"A": Ad.tolist(), "B": Bd.tolist(), "C": Cd.tolist(), "D": Dd.tolist(),
                            "input": "r_{k+1} per axis (one-sample look-ahead)",
                            "outputs": outs}}
    for j, aj in enumerate(cfg.axes):
        samp["K"][aj.name] = {}
        if aj.two_mass:
            samp["K_tool"][aj.name] = {}
        dr = aj.record_delay
        for i, ai in enumerate(cfg.axes):
            # recorded error = r - z^{-dr} y = (r - y) + (1 - z^{-dr}) y, y = r - e
            def Ge(s, j=j, i=i, dr=dr):
                e = G_samp(s, 3 * j, i, dr)
                dij = 1.0 if i == j else 0.0
                y = dij - e
                return dij - np.exp(-s * dr * Ts) * y
            c = taylor_coefficients(Ge, rho)
            samp["K"][aj.name][ai.name] = {"K_vel": c[1], "K_acc": c[2], "K_jerk": c[3], "G0": c[0]}
            if aj.two_mass:
                def Gt(s, j=j, i=i):
                    return (1.0 if i == j else 0.0) - G_samp(s, 3 * j + 2, i, 0)
                c = taylor_coefficients(Gt, rho)
                samp["K_tool"][aj.name][ai.name] = {"K_vel": c[1], "K_acc": c[2], "K_jerk": c[3],
                                                     "G0": c[0]}
    return {
        "assumptions": ("friction, backlash, periodic force, force limit, quantisation and noise "
                        "off; viscous damping kept. 'continuous': controller treated as continuous "
                        "(ideal derivatives, no ZOH); poles and num/den are delay-free, K includes "
                        "delays exactly; with feed-forward use 'sampled'. 'sampled': the exact "
                        "discrete loop the simulator runs."),
        "Ts": Ts,
        "continuous": cont,
        "sampled": samp,
    }


def _cont_delay_response(cfg, plant, s, C, j, i):
    """Tracking response C x / r_i of the continuous loop with in-loop measurement delays."""
    na, nz = len(cfg.axes), plant.nz
    R = np.linalg.solve(s * np.eye(nz) - plant.A, plant.Bu)  # z per unit u
    Px = np.array([[R[plant.pos(plant.motor[a.name]), k] for k in range(na)] for a in cfg.axes])
    Ff = np.zeros(na, dtype=complex)
    Fb = np.zeros((na, na), dtype=complex)
    for a_i, a in enumerate(cfg.axes):
        Kp, Kv, Ti, kvff, kaff = _controller_params(a)
        Cc = Kv * (1 + 1 / (Ti * s))
        if a_i == i:
            Ff[a_i] = Cc * (Kp + kvff * s) + kaff * s * s
        Fb[a_i, a_i] = Cc * (Kp + s) * np.exp(-s * a.delay * cfg.Ts)
    u = np.linalg.solve(np.eye(na) + Fb @ Px, Ff)
    zc = R @ u
    Cz = C[j, :nz]
    return Cz @ zc
