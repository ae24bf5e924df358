"""Identification with the options of ``fdid identify``: their definition (one parser, read by the
command line, the fleet's manifests and :func:`fdid_fmi.api.identify`), their checks, the checks
of the data and the identification they ask for (quasi-static, full-ls, pole-search, mimo)."""
from __future__ import annotations

import argparse
import math

import numpy as np

from ..errors import InputError
from ..model import DriveModel, check_name
from .argtypes import finite_float, int_in
from .traces import add_trace_arguments

METHODS = ("quasi-static", "full-ls", "pole-search", "mimo")
OUTPUT_KINDS = ("error", "velocity", "position", "tool_position", "tool_error", "acceleration")
MAX_REAL, MAX_COMPLEX, MAX_ORDER = 6, 6, 12     # poles searched per block (bounded work)
MAX_INTEGRATORS = 3
MAX_DC_ORDER = 3
_SEARCHED = ("pole-search", "mimo")
# which methods read each option: one given to another method would be silently ignored
READ_BY = {"structure": ("pole-search",), "jobs": ("pole-search",),
           **{k: _SEARCHED for k in ("search", "seed", "maxiter", "v_tilde", "v_tilde_range",
                                     "no_integral_action", "no_friction", "velocity", "ma_order",
                                     "same_sample", "real_hz", "omega_hz", "zeta", "n_real", "n_complex")},
           **{k: ("mimo",) for k in ("outputs", "coupled", "integrators", "dc_gain", "lock_complex",
                                     "external", "play_width")},
           **{k: ("quasi-static", "full-ls") for k in ("cutoff_hz", "filter_order")}}


def add_identify_parser(sub):
    """The ``identify`` parser of the command line (its help included), added to ``sub``; the fleet
    checks its manifests' options with it too. Returns the parser (``option_defaults`` set: the
    default of every option :data:`READ_BY` names)."""
    p = sub.add_parser("identify", help="identify a drive model from a trace",
                       description="Identify a feed-drive model from a measured trace and save it as JSON.")
    p.add_argument("trace", help="trace file (.csv/.txt, .mat, SINUMERIK .xml)")
    p.add_argument("--method", choices=METHODS, default="pole-search")
    p.add_argument("-o", "--output", default="model.json",
                   help="model JSON to write (default: model.json; an existing file is replaced)")
    p.add_argument("--axis", action="append", default=None,
                   help="axis to identify (repeatable; default: every axis with cmd and act)")
    s = p.add_argument_group("pole search")
    s.add_argument("--structure", choices=("auto", "rigid"), default=None,
                   help="auto: choose the structure of each axis from the data (rigid body, 2 real poles, "
                        "2 complex pairs, both; with and without integral action; by training free run "
                        "with a 5%% parsimony rule); rigid: the thesis's SISO model. Default: auto, unless "
                        "--n-real/--n-complex/--real-hz/--omega-hz/--zeta/--no-integral-action/"
                        "--no-friction/--v-tilde-range pin the structure")
    s.add_argument("--jobs", type=int_in(1, 1024, "--jobs"), default=None,
                   help="processes fitting the candidate structures of --structure auto (default: one per core)")
    s.add_argument("--search", choices=("vp", "de", "multistart", "direct"), default=None,
                   help="optimiser of the poles: vp (variable projection: Sobol screen and Gauss-Newton "
                        "searches from neighbouring structures' poles; default of --structure auto) or a "
                        "global one (thesis: GlobalSearch / MultiStart / pattern search; de is the default "
                        "of a pinned structure and the thorough choice for --structure auto)")
    s.add_argument("--seed", type=int_in(0, 2 ** 32 - 1, "the seed"), default=0,
                   help="random seed of the search, 0 .. 2**32-1 (default 0)")
    s.add_argument("--maxiter", type=int_in(1, 100000, "--maxiter"), default=None,
                   help="de: generations (default 40 + 10 x dimension); multistart: iterations of each "
                        "local search (default 200); direct: evaluations (default 1500); vp: "
                        "steps of each local search (default 20)")
    s.add_argument("--v-tilde", type=finite_float("--v-tilde", positive=True), default=None,
                   help="fix the friction transition velocity [mm/s] (default: searched)")
    s.add_argument("--v-tilde-range", default=None, metavar="LO:HI", help="search range of v_tilde [mm/s] (default: 1e-4 to 0.3 x the axis's largest speed)")
    s.add_argument("--no-integral-action", action="store_true",
                   help="the position loop has no integral action (P/PD, e.g. EMPS): adds the 1/P(s) "
                        "friction term")
    s.add_argument("--no-friction", action="store_true", help="leave the friction input out")
    s.add_argument("--velocity", choices=("backward", "central"), default="backward",
                   help="measured velocity estimate driving friction")
    s.add_argument("--ma-order", type=int_in(1, 1000, "--ma-order"), default=1, help="moving-average order of that velocity")
    s.add_argument("--same-sample", choices=("hold", "cubic", "quadratic"), default=None,
                   help="how the command of the predicted sample is taken from the samples before "
                        "(hold: a loop without look-ahead; cubic: feed-forward with one sample of "
                        "look-ahead, exact for constant jerk; quadratic: the same, exact for constant "
                        "acceleration); default: identify with all three, keep the lowest training "
                        "free-run error")
    s.add_argument("--real-hz", action="append", default=None, metavar="LO:HI",
                   help="bounds of one real pole [Hz] (repeat per pole; sets the number of real poles; default: 0.1 Hz to 0.95 x Nyquist)")
    s.add_argument("--omega-hz", action="append", default=None, metavar="LO:HI",
                   help="bounds of one complex pair's natural frequency [Hz] (repeat per pair; default: 0.5 Hz to 0.95 x Nyquist)")
    s.add_argument("--zeta", action="append", default=None, metavar="LO:HI",
                   help="damping bounds of each complex pair (repeat per pair, same order; default: 0.05:2)")
    m = p.add_argument_group("mimo")
    m.add_argument("--n-real", type=int_in(0, MAX_REAL, "--n-real"), default=None,
                   help=f"number of real poles searched (0 .. {MAX_REAL}; default: 1, or one per --real-hz)")
    m.add_argument("--n-complex", type=int_in(0, MAX_COMPLEX, "--n-complex"), default=None,
                   help=f"number of complex pairs searched (0 .. {MAX_COMPLEX}; default: 1, or one per --omega-hz)")
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
    m.add_argument("--play-width", type=finite_float("--play-width", positive=True), default=None,
                   metavar="MM", help="friction law: the play (presliding) of this half-width [mm] in place "
                                      "of sat(v/v_tilde) (default: sat; the structure choice tries 0.001 to 0.016 mm)"),
    q = p.add_argument_group("quasi-static / full-ls")
    q.add_argument("--cutoff-hz", type=finite_float("--cutoff-hz", positive=True), default=None,
                   help="Butterworth cutoff of the derivatives (default: min(50 Hz, 0.2 x Nyquist))")
    q.add_argument("--filter-order", type=int_in(1, 8, "--filter-order"), default=2)
    add_trace_arguments(p)
    p.set_defaults(option_defaults={k: p.get_default(k) for k in READ_BY})
    return p

def _pair(text, name):
    """HZ:ZETA of a locked complex pair: two finite positive numbers."""
    try:
        hz, zeta = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"'{text}' is not HZ:ZETA (two numbers)", source=name) from None
    if not (math.isfinite(hz) and math.isfinite(zeta) and hz > 0 and zeta > 0):
        raise InputError(f"'{text}': expected HZ > 0 and ZETA > 0", source=name)
    return hz, zeta

def _range(text, name):
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"'{text}' is not LO:HI (two numbers)", source=name) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise InputError(f"'{text}': expected finite LO < HI", source=name)
    return lo, hi

def _kv(items, name, conv, outputs, example):
    """Parse OUTPUT=VALUE options; OUTPUT must be one of the identified ``outputs``."""
    out = {}
    for it in items:
        if "=" not in it:
            raise InputError(f"'{it}' is not OUTPUT=VALUE (e.g. {example})", source=name)
        k, v = (x.strip() for x in it.split("=", 1))
        if k not in outputs:
            raise InputError(f"'{it}' names the output '{k}', which is not identified; the outputs "
                             f"are {list(outputs)} (--outputs)", source=name)
        if k in out:
            raise InputError(f"output '{k}' is given twice", source=name)
        out[k] = conv(v, it)
    return out

def _integrators(v, it):
    try:
        q = int(v)
    except ValueError:
        raise InputError(f"'{it}': the number of integrators must be an integer", source="--integrators") from None
    if not 0 <= q <= MAX_INTEGRATORS:
        raise InputError(f"'{it}': the number of integrators must be in 0 .. {MAX_INTEGRATORS}",
                         source="--integrators")
    return q

def _dc_gain(v, it):
    try:
        q, val = v.split(":")
        q, val = int(q), float(val)
    except ValueError:
        raise InputError(f"'{it}' is not OUTPUT=Q:VALUE (e.g. position=1:1.0)", source="--dc-gain") from None
    if not 0 <= q <= MAX_DC_ORDER or not math.isfinite(val):
        raise InputError(f"'{it}': Q must be in 0 .. {MAX_DC_ORDER} and VALUE finite", source="--dc-gain")
    return q, val

def check_arguments(args):
    """Check the identification options before the trace is read (one line on a bad value)."""
    structure_is_auto(args)     # --structure auto against a pinning flag
    n_real, n_complex = _orders(args)
    if n_real + 2 * n_complex > MAX_ORDER:
        raise InputError(f"{n_real} real poles and {n_complex} complex pairs make order "
                         f"{n_real + 2 * n_complex}; at most {MAX_ORDER} per block", source="--n-real/--n-complex")
    if n_real + n_complex == 0:
        raise InputError("the search needs at least one pole", source="--n-real/--n-complex")
    outputs = tuple(o.strip() for o in args.outputs.split(",") if o.strip())
    for o in outputs:
        if o not in OUTPUT_KINDS:
            raise InputError(f"unknown output '{o}'; expected some of {', '.join(OUTPUT_KINDS)}",
                             source="--outputs")
    if not outputs or len(set(outputs)) != len(outputs):
        raise InputError(f"'{args.outputs}': give each output once", source="--outputs")
    _kv(args.integrators, "--integrators", _integrators, outputs, "acceleration=2")
    _kv(args.dc_gain, "--dc-gain", _dc_gain, outputs, "position=1:1.0")
    for c in args.lock_complex:
        _pair(c, "--lock-complex")
    for ch in args.external:
        check_name(ch, "--external channel")
    for a in args.axis or []:
        check_name(a, "--axis")
    if args.axis and len(set(args.axis)) != len(args.axis):    # refused before it is identified twice
        raise InputError(f"{args.axis}: give each axis once", source="--axis")
    for opt in ("real_hz", "omega_hz", "zeta"):
        for r in getattr(args, opt) or []:
            _range(r, "--" + opt.replace("_", "-"))
    if args.v_tilde_range:
        _range(args.v_tilde_range, "--v-tilde-range")
    _refuse_unread(args)


def _refuse_unread(args):
    """An option the chosen method does not read is an error, not silently ignored."""
    for dest, methods in READ_BY.items():
        if args.method not in methods and getattr(args, dest) != args.option_defaults[dest]:
            flag = "--" + dest.replace("_", "-")
            raise InputError(f"{flag} is read by --method {' / '.join(methods)} only, not by "
                             f"--method {args.method}", source=flag)
    # v_tilde options: without friction (or with v_tilde fixed) they would be silently ignored
    # (--velocity / --ma-order stay: the diagnosis's velocity features read them from the record)
    if args.v_tilde is not None and args.v_tilde_range:
        raise InputError("--v-tilde fixes v_tilde; --v-tilde-range is the range it is searched in: "
                         "give one of them", source="--v-tilde-range")
    if args.play_width is not None and args.play_width > MAX_PLAY_MM:
        raise InputError(f"{args.play_width:g} mm: a half-width of presliding above {MAX_PLAY_MM:g} mm is "
                         "not friction; expected a few micrometres, e.g. 0.004", source="--play-width")
    if args.no_friction and args.play_width is not None:
        raise InputError("--play-width sets the friction law, which --no-friction leaves out",
                         source="--play-width")
    if args.no_friction or args.play_width is not None:
        why = "--no-friction leaves out" if args.no_friction else "--play-width replaces by the play"
        for dest in ("v_tilde", "v_tilde_range"):
            if getattr(args, dest) != args.option_defaults[dest]:
                flag = "--" + dest.replace("_", "-")
                raise InputError(f"{flag} sets the friction input sat(v/v_tilde), which {why}",
                                 source=flag)
    if args.jobs is not None and not structure_is_auto(args):
        raise InputError("--jobs sets the processes fitting the candidates of --structure auto; "
                         "here the structure is pinned", source="--jobs")

MAX_POSITION_MM = 1e9          # 1000 km: anything larger is a unit/scale error
MAX_PLAY_MM = 1.0              # a presliding travel of millimetres is no friction (a unit error)
MIN_SPAN_MM = 1e-9             # a commanded motion smaller than this is no excitation


def check_data_range(trace, axes=None):
    """Refuse position data whose scale no identification can use (one line naming the column).

    Positions (roles cmd/act/tool) must stay within +-MAX_POSITION_MM, and every commanded
    position must move by more than MIN_SPAN_MM; otherwise every candidate model's prediction
    error over/underflows and the search has nothing to minimise."""
    import numpy as np
    for ax in axes or trace.axes:
        for role in ("cmd", "act", "tool"):
            if not trace.has(ax, role):
                continue
            name = trace.roles[ax][role]
            x = np.asarray(trace.channels[name].data, float)
            big = float(np.max(np.abs(x)))
            if big > MAX_POSITION_MM:
                raise InputError(f"positions reach {big:.3g} mm (more than {MAX_POSITION_MM:g} mm); "
                                 f"check the unit and scale of this column (--unit)",
                                 source=trace.source, column=name)
            if role == "cmd":
                span = float(np.max(x) - np.min(x))
                if not span > MIN_SPAN_MM:
                    raise InputError(f"the commanded position moves by only {span:.3g} mm; there is no "
                                     f"motion to identify from (check the unit and scale)",
                                     source=trace.source, column=name)


def _orders(args):
    n_real = args.n_real if args.n_real is not None else (len(args.real_hz) if args.real_hz else 1)
    n_complex = args.n_complex if args.n_complex is not None else (
        len(args.omega_hz) if args.omega_hz else 1)
    return n_real, n_complex

def bounds_from_args(args, Ts, n_real, n_complex):
    from ..identify.structure import Bounds, default_bounds
    b = default_bounds(Ts, n_real, n_complex)
    real = [_range(r, "--real-hz") for r in args.real_hz] if args.real_hz else b.real_hz
    omega = [_range(r, "--omega-hz") for r in args.omega_hz] if args.omega_hz else b.omega_hz
    zeta = [_range(r, "--zeta") for r in args.zeta] if args.zeta else b.zeta
    vt = _range(args.v_tilde_range, "--v-tilde-range") if args.v_tilde_range else None
    return Bounds(real, omega, zeta, vt)

PINNING = ("n_real", "n_complex", "real_hz", "omega_hz", "zeta", "v_tilde_range", "play_width")


def structure_is_auto(args):
    """True when the pole search chooses the structure (no flag pins it)."""
    if args.method != "pole-search" or args.structure == "rigid":
        return False
    pinned = [k for k in PINNING if getattr(args, k, None)] + \
        [k for k in ("no_integral_action", "no_friction") if getattr(args, k, False)]
    if pinned and args.structure == "auto":
        raise InputError(f"--structure auto chooses the structure; it cannot be combined with "
                         f"{', '.join('--' + k.replace('_', '-') for k in pinned)}", source="--structure")
    return not pinned


def check_v_tilde(v_tilde, pieces, axes, ma_order=1, velocity="backward", option="--v-tilde"):
    """Refuse a fixed v_tilde (or the upper end of its search range) at or above an axis's
    largest speed, the velocity the friction regressor sat(v/v_tilde) of thesis Eqn 4.10 is built
    from: it would never saturate on these data (the default search range is 1e-4 to 0.3 x that
    speed)."""
    from ..identify.lsfit import position_and_velocity
    for ax in axes:
        vmax = max(float(np.max(np.abs(position_and_velocity(p, ax, ma_order, velocity)[1]))) for p in pieces)
        if v_tilde >= vmax:
            raise InputError(f"{option} {v_tilde:g} mm/s is not below the largest speed of axis '{ax}' in "
                             f"the data ({vmax:.3g} mm/s): sat(v/v_tilde) would never saturate; give a "
                             f"smaller value or leave it out to search it", source=option)


def identified_axes(trace, axis=None):
    """The axes ``fdid identify`` identifies: ``axis`` (the ``--axis`` list) when given, else every
    axis of ``trace`` with both a commanded and a measured position."""
    return axis or [a for a in trace.axes if trace.has(a, "cmd") and trace.has(a, "act")]


def unidentified_notes(trace, axis=None):
    """What the trace lacks, said before the identification: an axis with a command but no
    measurement (or the reverse) is not identified. Empty when ``axis`` names the axes, or when no
    axis can be identified (an error says so then)."""
    if axis or not identified_axes(trace):
        return []
    notes = []
    for a in trace.axes:
        if a not in identified_axes(trace) and trace.has(a, "cmd") != trace.has(a, "act"):
            lacking = "act" if trace.has(a, "cmd") else "cmd"
            kind = {"act": "measured", "cmd": "commanded"}[lacking]
            notes.append(f"axis {a} has no {kind} position in {trace.source} and is not identified "
                         f"(map its column with --map {a}.{lacking}=COLUMN)")
    return notes


def identify_from_args(trace, args, progress=True):
    """Run the identification the arguments ask for; returns the model (what the trace lacks:
    :func:`unidentified_notes`)."""
    from ..identify import (identify_auto, identify_full_ls, identify_mimo, identify_quasi_static,
                            identify_siso, mimo_structure)
    pieces = trace.select(trace.meta.get("ranges"))
    axes = identified_axes(trace, args.axis)
    if not axes and trace.meta.get("layout") == "sinumerik-sat":    # --map does not apply to it
        raise InputError("this SINUMERIK trace is a speed-loop frequency-response measurement (channels "
                         f"{sorted(trace.channels)}), with no commanded or actual positions to identify a "
                         "drive from: read it with fdid_fmi.io.speed_loop_frf, and record positions with "
                         "the servo trace for fdid identify", source=trace.source)
    if not axes:
        raise InputError("the trace has no axis with both 'cmd' and 'act' channels; use --map",
                         source=trace.source)
    from ..identify.ranges import check_externals
    check_externals(trace, axes, getattr(args, "external", None) or (), what="--external")
    if getattr(args, "v_tilde", None) is not None:
        check_v_tilde(args.v_tilde, pieces, axes, args.ma_order, args.velocity, "--v-tilde")
    elif getattr(args, "v_tilde_range", None):
        high = _range(args.v_tilde_range, "--v-tilde-range")[1]
        check_v_tilde(high, pieces, axes, args.ma_order, args.velocity, "--v-tilde-range (upper end)")
    if args.method == "quasi-static":
        return identify_quasi_static(pieces, axes, cutoff_hz=args.cutoff_hz, order=args.filter_order)
    if args.method == "full-ls":
        models = [identify_full_ls(pieces, ax, cutoff_hz=args.cutoff_hz, order=args.filter_order)
                  for ax in axes]
        return models[0] if len(models) == 1 else DriveModel.combine(models, method="full-ls")
    if structure_is_auto(args):
        models = [identify_auto(pieces, ax, same_sample=args.same_sample, v_tilde=args.v_tilde,
                                    method=args.search or "vp", seed=args.seed, maxiter=args.maxiter,
                                    velocity=args.velocity, ma_order=args.ma_order,
                                    workers=args.jobs) for ax in axes]
        return models[0] if len(models) == 1 else DriveModel.combine(models, method="pole-search")
    n_real, n_complex = _orders(args)
    bounds = bounds_from_args(args, trace.Ts, n_real, n_complex)
    common = dict(bounds=bounds, v_tilde=args.v_tilde, method=args.search or "de", seed=args.seed,
                  maxiter=args.maxiter, progress=progress)
    if args.method == "pole-search":
        if n_real != 1 or n_complex != 1:
            raise InputError("the SISO pole search has one real pole and one complex pair; use --method mimo",
                             source="--n-real/--n-complex")
        models = [identify_siso(pieces, ax, integral_action=not args.no_integral_action,
                                    velocity=args.velocity, ma_order=args.ma_order,
                                    friction=not args.no_friction, same_sample=args.same_sample,
                                    **common) for ax in axes]
        return models[0] if len(models) == 1 else DriveModel.combine(models, method="pole-search")
    outputs = tuple(o.strip() for o in args.outputs.split(",") if o.strip())
    kw = dict(outputs=outputs, n_real=n_real, n_complex=n_complex,
              friction=not args.no_friction and args.play_width is None, play_mm=args.play_width,
              integral_action=not args.no_integral_action,
              integrators=_kv(args.integrators, "--integrators", _integrators, outputs, "acceleration=2"),
              dc_gain=_kv(args.dc_gain, "--dc-gain", _dc_gain, outputs, "position=1:1.0"),
              locked_complex=[_pair(c, "--lock-complex") for c in args.lock_complex],
              velocity=args.velocity, ma_order=args.ma_order, externals=tuple(args.external),
              same_sample=args.same_sample)
    if args.coupled:
        st = mimo_structure(tuple(axes), coupled=True, **kw)
        return identify_mimo(pieces, st, **common)
    models = [identify_mimo(pieces, mimo_structure((ax,), **kw), **common) for ax in axes]
    return models[0] if len(models) == 1 else DriveModel.combine(models, method="mimo")


class _Parser(argparse.ArgumentParser):
    """argparse raising InputError (no usage, no exit), without abbreviations of an option."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise InputError(message)

    def exit(self, status=0, message=None):
        raise InputError((message or "bad options").strip())


def _parser():
    """The root parser and its ``identify`` parser."""
    root = _Parser(prog="fdid", add_help=False)
    return root, add_identify_parser(root.add_subparsers(dest="command"))


# the options that are not the identification's: reading the trace, the output file
NOT_IDENTIFY = ("trace", "output", "axis", "method", "map", "unit", "range", "layout", "axes",
                "help", "option_defaults")


def identify_options():
    """The identification options as Python keywords (``v_tilde`` for ``--v-tilde``) -> whether
    each may be given several times (a list)."""
    return {a.dest: isinstance(a, (argparse._AppendAction, argparse._ExtendAction))
            for a in _parser()[1]._actions if a.dest not in NOT_IDENTIFY}


def identify_namespace(method="pole-search", axes=None, options=None):
    """The namespace ``fdid identify TRACE --method METHOD --axis A ... <options>`` parses to, with
    its checks (:func:`check_arguments`) made. ``options``: keyword -> value (``True`` for a flag,
    a list for a repeatable option, None for the default).

    Raises
    ------
    InputError  an unknown option, a bad value or a combination ``fdid identify`` refuses
    """
    known = identify_options()
    tokens = ["identify", "<trace>", f"--method={method}"]
    if isinstance(axes, str):
        axes = [axes]
    for a in axes or ():
        tokens.append(f"--axis={a}")
    for key, value in (options or {}).items():
        if key not in known:
            raise InputError(f"unknown identification option '{key}'; the options are "
                             f"{', '.join(sorted(known))}", column=key)
        flag = "--" + key.replace("_", "-")
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        if len(values) > 1 and not known[key]:
            raise InputError(f"option '{key}' takes one value, got {value!r}", column=key)
        for v in values:
            if v is None or v is False:
                continue
            tokens.append(flag if v is True else f"{flag}={v}")   # = : a value may start with '-'
    args = _parser()[0].parse_args(tokens)
    check_arguments(args)
    return args


def nondefault_options(args):
    """The identification options of a parsed namespace that differ from their defaults, as the
    keywords of :func:`fdid_fmi.api.identify` (which parses them again: one path for the command,
    the fleet and Python callers)."""
    defaults = _parser()[1].parse_args(["<trace>"])
    return {k: getattr(args, k) for k in identify_options() if getattr(args, k) != getattr(defaults, k)}
