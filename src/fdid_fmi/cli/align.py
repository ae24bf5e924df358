"""``fdid align CONTROLLER --acc FILE [...] --kgm FILE [...] -o aligned.csv``: tool-side sensors
recorded by separate systems brought onto the controller trace (thesis ch. 7.2.1).

Each ``--acc`` / ``--kgm`` takes the sensor file and optional ``KEY=VALUE`` settings:

=========  ==========================================================================
key        meaning
=========  ==========================================================================
cols       the sensor's x,y(,z) columns (names or 1-based numbers), e.g. cols=ax,ay,az
t          its time column (default: found by name)
unit       unit of its columns when the names do not say it (g, m_s2, um, mm, ...)
axes       machine axes it provides, e.g. axes=x,y (default x,y)
name       sensor name (default: file stem)
sign       -1 for a sensor subtracted (table accelerometer in head - table); acc only
=========  ==========================================================================
"""
from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError, one_line
from ..pipeline.argtypes import finite_float
from ..pipeline.traces import add_trace_arguments, trace_from_args

SENSOR_KEYS = {"cols", "t", "unit", "axes", "name", "sign"}


def register(sub):
    p = sub.add_parser(
        "align", help="align accelerometer / grid-encoder files onto the controller trace",
        description="Bring separately recorded tool-side sensors (3-axis accelerometers, a 2-D grid "
                    "encoder) onto the controller trace's time base and axes: time offset and clock "
                    "drift, accelerometer orientation (Eqn 7.1), gravity and bias, grid-plate angle "
                    "and origin, anti-alias resampling to Ts. Writes one trace with <axis>_tool_mm "
                    "and <axis>_acc_mm_s2 for fdid identify / diagnose, and every channel of the "
                    "controller's trace, those without a role (currents, loads, status words) too.")
    p.add_argument("controller", help="the controller's trace (commanded and encoder positions)")
    p.add_argument("--acc", nargs="+", action="append", default=[], metavar="FILE_OR_KEY=VALUE",
                   help="accelerometer file and settings, e.g. --acc head.csv axes=x unit=g "
                        "(repeat for more sensors)")
    p.add_argument("--kgm", nargs="+", action="append", default=[], metavar="FILE_OR_KEY=VALUE",
                   help="grid-encoder file and settings, e.g. --kgm kgm.csv cols=X,Y unit=um")
    p.add_argument("-o", "--output", required=True, help="aligned trace CSV to write")
    p.add_argument("--json", default=None, metavar="OUT.json",
                   help="write every step's estimate and uncertainty as JSON (reusable by --orientation; default: "
                        "not written)")
    p.add_argument("--orientation", default=None, metavar="CALIB.json",
                   help="accelerometer orientations from a calibration run's --json (two axes moving; default: "
                        "estimated from this run)")
    p.add_argument("--lowpass", type=finite_float("--lowpass", positive=True), default=10.0, metavar="HZ",
                   help="low-pass of the estimation signals, below the first tool-side mode (default 10)")
    p.add_argument("--window", type=finite_float("--window", positive=True), default=1.0, metavar="S",
                   help="window of the lag estimates for the clock drift (default 1 s)")
    p.add_argument("--max-offset", type=finite_float("--max-offset", positive=True), default=None, metavar="S",
                   help="largest time offset searched (default: any)")
    add_trace_arguments(p)
    p.set_defaults(func=run)


def parse_sensor(tokens, kind):
    """``[FILE, KEY=VALUE, ...]`` -> keyword arguments of ``read_sensor``."""
    opt = f"--{'acc' if kind == 'accelerometer' else 'kgm'}"
    tokens = [str(x) for x in tokens]

    def is_setting(tok):
        # KEY=VALUE, unless it names an existing file whose '=' is not a known setting's (a
        # folder like date=2026-11-23/ holding the sensor file)
        return "=" in tok and (tok.split("=", 1)[0].strip() in SENSOR_KEYS or not Path(tok).is_file())

    files = [x for x in tokens if not is_setting(x)]
    if len(files) != 1:
        raise InputError(f"give exactly one file per {opt} (then KEY=VALUE settings), got {files or 'none'}",
                         source=opt)
    kw = {"path": files[0], "kind": kind}
    seen = {}
    for tok in tokens:
        if not is_setting(tok):
            continue
        k, v = (s.strip() for s in tok.split("=", 1))
        if k not in SENSOR_KEYS:
            raise InputError(f"unknown setting '{k}'; expected one of {sorted(SENSOR_KEYS)}", source=opt,
                             column=k)
        if k in seen:                    # the later one would win without a word
            raise InputError(f"setting '{k}' given twice ('{seen[k]}' and '{tok}')", source=opt, column=k)
        seen[k] = tok
        if not v:
            raise InputError(f"'{tok}' has no value", source=opt, column=k)
        if not v.isprintable():          # a line break in a name split the table and the messages
            raise InputError(f"'{one_line(tok)}' holds a control character (line break, tab, ...); "
                             f"give {k} in plain characters", source=opt, column=k)
        if k == "cols":
            kw["columns"] = [c.strip() for c in v.split(",") if c.strip()]
        elif k == "axes":
            kw["axes"] = tuple(a.strip() for a in v.split(",") if a.strip())
        elif k == "t":
            kw["time"] = v
        elif k == "sign":
            if v not in ("1", "+1", "-1"):
                raise InputError(f"sign must be +1 or -1, got '{v}'", source=opt, column="sign")
            if kind != "accelerometer":
                raise InputError("sign applies to accelerometers only", source=opt, column="sign")
            kw["sign"] = float(v)
        else:
            kw[k] = v
    if "name" not in kw and not Path(files[0]).stem.isprintable():    # the default name: the file's stem
        raise InputError(f"the sensor name would be the file name '{one_line(Path(files[0]).stem)}', which "
                         f"holds a control character; give name=... in plain characters", source=opt,
                         column="name")
    return kw


def load_orientation(path):
    """Accelerometer rotations from an ``fdid align --json`` file: ``{name: {"rotation", "estimates"}}``."""
    from ..io.common import read_text_file
    src = str(path)
    try:
        d = json.loads(read_text_file(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg}, line {exc.lineno})", source=src) from None
    if not isinstance(d, dict) or d.get("format") != "fdid-fmi alignment":
        raise InputError("is not an alignment file written by fdid align --json", source=src)
    out = {}
    sensors = d.get("sensors", [])
    if not isinstance(sensors, list) or not all(isinstance(s, dict) and isinstance(s.get("name"), str)
                                                and isinstance(s.get("estimates", []), list)
                                                for s in sensors):
        raise InputError("'sensors' must be a list of sensor entries with a name", source=src,
                         column="sensors")
    for s in sensors:
        if s.get("kind") == "accelerometer" and s.get("rotation") is not None:
            out[s["name"]] = {"rotation": s["rotation"], "estimates": s.get("estimates", [])}
    if not out:
        raise InputError("holds no accelerometer orientation (its run moved fewer than two axes)",
                         source=src)
    return out


def run(args):
    from ..align import align, read_sensor
    from ..align.writer import write_trace_csv
    from ..outputs import atomic_write, check_output, same_file
    specs = [parse_sensor(t, "accelerometer") for t in args.acc] + \
            [parse_sensor(t, "grid_encoder") for t in args.kgm]
    if not specs:
        raise InputError("give at least one sensor: --acc FILE or --kgm FILE")   # (prog says fdid align)
    if args.orientation and not args.acc:      # it would be read and not used
        raise InputError("--orientation holds accelerometer orientations; it applies with --acc",
                         source="--orientation")
    inputs = [args.controller] + [s["path"] for s in specs] + ([args.orientation] if args.orientation else [])
    check_output(args.output, inputs=inputs, what="aligned trace")
    if args.json:
        if same_file(args.json, args.output):      # not "would overwrite the input file" (it is no input)
            raise InputError("the JSON file and the aligned trace (-o) are the same file; give two names",
                             source=args.json, column="--json")
        check_output(args.json, inputs=inputs, what="JSON file")
    if getattr(args, "range", None):
        raise InputError("--range does not apply to fdid align (the whole record is aligned); give it "
                         "to fdid identify / diagnose on the aligned trace", source="--range")
    ctrl = trace_from_args(args.controller, args)
    records = [read_sensor(**s) for s in specs]
    orient = load_orientation(args.orientation) if args.orientation else None
    res = align(ctrl, records, orientation=orient, lowpass_hz=args.lowpass, window_s=args.window,
                max_offset_s=args.max_offset)
    print(res.table())
    notes = []
    write_trace_csv(res.trace, args.output, notes=notes)
    if args.json:
        atomic_write(args.json, res.to_json())
    tr = res.trace
    added = ", ".join(f"{a}.{r}" for a in tr.axes for r in ("tool", "acc") if tr.has(a, r))
    print(f"aligned trace: {tr.n} samples, {tr.t[0]:.4f} to {tr.t[-1]:.4f} s at Ts {tr.Ts:g} s, "
          f"{added} -> {args.output}" + (f"; estimates -> {args.json}" if args.json else ""))
    kept = tr.extra_channels
    if kept:       # the controller's channels without a role, on the same rows
        print(f"kept {len(kept)} controller channel(s) without a role: {', '.join(kept)}")
    for n in notes:
        print(n)
    for m in res.missing:
        print(f"missing: {m}")
    return 0


__all__ = ["register", "run", "parse_sensor", "load_orientation"]

