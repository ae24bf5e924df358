"""Least-squares projection for a candidate pole set (thesis Eqn 4.16, 5.8-5.17).

Given the poles (and v_tilde), :class:`LSProblem` builds the regressors of every input
(``regressors.py``), scales them by their infinity norm (Eqn 5.8-5.9), solves one LS problem per
output for its numerator terms (Eqn 5.10) with the terms known to be zero left out, applies the
d.c.-gain constraints as fixed terms moved to the output side (Eqn 5.13-5.17), unscales the
numerators (Eqn 5.12) and returns the objective: the RMS of the output prediction errors with
each output scaled by its infinity norm (W_z), as in section 5.2.3.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.linalg import lapack

from .. import kernel
from ..errors import InputError
from ..signals import measured_velocity
from . import regressors as rg
from .ranges import check_externals, training_ranges
from .structure import OUTPUT_SOURCES, Structure


@dataclass
class Segment:
    """Prepared data of one data range: fixed inputs, measured velocities, outputs."""

    W: np.ndarray          # (m, N) inputs; friction/feature rows filled per candidate
    wref: np.ndarray       # (m,) offsets removed from command inputs
    dw: np.ndarray         # (m,) ramp increment at the start
    vel: dict              # axis -> measured velocity (mm/s), drives friction
    pos: dict              # axis -> measured position (mm), drives position features
    cmd: dict              # axis -> commanded position (mm), for features with source "command"
    Z: np.ndarray          # (p, N) measured outputs
    known: np.ndarray      # (p, N) their same-sample part, not fitted (error outputs: x_r,k - x_r,k-1)
    R: int = 0             # run-up samples prepended to W, vel, pos (not fitted)
    late_part: np.ndarray | None = None   # (m, N) w - w^ of the inputs from outside (other
                                          # rows zero), set by the first design


@dataclass
class Fit:
    """Result of the LS projection for one pole set."""

    J: float                    # objective (scaled RMS), penalised if a sign constraint fails
    a: np.ndarray               # monic A(s)
    b: dict                     # (output name, input name) -> numerator (n+1,) as FITTED
    rms: np.ndarray             # per-output RMS prediction error (unscaled units)
    feasible: bool
    v_tilde: dict               # axis -> v_tilde used


def position_and_velocity(tr, axis, ma_order=1, velocity="backward"):
    """The position (mm) and velocity (mm/s) of ``axis`` the friction regressor sat(v/v_tilde) is
    built from: the measured position (the command where none is recorded) and the drive's
    velocity channel, else the filtered difference of that position (``measured_velocity``)."""
    x = np.asarray(tr.act(axis) if tr.has(axis, "act") else tr.cmd(axis), float)
    v = (np.asarray(tr.get(axis, "vel"), float) if tr.has(axis, "vel")
         else measured_velocity(x, tr.Ts, ma_order, velocity))
    return x, v


class LSProblem:
    """The data of an identification, ready for fast repeated LS projections.

    Parameters
    ----------
    traces : list[Trace]  data ranges (same Ts)
    structure : Structure
    """

    def __init__(self, traces, structure: Structure):
        structure.check()
        self.s = structure
        externals = [ins.channel for ins in structure.inputs if ins.kind == "external"]
        traces = training_ranges(traces, structure.axes, externals)
        for tr in traces:
            check_externals(tr, structure.axes, externals)
        self.traces = traces
        self.Ts = traces[0].Ts
        self.n = structure.order
        self.late = np.array([ins.late for ins in structure.inputs], bool)
        if structure.same_sample is None:
            raise InputError("LSProblem needs a same-sample prediction (structure.same_sample)",
                             column="same_sample")
        self.coef = rg.SAME_SAMPLE[structure.same_sample]
        self.m = len(structure.inputs)
        self.p = len(structure.outputs)
        for ins in structure.inputs:
            # a constant input's regressors (its d.c. term apart) are rounding noise (1e-15) that
            # the column scaling of the LS turned into numerators of 1e13 and a worse model
            if ins.kind == "external" and all(np.ptp(tr.extra(ins.channel)) == 0 for tr in traces):
                raise InputError(f"the external input is constant ({float(traces[0].extra(ins.channel)[0]):g}) "
                                 f"in every data range: it carries nothing to identify; leave it out",
                                 source=traces[0].source, column=ins.channel)
        self.segments = [self._segment(tr) for tr in traces]
        self.N = sum(sg.Z.shape[1] for sg in self.segments)
        need = 20 * (self.n + 1) * self.m
        if self.N < need:
            raise InputError(f"{self.N} samples are too few for an order-{self.n} model with {self.m} "
                             f"inputs (need at least {need})", source=traces[0].source, column="samples")
        Zall = np.concatenate([sg.Z for sg in self.segments], axis=1)
        self.Wz = np.max(np.abs(Zall - Zall.mean(axis=1, keepdims=True)), axis=1)
        for o, w in zip(structure.outputs, self.Wz):
            if not w > 0:
                raise InputError(f"output '{o.name}' is constant over the data range: nothing to fit",
                                 source=traces[0].source, column=o.name)
        self.Z = Zall - np.concatenate([sg.known for sg in self.segments], axis=1)   # LS target
        self.zz = np.sum(self.Z ** 2, axis=1)
        # per output: which (input, l) columns are estimated / fixed
        self.cols, self.fixed = [], []
        self.allow = {}
        for o in structure.outputs:
            est, fix = [], []
            for i, ins in enumerate(structure.inputs):
                allow = structure.allowed(o.name, ins.name)
                if o.integrators:
                    allow[self.n - o.integrators + 1:] = False   # terms that integrate away (5.28)
                key = (o.name, ins.name)
                if key in structure.dc_gain:
                    q, _ = structure.dc_gain[key]
                    if not 0 <= q <= self.n:
                        raise InputError(f"d.c.-gain order {q} outside 0..{self.n}", column=str(key))
                    allow[self.n - q + 1:] = False
                    allow[self.n - q] = False
                    fix.append((i, self.n - q, key))
                self.allow[key] = allow.copy()
                est.extend((i, l) for l in np.flatnonzero(allow))
            self.cols.append(est)
            self.fixed.append(fix)
        used = sorted({c for cs in self.cols for c in cs} | {(i, l) for fx in self.fixed for i, l, _ in fx})
        self.used = used
        self.col_index = {c: k for k, c in enumerate(used)}
        # per used column: its input, regressor row and whether the input comes from outside
        self._col_input = np.array([i for i, _ in used], dtype=np.intc)
        self._col_l = np.array([l for _, l in used], dtype=int)
        self._col_late = np.ascontiguousarray(self.late[self._col_input], dtype=np.intc)
        self._dc_rows = [(r, i) for r, (i, l) in enumerate(used) if l == self.n]
        self._index_outputs()

    def _index_outputs(self):
        """What :meth:`project` reads per output, worked out once (it runs at every pole set):
        the estimated columns and their block of G, the fixed columns with their d.c.-gain
        value (Eqn 5.16), and for every input the lags l whose coefficient is a numerator
        term with its column."""
        self._est, self._est_block, self._fix, self._terms = [], [], [], []
        for j, o in enumerate(self.s.outputs):
            idx = np.array([self.col_index[c] for c in self.cols[j]], dtype=int)
            self._est.append(idx)
            self._est_block.append(np.ix_(idx, idx))
            self._fix.append([(self.col_index[(i, l)], self.s.dc_gain[key][1]) for i, l, key in self.fixed[j]])
            terms = []
            for i, ins in enumerate(self.s.inputs):
                fixed_l = {fl for fi, fl, _ in self.fixed[j] if fi == i}
                ls = [l for l in range(self.n + 1) if (i, l) in self.col_index
                      and (self.allow[(o.name, ins.name)][l] or l in fixed_l)]
                terms.append(((o.name, ins.name), np.array(ls, dtype=int),
                              np.array([self.col_index[(i, l)] for l in ls], dtype=int)))
            self._terms.append(terms)

    # ------------------------------------------------------------ data
    def _segment(self, tr):
        """Inputs, velocities and outputs of one data range. A range that starts accelerating
        gets the simulator's run-up from rest (``simulate.run_up``): R samples prepended to the
        inputs and dropped from the LS, so regressors and free run start identically."""
        from ..simulate import run_up
        s = self.s
        N = tr.n
        cmds = {ins.axis: np.asarray(tr.cmd(ins.axis), float) for ins in s.inputs if ins.kind == "command"}
        R, ext, v0 = run_up(cmds, tr.Ts)
        W = np.zeros((self.m, N + R))
        wref = np.zeros(self.m)
        dw = np.zeros(self.m)
        vel, pos = {}, {}
        for ax in s.axes:
            x, v = position_and_velocity(tr, ax, s.ma_order, s.velocity)
            pre = ext[ax][:R]
            vpre = np.diff(ext[ax][: R + 1]) / tr.Ts if R else np.zeros(0)
            pos[ax] = np.concatenate([pre - cmds[ax][0] + x[0], x])
            vel[ax] = np.concatenate([vpre, v])
        for i, ins in enumerate(s.inputs):
            if ins.kind == "command":
                c = ext[ins.axis]
                if np.ptp(c) <= 0:
                    raise InputError(f"the commanded position of axis '{ins.axis}' does not move in this "
                                     f"range: nothing to identify", source=tr.source, column=ins.name)
                wref[i] = cmds[ins.axis][0]
                W[i] = c - wref[i]
                # the steady ramp the record (or its run-up) starts on, as the simulator starts it
                dw[i] = v0[ins.axis] * tr.Ts if R else W[i, 1] - W[i, 0]
            elif ins.kind == "external":
                e = np.asarray(tr.extra(ins.channel), float)
                W[i] = np.concatenate([np.full(R, e[0]), e])
            elif ins.kind == "feature":     # fixed parameters: rows independent of the search
                src = ext if ins.params.get("source", "command") == "command" else pos
                c = cmds[ins.axis]          # the simulator's start: its start velocity's sign
                start = np.sign(v0[ins.axis] if R else (c[1] - c[0] if c.size > 1 else 0.0))
                W[i] = feature_signal(ins.params, vel[ins.axis], src[ins.axis], start)
        Z = np.zeros((self.p, N))
        known = np.zeros((self.p, N))
        for j, o in enumerate(s.outputs):
            Z[j] = _measured_output(tr, o)
            if o.is_error:
                # e_k = x_r,k - x_k and x_k uses x^_r,k (regressors.py): x_r,k - x^_r,k is known
                c = ext[o.axis]
                known[j] = rg.same_sample_part(c[None], [0.0 if R else c[1] - c[0]], self.coef)[0, R:]
        return Segment(W=W, wref=wref, dw=dw, vel=vel, pos=pos, cmd=ext, Z=Z, known=known, R=R)

    def fill_nonlinear_inputs(self, sg, v_tilde, override=None):
        """Friction rows of the inputs for the given v_tilde (per axis); the rest of ``sg.W``.

        ``override`` maps an input index to the values to use after the run-up (the friction
        signal a simulation produced, see ``pole_search.refine_friction``).
        """
        W = sg.W.copy()
        for i, ins in enumerate(self.s.inputs):
            if override and i in override:
                W[i, : sg.R] = np.clip(sg.vel[ins.axis][: sg.R] / v_tilde[ins.axis], -1.0, 1.0)
                W[i, sg.R:] = override[i]
            elif ins.kind == "friction":
                W[i] = np.clip(sg.vel[ins.axis] / v_tilde[ins.axis], -1.0, 1.0)
        return W

    # ------------------------------------------------------------ projection
    def design(self, a, v_tilde, overrides=None):
        """Regressors of the used columns, stacked over segments: (columns, samples)."""
        den, F = rg.tustin_basis(a, self.Ts)
        Fr = F[self._col_l]
        late_c = Fr[:, 0] / den[0]
        blocks = []
        for k, sg in enumerate(self.segments):
            W = self.fill_nonlinear_inputs(sg, v_tilde, overrides[k] if overrides else None)
            R = rg.allpole_filter(den, W, W[:, 0], sg.dw)
            if sg.late_part is None and self.late.any():
                # causal: D0 w[k] -> D0 w^[k] for inputs from outside. Their rows (commands,
                # external channels, features of the command) depend neither on the poles nor
                # on v_tilde, and overrides replace friction rows only: computed once
                sg.late_part = np.zeros_like(W)
                sg.late_part[self.late] = rg.same_sample_part(W[self.late], sg.dw[self.late], self.coef)
            # the used regressors, run-up dropped: (len(used), N)
            Mt = kernel.regressor_rows(R, self.n, self._col_input, Fr, sg.R, self._col_late, late_c,
                                       sg.late_part)
            for r, i in self._dc_rows:
                if sg.wref[i] != 0.0:
                    Mt[r] += sg.wref[i] / a[-1]              # d.c. response of the removed offset
            blocks.append(Mt)
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)

    def project(self, a, v_tilde, want_residuals=False, overrides=None):
        """LS projection for one pole set; returns a :class:`Fit` (and residuals if asked).

        ``overrides``: per segment, {input index: values} replacing computed input rows.
        """
        unusable = Fit(J=1e6, a=np.asarray(a), b={}, rms=np.full(self.p, np.inf), feasible=False,
                       v_tilde=dict(v_tilde))
        if not np.all(np.isfinite(a)):
            return (unusable, None) if want_residuals else unusable
        Ms = self.design(a, v_tilde, overrides)
        # max |M| per row without an |M| array; NaN and inf reach r (max and min propagate them)
        r = np.maximum(Ms.max(axis=1), -Ms.min(axis=1))
        if not np.all(np.isfinite(r)):    # a pole set the Tustin filter cannot represent
            return (unusable, None) if want_residuals else unusable
        Z = self.Z
        r[r == 0] = 1.0
        Ms /= r[:, None]                                      # Eqn 5.9, in place: design's array is fresh
        G = Ms @ Ms.T
        MZ = Ms @ Z.T                                         # (k, p)
        b, rms, feasible, finite, res_all = {}, np.zeros(self.p), True, True, []
        total = 0.0
        # absurd values (a d.c. gain of 1e300, v_tilde of 1e308) overflow here: the non-finite
        # result is refused below, without a warning line for the user
        with np.errstate(over="ignore", invalid="ignore"):
            for j in range(self.p):
                z_off = np.zeros(len(self.used))
                for k, value in self._fix[j]:
                    z_off[k] = value * a[-1] * r[k]                # Eqn 5.16
                idx = self._est[j]
                rhs = MZ[:, j] - G @ z_off
                theta = np.zeros(len(self.used))
                if idx.size:
                    theta[idx] = _solve_normal(G[self._est_block[j]], rhs[idx])
                full = theta + z_off
                if want_residuals:
                    res = Z[j] - full @ Ms
                    sse = float(res @ res)
                    res_all.append(res)
                else:
                    sse = max(float(self.zz[j] - 2 * full @ MZ[:, j] + full @ G @ full), 0.0)
                rms[j] = np.sqrt(sse / self.N)
                total += sse / self.Wz[j] ** 2
                coef = full / r                                   # Eqn 5.12
                finite = finite and bool(np.isfinite(coef).all())   # the numerators are taken from it
                for key, ls, ks in self._terms[j]:
                    bb = np.zeros(self.n + 1)
                    bb[ls] = coef[ks]
                    b[key] = bb
        if not (finite and np.all(np.isfinite(rms))):
            # e.g. v_tilde = 1e308 mm/s: a friction regressor of 1e-306 unscaled into inf numerators
            return (unusable, None) if want_residuals else unusable
        for (oname, iname), sign in self.s.friction_sign.items():
            allow = self.allow[(oname, iname)]
            if allow.any():
                lowest = np.flatnonzero(allow)[-1]
                if sign * b[(oname, iname)][lowest] < 0:
                    feasible = False
        J = float(np.sqrt(total / (self.N * self.p)))
        fit = Fit(J=J if feasible else 10.0 + J, a=np.asarray(a), b=b, rms=rms, feasible=feasible,
                  v_tilde=dict(v_tilde))
        if want_residuals:
            return fit, np.array(res_all)
        return fit


# A regressor whose Cholesky pivot keeps less than this share of its column's energy (d_i^2 / G_ii:
# 1 - R^2 of the column on the earlier ones) is collinear to rounding: two identical feature rows (a
# backlash sat(v / v_b) at v_b = v_tilde beside the friction row), or a pole set whose filtered
# numerator rows coincide (singular-value ratios of G of 1e-14 with the next at 1e-4, seen in
# the mode refits). Cholesky then returns rounding along the null direction: coefficients of
# +-0.48 instead of 1e-3 that fit the training data equally and free-run 2.9 mm off on another
# trace, depending on the machine's BLAS kernels (AVX2 or AVX-512). Such systems get the
# minimum-norm solution with directions below COLLINEAR_RTOL of the largest singular value of G
# dropped (gelsd), the same on every machine. Legitimate pivots of the searches reach ~1e-11.
COLLINEAR_RTOL = 1e-12


def _solve_normal(G, rhs):
    """Solution of the normal equations G theta = rhs: Cholesky (LAPACK ``posv``, what
    ``scipy.linalg.solve(assume_a="pos")`` computes, without its condition estimate and checks:
    this runs at every pole set of the search); the truncated minimum-norm least-squares solution
    when G is not positive definite or a pivot shows collinear regressors (see COLLINEAR_RTOL)."""
    c, x, info = lapack.dposv(G, rhs)
    if info == 0 and np.all(np.diag(c) ** 2 > COLLINEAR_RTOL * np.diag(G)):
        return x
    return linalg.lstsq(G, rhs, cond=COLLINEAR_RTOL, check_finite=False)[0]


def feature_signal(params, vel, pos, direction=0.0):
    """Feature input over a record from measured velocity and the position its ``source`` names
    (the simulator's ``feature_value``, applied to measured signals); ``direction``: the sign of
    the simulator's start velocity (the play starts slid through in that direction)."""
    f = params["function"]
    if f == "play":
        return play_signal(pos, params["width_mm"], direction)
    if f == "play_stribeck":        # the play and the velocity of the previous step, as simulated
        vp = np.concatenate([vel[:1], vel[:-1]])
        return play_signal(pos, params["width_mm"], direction) * np.exp(-(vp / params["v_s"]) ** 2)
    if f in ("sin_position", "cos_position"):
        arg = 2 * np.pi * pos / params["period_mm"]
        return np.sin(arg) if f == "sin_position" else np.cos(arg)
    s = np.clip(vel / params["v_tilde"], -1.0, 1.0)
    if f == "sat":
        return s
    if f == "abs_sat":
        return np.abs(s)
    if f == "stribeck":
        return s * np.exp(-(vel / params["v_s"]) ** 2)
    raise InputError(f"unknown feature function '{f}'", column="feature")


def play_signal(x, b, direction):
    """The play feature over a record of positions x (mm), as the simulator applies it (its
    ``feature_value`` and ``update_state``: the feature reads the previous step's position):
    w_0 = ``direction`` (the start ramp's: +-1 moving, 0 at rest), h = x_0 - b direction, and
    for k >= 1: h = min(max(h, x_k-1 - b), x_k-1 + b), w_k = (x_k-1 - h) / b, exactly +-1 where
    h sits on a bound."""
    x = np.asarray(x, float)
    w = np.empty_like(x)
    w[0] = direction
    h = x[0] - b * direction
    for k in range(1, x.size):
        xp = float(x[k - 1])
        lo, hi = xp - b, xp + b
        h = min(max(h, lo), hi)
        w[k] = 1.0 if h <= lo else (-1.0 if h >= hi else (xp - h) / b)
    return w


def _measured_output(tr, o):
    src = OUTPUT_SOURCES[o.kind]
    ax = o.axis
    if src == "cmd-act":
        return np.asarray(tr.cmd(ax), float) - np.asarray(tr.act(ax), float)
    if src == "cmd-tool":
        return np.asarray(tr.cmd(ax), float) - np.asarray(tr.get(ax, "tool"), float)
    if src == "vel" and not tr.has(ax, "vel"):
        return measured_velocity(np.asarray(tr.act(ax), float), tr.Ts)
    return np.asarray(tr.get(ax, src), float)
