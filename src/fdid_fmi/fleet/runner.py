"""Run a fleet: skip what is done, submit the rest to a process pool or a Dask cluster, collect.

:func:`run_fleet` is the Python API of ``fdid fleet run``.

Execution
---------
* default: a local :func:`fdid_fmi.workers.process_pool` (``spawn`` processes, so no state
  leaks from the caller; one BLAS thread each) with ``workers`` processes (default: the
  machine's cores);
* ``scheduler="tcp://host:8786"`` (or ``client=`` an existing ``dask.distributed.Client``, e.g.
  of a ``LocalCluster``): every entry is one ``Client.submit`` task, results are collected with
  ``distributed.as_completed``. The workers need the same Python environment: ``fdid-fmi`` and
  its dependencies (numpy, scipy, fmpy, control, matplotlib, dask[distributed], threadpoolctl)
  and gcc (FMU export compiles C), and they must see the manifest's trace files and ``--out``
  at the same paths (a shared file system).

Both paths submit the same function, :func:`fdid_fmi.fleet.work.run_entry`, so the results are the
same. There is no scheduling here beyond ``submit`` and ``as_completed``.

Reliability
-----------
Each entry has a content hash (:func:`~.manifest.entry_hash`: trace bytes, options, software
version = package version + a digest of the package's source, :func:`~.manifest.software_version`). An entry whose ``entry.json`` holds the same hash, a success (or a failure that follows
from its inputs) and whose outputs are the ones it wrote (sha256) is not submitted again; with a
previous fleet result, the comparison is keyed as well (hash + previous model file + thresholds),
for a failure too. A killed worker loses only
the entries it was running: on a Dask cluster the scheduler re-runs them on another worker (or
they are reported ``failed`` as not deterministic); a broken local pool is replaced once and the
unfinished entries resubmitted. Everything left unfinished is done by the next run.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from .. import __version__
from ..errors import InputError
from ..outputs import remove_orphan_temp_files
from ..workers import process_pool, worker_count
from .compare import Thresholds
from .manifest import Manifest, entry_hash, file_digest, load_manifest, software_version
from .work import ENTRY_FILE, EntryResult, PreviousModel, WorkItem, outputs_intact, run_entry

FLEET_FILE = "fleet.json"
FLEET_HTML = "fleet.html"
FORMAT = "fdid-fmi-fleet"
FORMAT_VERSION = 1

__all__ = ["FleetResult", "run_fleet", "load_fleet_result", "FLEET_FILE", "FLEET_HTML"]


@dataclass
class FleetResult:
    """Outcome of :func:`run_fleet`.

    Attributes
    ----------
    out : str                 output folder
    manifest : str
    previous : str or None    the previous fleet folder compared with
    previous_version : str    software version of the previous run (None without one)
    executor : str            ``local pool (N processes)`` or ``dask <scheduler>``
    workers : int
    entries : list of EntryResult, in manifest order
    executed : list of str    keys of the entries run now (work done)
    skipped : list of str     keys reused from a finished run with the same inputs
    thresholds : Thresholds
    wall_s : float
    started_utc, version : str
    """

    out: str
    manifest: str
    previous: str | None
    executor: str
    workers: int
    entries: list = field(default_factory=list)
    executed: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    thresholds: Thresholds = field(default_factory=Thresholds)
    wall_s: float = 0.0
    started_utc: str = ""
    version: str = __version__
    previous_version: str | None = None

    @property
    def failed(self):
        """Entries that did not complete, including those whose FMU validation failed."""
        return [e for e in self.entries if not e.ok]

    @property
    def validation_failed(self):
        """Entries that ran every stage but whose FMU validation failed (status ``validation_failed``)."""
        return [e for e in self.entries if e.status == "validation_failed"]

    @property
    def changed(self):
        return [e for e in self.entries if e.ok and e.change is not None and e.change.changed]

    def entry(self, key):
        return next((e for e in self.entries if e.key == key), None)

    def to_dict(self):
        return {"format": FORMAT, "format_version": FORMAT_VERSION, "out": self.out, "manifest": self.manifest,
                "previous": self.previous, "executor": self.executor, "workers": self.workers,
                "executed": list(self.executed), "skipped": list(self.skipped),
                "thresholds": self.thresholds.to_dict(), "wall_s": self.wall_s,
                "started_utc": self.started_utc, "version": self.version,
                "previous_version": self.previous_version,
                "counts": {"entries": len(self.entries), "ok": sum(e.ok for e in self.entries),
                           "failed": len(self.failed), "validation_failed": len(self.validation_failed),
                           "changed": len(self.changed)},
                "table": table_rows(self), "entries": [e.to_dict() for e in self.entries]}

    @classmethod
    def from_dict(cls, d, source="fleet.json"):
        if d.get("format") != FORMAT:
            raise InputError(f"not a fleet result (format {d.get('format')!r})", source=source)
        return cls(out=d["out"], manifest=d["manifest"], previous=d.get("previous"), executor=d["executor"],
                   workers=d["workers"], entries=[EntryResult.from_dict(e) for e in d["entries"]],
                   executed=d.get("executed", []), skipped=d.get("skipped", []),
                   thresholds=Thresholds.from_dict(d.get("thresholds", {})), wall_s=d.get("wall_s", 0.0),
                   started_utc=d.get("started_utc", ""), version=d.get("version", ""),
                   previous_version=d.get("previous_version"))

    def summary(self):
        """Lines a maintenance engineer reads first."""
        from .report import summary_lines
        return summary_lines(self)


def _worst(values):
    """Largest of ``values``, NaN (not computed) when one of them is None or NaN, None when there
    are none: ``max`` let a NaN vanish when it came after a number; then a figure not computed
    counted as ``inf`` and fleet.html showed "inf" (a diverged FMU's figure) where fleet.json has
    null. A genuine ``inf`` stays ``inf``."""
    vals = [float("nan") if v is None or v != v else float(v) for v in values]
    if any(v != v for v in vals):
        return float("nan")
    return max(vals, default=None)


def table_rows(fr: FleetResult):
    """One flat row per entry: the fleet's JSON table (and the HTML table)."""
    rows = []
    for e in fr.entries:
        v = e.validation
        rows.append({
            "machine": e.machine, "axis": e.axis, "status": e.status,
            "changed": bool(e.change.changed) if e.change else None,
            "change": e.change.summary if (e.change and e.change.changed) else "",
            "error": e.error or "",
            "fmu_rms_um": _worst(x.rms_um for x in v),
            "fmu_max_um": _worst(x.max_um for x in v),
            "fmu_vs_reference_mm": _worst(x.max_abs_diff_reference_mm for x in v),
            "model_rms_motor_um": e.errors_um.get("motor"), "model_rms_tool_um": e.errors_um.get("tool"),
            "friction_peak_um": e.signature.friction_peak_um if e.signature else None,
            "effects_added": [x.get("kind") for x in e.effects_added],
            "notes": list(e.notes),
            "wall_s": e.timings.total_s,
            "run": "done now" if e.key in fr.executed else "reused" if e.key in fr.skipped else "not run",
        })
    return rows


def load_fleet_result(folder) -> FleetResult:
    """Read ``FOLDER/fleet.json`` written by :func:`run_fleet`."""
    p = Path(folder)
    f = p / FLEET_FILE if p.is_dir() else p
    if not f.is_file():
        raise InputError("no fleet result here (fleet.json missing)", source=str(p))
    try:
        d = json.loads(f.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read the fleet result ({exc})", source=str(f)) from None
    if not isinstance(d, dict):
        raise InputError(f"not a fleet result (a JSON {type(d).__name__})", source=str(f))
    try:
        return FleetResult.from_dict(d, source=str(f))
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"a fleet result this version cannot read ({type(exc).__name__}: {exc}); "
                         f"expected fleet.json format {FORMAT} {FORMAT_VERSION} as fdid fleet run writes it",
                         source=str(f)) from None


# ----------------------------------------------------------------------------- planning
def _previous_models(previous):
    """key -> PreviousModel from a previous fleet folder, key -> why the previous model of that
    key cannot be used, the folder's name and the previous software version.

    The model file must be the one that fleet.json recorded (its sha256 in ``output_digests``): a
    later run into that folder, interrupted or failed, may have replaced ``model.json`` while
    fleet.json still holds the old signature and errors (the comparison mixed the two). Such an
    entry (and one whose recorded model is gone) gets an error naming the file instead of a
    comparison; a result written before the digests were recorded is taken as it is.
    """
    if previous is None:
        return {}, {}, None, None
    fr = load_fleet_result(previous)
    base = Path(previous) / "entries"
    out, problems = {}, {}
    for e in fr.entries:
        if not e.ok or e.signature is None or "model" not in e.outputs:
            continue
        mp = base / f"{e.machine}__{e.axis}" / e.outputs["model"]
        listed = f"{Path(previous) / FLEET_FILE} lists for {e.key}"
        digest = e.output_digests.get("model")
        if not mp.is_file():
            if digest:
                problems[e.key] = (f"the previous model {mp} is missing, though {listed} (removed since): "
                                   f"compare with another --previous folder, or run without it")
            continue
        if digest and file_digest(mp) != digest:
            problems[e.key] = (f"the previous model {mp} is not the one {listed} (its sha256 differs: "
                               f"replaced since, e.g. by a later run into that folder that was interrupted "
                               f"or failed); compare with another --previous folder, or run without it")
            continue
        out[e.key] = PreviousModel(str(mp.resolve()), asdict(e.signature), dict(e.errors_um),
                                   f"{Path(previous).name}/{e.key}", dict(e.spec) or None,
                                   tuple(e.trace_digests))
    return out, problems, str(Path(previous)), fr.version


def _compare_key(input_hash, prev: PreviousModel | None, thresholds: Thresholds):
    if prev is None:
        return None
    h = hashlib.sha256()
    h.update(input_hash.encode())
    h.update(file_digest(prev.model_path).encode())
    h.update(json.dumps(prev.errors_um, sort_keys=True).encode())
    h.update(json.dumps(thresholds.to_dict(), sort_keys=True).encode())
    return h.hexdigest()


def _finished(entry_dir: Path, input_hash, compare_key):
    """The entry's stored result when it is complete for these inputs (else None)."""
    p = entry_dir / ENTRY_FILE
    if not p.is_file():
        return None
    try:
        res = EntryResult.from_dict(json.loads(p.read_text()))
    except (OSError, ValueError, TypeError, KeyError):
        return None
    if res.input_hash != input_hash:
        return None
    if res.ok:
        if res.compare_key != compare_key:
            return None
        if not outputs_intact(entry_dir, res):
            return None
        return res
    # a failure follows from the inputs -- including the previous model it was compared with
    return res if res.deterministic and res.compare_key == compare_key else None


# ----------------------------------------------------------------------------- executors
class _LocalPool:
    """A local process pool behind the two calls the runner uses."""

    def __init__(self, workers):
        import multiprocessing
        self.workers = workers
        self.pool = process_pool(workers, multiprocessing.get_context("spawn"))
        self.name = f"local pool ({workers} processes)"

    def submit(self, fn, item):
        return self.pool.submit(fn, item)

    def as_completed(self, futures):
        from concurrent.futures import as_completed
        return as_completed(futures)

    def close(self, interrupted=False):
        """Shut the pool down; ``interrupted`` (Ctrl-C): without waiting, its workers terminated.
        A plain shutdown waits for the entries already handed to the workers (the running ones and
        one queued more, which a worker takes after its Ctrl-C): an entry that had not started
        would run in full after the interrupt. A terminated worker's outputs are atomic; its
        temporary files are removed by the runner."""
        if not interrupted:
            self.pool.shutdown(wait=True, cancel_futures=True)
            return
        # Python 3.11 has no public way to stop the workers (3.14: terminate_workers)
        procs = list((getattr(self.pool, "_processes", None) or {}).values())
        self.pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.terminate()
        for proc in procs:
            proc.join(timeout=10)


class _Dask:
    """A ``dask.distributed.Client`` behind the same two calls."""

    def __init__(self, scheduler=None, client=None):
        from distributed import Client
        self.own = client is None
        if client is None:
            try:
                client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:    # ValueError: not an address
                raise InputError(f"cannot connect to the Dask scheduler ({exc}); expected an address like "
                                 f"tcp://HOST:8786", source=str(scheduler)) from None
        self.client = client
        try:
            info = client.scheduler_info()
        except Exception:
            self.close()            # a client this runner opened is not left behind
            raise
        self.workers = len(info.get("workers", {}))
        self.name = f"dask {client.scheduler.address} ({self.workers} workers)"
        self.futures = []

    def submit(self, fn, item):
        fut = self.client.submit(fn, item, pure=False,
                                 key=f"fdid-fleet-{item.spec.dirname}-{item.input_hash[:12]}-{time.time_ns()}")
        self.futures.append(fut)
        return fut

    def as_completed(self, futures):
        from distributed import as_completed
        return as_completed(futures)

    def close(self, interrupted=False):
        """Close the client this runner opened; ``interrupted`` (Ctrl-C): first cancel the entries
        not finished (the cluster would go on with them after the command has ended). An
        entry a worker is running finishes there (a Dask task is not stopped); its outputs are
        atomic."""
        if interrupted and self.futures:
            self.client.cancel([f for f in self.futures if not f.done()])
        if self.own:
            self.client.close()


def _lost(item: WorkItem, exc) -> EntryResult:
    """Result of an entry whose worker died (not deterministic: the next run retries it)."""
    msg = " ".join(f"{type(exc).__name__}: {exc}".split())[:300]
    return EntryResult(item.spec.machine, item.spec.axis, "failed", item.input_hash,
                       error=f"worker lost while running this entry ({msg}); rerun to finish it",
                       deterministic=False,
                       finished_utc=datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"))


# ----------------------------------------------------------------------------- run
def _make_folder(path: Path) -> list:
    """Create the folder ``path`` (and its missing parents); return the folders this call created,
    deepest first (those :func:`_remove_empty` may take away again)."""
    created, p = [], path
    while not os.path.lexists(p) and p.parent != p:
        created.append(p)
        p = p.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_empty(created)
        raise InputError(f"cannot create the output folder ({exc.strerror or exc})", source=str(path.parent)) from None
    return created


def _remove_empty(created):
    """Remove the folders :func:`_make_folder` created, deepest first, while they are empty
    (never a folder that existed before, nor anything in it)."""
    for d in created:
        try:
            d.rmdir()
        except OSError:
            break


def _prepare(man, out, previous, scheduler, workers, client, thresholds):
    """The entries to run (those already done with the same inputs are skipped) and the executor
    (local pool or Dask cluster; None when nothing is to be done)."""
    if previous is not None and Path(previous).resolve() == out.resolve():
        raise InputError("--previous must be another fleet folder than --out", source=str(previous))
    prev_models, prev_problems, prev_name, prev_version = _previous_models(previous)
    workers = worker_count(workers)

    version = software_version()
    results: dict[str, EntryResult] = {}
    todo: list[WorkItem] = []
    skipped = []
    for spec in man.entries:
        h = entry_hash(spec, version)
        prev = prev_models.get(spec.key) if spec.error is None else None
        ck = _compare_key(h, prev, thresholds)
        edir = out / "entries" / spec.dirname
        if spec.error is not None:      # (its names may not be usable as a folder)
            results[spec.key] = EntryResult(spec.machine, spec.axis, "failed", h, error=spec.error,
                                            deterministic=True)
            continue
        if spec.key in prev_problems:   # not run: its comparison would mix two models
            results[spec.key] = EntryResult(spec.machine, spec.axis, "failed", h, error=prev_problems[spec.key],
                                            deterministic=True, spec=spec.to_dict())
            continue
        done = _finished(edir, h, ck)
        if done is not None:
            results[spec.key] = done
            skipped.append(spec.key)
            continue
        todo.append(WorkItem(spec, str(edir.resolve()), h, version, prev, thresholds.to_dict(), ck))

    ex = None
    if todo:
        if scheduler is not None or client is not None:
            ex = _Dask(scheduler, client)
        else:
            ex = _LocalPool(workers)
    return ex, todo, results, skipped, prev_name, prev_version, version


def run_fleet(manifest, out, previous=None, scheduler=None, workers=None, client=None, progress=True,
              retries=1) -> FleetResult:
    """Identify, export, validate, diagnose (and compare) every entry of a fleet manifest.

    Parameters
    ----------
    manifest : path of a ``.toml``/``.csv`` manifest, or a :class:`~.manifest.Manifest`
    out : folder for ``fleet.json``, ``fleet.html`` and ``entries/<machine>__<axis>/``
    previous : folder of a previous fleet result: each new model is compared with the last one of
        the same axis, and the report lists the axes that changed
    scheduler : address of a Dask scheduler (``tcp://host:8786``); default: a local process pool
    workers : processes of the local pool (None: every core, ``os.cpu_count()``)
    client : an existing ``dask.distributed.Client`` (e.g. of a ``LocalCluster``), instead of
        ``scheduler``
    progress : show a tqdm bar (entries done / failed, ETA) on stderr
    retries : times a broken local pool is replaced and its unfinished entries resubmitted

    Returns
    -------
    FleetResult  (also written to ``out/fleet.json`` and ``out/fleet.html``, atomically)
    """
    from .report import write_fleet_report
    t_start = time.perf_counter()
    started = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    man = manifest if isinstance(manifest, Manifest) else load_manifest(manifest)
    thresholds = Thresholds.from_dict(man.thresholds, source=f"{man.source} [thresholds]")
    out = Path(out)
    created = _make_folder(out / "entries")     # made now: an unwritable --out fails before any wait
    try:
        ex, todo, results, skipped, prev_name, prev_version, version = _prepare(
            man, out, previous, scheduler, workers, client, thresholds)
    except BaseException:       # no scheduler, a bad --previous, Ctrl-C: leave no empty output folder
        _remove_empty(created)
        raise
    executed = [w.spec.key for w in todo]
    bar = None
    if progress and todo:
        from tqdm import tqdm
        bar = tqdm(total=len(todo), desc="fleet", unit="entry", file=sys.stderr, dynamic_ncols=True)
    try:
        pending = list(todo)
        attempt = 0
        while pending:
            futures = {ex.submit(run_entry, item): item for item in pending}
            pending = []
            broken = None
            for fut in ex.as_completed(list(futures)):
                item = futures[fut]
                try:
                    res = fut.result()
                except Exception as exc:  # noqa: BLE001 - a dead worker / broken pool
                    if type(exc).__name__ == "BrokenProcessPool" and attempt < retries:
                        broken = exc
                        pending.append(item)
                        continue
                    res = _lost(item, exc)
                results[item.spec.key] = res
                if bar is not None:
                    bar.update(1)
                    nf = sum(1 for k in executed if k in results and not results[k].ok)
                    bar.set_postfix(done=sum(1 for k in executed if k in results) - nf, failed=nf)
            if pending and broken is not None:
                attempt += 1
                ex.close()
                ex = _LocalPool(ex.workers)
    # Ctrl-C, or a fault of this loop (no entry can finish after it): stop the workers now and
    # leave no half-written entry folder
    except BaseException:
        if bar is not None:
            bar.close()
            bar = None
        if ex is not None:
            ex.close(interrupted=True)
            ex = None
        for item in todo:
            remove_orphan_temp_files(item.entry_dir)
            _remove_empty([Path(item.entry_dir)])
        raise
    finally:
        if bar is not None:
            bar.close()
        if ex is not None:
            ex.close()
    # every worker has stopped: a temporary file left in an entry folder belongs to a killed writer
    for item in todo:
        remove_orphan_temp_files(item.entry_dir)
    fr = FleetResult(out=str(out), manifest=str(man.source), previous=prev_name,
                     executor=ex.name if ex is not None else "none (nothing to do)",
                     workers=ex.workers if ex is not None else 0,
                     entries=[results[s.key] for s in man.entries], executed=executed, skipped=skipped,
                     thresholds=thresholds, wall_s=time.perf_counter() - t_start, started_utc=started,
                     version=version, previous_version=prev_version)
    write_fleet_report(fr, out)
    return fr
