"""The public Python API: trace -> model -> FMU, validation, diagnosis and planning.

The commands ``fdid identify``, ``simulate``, ``export``, ``validate``, ``diagnose`` and
``plan``, the fleet and the demo run through these functions; what the commands add is argument
parsing and printing. Positions are in mm, velocities in mm/s, times in s; the fits' errors are
reported in µm. (The examples read the traces bundled in the project's ``examples/`` folder.)

>>> import fdid_fmi as fd
>>> trace = fd.read_trace("examples/virtual_xy_moves.csv")
>>> model = fd.identify(trace, method="full-ls")
>>> sim = fd.simulate(model, fd.read_trace("examples/virtual_circle.csv"))
>>> sorted(sim.axes)
['x', 'y']

Bad input (a file, a column, an option value) raises :class:`~fdid_fmi.errors.InputError`, one
line naming the file, column or option.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError
from .model import DriveModel, load_model
from .simulate import simulate
from .trace import Trace

__all__ = ["read_trace", "identify", "load_model", "export_fmu", "ExportResult", "validate",
           "diagnose", "plan", "PlanResult", "simulate"]


# ----------------------------------------------------------------------------- traces
def read_trace(path, *, mapping=None, units=None, ranges=None, layout="auto", axes=None) -> Trace:
    """Read a measured servo trace (CSV/text, MATLAB ``.mat``, SINUMERIK ``.xml``).

    Parameters
    ----------
    path : str or Path
        The trace file; the reader follows its extension.
    mapping : dict, optional
        Which column is what: ``{"t": "t_s", "x.cmd": "x_cmd_mm", "x.act": "x_mm"}`` (roles
        ``cmd``, ``act``, ``tool``, ``vel``, ``acc``, ``cur``, ``err``; a column name or its
        1-based number). Default: from the column names (``x_cmd_mm``, ``x_mm``, ...).
    units : dict, optional
        ``{column: unit}`` where the column name does not say it (``{"x_pos": "um"}``).
    ranges : str or sequence of (start_s, stop_s), optional
        Data ranges in seconds (``"0.5:3.2,4:6"``, ``[(0.5, 3.2), (4, 6)]``; an empty end in a
        text is the data's end): ``identify``
        fits on them, and ``trace.select(trace.meta["ranges"])`` gives the pieces.
    layout : str
        Text layout: ``auto`` (default), ``columns``, ``siso-gui``, ``verify-gui``.
    axes : sequence of str, optional
        Axis names of the GUI layouts (default ``x`` / ``x, y``) or the ``.mat`` EMPS axis.

    Returns
    -------
    Trace
        Positions in mm, time in s; the reader's notes (units assumed or doubtful) in
        ``trace.meta["notes"]``.

    Raises
    ------
    InputError
        The file is missing or unreadable, a column or unit is unknown, a range lies outside
        the data.

    Examples
    --------
    >>> tr = read_trace("examples/virtual_xy_moves.csv")
    >>> tr.axes, tr.Ts
    (['x', 'y'], 0.0006)
    >>> cut = read_trace("examples/virtual_xy_moves.csv", ranges="0:1,2:3")
    >>> [piece.n for piece in cut.select(cut.meta["ranges"])]
    [1667, 1667]
    """
    from .io.ranges import parse_ranges
    from .pipeline.traces import parse_mapping, parse_units, read_with_options
    mapping = parse_mapping(_tokens(mapping)) or None
    units = parse_units(_tokens(units)) or None
    if isinstance(ranges, str):
        ranges = [ranges]
    if ranges and all(isinstance(r, str) for r in ranges):      # "START:STOP[,START:STOP]" texts
        ranges = parse_ranges(list(ranges))
    elif ranges:
        ranges = parse_ranges([",".join(f"{a}:{b}" for a, b in ranges)])
    if isinstance(axes, str):
        axes = [a.strip() for a in axes.split(",") if a.strip()]
    return read_with_options(path, mapping, units, ranges or [], layout or "auto",
                             tuple(axes) if axes else None)


def _tokens(table):
    """``KEY=VALUE`` tokens of a dict (or the tokens themselves)."""
    if table is None:
        return []
    if isinstance(table, dict):
        return [f"{k}={v}" for k, v in table.items()]
    return [table] if isinstance(table, str) else list(table)


def _trace(trace):
    return trace if isinstance(trace, Trace) else read_trace(trace)


# ----------------------------------------------------------------------------- identify
def identify(trace, method="pole-search", *, axes=None, progress=False, **options):
    """Identify a feed-drive model from a measured trace.

    Parameters
    ----------
    trace : Trace or path
        Commanded (``cmd``) and measured (``act``) positions, mm; its ``meta["ranges"]``
        (:func:`read_trace`) are the data fitted.
    method : str
        ``pole-search`` (default: the thesis's pole search with LS projection, the structure
        chosen from the data), ``mimo``, ``full-ls`` (the linear least-squares baseline) or
        ``quasi-static`` (gains on the command's velocity, acceleration and jerk).
    axes : sequence of str, optional
        Axes to identify (default: every axis with ``cmd`` and ``act``).
    progress : bool
        Show the search's progress bar (stderr).
    **options
        The options of ``fdid identify`` with ``_`` for ``-`` (``seed=0``, ``v_tilde=0.5`` [mm/s],
        ``structure="rigid"``, ``no_friction=True``, ``real_hz=["1:50"]`` [Hz], ``maxiter=20``,
        ``cutoff_hz=20`` ...; ``fdid identify --help`` lists them): a flag is ``True``, a
        repeatable option a list.

    Returns
    -------
    DriveModel or QuasiStaticModel
        The model, ``Ts`` the trace's sample time. How it was found: :attr:`DriveModel.records`,
        one :class:`~fdid_fmi.identify.record.PoleSearchRecord` per pole-search / MIMO block
        (poles in Hz, friction transition velocity ``v_tilde_mm_s``, the structure chosen);
        ``QuasiStaticModel.gains`` (s, s^2, s^3) for the quasi-static one.

    Raises
    ------
    InputError
        An unknown option, a bad value or combination (as ``fdid identify`` refuses it), a trace
        without an axis to identify, positions of an unusable scale.

    Examples
    --------
    >>> tr = read_trace("examples/virtual_xy_moves.csv")
    >>> qs = identify(tr, method="quasi-static")
    >>> sorted(qs.gains["x"])
    ['K_acc', 'K_jerk', 'K_vel']
    >>> identify(tr, method="full-ls", axes=["x"]).axes
    ['x']
    >>> m = identify(tr, axes=["x"], structure="rigid", maxiter=5)  # doctest: +SKIP
    >>> m.records[0].real_hz                                         # doctest: +SKIP
    [38.1...]
    >>> identify(tr, method="quasi-static", seed=1)
    Traceback (most recent call last):
    ...
    fdid_fmi.errors.InputError: --seed: --seed is read by --method pole-search / mimo only, not by --method quasi-static
    """
    from .pipeline.identify import check_data_range, identify_from_args, identify_namespace
    args = identify_namespace(method, axes, options)
    trace = _trace(trace)
    check_data_range(trace, args.axis)
    return identify_from_args(trace, args, progress=progress)


# ----------------------------------------------------------------------------- FMU export
@dataclass(frozen=True)
class ExportResult:
    """An exported FMU.

    Attributes
    ----------
    path : Path               the ``.fmu`` written
    fmi_version : int         2 or 3
    backend : str             ``c`` (native binaries) or ``python`` (pythonfmu)
    platforms : tuple of str  binaries built (``linux64``, ``win64``); empty for ``python``
    model_identifier : str
    size_bytes : int
    """

    path: Path
    fmi_version: int
    backend: str
    platforms: tuple
    model_identifier: str
    size_bytes: int


def export_fmu(model, path, fmi=2, *, platforms=("linux64",), backend="c", name=None) -> ExportResult:
    """Export a state-space model as an FMI co-simulation FMU (C code compiled with gcc).

    Parameters
    ----------
    model : DriveModel or path of a model JSON
        Quasi-static models have no state-space form and are refused.
    path : str or Path
        The ``.fmu`` to write (atomically, after fmpy's validator found no problem).
    fmi : 2 or 3
    platforms : sequence of str
        ``linux64`` and/or ``win64`` (C backend); ``sources/`` is always shipped.
    backend : str
        ``c`` (default, no Python at run time) or ``python`` (pythonfmu prototype, FMI 2).
    name : str, optional
        Model identifier (default: from the file name).

    Returns
    -------
    ExportResult

    Raises
    ------
    InputError
        A quasi-static model, a bad FMI version, platform or name, an unwritable path.

    Examples
    --------
    >>> m = identify(read_trace("examples/virtual_xy_moves.csv"), method="full-ls")
    >>> res = export_fmu(m, "drive.fmu")              # doctest: +SKIP
    >>> res.fmi_version, res.path.name                # doctest: +SKIP
    (2, 'drive.fmu')
    """
    from .fmu import export_fmu as _export
    from .fmu.export import model_identifier_for
    if isinstance(platforms, str):
        platforms = [p.strip() for p in platforms.split(",") if p.strip()]
    platforms = tuple(platforms)
    if not platforms:
        raise InputError("no platform given (linux64, win64)", column="platforms")
    if backend == "python" and platforms != ("linux64",):
        raise InputError("platforms apply to the C backend; pythonfmu builds its own binaries",
                         column="platforms")
    out = _export(model, path, fmi_version=fmi, platforms=platforms, backend=backend, model_identifier=name)
    return ExportResult(path=Path(out), fmi_version=int(fmi), backend=backend,
                        platforms=() if backend == "python" else platforms,
                        model_identifier=name or model_identifier_for(out),
                        size_bytes=Path(out).stat().st_size)


# ----------------------------------------------------------------------------- validation
def validate(fmu, trace, *, model=None, tolerance_mm=1e-9):
    """Run an FMU through fmpy on a trace's commands; compare it with the reference simulator
    and the measurement.

    Parameters
    ----------
    fmu : str or Path, or ExportResult
    trace : Trace or path
        Commanded positions of the model's axes (and measured ones for the discrepancy), at the
        model's sample time. The whole trace is run; for ``--range`` pieces pass
        ``trace.select(trace.meta["ranges"])`` one by one.
    model : DriveModel or path, optional
        The reference model (default: the ``resources/model.json`` inside the FMU).
    tolerance_mm : float
        Largest accepted |FMU - reference| [mm].

    Returns
    -------
    ValidationResult
        ``ok``; ``problems`` (fmpy's and the failed checks); ``max_abs_diff_reference_mm``
        (FMU vs reference simulator, mm); ``axes[axis]["rms_um"/"max_um"]`` (the FMU's
        tracking-error discrepancy to the measurement, µm); ``contour`` (two axes); ``table()``.

    Raises
    ------
    InputError
        The file is no FMU, the trace does not fit it (axes, sample time).

    Examples
    --------
    >>> r = validate("drive.fmu", read_trace("examples/virtual_circle.csv"))  # doctest: +SKIP
    >>> r.ok, r.max_abs_diff_reference_mm < 1e-9                              # doctest: +SKIP
    (True, True)
    """
    from .fmu.validate import validate_fmu
    if isinstance(fmu, ExportResult):
        fmu = fmu.path
    return validate_fmu(fmu, _trace(trace), model=model, tolerance_mm=tolerance_mm)


# ----------------------------------------------------------------------------- diagnosis
def diagnose(model, train, val=None, *, detectors=None, min_gain=0.05, max_loss=0.01, max_steps=4,
             maxiter=25, exclude=(), jobs=None, progress=None, search="de"):
    """Find what the model's residual says it lacks (friction at reversals, a mode, dead time,
    a position-periodic force, coupling), add it, refit, keep only what lowers the held-out error.

    Parameters
    ----------
    model : DriveModel or path
        A pole-search or MIMO model (or the per-axis combination ``identify`` makes of several).
    train : Trace or path
        Data the effects are fitted on.
    val : Trace or path, optional
        Held-out data the keep criterion is judged on (default: ``train`` split at the standstill
        nearest its middle: the first part fitted, the second held out).
    detectors : sequence of str, optional
        Detector families (``friction``, ``mode``, ``delay``, ``periodic``, ``coupling``);
        default all.
    min_gain, max_loss : float
        Keep an effect when the held-out RMS falls by at least ``min_gain`` (fraction) and no
        scored channel rises by more than ``max_loss``.
    max_steps : int
        At most this many effects added (per axis of a combined model).
    maxiter : int
        Iterations of each refit's pole search: steps of each local search of ``vp``,
        generations of ``de``.
    exclude : sequence of str
        Channels never used as inputs.
    jobs : int, optional
        Processes running the independent refits (default: one per core; 1: in this process);
        the result is the same for any number.
    progress : callable(str), optional
        Called with progress messages.
    search : str
        Pole search of every refit: ``de`` (default: differential evolution) or ``vp``
        (variable projection from the current poles or a Sobol screen, as ``identify``'s
        default: about half the CPU time, and on some runs a different effect named).

    Returns
    -------
    Diagnosis
        ``final`` (the model with every kept effect), ``effects_added``, ``before``/``after``
        (error tables, µm, per trace and channel), ``notes``; ``to_json()``.

    Raises
    ------
    InputError
        A quasi-static or Full LS model, a trace that does not fit it, a bad option.

    Examples
    --------
    >>> d = diagnose("model.json", read_trace("examples/virtual_xy_moves.csv"),   # doctest: +SKIP
    ...              read_trace("examples/virtual_circle.csv"), maxiter=5)
    >>> [e["kind"] for e in d.effects_added]                                     # doctest: +SKIP
    []
    """
    from .diagnose import diagnose as _diagnose
    if isinstance(model, (str, Path)):
        model = load_model(model)
    if not isinstance(model, DriveModel):
        raise InputError("diagnosis refits the model with the pole search and needs a pole-search or MIMO "
                         "model (fdid identify --method pole-search or mimo), not a quasi-static one",
                         column="identification")
    return _diagnose(model, _trace(train), None if val is None else _trace(val),
                     detectors=None if detectors is None else list(detectors), min_gain=min_gain,
                     max_loss=max_loss, max_steps=max_steps, maxiter=maxiter, exclude=list(exclude),
                     workers=jobs, progress=progress, search=search)


# ----------------------------------------------------------------------------- planning
@dataclass
class PlanResult:
    """An NC program run through the twin.

    Attributes
    ----------
    program : Program                 the blocks read (``notes``, ``ignored``, ``axes_used``)
    interpolation : Interpolation     commanded positions at ``Ts`` (``t``, ``positions``)
    prediction : Prediction           predicted positions, tracking and contour errors (mm);
                                      per block ``blocks``, whole program ``summary``
                                      (``cycle_time_s``, ``contour_max_um``, ...)
    feed_plan : FeedPlan or None      per-block feeds within the tolerance (``optimize=True``)
    model : DriveModel                the twin (an FMU's ``resources/model.json``)
    fmu : str or None                 the FMU path when the twin runs as an FMU
    axes : list of str                the twin's axes
    Ts : float                        sample time, s
    limits : dict or None             axis -> AxisLimits (mm/s, mm/s^2, mm/s^3) interpolated
                                      within; None with ``commands``
    limit_sources : dict              axis -> where its limits came from
    notes : list of str               what was done that the caller should know (resampling)
    """

    program: object
    interpolation: object
    prediction: object
    feed_plan: object = None
    model: object = None
    fmu: str | None = None
    axes: list = field(default_factory=list)
    Ts: float = 0.0
    limits: dict | None = None
    limit_sources: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def summary(self):
        """The whole program's figures (``prediction.summary``)."""
        return self.prediction.summary


def plan(model, program, *, fmu=None, tol_mm=None, limits=None, limits_from=None, commands=None,
         start=(0.0, 0.0, 0.0), corner_angle_deg=None, in_position_mm=None, optimize=False,
         margin=None, progress=False) -> PlanResult:
    """Predict an NC program's tracking and contour errors per block; optionally find per-block
    feeds that keep the contour error within ``tol_mm`` at the shortest cycle time.

    Parameters
    ----------
    model : DriveModel, path of a model JSON, or None
        The twin (its ``limits``, recorded from its identification traces, are those interpolated
        within unless ``limits``/``limits_from`` give others). None when ``fmu`` is given.
    program : str, Path or Program
        ISO / RS-274 part program (``.nc``).
    fmu : str or Path, optional
        An exported drive FMU as the twin (run through fmpy), in place of ``model``.
    tol_mm : float, optional
        Contour tolerance [mm]: blocks above it are flagged.
    limits : dict, optional
        ``{axis: (v [mm/s], a [mm/s^2], j [mm/s^3])}`` or AxisLimits; they win over the others.
    limits_from : Trace, optional
        A recorded trace of the same machine to estimate the limits from.
    commands : Trace, optional
        The controller's interpolated setpoints (``cmd`` channels), in place of interpolating.
    start : (x, y, z)
        Position before the first block [mm].
    corner_angle_deg : float, optional
        No stop at junctions whose tangents differ by at most this angle (default: exact stop).
    in_position_mm : float, optional
        After every rapid the next block waits until every axis's predicted tracking error is
        within this window (default 0.01 mm; 0: no wait).
    optimize : bool
        Find per-block feeds within ``tol_mm`` (needs ``tol_mm``).
    margin : float, optional
        The optimised feeds aim at ``tol_mm * (1 - margin)`` (default 0.02).
    progress : bool
        Progress bars (stderr, only on a terminal).

    Returns
    -------
    PlanResult

    Raises
    ------
    InputError
        A program without motion, axes the twin cannot predict, missing limits, bad options.

    Examples
    --------
    >>> m = identify(read_trace("examples/virtual_xy_moves.csv"), method="full-ls")
    >>> p = plan(m, "examples/pocket_corner.nc", tol_mm=0.02,
    ...          limits={"x": (100, 2000, 1e5), "y": (100, 2000, 1e5), "z": (100, 2000, 1e5)})
    >>> len(p.prediction.blocks) == len(p.program.blocks), p.summary["cycle_time_s"] > 0
    (True, True)
    """
    from .plan import read_program
    from .plan.interpolate import IN_POSITION_MM, AxisLimits, InPosition, commands_from_trace, interpolate
    from .plan.ncprogram import Program
    from .plan.optimize import check_optimisable, optimize_feeds
    from .plan.predict import fmu_axes, model_from_fmu, predict
    from .simulate import fits_sample_time

    if (model is None) == (fmu is None):
        raise InputError("give the twin as a model or as an FMU (one of them)", column="model")
    if optimize and tol_mm is None:
        raise InputError("optimize needs tol_mm (the contour tolerance in mm)", column="tol_mm")
    if commands is not None and (optimize or limits or limits_from is not None
                                 or corner_angle_deg is not None or in_position_mm is not None):
        raise InputError("commands replaces the interpolation: leave out optimize, limits, limits_from, "
                         "corner_angle_deg and in_position_mm", column="commands")
    prog = program if isinstance(program, Program) else read_program(program, start=list(start))
    twin_name = str(fmu) if fmu is not None else str(model) if isinstance(model, (str, Path)) else "the model"
    if fmu is None:
        if isinstance(model, (str, Path)):
            model = load_model(model)
        if not isinstance(model, DriveModel):
            raise InputError("plan needs a state-space model (identify with pole-search, mimo or full-ls)",
                             source=twin_name)
        Ts, axes = model.Ts, model.axes
    else:
        fmu = str(fmu)
        axes, _ = fmu_axes(fmu)
        model = model_from_fmu(fmu)
        Ts = model.Ts
    bad = [a for a in axes if a not in ("x", "y", "z")]
    if bad:
        raise InputError(f"the model's axes {bad} are not x, y or z (the program's axes)",
                         source=twin_name, column="axes")
    if not prog.blocks:
        raise InputError("the program has no motion block (G0, G1, G2, G3 or G4)", source=prog.source)
    if not prog.axes_used:
        raise InputError("the program moves no axis (every block ends where it starts): there is no "
                         "error to predict", source=prog.source)
    if not any(a in axes for a in prog.axes_used):
        raise InputError(f"the program moves only the axes {prog.axes_used}, none of which the twin "
                         f"models (axes {axes}): there is no error to predict or feed to optimise",
                         source=prog.source)
    # a contour error needs two axes: with one, the program's path in a plane would read 0.00 um
    # and "every block stays inside" the tolerance
    if len(axes) < 2 and len(prog.axes_used) >= 2:
        raise InputError(f"the twin models one axis ({axes[0]}) of the axes the program moves "
                         f"{prog.axes_used}: a contour error needs the path's plane; give a twin of "
                         f"(at least) two axes", source=twin_name, column="axes")
    if optimize:       # optimize_feeds checks it too, after the table
        check_optimisable(axes, source=twin_name)
    notes, lim, origin, in_pos = [], None, {}, None
    if commands is not None:
        tr, recorded_Ts = commands, commands.Ts
        if not fits_sample_time(recorded_Ts, Ts):   # the controller's cycle need not be the model's
            tr = tr.resample(Ts)
        ip = commands_from_trace(prog, tr, axes, Ts=Ts)
        if tr.Ts != recorded_Ts:                # said, not silent
            notes.append(f"the setpoints of {commands.source}, recorded at Ts = {recorded_Ts:g} s, are "
                         f"resampled to the model's Ts = {Ts:g} s")
    else:
        given = {a: v if isinstance(v, AxisLimits) else AxisLimits(*(float(x) for x in v))
                 for a, v in (limits or {}).items()}
        lim, origin = _plan_limits(prog, model, axes, given, limits_from,
                                   f"{fmu}:resources/model.json" if fmu is not None else twin_name)
        window = IN_POSITION_MM if in_position_mm is None else in_position_mm
        in_pos = InPosition(model, window) if window > 0 else None
        ip = interpolate(prog, lim, Ts, progress=progress, corner_angle_deg=corner_angle_deg, in_position=in_pos)
        ip.info["limit_sources"] = origin
    twin = {"model": model} if fmu is None else {"fmu": fmu}
    pr = predict(ip, tol_mm=tol_mm, program=prog, **twin)
    fpl = None
    if optimize:
        given = {} if margin is None else {"margin": margin}    # else optimize_feeds' default
        fpl = optimize_feeds(prog, lim, Ts, tol_mm, progress=progress, before=pr,
                             corner_angle_deg=corner_angle_deg, in_position=in_pos, **given, **twin)
    return PlanResult(program=prog, interpolation=ip, prediction=pr, feed_plan=fpl, model=model, fmu=fmu,
                      axes=list(axes), Ts=Ts, limits=lim, limit_sources=origin, notes=notes)


def _plan_limits(prog, model, twin_axes, given, limits_from, src):
    """The limits of every axis the program moves, and where each came from.

    In order of precedence: ``given``, ``limits_from`` (a trace), the limits the model recorded
    from its identification traces (``DriveModel.limits``). An axis the program moves that the
    twin does not model (Z on an XY twin) and that none of these gives follows its command
    ideally: it gets the slowest of the twin's axes' limits, said in the summary and the report.
    """
    from .plan.interpolate import AxisLimits, limits_from_trace
    lim, origin = {}, {}
    for a, d in (model.limits or {}).items():
        lim[a] = AxisLimits(d["v_mm_s"], d["a_mm_s2"], d["j_mm_s3"])
        origin[a] = f"recorded in the model from its identification traces ({d.get('method', '')})"
    if limits_from is not None:
        for a, v in limits_from_trace(limits_from).items():
            lim[a], origin[a] = v, f"--limits-from {limits_from.source}"
    for a, v in given.items():
        lim[a], origin[a] = v, "--limits"
    missing = [a for a in prog.axes_used if a in twin_axes and a not in lim]
    if missing:
        why = ("records none (a model saved before format version 3, which records the feed, acceleration "
               "and jerk of its identification traces)" if not model.limits else
               "records none for them (its identification traces did not move them)")
        raise InputError(f"the program moves axes {missing}, which have no limits: {src} {why}: give --limits "
                         f"V,A,J (mm/s, mm/s^2, mm/s^3) or AXIS=V,A,J, or --limits-from TRACE"
                         + (", or identify the model again" if not model.limits else ""),
                         source=prog.source, column="--limits")
    known = [lim[a] for a in twin_axes if a in lim]
    for a in prog.axes_used:
        if a not in lim:        # not modelled and not given: it follows its command ideally
            lim[a] = AxisLimits(min(x.v for x in known), min(x.a for x in known), min(x.j for x in known))
            origin[a] = ("default for an axis the twin does not model: the slowest of the twin's axes' "
                         "limits (give --limits AXIS=V,A,J for its own)")
    return lim, origin
