"""A plant's fleet: identify, export, validate, diagnose and watch many axes as independent units
of work, on a local process pool or a Dask cluster.

>>> from fdid_fmi.fleet import run_fleet                       # doctest: +SKIP
>>> night1 = run_fleet("night1.toml", "out/night1")
>>> night2 = run_fleet("night2.toml", "out/night2", previous="out/night1")
>>> [(e.key, e.change.summary) for e in night2.changed]

* :mod:`.manifest` - TOML/CSV manifests -> :class:`EntrySpec`; the content hash of an entry;
* :mod:`.work` - one entry: identify -> export -> validate -> diagnose -> compare (:func:`run_entry`);
* :mod:`.compare` - the new model against the last one of the axis, with thresholds and evidence;
* :mod:`.runner` - :func:`run_fleet`: skip what is done, submit the rest, collect, report;
* :mod:`.report` - ``fleet.json`` (table) and ``fleet.html``;
* :mod:`.virtual` - a virtual plant fleet with known truth (traces + manifests, night after night).
"""
from .compare import ChangeReport, ModelSignature, Thresholds, compare_models
from .manifest import EntrySpec, Manifest, entry_hash, load_manifest, parse_manifest_text
from .runner import FleetResult, load_fleet_result, run_fleet
from .work import EntryResult, StageTimes, ValidationFigures, run_entry

__all__ = ["run_fleet", "FleetResult", "load_fleet_result", "EntryResult", "StageTimes", "ValidationFigures",
           "run_entry", "EntrySpec", "Manifest", "load_manifest", "parse_manifest_text", "entry_hash",
           "Thresholds", "ChangeReport", "ModelSignature", "compare_models"]
