"""Full LS identification (thesis section 4.2, Eqn 4.1-4.9): the benchmark baseline.

Eight parameters by one unconstrained LS (Eqn 4.7) of the measured position on

    x_k = a_i e_i,k - a_1 x'_k - a_2 x''_k + b_0 x_r,k + b_1 x_r'_k + b_2 x_r''_k - PV d+ - NV d-

with e_i the integrated tracking error (Eqn 4.6) and the derivatives of the MEASURED position
taken numerically (zero-phase Butterworth filtered; this is the method's known weakness). The
parameters map back (Eqn 4.5) to the closed loop

    (s^3 + a1 s^2 + a2 s + a3) x = (b0 s^3 + b1 s^2 + b2 s + a3) x_r - s (d+ PV + d- NV)

whose poles are checked against Eqn 4.8-4.9. The result is returned as a DriveModel (Tustin
discretised like the pole-search models) so it is simulated from x_r alone, exported and
compared with exactly the same machinery: Coulomb friction as a sat() with a narrow transition
band (PV/NV are a sign function) plus an asymmetry term |sat|.
"""
from __future__ import annotations

import numpy as np
from scipy import optimize

from ..errors import InputError, finite_number
from ..signals import butter_filtfilt, derivative
from .limits import recorded_limits
from .lsfit import Fit
from .pole_search import assemble
from .ranges import training_ranges
from .structure import InputSpec, OutputSpec, Structure


def pole_constraints(a, p_min_hz=0.1, wn_min_hz=0.1, zeta_min=0.05, zeta_max=10.0):
    """Pole check of Eqn 4.8-4.9 for s^3 + a1 s^2 + a2 s + a3 = (s + p)(s^2 + 2 zeta wn s + wn^2).

    Returns a dict with p [Hz], wn [Hz], zeta, the roots, ``stable`` and ``satisfied``.
    """
    roots = np.roots(a)
    stable = bool(np.all(roots.real < 0))
    cplx = [r for r in roots if abs(r.imag) > 1e-9 * max(1.0, abs(r))]
    real = sorted([r.real for r in roots if abs(r.imag) <= 1e-9 * max(1.0, abs(r))], key=lambda v: -v)
    if cplx:
        r = cplx[0]
        wn, zeta, p = abs(r), -r.real / abs(r), -real[0] if real else float("nan")
    else:  # three real roots: the fastest is p, the other two form a pair with zeta >= 1
        r1, r2, r3 = real[0], real[1], real[2]
        p = -r3
        wn = np.sqrt(r1 * r2) if r1 * r2 > 0 else 0.0
        zeta = -(r1 + r2) / (2 * wn) if wn > 0 else float("nan")
    out = {"p_hz": float(p / (2 * np.pi)), "wn_hz": float(wn / (2 * np.pi)), "zeta": float(zeta),
           "roots": [[float(r.real), float(r.imag)] for r in roots], "stable": stable}
    out["satisfied"] = bool(stable and p >= 2 * np.pi * p_min_hz and wn >= 2 * np.pi * wn_min_hz
                            and zeta_min <= zeta <= zeta_max)
    return out


def _continuous(theta):
    """Continuous closed-loop coefficients from the LS parameters (Eqn 4.5 inverted)."""
    ai, al1, al2, be0, be1, be2, dp, dm = theta
    if al2 == 0:
        raise InputError("Full LS failed: the acceleration coefficient is zero (no excitation)")
    a2 = 1.0 / al2
    return np.array([1.0, al1 * a2, a2, ai * a2]), be2 * a2, be1 * a2, be0 * a2, dp * a2, dm * a2


def _constrained_ls(Phi, Y, scale, check, p_min_hz, wn_min_hz=0.1, zeta_min=0.05, zeta_max=10.0):
    """Eqn 4.7 subject to the pole constraints of Eqn 4.9 (the constrained LS of [3]).

    For fixed poles (p, wn, zeta) the characteristic coefficients a1..a3 are known, the alpha terms
    move to the left-hand side and the remaining parameters (beta, delta) follow by LS; a bounded
    local search over the poles, started from the unconstrained solution clipped into the box,
    minimises the same equation error as the unconstrained method.
    """
    lo = np.array([np.log(2 * np.pi * p_min_hz), np.log(2 * np.pi * wn_min_hz), zeta_min])
    hi = np.array([np.log(2 * np.pi * 1e4), np.log(2 * np.pi * 1e4), zeta_max])
    lin = [3, 4, 5, 6, 7]

    def solve(z):
        p, wn, zeta = np.exp(z[0]), np.exp(z[1]), z[2]
        a = np.convolve([1.0, p], [1.0, 2 * zeta * wn, wn * wn])
        a2 = a[2]
        alpha = np.array([a[3] / a2, a[1] / a2, 1.0 / a2])
        rhs = Y - Phi[:, :3] @ alpha
        beta = np.linalg.lstsq(Phi[:, lin] / scale[lin], rhs, rcond=None)[0] / scale[lin]
        theta = np.concatenate([alpha, beta])
        r = Y - Phi @ theta
        return float(r @ r), theta

    x0 = np.clip([np.log(max(2 * np.pi * abs(check["p_hz"]), 1e-9)),
                  np.log(max(2 * np.pi * check["wn_hz"], 1e-9)),
                  check["zeta"] if np.isfinite(check["zeta"]) else 0.7], lo, hi)
    best = None
    for start in (x0, 0.5 * (lo + hi), np.array([lo[0] + 1.0, x0[1], 0.7])):
        res = optimize.minimize(lambda z: solve(z)[0], np.clip(start, lo, hi), method="L-BFGS-B",
                                bounds=list(zip(lo, hi)))
        if best is None or res.fun < best.fun:
            best = res
    return solve(best.x)[1]


def identify_full_ls(traces, axis="x", cutoff_hz=None, order=2, v_tilde=None, p_min_hz=0.1):
    """Full LS model of one axis (Eqn 4.7) as a DriveModel.

    Parameters
    ----------
    traces : Trace or list[Trace]
    axis : str
    cutoff_hz, order : Butterworth filter of the numerical derivatives (default min(50 Hz, 0.2 Nyq))
    v_tilde : float, mm/s, transition band standing in for the sign function in simulation
        (default 1e-3 x max |v|)
    p_min_hz : float, the pole constraint of Eqn 4.9; when the unconstrained LS violates
        Eqn 4.9 the fit is repeated with the poles constrained (constrained LS of [3])

    Raises
    ------
    InputError if the unconstrained LS gives an unstable closed loop (lack of excitation).
    """
    from .quasi_static import MIN_SAMPLES_PER_GAIN, check_excitation, default_cutoff
    p_min_hz = finite_number(p_min_hz, "p_min_hz", positive=True)
    v_tilde = None if v_tilde is None else finite_number(v_tilde, "v_tilde", positive=True)
    traces = training_ranges(traces, [axis], roles=("cmd", "act"))
    Ts = traces[0].Ts
    # None is the default, 0 a bad value (not silently "the default")
    cutoff_hz = default_cutoff(Ts) if cutoff_hz is None else finite_number(cutoff_hz, "cutoff_hz", positive=True)
    rows, ys, vmax = [], [], 0.0
    for tr in traces:
        xr, x = np.asarray(tr.cmd(axis), float), np.asarray(tr.act(axis), float)
        if np.ptp(xr) <= 0:
            raise InputError(f"axis '{axis}' does not move in the data range", source=tr.source,
                             column=f"{axis}.cmd")
        # positions relative to the range's first command: a drive's law does not depend on where
        # the axis is, but Eqn 4.7's LS does (an offset of 5 mm goes into the friction columns,
        # which sum to ~1 in motion: free run 3.2 -> 209 um)
        xr, x = xr - xr[0], x - xr[0]
        ei = Ts * np.cumsum(xr - x)                                         # Eqn 4.6
        xd = butter_filtfilt(derivative(x, Ts, 1), Ts, cutoff_hz, order)
        xdd = butter_filtfilt(derivative(xd, Ts, 1), Ts, cutoff_hz, order)
        xrd = butter_filtfilt(derivative(xr, Ts, 1), Ts, cutoff_hz, order)
        xrdd = butter_filtfilt(derivative(xrd, Ts, 1), Ts, cutoff_hz, order)
        pv, nv = (xd > 0).astype(float), (xd < 0).astype(float)
        rows.append(np.column_stack([ei, -xd, -xdd, xr, xrd, xrdd, -pv, -nv]))
        ys.append(x)
        vmax = max(vmax, float(np.max(np.abs(xd))))
    Phi, Y = np.vstack(rows), np.concatenate(ys)
    need = MIN_SAMPLES_PER_GAIN * Phi.shape[1]
    if Phi.shape[0] < need:     # 3 samples for 8 parameters were fitted (min-norm) and reported
        raise InputError(f"{Phi.shape[0]} samples are too few for the {Phi.shape[1]} parameters of "
                         f"Eqn 4.7 (need at least {need})", source=traces[0].source, column="samples")
    check_excitation(Phi[:, [4, 5]], cutoff_hz, axis, traces[0].source,
                     gains=("beta_1", "the acceleration terms of Eqn 4.7 (alpha_2, beta_2)"))
    scale = np.max(np.abs(Phi), axis=0)
    scale[scale == 0] = 1.0
    theta = np.linalg.lstsq(Phi / scale, Y, rcond=None)[0] / scale          # Eqn 4.7
    a, b0, b1, b2, dnp, dnm = _continuous(theta)
    check = pole_constraints(a, p_min_hz=p_min_hz)
    constrained = False
    if not check["satisfied"]:
        # the constrained LS of [3], in two steps: the slow real pole p ~ a3/a2 = alpha_i bounded
        # below (a linear bound, cheap and usually enough), then all three poles of Eqn 4.9
        lo = np.full(8, -np.inf)
        lo[0] = 2 * np.pi * p_min_hz * scale[0]
        theta = optimize.lsq_linear(Phi / scale, Y, bounds=(lo, np.full(8, np.inf))).x / scale
        a, b0, b1, b2, dnp, dnm = _continuous(theta)
        if not pole_constraints(a, p_min_hz=p_min_hz)["satisfied"]:
            theta = _constrained_ls(Phi, Y, scale, check, p_min_hz)
            a, b0, b1, b2, dnp, dnm = _continuous(theta)
        check = pole_constraints(a, p_min_hz=p_min_hz)
        constrained = True
    if not check["stable"]:
        raise InputError(f"Full LS gave an unstable closed loop (roots {check['roots']} rad/s): the data "
                         "lack excitation for this method; use the pole search", source=traces[0].source)
    a1, a2, a3 = a[1], a[2], a[3]
    ai, al1, al2, be0, be1, be2, dp, dm = theta
    vt = v_tilde if v_tilde is not None else 1e-3 * vmax
    st = Structure(inputs=[InputSpec("command", axis), InputSpec("friction", axis),
                           InputSpec("feature", axis, params={"function": "abs_sat", "v_tilde": vt})],
                   outputs=[OutputSpec("error", axis)], n_real=3, n_complex=0, same_sample="quadratic")
    c, o = 0.5 * (dnp - dnm), 0.5 * (dnp + dnm)   # d = c sign(v) + o |sign(v)|
    en, ci, fi, gi = f"{axis}_error", f"{axis}_cmd", f"{axis}_dnf", f"{axis}_abs_sat"
    b = {(en, ci): np.array([1.0 - b0, a1 - b1, a2 - b2, 0.0]),             # e/x_r = (P - N)/P
         (en, fi): np.array([0.0, 0.0, c, 0.0]), (en, gi): np.array([0.0, 0.0, o, 0.0])}
    # the continuous model, Tustin-discretised; causal through the command extrapolated from the
    # samples before (its continuous fit has no notion of the controller's sample delay)
    model = assemble(st, Fit(J=0.0, a=a, b=b, rms=None, feasible=True, v_tilde={axis: vt}), Ts)
    model.method = "full-ls"
    model.poles = [complex(r) for r in np.roots(a)]
    model.identification = {
        "theta": {"alpha_i": ai, "alpha_1": al1, "alpha_2": al2, "beta_0": be0, "beta_1": be1,
                  "beta_2": be2, "delta_plus": dp, "delta_minus": dm},
        "continuous": {"a": a.tolist(), "b": [b0, b1, b2, a3], "d_plus": dnp, "d_minus": dnm},
        "pole_constraints": check, "constrained": constrained, "cutoff_hz": cutoff_hz,
        "v_tilde_mm_s": {axis: vt},
    }
    model.metrics = {"fit_rms_mm": float(np.sqrt(np.mean((Y - Phi @ theta) ** 2)))}
    model.provenance = {"data": [{"source": tr.source, "sha256": tr.meta.get("sha256") or tr.fingerprint()}
                                 for tr in traces]}
    model.limits = recorded_limits(traces, model.axes)
    return model
