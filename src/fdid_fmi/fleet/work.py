"""One fleet entry, start to finish: identify -> export -> validate -> diagnose -> compare.

:func:`run_entry` is what a worker (local process or Dask worker) executes. It takes a
:class:`WorkItem` (plain, picklable), writes the entry's outputs into its own folder, each file
atomically (temporary file in the same folder, then ``os.replace``; :mod:`fdid_fmi.outputs`), and
returns an :class:`EntryResult`. ``entry.json`` is written last: its presence with the entry's
input hash and the sha256 of every output it lists is what marks the work as done, so a worker
killed half-way (also one rebuilding the entry for other inputs) leaves no result that a rerun
could mistake for a finished one. A failure is kept (not retried) only when it follows from the
inputs (:func:`from_inputs`): a compiler missing on a worker or a full disk is retried. A failed
entry lists no outputs: what it wrote before failing (a model and FMU never validated) is removed.
The cheap checks of the data (scale, the held-out traces' sample time) come before identification.

Output folder ``OUT/entries/<machine>__<axis>/``:

``model.json``            the identified model (``fdid identify`` with the entry's options)
``<machine>_<axis>.fmu``  FMI co-simulation FMU (``fdid export``)
``validation.json``       the FMU through fmpy vs reference simulator and measurement, per trace
``diagnosis.json``        effects found/added and the error before/after (when ``diagnose``)
``model_diagnosed.json``  the model with the kept effects (when diagnosis kept any)
``entry.html``            the entry's report
``entry.json``            :class:`EntryResult`
"""
from __future__ import annotations

import json
import os
import socket
import time
import traceback
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..errors import FdidError, InputError, naming
from .compare import ChangeReport, ModelSignature, Thresholds, compare_models, model_signature
from .manifest import EntrySpec, file_digest, identify_args, manifest_words

__all__ = ["StageTimes", "ValidationFigures", "PreviousModel", "WorkItem", "EntryResult", "run_entry",
           "validate_entry_fmu", "validation_figures", "validation_failure", "ENTRY_FILE"]

ENTRY_FILE = "entry.json"


@dataclass
class StageTimes:
    """Wall time of each stage of one entry [s] (0 for a stage not run or reused)."""

    read_s: float = 0.0
    identify_s: float = 0.0
    export_s: float = 0.0
    validate_s: float = 0.0
    diagnose_s: float = 0.0
    compare_s: float = 0.0
    total_s: float = 0.0


@dataclass
class ValidationFigures:
    """The FMU on one trace: discrepancy to the measurement and agreement with the reference.

    ``passed`` is ``fdid validate``'s verdict (:attr:`fdid_fmi.fmu.validate.ValidationResult.ok`:
    no fmpy problem, no non-finite output, FMU within the tolerance of the reference simulator);
    None in results written before it was recorded. The fleet also needs the discrepancy to the
    measurement: a figure that is missing (the trace has no measured position of the axis) or not
    finite fails the entry's validation as well (:meth:`failures`).
    """

    trace: str
    rms_um: float
    max_um: float
    max_abs_diff_reference_mm: float
    problems: list = field(default_factory=list)
    passed: bool | None = None

    def failures(self):
        """Why this validation fails the entry (one short text each; empty when it passes)."""
        out = [f"{self.trace}: {p}" for p in self.problems]
        if self.passed is False and not out:
            out.append(f"{self.trace}: fdid validate did not pass the FMU")
        if not all(isinstance(x, (int, float)) and np.isfinite(x) for x in (self.rms_um, self.max_um)):
            out.append(f"{self.trace}: no finite tracking-error discrepancy of the FMU to the measurement "
                       f"(the trace has no measured position of the axis, or the figure is not finite)")
        return out

    @property
    def ok(self):
        return not self.failures()


@dataclass(frozen=True)
class PreviousModel:
    """The last model of the same axis (from a previous fleet result).

    ``spec`` and ``trace_digests`` say which traces it was made from: when they are unchanged, the
    old model's error on them is recomputed with the running software (so that both sides of the
    comparison use the same simulator); otherwise the stored ``errors_um`` are used.
    """

    model_path: str
    signature: dict
    errors_um: dict
    source: str
    spec: dict | None = None
    trace_digests: tuple = ()


@dataclass(frozen=True)
class WorkItem:
    """Everything :func:`run_entry` needs (picklable; no open files, no clients)."""

    spec: EntrySpec
    entry_dir: str
    input_hash: str
    version: str
    previous: PreviousModel | None = None
    thresholds: dict = field(default_factory=dict)
    compare_key: str | None = None


@dataclass
class EntryResult:
    """Outcome of one entry.

    Attributes
    ----------
    machine, axis : str
    status : ``ok``, ``failed``, or ``validation_failed``: every stage ran but the FMU's validation
             on a held-out trace found problems (:meth:`ValidationFigures.failures`; ``error``
             names them); its outputs are kept for inspection and the next run redoes it
    input_hash : str          content hash of traces + options + version (see manifest.entry_hash)
    error : str or None       the one-line reason of a failure
    deterministic : bool      the failure follows from the inputs (bad file, option, data): a rerun
                              with the same inputs skips it; other failures are retried
    outputs : dict            name -> file path relative to the entry folder (none when ``failed``)
    timings : StageTimes
    signature : ModelSignature or None
    errors_um : dict          channel (``motor``, ``tool``) -> RMS of the model's free-run position
                              error on the entry's traces [µm]
    validation : list of ValidationFigures
    effects_added : list of dict   what diagnosis kept
    change : ChangeReport or None  comparison with the previous model of the axis
    compare_key : str or None
    spec : dict               the manifest entry (EntrySpec.to_dict())
    trace_digests : list      sha256 of each trace file used
    worker : str              host:pid that did the work
    finished_utc : str
    reused_build : bool       identification, export, validation and diagnosis were reused from a
                              finished run with the same inputs (only the comparison was redone)
    output_digests : dict     name -> sha256 of each output file as this result wrote it: a file
                              that another (killed) run has since replaced is not taken as this
                              result's
    notes : list of str       how the traces were read where that may be wrong (units assumed or
                              doubtful: ``trace.meta["notes"]``), each ``<file>: <note>``
    """

    machine: str
    axis: str
    status: str
    input_hash: str
    error: str | None = None
    deterministic: bool = False
    outputs: dict = field(default_factory=dict)
    timings: StageTimes = field(default_factory=StageTimes)
    signature: ModelSignature | None = None
    errors_um: dict = field(default_factory=dict)
    validation: list = field(default_factory=list)
    effects_added: list = field(default_factory=list)
    change: ChangeReport | None = None
    compare_key: str | None = None
    spec: dict = field(default_factory=dict)
    trace_digests: list = field(default_factory=list)
    worker: str = ""
    finished_utc: str = ""
    reused_build: bool = False
    output_digests: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def key(self):
        return f"{self.machine}/{self.axis}"

    @property
    def ok(self):
        return self.status == "ok"

    def to_dict(self):
        from ..model import jsonable
        return jsonable(asdict(self))

    @classmethod
    def from_dict(cls, d):
        d = dict(d)
        d["timings"] = StageTimes(**d.get("timings", {}))
        d["signature"] = ModelSignature(**d["signature"]) if d.get("signature") else None
        d["validation"] = [ValidationFigures(**v) for v in d.get("validation", [])]
        d["change"] = ChangeReport.from_dict(d.get("change"))
        return cls(**d)


# ----------------------------------------------------------------------------- stages
def validate_entry_fmu(fmu_path, trace, model, axis, name=None) -> ValidationFigures:
    """The one call into FMU validation (:func:`fdid_fmi.api.validate`, ``fdid validate``'s).

    Returns the FMU's tracking-error discrepancy to the measurement on ``axis`` [µm], its largest
    difference from the reference simulator [mm] and the problems found; ``name``: the trace's name
    in them (default its file path).
    """
    from ..api import validate
    return validation_figures(validate(fmu_path, trace, model=model), trace, axis, name)


def validation_figures(res, trace, axis, name=None) -> ValidationFigures:
    """The fleet's figures of a :class:`~fdid_fmi.fmu.validate.ValidationResult` on ``trace``, with
    its verdict (``res.ok``, the one ``fdid validate`` gives as its exit code). ``name``: the
    trace's name in them; the fleet gives the path as the manifest gives it
    (:meth:`EntrySpec.trace_name`: the file name alone named two held-out traces
    ``night1/m01_x.csv`` and ``night2/m01_x.csv`` alike); default the file name."""
    d = res.axes.get(axis, {})
    return ValidationFigures(trace=Path(str(trace.source)).name if name is None else str(name),
                             rms_um=float(d.get("rms_um", float("nan"))),
                             max_um=float(d.get("max_um", float("nan"))),
                             max_abs_diff_reference_mm=float(res.max_abs_diff_reference_mm),
                             problems=list(res.problems), passed=bool(res.ok))


def validation_failure(validation):
    """One line naming why the entry's FMU validation fails (None when every trace passes)."""
    reasons = [r for v in validation for r in v.failures()]
    if not validation:
        reasons = ["the FMU was not validated on any trace"]
    return _one_line("FMU validation failed: " + "; ".join(reasons)) if reasons else None


def channel_errors(model, traces, axis):
    """RMS free-run position error [µm] of ``model`` over ``traces`` per measured channel, and the
    residuals (measured - predicted, mm) on the first trace.

    Channels: ``motor`` (the encoder, ``act``) and ``tool`` (the ``tool`` channel, when the
    traces have one and the model predicts the motor side; a model fitted on the tool side has
    only ``tool``). The tool channel is compared with the model's tool-side output where it has
    one (it carries the drive train's lost motion), else with its motor-side position.
    """
    from ..simulate import simulate
    side = model.position_side(axis)
    acc, residuals = {}, {}
    for k, tr in enumerate(traces):
        out = simulate(model, tr).axes[axis]
        pred = {"motor": out["position"], "tool": out.get("tool_position", out["position"])}
        chans = {"tool": "tool"} if side == "tool" else {"motor": "act", "tool": "tool"}
        for ch, role in chans.items():
            if not tr.has(axis, role):
                continue
            r = np.asarray(tr.get(axis, role), float) - pred[ch]
            s, n = acc.get(ch, (0.0, 0))
            acc[ch] = (s + float(r @ r), n + r.size)
            if k == 0:
                residuals[ch] = (r, np.asarray(tr.cmd(axis), float), float(tr.Ts))
    errors = {ch: float(np.sqrt(s / n) * 1e3) for ch, (s, n) in acc.items()}
    return errors, residuals


def _read_traces(spec: EntrySpec, notes=None):
    """The entry's traces, read as ``fdid identify`` reads them; the readers' notes (units assumed
    or doubtful) and, for the identification trace, ``fdid identify``'s notes on a position that
    does not follow its command (:func:`~fdid_fmi.io.follow.follow_notes`) are appended to
    ``notes`` as each trace is read (``<trace name>: <note>``, with the advice in the manifest's
    words), so that those of the traces read before a failing one are kept."""
    from ..api import read_trace
    from ..io.follow import follow_notes
    traces = []
    for k, p in enumerate(spec.traces):
        args = identify_args(p, spec)
        # the reader names the resolved path; the manifest's words are wanted; the reader's notes
        # are kept in EntryResult.notes
        with naming(spec.trace_name(k), replaces=p):
            # 'range' selects data of the identification trace; the held-out ones are whole
            tr = read_trace(p, mapping=args.map, units=args.unit, ranges=None if k else args.range,
                            layout=args.layout, axes=args.axes)
        if notes is not None:
            said = tr.meta.get("notes", []) + (follow_notes(tr, [spec.axis]) if k == 0 else [])
            notes += [manifest_words(f"{spec.trace_name(k)}: {n}") for n in said]
        traces.append(tr)
    return traces


def _check_traces(spec: EntrySpec, traces):
    """The cheap checks of the data, before identification: the identification trace has the
    entry's axis with 'cmd' and 'act'; every trace's positions are of a usable scale (``fdid
    identify``'s :func:`~fdid_fmi.pipeline.identify.check_data_range`: positions x1e10 were identified
    and then failed validation with a misleading message); each held-out trace has the axis's
    command and the identification trace's sample time (the model's, which the FMU runs at: a
    held-out trace at 2 ms against 1 ms failed only after identification and export)."""
    from ..pipeline.identify import check_data_range
    ax, train = spec.axis, traces[0]
    if ax not in train.axes or not (train.has(ax, "cmd") and train.has(ax, "act")):
        raise InputError(f"the trace has no axis '{ax}' with 'cmd' and 'act' channels "
                         f"(axes found: {train.axes}); check the entry's map", source=spec.trace_name(0))
    for k, tr in enumerate(traces):
        name = spec.trace_name(k)
        if k and not tr.has(ax, "cmd"):
            raise InputError(f"this held-out trace has no commanded position of axis '{ax}' (axes found: "
                             f"{tr.axes}); the FMU cannot be validated on it: check the entry's map",
                             source=name)
        try:
            check_data_range(tr, [ax])
        except InputError as exc:
            raise InputError(exc.message, source=name, column=exc.column, row=exc.row) from None
        if k and abs(tr.Ts - train.Ts) > 1e-9 * train.Ts:
            raise InputError(f"this held-out trace is sampled at {tr.Ts:g} s, the identification trace "
                             f"{spec.trace_name(0)} (and so the model and its FMU) at {train.Ts:g} s; give "
                             f"held-out traces sampled alike", source=name, column=tr.meta.get("time_column"))


def _identify(spec, trace):
    """``fdid identify``'s checks of the options (made at manifest load as well; again here for an
    :class:`EntrySpec` made in Python) and its identification of the entry's axis."""
    from ..api import identify
    from ..pipeline.identify import check_arguments, nondefault_options, structure_is_auto
    args = identify_args(spec.traces[0], spec)
    check_arguments(args)
    options = nondefault_options(args)
    if args.jobs is None and structure_is_auto(args):   # the fleet runs its entries in parallel already
        options["jobs"] = 1
    return identify(trace, args.method, axes=args.axis or [spec.axis], **options)


def _save_json(path, data):
    from ..model import jsonable
    from ..outputs import atomic_write
    atomic_write(path, json.dumps(jsonable(data), indent=1, default=float, allow_nan=False))


def _save_model(model, path):
    from ..outputs import atomic_path
    with atomic_path(path) as tmp:
        model.save(tmp)


def outputs_intact(entry_dir, res: EntryResult):
    """Every output file of ``res`` is present with the bytes ``res`` wrote (its digest).

    A worker killed while rebuilding an entry for other inputs leaves the new model or FMU beside
    the old ``entry.json``; with the old inputs back, that mixture must not pass as done.
    """
    entry_dir = Path(entry_dir)
    if set(res.output_digests) != set(res.outputs):
        return False
    return all((entry_dir / f).is_file() and file_digest(entry_dir / f) == res.output_digests[name]
               for name, f in res.outputs.items())


def _existing(entry_dir: Path, input_hash):
    """A finished, successful result with the same inputs whose output files are all intact."""
    p = entry_dir / ENTRY_FILE
    if not p.is_file():
        return None
    try:
        res = EntryResult.from_dict(json.loads(p.read_text()))
    except (ValueError, TypeError, KeyError):
        return None
    if res.input_hash != input_hash or not res.ok:
        return None
    if not outputs_intact(entry_dir, res):
        return None
    return res


def run_entry(item: WorkItem) -> EntryResult:
    """Run one fleet entry (see the module docstring); never raises for a failing entry.

    Returns
    -------
    EntryResult  with ``status`` ``ok``, or ``failed`` / ``validation_failed`` and a one-line
                 ``error``
    """
    from ..model import load_model
    spec = item.spec
    t_start = time.perf_counter()
    res = EntryResult(spec.machine, spec.axis, "failed", item.input_hash, spec=spec.to_dict(),
                      worker=f"{socket.gethostname()}:{os.getpid()}")
    out = Path(item.entry_dir)
    try:
        if spec.error:
            raise InputError(spec.error)
        out.mkdir(parents=True, exist_ok=True)
        tm = StageTimes()
        t0 = time.perf_counter()
        notes = res.notes = []      # filled while reading: a failing entry keeps its notes
        traces = _read_traces(spec, notes)
        _check_traces(spec, traces)
        digests = [file_digest(p) for p in spec.traces]
        tm.read_s = time.perf_counter() - t0
        old = _existing(out, item.input_hash)
        if old is not None:
            res = old
            res.reused_build = True
            res.worker = f"{socket.gethostname()}:{os.getpid()}"
            tm = res.timings
            model = load_model(out / res.outputs["model"])
        else:
            model = _build(spec, traces, out, res, tm)
        res.notes = notes
        if item.previous is not None:
            t0 = time.perf_counter()
            res.change = _compare(item, model, traces)
            tm.compare_s = time.perf_counter() - t0
            res.compare_key = item.compare_key
        else:
            res.change, res.compare_key = None, None
        # the validation's verdict decides (an entry is not "ok" whatever it finds); not
        # kept for a rerun: the FMU's binary and its run depend on the worker's compiler and fmpy
        failure = validation_failure(res.validation)
        res.status, res.error, res.deterministic = ("validation_failed" if failure else "ok"), failure, False
        res.spec, res.trace_digests = spec.to_dict(), digests
        tm.total_s = (time.perf_counter() - t_start if old is None else
                      tm.read_s + tm.identify_s + tm.export_s + tm.validate_s + tm.diagnose_s + tm.compare_s)
        res.timings = tm
    except FdidError as exc:       # in the manifest's words (options.v_tilde, not --v-tilde)
        res.status, res.error, res.deterministic = "failed", _one_line(manifest_words(exc)), from_inputs(exc, out)
    except Exception as exc:  # noqa: BLE001 - one failing entry must not stop the fleet
        last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
        where = f" ({Path(last.filename).name}:{last.lineno})" if last else ""
        res.status, res.error, res.deterministic = "failed", _one_line(f"{type(exc).__name__}: {exc}{where}"), False
    res.finished_utc = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    built = res.status in ("ok", "validation_failed")     # every stage ran: outputs and a report
    if res.status == "failed":
        res.timings.total_s = time.perf_counter() - t_start
        _drop_outputs(out, res)
        # a failure may come from the comparison (the previous model): it holds for this previous
        # result and these thresholds only
        res.compare_key = item.compare_key
    try:
        if out.is_dir() or built:
            if built:
                _entry_report(res, out)
                res.output_digests = {name: file_digest(out / f) for name, f in res.outputs.items()}
            _save_json(out / ENTRY_FILE, res.to_dict())
    except FdidError as exc:       # cannot write the result: report it, the rerun retries
        res.status, res.error, res.deterministic = "failed", _one_line(str(exc)), False
    return res


def _one_line(text):
    return " ".join(str(text).split())[:500]


def _drop_outputs(out: Path, res: EntryResult):
    """A failed entry has no outputs: the files it wrote before failing (a model and FMU never
    validated, when the failure came after identification and export) are removed and not listed
    (they were listed as the entry's outputs in fleet.json). The entry's other files are not
    touched; the next run builds the entry again (only a success is reused)."""
    for f in res.outputs.values():
        p = out / f
        if p.parent == out:         # an output's name, never a path elsewhere
            try:
                p.unlink(missing_ok=True)
            except OSError:
                pass
    res.outputs, res.output_digests = {}, {}


def from_inputs(exc, entry_dir) -> bool:
    """Whether a failure follows from the entry's inputs (traces, options, previous model), so that
    a rerun with the same inputs may reuse it. Not so: the C compiler missing on this worker or
    failing (killed, out of memory), an output of the entry's own folder that cannot be written
    (disk full) -- those were kept as failed by every rerun until the inputs changed."""
    from ..fmu.build import BuildError, CompilerNotFound, NoRoomError
    if isinstance(exc, (BuildError, CompilerNotFound, NoRoomError)):      # NoRoomError: a full disk
        return False
    if isinstance(exc, InputError):
        if exc.source:
            try:
                Path(exc.source).resolve().relative_to(Path(entry_dir).resolve())
                return False                     # cannot write the entry's own output
            except (ValueError, OSError):
                pass
    return True


def _build(spec, traces, out, res, tm):
    """Identify, export, validate and (optionally) diagnose; fills ``res``; returns the model."""
    from ..api import diagnose, export_fmu
    from ..model import DriveModel
    train = traces[0]
    held = traces[1:] or traces[:1]
    t0 = time.perf_counter()
    with naming(spec.trace_name(0)):     # as fdid identify names its trace
        model = _identify(spec, train)
    if not isinstance(model, DriveModel):
        raise InputError("the fleet needs a state-space model (method pole-search or mimo), "
                         "not a quasi-static one", column="method")
    _save_model(model, out / "model.json")
    tm.identify_s = time.perf_counter() - t0
    res.outputs = {"model": "model.json"}

    t0 = time.perf_counter()
    fmu = export_fmu(model, out / f"{spec.machine}_{spec.axis}.fmu".replace("-", "_"), fmi=spec.fmi).path
    tm.export_s = time.perf_counter() - t0
    res.outputs["fmu"] = fmu.name

    t0 = time.perf_counter()
    res.validation = []
    for k, tr in enumerate(held, start=1 if len(traces) > 1 else 0):
        with naming(spec.trace_name(k)):
            res.validation.append(validate_entry_fmu(fmu, tr, model, spec.axis, spec.trace_name(k)))
    _save_json(out / "validation.json", [asdict(v) for v in res.validation])
    tm.validate_s = time.perf_counter() - t0
    res.outputs["validation"] = "validation.json"

    final = model
    if spec.diagnose:
        t0 = time.perf_counter()
        diag = diagnose(model, train, traces[1] if len(traces) > 1 else None,
                        detectors=list(spec.detectors) if spec.detectors else None, jobs=1)
        tm.diagnose_s = time.perf_counter() - t0
        _save_json(out / "diagnosis.json", diag.to_json())
        res.outputs["diagnosis"] = "diagnosis.json"
        res.effects_added = [dict(e) for e in diag.effects_added]
        if diag.effects_added:
            final = diag.final
            _save_model(final, out / "model_diagnosed.json")
            res.outputs["model_diagnosed"] = "model_diagnosed.json"
    res.signature = model_signature(model, spec.axis)
    res.signature.effects = model_signature(final, spec.axis).effects
    res.errors_um, _ = channel_errors(model, traces, spec.axis)
    res.outputs["report"] = "entry.html"
    return model


def _compare(item: WorkItem, model, traces):
    from ..model import load_model
    prev = item.previous
    old = load_model(prev.model_path)
    if item.spec.axis not in getattr(old, "axes", []):
        raise InputError(f"the previous model has no axis '{item.spec.axis}'", source=prev.model_path)
    on_new, residuals = channel_errors(old, traces, item.spec.axis)
    new_on_new, _ = channel_errors(model, traces, item.spec.axis)
    on_old = _old_on_old(prev, old, item.spec.axis)
    errors = {}
    for ch in sorted(set(on_new) | set(on_old)):
        errors[ch] = {"old_on_old": on_old.get(ch), "old_on_new": on_new.get(ch),
                      "new_on_new": new_on_new.get(ch)}
    new_sig = model_signature(model, item.spec.axis)
    new_sig.effects = _final_effects(item, model)
    return compare_models(ModelSignature(**prev.signature), new_sig, errors, residuals,
                          Thresholds.from_dict(item.thresholds), previous=prev.source)


def _old_on_old(prev: PreviousModel, old, axis):
    """The old model's error on its own traces, recomputed when those files are unchanged."""
    from .manifest import file_digest
    if prev.spec and prev.trace_digests and all(
            file_digest(p) == d for p, d in zip(prev.spec.get("traces", []), prev.trace_digests)):
        sp = dict(prev.spec)
        sp["traces"] = tuple(sp["traces"])
        sp["identify"] = tuple(sp["identify"])
        sp["detectors"] = tuple(sp["detectors"]) if sp.get("detectors") else None
        sp["names"] = tuple(sp.get("names") or ())
        errors, _ = channel_errors(old, _read_traces(EntrySpec(**sp)), axis)
        return errors
    return dict(prev.errors_um)


def _final_effects(item, model):
    p = Path(item.entry_dir) / "model_diagnosed.json"
    if p.is_file():
        from ..model import load_model
        return model_signature(load_model(p), item.spec.axis).effects
    return model_signature(model, item.spec.axis).effects


def _entry_report(res: EntryResult, out: Path):
    from ..outputs import atomic_write
    from ..report import Report
    rep = Report(f"Fleet entry {res.key}", meta={"input hash": res.input_hash[:16], "worker": res.worker})
    sig = res.signature
    lines = [f"Status: {res.status}." + (f" {res.error}" if res.error else "")]
    if sig is not None:
        # a model without friction has neither figure (None): "none", not 0
        peak = "none" if sig.friction_peak_um is None else f"{sig.friction_peak_um:.3g} µm"
        vt = "none" if sig.v_tilde_mm_s is None else f"{sig.v_tilde_mm_s:.3g} mm/s"
        lines.append("Poles [Hz]: " + ", ".join(f"{re:.3g}{im:+.3g}j" for re, im in sig.poles_hz)
                     + f"; friction step peak {peak}; v_tilde {vt}; effects {sig.effects or 'none'}.")
    if res.change is not None:
        lines.append(f"Against {res.change.previous}: {res.change.summary}.")
    rep.add_text("\n\n".join(lines), heading="Summary")
    if res.validation:
        rep.add_table("validation", [{"trace": v.trace, "e RMS discrepancy [µm]": v.rms_um,
                                      "e MAX discrepancy [µm]": v.max_um,
                                      "max |FMU - reference| [mm]": v.max_abs_diff_reference_mm,
                                      "problems": len(v.problems),
                                      "passes": "yes" if v.ok else "no"} for v in res.validation],
                      caption="The FMU through fmpy on the held-out traces (the training trace when "
                              "there is none).")
    if res.errors_um:
        rep.add_table("errors", [{"channel": k, "free-run position error RMS [µm]": v}
                                 for k, v in res.errors_um.items()])
    if res.change is not None and res.change.evidence:
        rep.add_text("\n\n".join(res.change.evidence), heading="Evidence of change")
    rep.add_table("timings", [{"stage": k, "wall time [s]": v} for k, v in asdict(res.timings).items()])
    rep.add_data("entry", res.to_dict())
    atomic_write(out / "entry.html", rep.html())
