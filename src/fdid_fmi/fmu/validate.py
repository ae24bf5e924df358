"""Validate an exported FMU the way co-simulation masters run it.

``validate_fmu(fmu_path, trace, model=None)`` runs three comparisons:

1. ``fmpy.validation.validate_fmu``: modelDescription.xml schema, names, ModelStructure...
   (any problem it reports is listed in ``problems``);
2. the FMU run by ``fmpy.simulate_fmu`` with an input table of the measured commanded positions
   (``step_size`` = the model's Ts, outputs recorded after every ``doStep``: what fmpy, ecos,
   libcosim and other masters do), rows aligned by time, against
   :func:`fdid_fmi.simulate.simulate` on the same trace: largest absolute difference of every
   position / velocity / tool output at the same time stamps (target <= 1e-9 mm). A non-finite
   output anywhere is a problem;
3. the FMU's prediction against the measurement: RMS and maximum of the tracking-error
   discrepancy (x_cmd(t_k) - x_FMU(t_k) - measured e(t_k)) per axis in µm, and for two or more
   axes the contour-error discrepancy of the first two axes;
4. the FMU run at a master's coarser communication step (:func:`coarse_step`: the output
   interval ``fmpy.simulate_fmu`` picks when given ``step_size`` alone), against the reference at
   the same time stamps: with the inputs held over each step (``fmpy.simulate_fmu``), and with
   what a master can pass within a step (:func:`run_coarse`): FMI 2 input derivatives
   (``fmi2SetRealInputDerivatives``, slopes of the input table as fmpy computes them), FMI 3
   the inputs of every sample in intermediate update mode. So a user sees both figures: "fed
   every sample" (2.) and "held (or interpolated) inputs at the master's step".

Timing. The models are causal: an output read after ``doStep(t_k, Ts)`` is the prediction for
t_k+1, so row k of the master's table is the model at t_k, and the tracking error at t_k is
x_cmd(t_k) - ``<axis>_x`` of row k (the FMU has no error output: it would pair the command it
holds, of t_k, with the position of t_k+1).
"""
from __future__ import annotations

import contextlib
import io
import json
import shutil
import tempfile
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model import DriveModel, jsonable, load_model
from ..trace import Trace
from .archive import check_fmu_archive, extract_fmu, read_member


@dataclass
class ValidationResult:
    """Outcome of :func:`validate_fmu`.

    Attributes
    ----------
    fmu : str                       FMU file
    problems : list[str]            fmpy validation problems and failed checks (empty = none)
    max_abs_diff_reference_mm : float
        max |FMU - reference simulator| over all position and tool-side outputs (mm)
    max_abs_diff_reference_velocity_mm_s : float
    axes : dict axis -> {"rms_um", "max_um"}   tracking-error discrepancy vs the measurement
    contour : dict or None          {"axes": [a, b], "rms_um", "max_um"} contour-error discrepancy
    n_samples : int
    steps_per_second : float        FMU steps per second through fmpy (including Python overhead)
    fmi_version : str
    tolerance_mm : float            the agreement target of the reference comparison
    start : str                     how the FMU and the reference were started
    reference_sensitivity_mm : float or None
        only when the FMU misses the target: how far the reference itself moves when the
        commands are perturbed by 1e-12 mm (a measure of the trace's chaotic sensitivity)
    unmeasured : list[str]          axes whose measured position the trace lacks: no
                                    discrepancy to the measurement was computed for them
    coarse_step_s : float           the master's coarse communication step of check 4, s
    coarse_samples : int            that step in samples
    max_abs_diff_held_mm : float    max |FMU - reference| of the positions at that step, inputs held
    max_abs_diff_interpolated_mm : float or None
        the same with the inputs the master can pass within a step: FMI 2 input derivatives
        (canInterpolateInputs), FMI 3 the inputs of each sample in intermediate update mode
    """

    fmu: str
    problems: list = field(default_factory=list)
    max_abs_diff_reference_mm: float = float("nan")
    max_abs_diff_reference_velocity_mm_s: float = float("nan")
    axes: dict = field(default_factory=dict)
    contour: dict | None = None
    n_samples: int = 0
    steps_per_second: float = float("nan")
    fmi_version: str = ""
    tolerance_mm: float = 1e-9
    start: str = ""
    reference_sensitivity_mm: float | None = None
    unmeasured: list = field(default_factory=list)
    coarse_step_s: float = float("nan")
    coarse_samples: int = 0
    max_abs_diff_held_mm: float = float("nan")
    max_abs_diff_interpolated_mm: float | None = None

    @property
    def ok(self):
        return not self.problems and self.max_abs_diff_reference_mm <= self.tolerance_mm

    def to_dict(self):
        d = asdict(self)
        d["ok"] = self.ok
        return jsonable(d)

    def _coarse_lines(self):
        if not np.isfinite(self.coarse_step_s):
            return []
        n = self.coarse_samples
        lines = [f"fed every sample (step = Ts): max |FMU - reference| = {self.max_abs_diff_reference_mm:.3g} mm",
                 f"held inputs at a master's step of {self.coarse_step_s:g} s ({n} samples): max |FMU - reference| "
                 f"= {self.max_abs_diff_held_mm:.3g} mm"]
        if self.max_abs_diff_interpolated_mm is not None:
            how = ("inputs of every sample given in intermediate update mode" if self.fmi_version.startswith("3")
                   else "interpolated inputs (input derivatives)")
            lines.append(f"{how} at {self.coarse_step_s:g} s: max |FMU - reference| = "
                         f"{self.max_abs_diff_interpolated_mm:.3g} mm")
        return lines

    def table(self):
        """Markdown table of the comparison."""
        n_fmpy = sum(p.startswith("fmpy:") for p in self.problems)
        lines = [f"FMU {self.fmu} (FMI {self.fmi_version}), {self.n_samples} samples",
                 "fmpy validation: " + (f"{n_fmpy} problem(s)" if n_fmpy else "no problems"),
                 f"max |FMU - reference| = {self.max_abs_diff_reference_mm:.3g} mm "
                 f"(velocity {self.max_abs_diff_reference_velocity_mm_s:.3g} mm/s; "
                 f"target <= {self.tolerance_mm:g} mm)",
                 f"start: {self.start}",
                 *self._coarse_lines(),
                 "",
                 "| axis | e RMS discrepancy [µm] | e MAX discrepancy [µm] |",
                 "|---|---:|---:|"]
        for a, d in self.axes.items():
            lines.append(f"| {a} | {d['rms_um']:.3f} | {d['max_um']:.3f} |")
        for a in self.unmeasured:
            lines.append(f"| {a} | not computed: the trace has no measured position of axis {a} | |")
        if self.contour:
            lines.append(f"| contour {'/'.join(self.contour['axes'])} | {self.contour['rms_um']:.3f} | "
                         f"{self.contour['max_um']:.3f} |")
        for p in self.problems:
            lines.append(f"problem: {p}")
        return "\n".join(lines)


# --------------------------------------------------------------------------- FMU driver
class FmuRunner:
    """Drive an extracted FMU through fmpy, one sample at a time (FMI 2.0 or 3.0)."""

    def __init__(self, fmu_path, instance_name="fdid", logger=None):
        from fmpy import read_model_description
        self.fmu_path = str(fmu_path)
        check_fmu_archive(self.fmu_path)        # before fmpy inflates or unpacks anything
        self.md = read_model_description(self.fmu_path)
        self.version = self.md.fmiVersion
        if self.md.coSimulation is None:
            raise InputError("the FMU has no Co-Simulation interface", source=self.fmu_path)
        self._dir = tempfile.mkdtemp(prefix="fdid_run_")
        extract_fmu(self.fmu_path, self._dir)
        self.vars = {v.name: v for v in self.md.modelVariables}
        ident = self.md.coSimulation.modelIdentifier
        kw = dict(unzipDirectory=self._dir, modelIdentifier=ident, instanceName=instance_name)
        if self.version.startswith("3"):
            from fmpy.fmi3 import FMU3Slave
            self.fmu = FMU3Slave(guid=self.md.guid, **kw)
        else:
            from fmpy.fmi2 import FMU2Slave
            self.fmu = FMU2Slave(guid=self.md.guid, **kw)
        self._logger = logger

    def vr(self, name):
        if name not in self.vars:
            raise InputError(f"the FMU has no variable '{name}'", source=self.fmu_path, column=name)
        return self.vars[name].valueReference

    def close(self):
        try:
            self.fmu.freeInstance()
        except Exception:  # noqa: BLE001 - best effort clean-up
            pass
        shutil.rmtree(self._dir, ignore_errors=True)

    def start(self, start_time=0.0, stop_time=None, intermediate=None):
        """Instantiate and enter initialization mode (FMI 2: through fmi2SetupExperiment).

        ``intermediate`` (FMI 3): ``(callback, input value references)`` for intermediate update."""
        f = self.fmu
        if self.version.startswith("3"):
            if intermediate:
                f.instantiate(loggingOn=False, intermediateUpdate=intermediate[0],
                              requiredIntermediateVariables=list(intermediate[1]))
            else:
                f.instantiate(loggingOn=False)
            f.enterInitializationMode(startTime=start_time, stopTime=stop_time)
        else:
            f.instantiate(loggingOn=False, callbacks=self._logger)
            f.setupExperiment(startTime=start_time, stopTime=stop_time)
            f.enterInitializationMode()

    def run(self, inputs, n, Ts, outputs, parameters=None, booleans=None, comm_step=1, start_time=0.0,
            read="before"):
        """Simulate ``n`` samples.

        Parameters
        ----------
        inputs : dict name -> array (n,)       FMU inputs, sample k applied before reading step k
        outputs : list of names                read at every communication point
        parameters : dict name -> float        set before exitInitializationMode
        booleans : dict name -> bool
        comm_step : int                        communication step in samples (inputs held)
        read : ``before`` (default): outputs of sample k read after its input is set, before
               doStep; ``after``: read after doStep, before the next input (what fmpy's
               simulate_fmu and most masters record: row k = time t_k + h, input k held)

        Returns
        -------
        dict name -> array (n // comm_step,)
        """
        f = self.fmu
        three = self.version.startswith("3")
        in_vr = [self.vr(k) for k in inputs]
        in_val = np.column_stack([np.asarray(inputs[k], float) for k in inputs]) if inputs else np.zeros((n, 0))
        out_vr = [self.vr(k) for k in outputs]
        setr = f.setFloat64 if three else f.setReal
        getr = f.getFloat64 if three else f.getReal
        self.start(start_time)
        for k, v in (parameters or {}).items():
            setr([self.vr(k)], [float(v)])
        for k, v in (booleans or {}).items():
            f.setBoolean([self.vr(k)], [bool(v)])
        if in_vr:
            setr(in_vr, list(in_val[0]))
        f.exitInitializationMode()
        steps = range(0, n - n % comm_step if comm_step > 1 else n, comm_step)
        out = np.empty((len(steps), len(out_vr)))
        h = comm_step * Ts
        t = start_time
        for j, k in enumerate(steps):
            if in_vr:
                setr(in_vr, list(in_val[k]))
            if read == "before":
                out[j] = getr(out_vr)
            f.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            if read != "before":
                out[j] = getr(out_vr)
            t = start_time + (j + 1) * h
        f.terminate()
        return {name: out[:, i] for i, name in enumerate(outputs)}


def run_fmu(fmu_path, commands, Ts, start_velocity=None, externals=None, parameters=None,
            booleans=None, outputs=None, comm_step=1, read="before"):
    """Run an fdid FMU through fmpy from commanded positions.

    Parameters
    ----------
    commands : dict axis -> commanded position array (mm)
    Ts : float, s          sample time of the commands (= the model's)
    start_velocity : dict axis -> mm/s (sets ``<axis>_v0``)
    externals : dict FMU input name -> array
    parameters, booleans : extra parameter values
    outputs : list of variable names (default: every output)
    comm_step : communication step in samples; read : see :meth:`FmuRunner.run`

    Returns
    -------
    dict variable name -> array
    """
    r = FmuRunner(fmu_path)
    try:
        n = len(next(iter(commands.values())))
        ins = {f"{a}_x_cmd": np.asarray(c, float) for a, c in commands.items()}
        ins.update({k: np.asarray(v, float) for k, v in (externals or {}).items()})
        params = dict(parameters or {})
        for a, v in (start_velocity or {}).items():
            params[f"{a}_v0"] = float(v)
        if outputs is None:
            outputs = [v.name for v in r.md.modelVariables if v.causality == "output"]
        return r.run(ins, n, Ts, outputs, params, booleans, comm_step=comm_step, read=read)
    finally:
        r.close()


# --------------------------------------------------------------------------- validation
def _model_from_fmu(fmu_path):
    try:
        d = json.loads(read_member(fmu_path, "resources/model.json"))
    except KeyError:
        raise InputError("the FMU carries no resources/model.json; pass the model (--model)",
                         source=str(fmu_path)) from None
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise InputError("resources/model.json in the FMU is not JSON", source=str(fmu_path)) from None
    return DriveModel.from_dict(d, source=f"{fmu_path}:resources/model.json")


# what defines the simulation (metrics, provenance and notes may differ between copies)
_SIMULATED = ("Ts", "A", "B", "C", "D", "inputs", "outputs")


def _carried_differences(fmu_path, model):
    """What of the simulation (``_SIMULATED``) the model the FMU carries (``resources/model.json``)
    does differently from the reference; empty when it carries none, an unreadable one, or the same."""
    try:
        carried = _model_from_fmu(fmu_path).to_dict()
    except InputError:          # no zip, no resources/model.json, or not a model
        return []
    given = model.to_dict()
    return [k for k in _SIMULATED if json.dumps(carried[k], sort_keys=True) != json.dumps(given[k], sort_keys=True)]


def run_master(fmu_path, t, inputs, outputs, start_values=None, step_size=None):
    """Run an FMU as co-simulation masters do: ``fmpy.simulate_fmu`` with an input table.

    Parameters
    ----------
    t : (N,) time stamps of the input table, s, on the grid t0 + k step_size
    inputs : dict FMU input name -> (N,) values (held over each step)
    outputs : list of FMU output names
    start_values : dict name -> value (parameters such as ``<axis>_v0``)
    step_size : s; default the FMU's default experiment step

    Returns
    -------
    dict name -> (N,) outputs; row k recorded at t[k] (row 0 after initialisation, row k > 0
    after ``doStep(t[k-1], step_size)``)
    """
    from fmpy import read_model_description, simulate_fmu
    if step_size is None:
        step_size = read_model_description(str(fmu_path)).defaultExperiment.stepSize
    h = float(step_size)
    sig = _input_table(t, inputs)
    res = simulate_fmu(str(fmu_path), start_time=float(t[0]), stop_time=float(t[-1]), step_size=h,
                       output_interval=h, input=sig, output=list(outputs),
                       start_values=dict(start_values or {}), validate=False)
    if len(res) != len(t) or np.max(np.abs(res["time"] - t)) > 0.5 * h:
        raise InputError(f"fmpy.simulate_fmu recorded {len(res)} rows for {len(t)} input samples: "
                         f"the FMU does not step at {h:g} s", source=str(fmu_path))
    return {k: np.asarray(res[k], float) for k in outputs}


def _input_table(t, inputs):
    """``fmpy.simulate_fmu``'s input table: a structured array of ``time`` and one field per input."""
    sig = np.zeros(len(t), dtype=[("time", float)] + [(k, float) for k in inputs])
    sig["time"] = t
    for k, v in inputs.items():
        sig[k] = v
    return sig


def coarse_step(duration, Ts):
    """The communication step of a master that is not told to feed every sample: the output
    interval ``fmpy.simulate_fmu`` picks for a co-simulation FMU when given no
    ``output_interval`` (it ignores ``step_size`` then): the FMU's default experiment step (Ts)
    doubled until the run of ``duration`` s has at most 1000 steps; at least 2 samples (for a
    short record fmpy feeds every sample, and there is no coarse step to measure otherwise).

    Returns
    -------
    (h, n) : step in s, and in samples (h = n Ts)
    """
    n = 1
    while float(duration) / (n * Ts) > 1000:
        n *= 2
    n = max(n, 2)
    return n * Ts, n


def run_coarse(fmu_path, t, inputs, outputs, start_values, n, derivatives):
    """Run an FMU at a communication step of ``n`` samples of the input table ``(t, inputs)``
    (outputs read after each ``doStep``, as masters record them).

    With ``derivatives`` the master passes what the FMI version lets it pass within a step: in
    FMI 2, after setting each input, its slope at the communication point as
    ``fmpy.simulate_fmu(..., set_input_derivatives=True)`` computes it from the table (fmpy 0.3's
    own loop fails with other than nine inputs, so this loop does it); in FMI 3, the table's
    inputs of each internal sample, set in intermediate update mode. Otherwise the inputs are
    held over each step.

    Returns
    -------
    (rows, dict name -> values): table rows k the outputs belong to (time t[k]), and the outputs
    """
    from fmpy.simulation import Input
    r = FmuRunner(fmu_path, logger=_quiet_logger())
    try:
        f = r.fmu
        three = r.version.startswith("3")
        setr = f.setFloat64 if three else f.setReal
        getr = f.getFloat64 if three else f.getReal
        names = list(inputs)
        in_vr = [r.vr(k) for k in names]
        table = np.vstack([np.asarray(inputs[k], float) for k in names])
        out_vr = [r.vr(k) for k in outputs]
        Ts = float(t[1] - t[0]) if len(t) > 1 else 1.0
        t0 = float(t[0])

        def intermediate(env, time_, *rest):      # FMI 3: the inputs of the sample at time_
            setr(in_vr, list(table[:, int(round((time_ - t0) / Ts))]))

        r.start(t0, intermediate=(intermediate, in_vr) if derivatives and three else None)
        for k, v in (start_values or {}).items():
            setr([r.vr(k)], [float(v)])
        setr(in_vr, list(table[:, 0]))
        f.exitInitializationMode()
        rows = list(range(n, len(t), n))
        out = np.empty((len(rows), len(out_vr)))
        h = n * Ts
        for j, k in enumerate(rows):
            k0 = k - n
            tk = float(t[0]) + k0 * Ts
            setr(in_vr, list(table[:, k0]))
            if derivatives and not three:
                _, d = Input.interpolate(time=tk, t=np.asarray(t, float), table=table)
                f.setRealInputDerivatives(in_vr, [1] * len(in_vr), [float(x) for x in d])
            f.doStep(currentCommunicationPoint=tk, communicationStepSize=h)
            out[j] = getr(out_vr)
        f.terminate()
        return np.asarray(rows), {name: out[:, i] for i, name in enumerate(outputs)}
    finally:
        r.close()


def _quiet_logger():
    """An FMI 2 logger that drops messages (the coarse runs' note on held inputs is what they measure)."""
    from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2CallbackAllocateMemoryTYPE, \
        fmi2CallbackFreeMemoryTYPE, fmi2StepFinishedTYPE
    from fmpy import calloc, free
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(lambda *a: None)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    cb.stepFinished = fmi2StepFinishedTYPE()
    cb.componentEnvironment = None
    return cb


def validate_fmu(fmu_path, trace, model=None, tolerance_mm=1e-9, start="auto"):
    """Validate an FMU against the reference simulator and a measured trace.

    Parameters
    ----------
    fmu_path : str or Path
    trace : Trace            measured record with ``cmd`` (and ``act`` for the discrepancy)
                             channels of the model's axes
    model : DriveModel, path, or None
        The reference model; default: the ``resources/model.json`` inside the FMU.
    tolerance_mm : float     agreement target with the reference (problems list it when missed)
    start : ``auto`` or ``ramp``
        As in :func:`fdid_fmi.simulate.simulate`: with ``auto`` a record that starts
        accelerating is preceded by the reference's run-up from rest (``simulate.run_up``),
        fed to the FMU as well (earlier rows of the input table, dropped from the comparison);
        otherwise the FMU starts in the steady ramp at the commanded start velocity
        (``<axis>_v0``).

    Returns
    -------
    ValidationResult
    """
    import time

    from fmpy.validation import validate_fmu as fmpy_validate

    from ..simulate import rounding_sensitivity, run_up, simulate
    from .layout import build_layout
    from ..io.common import check_file
    fmu_path = check_file(fmu_path, what="FMU file")    # a directory is not "not found"
    check_fmu_archive(fmu_path)     # member paths and inflated sizes, before anything unpacks it
    if isinstance(tolerance_mm, bool) or not isinstance(tolerance_mm, (int, float, np.floating, np.integer)) \
            or not (np.isfinite(tolerance_mm) and tolerance_mm > 0):
        # NaN and <= 0 failed every FMU with a meaningless message, inf passed any FMU
        raise InputError(f"the tolerance must be a positive finite number of mm, got {tolerance_mm!r}",
                         column="tolerance")
    if not isinstance(trace, Trace):
        raise InputError(f"expected a Trace, got {type(trace).__name__}", column="trace")
    given = f"the reference model {model}" if isinstance(model, (str, Path)) else "the reference model"
    if model is None:
        model = _model_from_fmu(fmu_path)
    elif isinstance(model, (str, Path)):
        model = load_model(model)
    if not isinstance(model, DriveModel):
        raise InputError("the reference model must be a state-space DriveModel", column="model")
    res = ValidationResult(fmu=str(fmu_path), tolerance_mm=tolerance_mm, n_samples=trace.n)
    md = _model_description(fmu_path)
    res.problems = [f"fmpy: {p}" for p in fmpy_validate(str(fmu_path))]
    h = getattr(md.defaultExperiment, "stepSize", None) if md.defaultExperiment is not None else None
    if h is not None and float(h) > 0 and abs(float(h) - model.Ts) > 1e-9 * model.Ts:
        # the FMU would refuse every step, which reads as a missing binary for this platform;
        # checked before the trace, which a wrong --model would otherwise be blamed on
        raise InputError(f"the FMU steps at {float(h):g} s (its default experiment) but {given} at "
                         f"{model.Ts:g} s: the FMU was not exported from that model", source=str(fmu_path))
    axes = model.axes
    missing = [a for a in axes if not trace.has(a, "cmd")]
    if missing:
        raise InputError(f"the trace has no commanded position for axes {missing} of the model "
                         f"(map them with --map)", source=trace.source, column="cmd")
    if abs(trace.Ts - model.Ts) > 1e-9 * model.Ts:
        raise InputError(f"the trace is sampled at {trace.Ts:g} s but the model at {model.Ts:g} s",
                         source=trace.source, column="time")
    if start not in ("auto", "ramp"):
        raise InputError(f"start must be 'auto' or 'ramp', got {start!r}", column="start")
    ref = simulate(model, trace, start=start)
    Ts = model.Ts
    cmds = {a: np.asarray(trace.cmd(a), float) for a in axes}
    lay = build_layout(model)
    var = {(v.role, v.index): v.name for v in lay.variables}      # names by role (FmuLayout)
    ak = {a: k for k, a in enumerate(lay.axes)}
    names = {(role, a): var[(role, ak[a])] for a in axes for role in ("cmd", "pos", "vel", "tool")
             if (role, ak[a]) in var}
    have = {v.name for v in md.modelVariables}
    used = list(names.values()) + [var[("v0", ak[a])] for a in axes if ("v0", ak[a]) in var] + [
        v.name for v in lay.inputs if v.role == "ext"]
    lacking = [nm for nm in used if nm not in have]
    if lacking:         # not fmpy's "no field of name ...", which reads as a missing binary
        raise InputError(f"the FMU has no variable(s) {lacking} of the reference model: it was not "
                         "exported from this model (pass the model it was exported from with --model)",
                         source=str(fmu_path))
    # the same start as the reference: a run-up from rest for records that start accelerating
    # (simulate.run_up, as earlier rows of the table), else the steady ramp at the start velocity
    R, ext_cmds, v0_run = run_up(cmds, Ts) if start == "auto" else (0, cmds, {})
    table = {names[("cmd", a)]: ext_cmds[a] for a in axes}
    for v in lay.inputs:
        if v.role == "ext":
            p = model.inputs[v.index]
            x = np.asarray(trace.extra(p.params.get("channel", p.name)), float)
            table[v.name] = np.concatenate([np.full(R, x[0]), x])
    if R:
        v0 = {a: v0_run[a] for a in axes}
        res.start = f"run-up from rest over {R} samples (simulate.run_up)"
    else:
        v0 = {a: (c[1] - c[0]) / Ts for a, c in cmds.items()}
        res.start = "steady ramp at " + ", ".join(f"{a}_v0 = {v:.6g} mm/s" for a, v in v0.items())
    t = trace.t[0] + Ts * np.arange(-R, trace.n)          # the nominal grid of the trace
    t0 = time.perf_counter()
    try:
        outs = [n for (role, _), n in names.items() if role != "cmd"]
        out = run_master(fmu_path, t, table, outs, {var[("v0", ak[a])]: v for a, v in v0.items()}, Ts)
        out = {key: out[n][R:] for key, n in names.items() if key[0] != "cmd"}
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions (missing binary, FMI error)
        hint = "; does it have a binary for this platform?" if "platform" in str(exc) else ""
        raise InputError(f"the FMU could not be run through fmpy.simulate_fmu ({exc}){hint}",
                         source=str(fmu_path)) from None
    dt = time.perf_counter() - t0
    res.fmi_version = md.fmiVersion
    res.steps_per_second = (trace.n + R) / dt if dt > 0 else float("nan")
    for key, v in out.items():
        bad = ~np.isfinite(v)
        if bad.any():
            res.problems.append(f"output '{names[key]}' is not finite from t = "
                                f"{trace.t[int(np.argmax(bad))]:g} s on")
    dpos, dvel = 0.0, 0.0
    for a in axes:
        r = ref.axes[a]
        dpos = max(dpos, _maxdiff(out[("pos", a)], r["position"]))
        if ("tool", a) in out:
            dpos = max(dpos, _maxdiff(out[("tool", a)], r["tool_position"]))
        dvel = max(dvel, _maxdiff(out[("vel", a)], r["velocity"]))
    res.max_abs_diff_reference_mm = dpos
    res.max_abs_diff_reference_velocity_mm_s = dvel
    _coarse_figures(res, fmu_path, t, table, {a: names[("pos", a)] for a in axes},
                    {var[("v0", ak[a])]: v for a, v in v0.items()}, R, ref, Ts)
    if not dpos <= tolerance_mm:
        sens = rounding_sensitivity(model, trace, start)
        res.reference_sensitivity_mm = sens
        res.problems.append(_reference_problem(dpos, tolerance_mm, sens, _carried_differences(fmu_path, model)))
    _against_measurement(res, model, trace, cmds, out)
    return res


def _coarse_figures(res, fmu_path, t, table, pos_names, start_values, R, ref, Ts):
    """Check 4 of :func:`validate_fmu`: the positions at a master's coarse step, inputs held
    (``fmpy.simulate_fmu`` as a user first calls it) and with the inputs passed within the step
    (:func:`run_coarse`), against the reference at the same time stamps."""
    from fmpy import simulate_fmu
    h, n = coarse_step(t[-1] - t[0], Ts)
    res.coarse_step_s, res.coarse_samples = h, n
    if len(t) <= 2 * n:
        res.coarse_step_s = float("nan")      # too short a record for a coarser step
        return
    sig = _input_table(t, table)
    outs = list(pos_names.values())

    def worst(rows, got):
        keep = rows >= R        # rows of the run-up (before the record) are not compared
        d = 0.0
        for a, nm in pos_names.items():
            d = max(d, _maxdiff(np.asarray(got[nm])[keep], ref.axes[a]["position"][rows[keep] - R]))
        return d

    try:
        # the FMU's note on held inputs goes to fmpy's default logger, which prints it: kept out of
        # this report. (No logger= here: fmpy keeps one native pointer to the last logger passed to
        # simulate_fmu and calls it, freed, for every later FMU that logs through its defaults.)
        with contextlib.redirect_stdout(io.StringIO()):
            held = simulate_fmu(str(fmu_path), start_time=float(t[0]), stop_time=float(t[-1]),
                                output_interval=h, input=sig, output=outs, start_values=dict(start_values),
                                validate=False)
        rows = np.rint((np.asarray(held["time"]) - t[0]) / Ts).astype(int)
        res.max_abs_diff_held_mm = worst(rows, held)
        rows, got = run_coarse(fmu_path, t, table, outs, start_values, n, derivatives=True)
        res.max_abs_diff_interpolated_mm = worst(rows, got)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions
        res.problems.append(f"the FMU could not be run at a communication step of {h:g} s ({n} samples): {exc}")


def _reference_problem(d, tol, sens, carried_differences=()):
    """The problem of an FMU that misses the target ``tol`` by ``d`` (mm), with what explains it:
    the model the FMU carries differs from the reference (``carried_differences``: such a mix-up
    is otherwise easily blamed on friction), or the reference itself moves by ``sens`` (mm) when its
    commands are perturbed by 1e-12 mm, when that is as far: stick/slip decisions amplify rounding,
    and two compilations of the same C round differently (a maximum says nothing of where: a
    float32 FMU differed by less than such a sensitivity, so it is no pass, only a reason)."""
    msg = f"FMU and reference simulator differ by {d:.3g} mm (> {tol:g} mm)"
    if carried_differences:
        return msg + (f": the FMU carries another model (its resources/model.json differs from the "
                      f"reference in {', '.join(carried_differences)})")
    if sens >= d:
        # a model whose prediction is decided by rounding would pass on the tolerance alone
        # (EMPS's r2c2: 5.9e-8 mm FMU difference, 2.4e-3 mm rounding sensitivity)
        return msg + (f"; the reference itself moves by {sens:.3g} mm when its commands are perturbed by "
                      f"1e-12 mm (friction stick-slip amplifies rounding on this trace), so the model's "
                      f"prediction is determined only to {sens:.3g} mm here"
                      + (f", {sens / d:.3g}x this difference (fdid identify's structure table flags such "
                         f"structures 'not determined'; an unflagged one is not)" if sens > 100 * d else "")
                      + f"; if that is the cause, --tolerance {1.05 * sens:.2g} accepts it")
    return msg + (f", more than the reference itself moves when its commands are perturbed by 1e-12 mm "
                  f"({sens:.3g} mm): the FMU does not compute the reference model")


def _maxdiff(a, b):
    d = np.abs(np.asarray(a) - np.asarray(b))
    return float(np.max(d)) if np.isfinite(d).all() else float("inf")


def _against_measurement(res, model, trace, cmds, out):
    """Tracking- and contour-error discrepancy of the FMU's positions against the measurement."""
    from ..metrics import contour_error, measured_position
    axes = model.axes
    sides = {a: model.position_side(a) for a in axes}
    act = {a: np.asarray(measured_position(trace, a, sides[a]), float) for a in axes
           if trace.has(a, "tool" if sides[a] == "tool" else "act")}
    res.unmeasured = [a for a in axes if a not in act]
    for a, x in act.items():
        d = ((cmds[a] - out[("pos", a)]) - (cmds[a] - x)) * 1e3
        res.axes[a] = {"rms_um": float(np.sqrt(np.mean(d ** 2))), "max_um": float(np.max(np.abs(d)))}
    if len(act) >= 2:
        a, b = list(act)[:2]
        cxy = np.column_stack([cmds[a], cmds[b]])
        ce_pred = contour_error(cxy, np.column_stack([out[("pos", a)], out[("pos", b)]]))
        ce_meas = contour_error(cxy, np.column_stack([act[a], act[b]]))
        d = (ce_pred - ce_meas) * 1e3
        res.contour = {"axes": [a, b], "rms_um": float(np.sqrt(np.mean(d ** 2))),
                       "max_um": float(np.max(np.abs(d)))}


def _model_description(fmu_path):
    """The FMU's model description, or InputError when it is not a zip archive or its
    modelDescription.xml is missing or unreadable (before fmpy is asked to run it)."""
    from fmpy import read_model_description
    try:
        with zipfile.ZipFile(fmu_path) as zf:
            if "modelDescription.xml" not in zf.namelist():
                raise InputError("is not an FMU: the archive has no modelDescription.xml", source=str(fmu_path))
    except zipfile.BadZipFile:
        raise InputError("is not an FMU (not a zip archive)", source=str(fmu_path)) from None
    try:
        return read_model_description(str(fmu_path), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy / lxml raise plain exceptions on a damaged file
        raise InputError(f"the FMU's modelDescription.xml cannot be read ({exc})", source=str(fmu_path)) from None
