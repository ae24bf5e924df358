"""The slow pure-Python oracle of the simulation step (tests only).

This is the step of ``fmu_templates/fdid_core.c`` written out in Python, operation by operation
in the same order (sums left to right along each row, the same LU elimination), as it was the reference
simulator before the C core became the one definition. Tests run both and require the same
doubles: the C core is checked against an independent reading of the semantics in
``fdid_fmi/simulate.py``'s docstring.
"""
import itertools
import math

import numpy as np

from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel
from fdid_fmi.simulate import SimResult, run_up
from fdid_fmi.trace import Trace

_TOL = 1e-12


def _mv(M, v):
    """M @ v summed like the C core: left to right along each row (a cumulative sum is sequential;
    the core skips zero terms, which add exact zeros; it starts from +0.0, so a row summing to
    zero may differ in the sign of that zero, which compares equal)."""
    return np.cumsum(np.asarray(M) * v, axis=1)[:, -1] if M.shape[1] else np.zeros(M.shape[0])


def _lu_solve(M, r):
    """Gaussian elimination with partial pivoting on lists of floats, in the C core's order
    (``lu_solve`` in fmu_templates/fdid_core.c). Returns None if singular."""
    k = len(r)
    for c in range(k):
        piv, best = c, abs(M[c][c])
        for q in range(c + 1, k):
            if abs(M[q][c]) > best:
                best, piv = abs(M[q][c]), q
        if M[piv][c] == 0.0:
            return None
        if piv != c:
            M[c], M[piv] = M[piv], M[c]
            r[c], r[piv] = r[piv], r[c]
        for q in range(c + 1, k):
            f = M[q][c] / M[c][c]
            for j in range(c + 1, k):
                M[q][j] -= f * M[c][j]
            r[q] -= f * r[c]
    for q in range(k - 1, -1, -1):
        acc = r[q]
        for j in range(q + 1, k):
            acc -= M[q][j] * r[j]
        r[q] = acc / M[q][q]
    return r


class _Plan:
    """Index bookkeeping of a DriveModel, computed once per simulation."""

    def __init__(self, model: DriveModel, params=None):
        params = params or {}
        self.m = model
        ins = model.inputs
        self.axes = model.axes
        self.cmd = {p.axis: i for i, p in enumerate(ins) if p.kind == "command"}
        self.ext = [i for i, p in enumerate(ins) if p.kind == "external"]
        self.fric = [i for i, p in enumerate(ins) if p.kind == "friction"]
        self.feat = [i for i, p in enumerate(ins) if p.kind == "feature"]
        if len(self.fric) > 4:
            raise InputError("at most 4 friction inputs are supported", column="friction")
        self.pos = {a: model.output_index("position", a) for a in self.axes}
        self.err = {a: model.output_index("error", a) for a in self.axes}
        self.tool = {a: model.output_index("tool_position", a) for a in self.axes}
        self.vel = {a: model.output_index("velocity", a) for a in self.axes}
        # friction parameters (overridable like the FMU parameters)
        self.level, self.vt = [], []
        for i in self.fric:
            p = ins[i]
            on = params.get(f"{p.axis}_friction_on", True)
            lev = params.get(f"{p.axis}_friction_level", p.params.get("level", 1.0))
            vt = params.get(f"{p.axis}_v_tilde", p.params["v_tilde"])
            if not vt > 0:
                raise InputError(f"v_tilde must be > 0 mm/s, got {vt!r}", column=f"{p.axis}_v_tilde")
            self.level.append(float(lev) if on else 0.0)
            self.vt.append(float(vt))
        self.S, self.S2, self.G1 = model.steady_state_maps()
        # velocity source of each friction input: (output index, divide-by-Ts?)
        self.vsrc = []
        for i in self.fric:
            a = ins[i].axis
            if self.vel[a] is not None:
                self.vsrc.append((self.vel[a], False))
            else:
                self.vsrc.append((self.pos[a], True))
        self.branches = list(itertools.product((STICK, 0, 1, -1), repeat=len(self.fric)))


def _sat(x):
    return min(1.0, max(-1.0, x))


def feature_value(params, v_prev, x_cmd, x_prev, h=None):
    """Value of a ``feature`` input (see DriveModel) from the previous step's axis state (``h``:
    the play operator's state)."""
    f = params["function"]
    if f in ("play", "play_stribeck"):
        b = params["width_mm"]
        p = 1.0 if h <= x_prev - b else (-1.0 if h >= x_prev + b else (x_prev - h) / b)
        q = v_prev / params.get("v_s", 1.0)
        return p if f == "play" else p * math.exp(-(q * q))
    if f in ("sin_position", "cos_position"):
        x = x_cmd if params.get("source", "command") == "command" else x_prev
        arg = 2.0 * np.pi * x / params["period_mm"]
        # libm, like the C core (numpy's own exp/sin/cos may differ in the last bit)
        return math.sin(arg) if f == "sin_position" else math.cos(arg)
    s = _sat(v_prev / params["v_tilde"])
    if f == "sat":
        return s
    if f == "abs_sat":
        return abs(s)
    if f == "stribeck":
        q = v_prev / params["v_s"]
        return s * math.exp(-(q * q))
    raise InputError(f"unknown feature function '{f}'")


STICK = 2   # branch code: v_i = 0 held by |d_i| <= L_i (fdid_core.c, solve_friction)


def solve_friction(alpha, beta, level, vt, branches):
    """Solve d_i = L_i sat((alpha_i + sum_j beta_ij d_j) / vt_i) exactly, with stiction.

    Parameters
    ----------
    alpha : (m,) velocity with the friction inputs at zero
    beta : (m, m) d velocity_i / d d_j
    level, vt : (m,) friction levels L and transition velocities v_tilde
    branches : list of tuples over {STICK, 0: linear, +1, -1}, tried in order

    Returns
    -------
    d : (m,) friction input values
    """
    m = len(alpha)
    if m == 1:  # closed form, the common case
        L, v, a, b = float(level[0]), float(vt[0]), float(alpha[0]), float(beta[0][0])
        if L == 0.0:
            return np.zeros(1)
        if b < 0.0:
            d = -a / b
            if abs(d) <= L:
                return np.array([d])
        den = v - L * b
        if den > 0:
            d = L * a / den
            if abs(d) <= L:
                return np.array([d])
        for s in (1.0, -1.0):
            if s * (a + b * s * L) >= v * (1 - _TOL):
                return np.array([s * L])
        return np.array([L * _sat(a / v)])
    # plain floats: the same operations, in the same order, as the C core
    al = [float(x) for x in alpha]
    be = [[float(x) for x in row] for row in beta]
    lv = [float(x) for x in level]
    vv = [float(x) for x in vt]
    for br in branches:
        d = [br[i] * lv[i] if br[i] in (1, -1) else 0.0 for i in range(m)]
        un = [i for i in range(m) if br[i] in (STICK, 0)]
        sl = [i for i in range(m) if br[i] in (1, -1)]
        if un:
            M, rhs = [], []
            for q in un:
                acc = 0.0
                for j in sl:
                    acc += be[q][j] * d[j]
                g = lv[q] / vv[q]
                if br[q] == STICK:
                    M.append([be[q][c] for c in un])
                    rhs.append(-(al[q] + acc))
                else:
                    M.append([(1.0 if q == c else 0.0) - g * be[q][c] for c in un])
                    rhs.append(g * (al[q] + acc))
            sol = _lu_solve(M, rhs)
            if sol is None:
                continue
            for r, i in enumerate(un):
                d[i] = sol[r]
        ok = True
        for i in range(m):
            if br[i] == STICK:
                ok = lv[i] > 0.0 and be[i][i] < 0.0 and abs(d[i]) <= lv[i]
                if not ok:
                    break
                continue
            if lv[i] == 0.0:
                continue
            acc = 0.0
            for j in range(m):
                acc += be[i][j] * d[j]
            z = (al[i] + acc) / vv[i]
            if (br[i] == 0 and abs(z) > 1 + _TOL) or (br[i] == 1 and z < 1 - _TOL) or \
                    (br[i] == -1 and z > -1 + _TOL):
                ok = False
                break
        if ok:
            return np.array(d)
    return np.array([lv[i] * _sat(al[i] / vv[i]) for i in range(m)])


def oracle_simulate(model, trace_or_commands, Ts=None, start_velocity=None, params=None):
    """Free run like :func:`fdid_fmi.simulate.simulate` (run-up for a Trace that starts
    accelerating, steady ramp otherwise), in pure Python."""
    from fdid_fmi.simulate import _commands, _trim
    cmds, exts, t, ts = _commands(model, trace_or_commands, Ts, None)
    start_velocity_given = start_velocity
    if start_velocity is None:
        start_velocity = ({a: (c[1] - c[0]) / model.Ts for a, c in cmds.items()}
                          if isinstance(trace_or_commands, Trace) else {})
    plan = _Plan(model, params)
    if isinstance(trace_or_commands, Trace) and start_velocity_given is None:
        R, ext, v0 = run_up(cmds, model.Ts)
        if R:
            exts_r = {k: np.concatenate([np.full(R, v[0]), v]) for k, v in exts.items()}
            res = _run(plan, ext, exts_r, np.concatenate([t[0] - ts * np.arange(R, 0, -1), t]), v0)
            return _trim(res, R)
    return _run(plan, cmds, exts, t, start_velocity)


def _run(plan, cmds, exts, t, v0):
    m = plan.m
    A, B, C, D, G1, Ts = m.A, m.B, m.C, m.D, plan.G1, m.Ts
    N, nu, ny = len(t), B.shape[1], C.shape[0]
    ins = m.inputs
    uref = np.zeros(nu)
    for a, i in plan.cmd.items():
        uref[i] = cmds[a][0]
    yoff = _mv(G1, uref)
    v0 = {a: float(v0.get(a, 0.0)) for a in plan.axes}

    # --- initial state: steady ramp (see module docstring)
    u0 = np.zeros(nu)
    du = np.zeros(nu)
    for a, i in plan.cmd.items():
        du[i] = v0[a] * Ts
    for j, i in enumerate(plan.fric):
        u0[i] = plan.level[j] * _sat(v0[ins[i].axis] / plan.vt[j])
    for i in plan.ext:
        u0[i] = exts[ins[i].name][0]
    play = [i for i in plan.feat if ins[i].params["function"] in ("play", "play_stribeck")]
    for i in plan.feat:
        a = ins[i].axis
        # the play has slid through on the start ramp: h = x - b sign(v0), so the value is sign(v0)
        u0[i] = feature_value(ins[i].params, v0[a], cmds[a][0], cmds[a][0],
                              cmds[a][0] - float(np.sign(v0[a])) * ins[i].params["width_mm"]) \
            if i in play else feature_value(ins[i].params, v0[a], cmds[a][0], cmds[a][0])
    xi = _mv(plan.S, u0) - _mv(plan.S2, du)
    y0 = _mv(C, xi) + _mv(D, u0) + yoff
    x_prev = {a: y0[plan.pos[a]] - v0[a] * Ts for a in plan.axes}
    # the play has slid through on the start ramp: h = x - b sign(v0)
    hold = {i: x_prev[ins[i].axis] - float(np.sign(v0[ins[i].axis])) * ins[i].params["width_mm"] for i in play}
    v_prev = dict(v0)

    Y = np.empty((N, ny))
    U = np.empty((N, nu))
    V = {a: np.empty(N) for a in plan.axes}
    nf = len(plan.fric)
    beta = np.zeros((nf, nf))
    for j, (o, diff) in enumerate(plan.vsrc):
        for jj, i in enumerate(plan.fric):
            beta[j, jj] = D[o, i] / Ts if diff else D[o, i]
    u = np.zeros(nu)
    AB, CD = np.hstack([A, B]), np.hstack([C, D])      # the step acts on z = [xi; u]
    for k in range(N):
        for a, i in plan.cmd.items():
            u[i] = cmds[a][k] - uref[i]
        for i in plan.ext:
            u[i] = exts[ins[i].name][k]
        for i in plan.feat:
            a = ins[i].axis
            u[i] = feature_value(ins[i].params, v_prev[a], cmds[a][k], x_prev[a], hold.get(i))
        for i in plan.fric:
            u[i] = 0.0
        y = _mv(CD, np.concatenate([xi, u])) + yoff
        if nf:
            alpha = np.empty(nf)
            for j, (o, diff) in enumerate(plan.vsrc):
                alpha[j] = (y[o] - x_prev[ins[plan.fric[j]].axis]) / Ts if diff else y[o]
            d = solve_friction(alpha, beta, plan.level, plan.vt, plan.branches)
            for j, i in enumerate(plan.fric):
                u[i] = d[j]
            y = y + _mv(D[:, plan.fric], d)
        for a in plan.axes:
            v_prev[a] = y[plan.vel[a]] if plan.vel[a] is not None else (y[plan.pos[a]] - x_prev[a]) / Ts
            x_prev[a] = y[plan.pos[a]]
            V[a][k] = v_prev[a]
        for i in play:
            b = ins[i].params["width_mm"]
            hold[i] = min(max(hold[i], x_prev[ins[i].axis] - b), x_prev[ins[i].axis] + b)
        Y[k] = y
        U[k] = u
        xi = _mv(AB, np.concatenate([xi, u]))
    return SimResult(t=np.asarray(t), y=Y, u=U, axes=_axis_view(plan, Y, cmds, V),
                     output_names=[p.name for p in m.outputs])


def _axis_view(plan, Y, cmds, V):
    out = {}
    for a in plan.axes:
        x = Y[:, plan.pos[a]]
        e = Y[:, plan.err[a]] if plan.err[a] is not None else cmds[a] - x
        d = {"position": x, "error": e, "velocity": V[a]}
        if plan.tool[a] is not None:
            d["tool_position"] = Y[:, plan.tool[a]]
        out[a] = d
    return out
