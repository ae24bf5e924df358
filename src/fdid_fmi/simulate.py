"""The free run of a DriveModel: one definition, the C core ``fmu_templates/fdid_core.c``.

Every FMU compiles that file; the package builds it at install time (``fdid_fmi._kernel``) and
:func:`simulate` runs it through :mod:`fdid_fmi.kernel`, so the in-process prediction and an
exported FMU give the same doubles. A slow pure-Python reading of the same semantics lives only
in the tests (``tests/sim_oracle.py``).

Semantics (DESIGN.md "Simulation semantics")
--------------------------------------------
Causality. Position, velocity and tool-side outputs do not depend on the command of the same
sample (``model.delayed_input``): x_k is the prediction from the commands up to k-1, so an
output read after a co-simulation step ``doStep(t_k, Ts)`` is the model's value at t_k+1.
The error output is e_k = x_r,k - x_k with the command of the same sample (the FMU exports no
error output: a master forms x_cmd(t) - ``<axis>_x``(t) itself, docs/fmu-interface.md).

Offsets. Command inputs enter as deviations from their value at the first sample, u_ref; the
d.c. response G1 u_ref (G1 = C (I-A)^-1 B + D) is added to the outputs. This keeps the states
small whatever the absolute axis position is.

Initial state. The model starts in the steady state of a ramp: each command input moves at the
axis start velocity v0 (0 = at rest at the first commanded position; a record that starts in
motion passes its commanded start velocity). With u[k] = u0 + k du,
xi0 = (I-A)^-1 (B u0 - Delta), Delta = (I-A)^-1 B du. Friction inputs start at
L sat(v0 / v_tilde), play inputs slid through (sign(v0), 0 at rest); the previous position
x[-1] = x[0] - v0 Ts; the previous velocity is v0.

Step k, given xi, the inputs (commands, externals) and the axis states of step k-1:
1. feature inputs from the previous step's velocity / position (the play from its state h,
   which follows each new position: h <- min(max(h, x - b), x + b));
2. friction inputs d = L sat(v / v_tilde), where the axis velocity v is either a model
   ``velocity`` output or the backward difference (x[k] - x[k-1]) / Ts of the ``position``
   output. v depends on d through the feed-through D, so v = alpha + beta d is affine and
   sat is piecewise linear: the step is solved exactly by checking the branches
   stick (v = 0 held by |d| <= L, beta < 0) / linear / +1 / -1 for each friction input, in
   that order; the first consistent one wins. A one-sample lag instead limit-cycles at rest
   when L*|beta|/v_tilde >> 1, and without the stick branch an axis at rest creeps through
   the viscous transition band;
3. y = C xi + D u + G1 u_ref; xi <- A xi + B u.
Sums run left to right along each matrix row, with plain IEEE products (no fused multiply-add).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernel
from .errors import InputError
from .model import DriveModel, QuasiStaticModel
from .trace import Trace


@dataclass
class SimResult:
    """Free-run prediction.

    Attributes
    ----------
    t : ndarray, s
    y : ndarray (N, n_outputs)   all model outputs, in model units
    u : ndarray (N, n_inputs)    the inputs actually applied (friction/feature values included)
    axes : dict axis -> {"position", "error", "velocity", "tool_position"} arrays (mm, mm/s)
    output_names : list[str]
    """

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray
    axes: dict
    output_names: list


def fits_sample_time(ts, model_Ts):
    """Whether samples ``ts`` s apart fit a model of ``model_Ts`` s: 0.1 % apart at most (a
    controller's cycle rounds differently from the model's; NaN does not fit)."""
    return abs(ts - model_Ts) <= 1e-3 * model_Ts


def check_sample_time(ts, model_Ts, what="commands", source=None):
    """InputError (column 'Ts') when commands sampled at ``ts`` s do not fit a model of
    ``model_Ts`` s (:func:`fits_sample_time`): they must be resampled first."""
    if not fits_sample_time(ts, model_Ts):
        raise InputError(f"{what} are sampled at {ts:g} s but the model at {model_Ts:g} s; "
                         f"resample the trace", source=source, column="Ts")


def run_up(cmds, Ts, max_seconds=2.0):
    """Samples of command to prepend so that a record that starts accelerating starts at rest.

    A record cut out of a motion (EMPS starts at 14 mm/s, accelerating at 840 mm/s^2) has a
    start-up transient whatever steady state it is started from. The commands' first three
    samples define a parabola u0 + k du + k^2 dd; when its vertex (the rest point) lies in the
    past within ``max_seconds``, the parabola back to the vertex is a run-up that starts at rest
    and reaches the first sample with the right position, velocity and acceleration.

    The other axes of the record continue their first step backwards, a steady ramp at their
    start velocity (constant when they start at rest), so that a two-axis record whose second
    axis is already moving steadily is not started with that axis at rest.

    Returns
    -------
    R : int, run-up length in samples (0: none needed or not plausible)
    ext : dict axis -> extended commands (run-up + commands)
    v0 : dict axis -> start velocity of the extended commands, mm/s (0 on a run-up axis)
    """
    vertex = {}                          # axis -> (du, dd, k*) of a parabola whose rest point is past
    for a, c in cmds.items():
        if len(c) < 3:
            continue
        dd = 0.5 * (c[2] - 2 * c[1] + c[0])
        du = c[1] - c[0] - dd
        if dd != 0 and du != 0 and np.sign(dd) == np.sign(du) and du / (2 * dd) * Ts <= max_seconds:
            vertex[a] = (du, dd, du / (2 * dd))    # vertex at k = -k*
    R = int(np.ceil(max(v[2] for v in vertex.values()))) if vertex else 0
    if R == 0:
        return 0, dict(cmds), {}
    k = np.arange(-R, 0, dtype=float)
    ext, v0 = {}, {}
    for a, c in cmds.items():
        if a in vertex:
            du, dd, kv = vertex[a]
            kk = np.maximum(k, -kv)              # at rest before its vertex
            ext[a] = np.concatenate([c[0] + kk * du + kk * kk * dd, c])
            v0[a] = 0.0
        else:                                    # its first step continued backwards
            step = c[1] - c[0] if len(c) > 1 else 0.0
            ext[a] = np.concatenate([c[0] + k * step, c])
            v0[a] = step / Ts
    return R, ext, v0


def simulate(model, trace_or_commands, Ts=None, start_velocity=None, params=None, externals=None,
             start="auto"):
    """Free-run simulation of a model from commanded inputs alone.

    Parameters
    ----------
    model : DriveModel or QuasiStaticModel
    trace_or_commands : Trace, or dict ``{axis: commanded position array (mm)}``
    Ts : float, optional
        Sample time of the commands (taken from the trace otherwise); must equal ``model.Ts``.
    start_velocity : dict axis -> mm/s, optional
        Initial velocity v0 of each axis (a steady ramp start; axes of the model only; ``{}``:
        at rest). Default: 0 for command dicts; for a Trace, its first step over ``model.Ts``
        (a record that starts in motion).
    start : ``"auto"`` (default) or ``"ramp"``
        ``auto``: a Trace that starts accelerating gets a run-up from rest (:func:`run_up`, its
        other axes in their steady ramp), the most consistent initial state, unless
        ``start_velocity`` is given; otherwise (and always with ``ramp``) the steady ramp.
    params : dict, optional
        Parameter overrides like the FMU's, checked as the FMU checks them:
        ``<axis>_friction_on``, ``<axis>_friction_level`` (>= 0), ``<axis>_v_tilde`` (> 0, and with
        several friction inputs at least the level times ``model.vtilde_floor_per_level``).
    externals : dict name -> array, optional
        Values of ``external`` inputs, one finite value per command sample (taken from the
        trace's channels otherwise).

    Returns
    -------
    SimResult
    """
    if start not in ("auto", "ramp"):
        raise InputError(f"start must be 'auto' or 'ramp', got {start!r}", column="start")
    cmds, exts, t, ts = _commands(model, trace_or_commands, Ts, externals)
    if isinstance(model, QuasiStaticModel):
        given = [k for k, v in (("start_velocity", start_velocity), ("params", params),
                                ("externals", externals)) if v]
        if given:
            raise InputError(f"{', '.join(given)} do not apply to a quasi-static model", column=given[0])
        if len(t) < 2:      # it differentiates the commands
            raise InputError(f"a quasi-static prediction needs at least 2 command samples, got {len(t)}",
                             column="commands")
        from .identify.quasi_static import predict_quasi_static
        return predict_quasi_static(model, cmds, t)
    check_sample_time(ts, model.Ts)
    unknown = sorted(set(start_velocity or {}) - set(cmds))
    if unknown:
        raise InputError(f"start_velocity names axes {unknown}; the model's axes are {sorted(cmds)}",
                         column="start_velocity")
    for a, v in (start_velocity or {}).items():       # 'a' escaped as float()'s ValueError
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise InputError(f"the start velocity of axis '{a}' must be a number of mm/s, got {v!r}",
                             column="start_velocity")
    compiled = kernel.CompiledModel(model)
    if start_velocity is None and isinstance(trace_or_commands, Trace):
        if start == "auto":     # a given start velocity is a steady ramp start: no run-up
            R, ext, v0 = run_up(cmds, model.Ts)
            if R:
                exts_r = {k: np.concatenate([np.full(R, v[0]), v]) for k, v in exts.items()}
                t_r = np.concatenate([t[0] - ts * np.arange(R, 0, -1), t])
                return _trim(_run(compiled, ext, exts_r, t_r, v0, params), R)
        # the record's first step, over the model's sample time (the steady ramp the run steps)
        start_velocity = {a: (c[1] - c[0]) / model.Ts for a, c in cmds.items()}
    return _run(compiled, cmds, exts, t, start_velocity or {}, params)


def rounding_sensitivity(model, trace, start="auto", noise_mm=1e-12, seed=0):
    """max |simulate(commands) - simulate(commands + noise)| over the trace and the model's axes
    (mm, position): how far the prediction moves when every command carries ``noise_mm`` of
    (seeded) Gaussian noise, the size of rounding. Friction stick/slip decisions can amplify it:
    an FMU run by a master that rounds its inputs otherwise then cannot agree with this simulator
    (``fdid validate``), and a structure whose prediction is not determined to within its own error
    is not chosen (``identify.choose_structure``)."""
    from .trace import Channel
    rng = np.random.default_rng(seed)
    chans = dict(trace.channels)
    for a in model.axes:
        name = trace.roles[a]["cmd"]
        c = trace.channels[name]
        chans[name] = Channel(c.name, c.unit, c.data + noise_mm * rng.standard_normal(c.data.size))
    pert = Trace(t=trace.t, channels=chans, roles=trace.roles, source=trace.source, meta=dict(trace.meta),
                 jitter_tol=trace.jitter_tol)
    a = simulate(model, trace, start=start)
    b = simulate(model, pert, start=start)
    return float(max(np.max(np.abs(a.axes[x]["position"] - b.axes[x]["position"])) for x in model.axes))


def _trim(res, R):
    return SimResult(t=res.t[R:], y=res.y[R:], u=res.u[R:],
                     axes={a: {k: v[R:] for k, v in d.items()} for a, d in res.axes.items()},
                     output_names=res.output_names)


def _commands(model, src, Ts, externals):
    cmds, exts, t, ts = _command_arrays(model, src, Ts, externals)
    names = {p.name for p in model.inputs if p.kind == "external"} if isinstance(model, DriveModel) else set()
    unknown = sorted(set(externals or {}) - names)
    if unknown:
        raise InputError(f"externals names {unknown}, which are not external inputs of the model "
                         f"({sorted(names)})", column="externals")
    for k, v in exts.items():
        if v.shape != t.shape or not np.isfinite(v).all():
            raise InputError(f"external input '{k}' must be {t.size} finite numbers, one per command "
                             f"sample (got shape {v.shape})", column=k)
    return cmds, exts, t, ts


def _command_arrays(model, src, Ts, externals):
    axes = model.axes
    if isinstance(src, Trace):
        cmds = {a: np.asarray(src.cmd(a), float) for a in axes}
        t, ts = src.t, src.Ts
        if Ts is not None and not (isinstance(Ts, (int, float, np.integer, np.floating))
                                   and abs(Ts - ts) <= 1e-3 * ts):     # it was ignored
            raise InputError(f"Ts {Ts!r} differs from the trace's sample time {ts:g} s (give Ts only "
                             "with command arrays)", column="Ts")
        exts = {}
        if isinstance(model, DriveModel):
            for p in model.inputs:
                if p.kind == "external":
                    if externals and p.name in externals:
                        exts[p.name] = np.asarray(externals[p.name], float)
                    else:
                        exts[p.name] = np.asarray(src.extra(p.params.get("channel", p.name)), float)
        return cmds, exts, t, ts
    if Ts is None:
        raise InputError("Ts is needed when commands are given as arrays", column="Ts")
    missing = [a for a in axes if a not in src]
    if missing:
        raise InputError(f"no command for axes {missing}", column="commands")
    cmds = {a: np.asarray(src[a], float) for a in axes}
    n = len(next(iter(cmds.values())))
    for a, c in cmds.items():
        if c.shape != (n,) or not np.isfinite(c).all():
            raise InputError(f"command of axis '{a}' must be {n} finite numbers", column=a)
    exts = {k: np.asarray(v, float) for k, v in (externals or {}).items()}
    if isinstance(model, DriveModel):
        for p in model.inputs:
            if p.kind == "external" and p.name not in exts:
                raise InputError("external input not given", column=p.name)
    return cmds, exts, np.arange(n) * Ts, Ts


def _run(compiled, cmds, exts, t, v0, params):
    """Free run of commands (dict axis -> array) through the C core; see the module docstring."""
    m = compiled.model
    lay = compiled.layout
    N = len(t)
    C = np.column_stack([cmds[a] for a in lay.axes])
    E = np.zeros((N, len(m.inputs)))
    for i, p in enumerate(m.inputs):
        if p.kind == "external":
            E[:, i] = exts[p.name]
    v0 = np.array([float(v0.get(a, 0.0)) for a in lay.axes])
    Y, U, V = kernel.run(compiled, C, E, v0, params)
    if not np.isfinite(Y).all():
        k = int(np.argmax(~np.isfinite(Y).all(axis=1)))
        raise InputError(f"the model's outputs are not finite from sample {k} (t = {t[k]:g} s) on: "
                         "check its parameters", column="model")
    axes = {}
    for k, a in enumerate(lay.axes):
        x = Y[:, lay.axis_pos[k]]
        e = Y[:, lay.axis_err[k]] if lay.axis_err[k] >= 0 else cmds[a] - x
        axes[a] = {"position": x, "error": e, "velocity": V[:, k]}
        if lay.axis_tool[k] >= 0:
            axes[a]["tool_position"] = Y[:, lay.axis_tool[k]]
    return SimResult(t=np.asarray(t), y=Y, u=U, axes=axes, output_names=[p.name for p in m.outputs])
