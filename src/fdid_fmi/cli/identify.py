"""``fdid identify``: trace -> model JSON (quasi-static, full-ls, pole-search, mimo)."""
from __future__ import annotations

import sys

from ..errors import InputError
from ..model import DriveModel
from .mapping import add_trace_arguments, trace_from_args

METHODS = ("quasi-static", "full-ls", "pole-search", "mimo")

def register(sub):
    p = sub.add_parser("identify", help="identify a drive model from a trace",
                       description="Identify a feed-drive model from a measured trace and save it as JSON.")
    p.add_argument("trace", help="trace file (.csv/.txt, .mat, SINUMERIK .xml)")
    p.add_argument("--method", choices=METHODS, default="pole-search")
    p.add_argument("-o", "--output", default="model.json", help="model JSON to write")
    p.add_argument("--axis", action="append", default=None,
                   help="axis to identify (repeatable; default: every axis with cmd and act)")
    s = p.add_argument_group("pole search")
    s.add_argument("--search", choices=("de", "multistart", "direct"), default="de",
                   help="global optimiser (thesis: GlobalSearch / MultiStart / pattern search)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--maxiter", type=int, default=None)
    s.add_argument("--v-tilde", type=float, default=None,
                   help="fix the friction transition velocity [mm/s] (default: searched)")
    s.add_argument("--v-tilde-range", default=None, metavar="LO:HI", help="search range of v_tilde [mm/s]")
    s.add_argument("--no-integral-action", action="store_true",
                   help="the position loop has no integral action (P/PD, e.g. EMPS): adds the 1/P(s) "
                        "friction term")
    s.add_argument("--no-friction", action="store_true", help="leave the friction input out")
    s.add_argument("--velocity", choices=("backward", "central"), default="backward",
                   help="measured velocity estimate driving friction")
    s.add_argument("--ma-order", type=int, default=1, help="moving-average order of that velocity")
    s.add_argument("--real-hz", action="append", default=None, metavar="LO:HI",
                   help="bounds of one real pole [Hz] (repeat per pole; sets the number of real poles)")
    s.add_argument("--omega-hz", action="append", default=None, metavar="LO:HI",
                   help="bounds of one complex pair's natural frequency [Hz] (repeat per pair)")
    s.add_argument("--zeta", action="append", default=None, metavar="LO:HI",
                   help="damping bounds of each complex pair (repeat per pair, same order)")
    m = p.add_argument_group("mimo")
    m.add_argument("--n-real", type=int, default=None, help="number of real poles searched")
    m.add_argument("--n-complex", type=int, default=None, help="number of complex pairs searched")
    m.add_argument("--outputs", default="error",
                   help="comma list of outputs per axis: error, velocity, position, tool_position, "
                        "tool_error, acceleration")
    m.add_argument("--coupled", action="store_true",
                   help="one denominator for all axes, every output from every input")
    m.add_argument("--integrators", action="append", default=[], metavar="OUTPUT=N",
                   help="integrators appended to an output (acceleration=2 predicts tool position)")
    m.add_argument("--dc-gain", action="append", default=[], metavar="OUTPUT=Q:VALUE",
                   help="d.c.-gain constraint of order Q on the command path of OUTPUT (Eqn 5.15)")
    m.add_argument("--lock-complex", action="append", default=[], metavar="HZ:ZETA",
                   help="a known complex pole pair kept out of the search")
    m.add_argument("--external", action="append", default=[], metavar="CHANNEL",
                   help="use an extra trace channel as an input (e.g. pulses_N)")
    q = p.add_argument_group("quasi-static / full-ls")
    q.add_argument("--cutoff-hz", type=float, default=None, help="Butterworth cutoff of the derivatives")
    q.add_argument("--filter-order", type=int, default=2)
    add_trace_arguments(p)
    p.set_defaults(func=run)

def _range(text, name):
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"'{text}' is not LO:HI", column=name) from None
    return lo, hi

def _kv(items, name, conv):
    out = {}
    for it in items:
        if "=" not in it:
            raise InputError(f"'{it}' is not OUTPUT=VALUE", column=name)
        k, v = it.split("=", 1)
        out[k.strip()] = conv(v.strip())
    return out

def bounds_from_args(args, Ts, n_real, n_complex):
    from ..identify.structure import Bounds, default_bounds
    b = default_bounds(Ts, n_real, n_complex)
    real = [_range(r, "--real-hz") for r in args.real_hz] if args.real_hz else b.real_hz
    omega = [_range(r, "--omega-hz") for r in args.omega_hz] if args.omega_hz else b.omega_hz
    zeta = [_range(r, "--zeta") for r in args.zeta] if args.zeta else b.zeta
    vt = _range(args.v_tilde_range, "--v-tilde-range") if args.v_tilde_range else None
    return Bounds(real, omega, zeta, vt)

def identify_from_args(trace, args, progress=True):
    """Run the identification the arguments ask for; returns the model."""
    from .. import identify as idf
    pieces = trace.select(trace.meta.get("ranges"))
    axes = args.axis or [a for a in trace.axes if trace.has(a, "cmd") and trace.has(a, "act")]
    if not axes:
        raise InputError("the trace has no axis with both 'cmd' and 'act' channels; use --map",
                         source=trace.source)
    if args.method == "quasi-static":
        return idf.identify_quasi_static(pieces, axes, cutoff_hz=args.cutoff_hz, order=args.filter_order)
    if args.method == "full-ls":
        models = [idf.identify_full_ls(pieces, ax, cutoff_hz=args.cutoff_hz, order=args.filter_order)
                  for ax in axes]
        return models[0] if len(models) == 1 else DriveModel.combine(models, method="full-ls")
    n_real = args.n_real if args.n_real is not None else (len(args.real_hz) if args.real_hz else 1)
    n_complex = args.n_complex if args.n_complex is not None else (
        len(args.omega_hz) if args.omega_hz else 1)
    bounds = bounds_from_args(args, trace.Ts, n_real, n_complex)
    common = dict(bounds=bounds, v_tilde=args.v_tilde, method=args.search, seed=args.seed,
                  maxiter=args.maxiter, progress=progress)
    if args.method == "pole-search":
        if n_real != 1 or n_complex != 1:
            raise InputError("the SISO pole search has one real pole and one complex pair; use --method mimo",
                             column="--n-real/--n-complex")
        models = [idf.identify_siso(pieces, ax, integral_action=not args.no_integral_action,
                                    velocity=args.velocity, ma_order=args.ma_order,
                                    friction=not args.no_friction, **common) for ax in axes]
        return models[0] if len(models) == 1 else DriveModel.combine(models, method="pole-search")
    outputs = tuple(o.strip() for o in args.outputs.split(",") if o.strip())
    kw = dict(outputs=outputs, n_real=n_real, n_complex=n_complex, friction=not args.no_friction,
              integral_action=not args.no_integral_action,
              integrators=_kv(args.integrators, "--integrators", int),
              dc_gain=_kv(args.dc_gain, "--dc-gain", lambda v: (int(v.split(":")[0]), float(v.split(":")[1]))),
              locked_complex=[_range(c, "--lock-complex") for c in args.lock_complex],
              velocity=args.velocity, ma_order=args.ma_order, externals=tuple(args.external))
    if args.coupled:
        st = idf.mimo_structure(tuple(axes), coupled=True, **kw)
        return idf.identify_mimo(pieces, st, **common)
    models = [idf.identify_mimo(pieces, idf.mimo_structure((ax,), **kw), **common) for ax in axes]
    return models[0] if len(models) == 1 else DriveModel.combine(models, method="mimo")

def summary(model, trace=None):
    """Lines describing a model (and its free-run discrepancy on ``trace``)."""
    from ..metrics import measured_position, prediction_table
    from ..simulate import simulate
    lines = [f"method: {model.method}"]
    if isinstance(model, DriveModel):
        ident = model.identification
        blocks = ident.get("blocks", [ident])
        for b in blocks:
            if "real_hz" in b:
                cp = ", ".join(f"{w:.3f} Hz / zeta {z:.4f}" for w, z in b["complex_hz_zeta"])
                rp = ", ".join(f"{p:.3f} Hz" for p in b["real_hz"])
                lines.append(f"poles: real [{rp}]  complex [{cp}]  v_tilde {b['v_tilde_mm_s']} mm/s")
            elif "pole_constraints" in b:
                pc = b["pole_constraints"]
                lines.append(f"poles: p {pc['p_hz']:.3f} Hz, wn {pc['wn_hz']:.3f} Hz, zeta {pc['zeta']:.3f}"
                             f" (Eqn 4.9 {'satisfied' if pc['satisfied'] else 'violated'}"
                             f"{', constrained LS' if b.get('constrained') else ''})")
        lines.append(f"states: {model.n_states}, inputs: {[p.name for p in model.inputs]}, "
                     f"outputs: {[p.name for p in model.outputs]}")
    else:
        for ax, g in model.gains.items():
            lines.append(f"{ax}: K_vel {g['K_vel']:.6g} s, K_acc {g['K_acc']:.6g} s^2, K_jerk {g['K_jerk']:.6g} s^3")
    if trace is not None:
        sim = simulate(model, trace)
        lines.append(f"free run on {trace.source}:")
        lines.append(f"  {'axis':<5} {'e RMS um':>10} {'e MAX um':>10} {'pred-err RMS um':>16} "
                     f"{'pred-err MAX um':>16} {'% of RMS':>9}")
        for ax in model.axes:
            side = model.position_side(ax) if isinstance(model, DriveModel) else "motor"
            e = trace.cmd(ax) - measured_position(trace, ax, side)
            tb = prediction_table(e, sim.axes[ax]["error"])
            lines.append(f"  {ax + (' (tool)' if side == 'tool' else ''):<5} {tb['actual']['rms_um']:10.3f} {tb['actual']['max_um']:10.3f} "
                         f"{tb['discrepancy']['rms_um']:16.3f} {tb['discrepancy']['max_um']:16.3f} "
                         f"{tb['discrepancy_pct_of_rms']:9.3f}")
    return lines

def run(args):
    trace = trace_from_args(args.trace, args)
    model = identify_from_args(trace, args, progress=sys.stderr.isatty())
    model.save(args.output)
    for line in summary(model, trace):
        print(line)
    print(f"model written to {args.output}")
    return 0

__all__ = ["register", "identify_from_args", "summary"]
