"""Fleet manifests: which axes to identify, from which trace files, how (TOML or CSV).

TOML (read with the standard library's ``tomllib``)::

    [defaults]                       # optional, applied to every entry (an entry's keys win)
    map = { t = "t_s" }
    options = { diagnose = false }

    [thresholds]                     # optional, change-watch thresholds (see fleet.compare)
    error_ratio = 2.0

    [[entry]]
    machine = "m01"
    axis = "x"
    traces = ["m01_x.csv"]           # first file: identification; the others: held out
    map = { "x.cmd" = "x_cmd_mm", "x.act" = "x_mm", "x.tool" = "x_tool_mm" }
    units = { }                      # column -> unit, when the names do not say it
    options = { method = "pole-search", seed = 0, diagnose = true }

CSV (one entry per row; a header line naming the columns)::

    machine,axis,traces,map,units,options
    m01,x,m01_x.csv;m01_x_val.csv,t=t_s x.cmd=x_cmd_mm x.act=x_mm,,diagnose=false seed=0

``traces`` are separated by ``;``; ``map``/``units``/``options`` are space-separated
``KEY=VALUE`` tokens. Paths are relative to the manifest's folder.

Options
-------
Identification options are those of ``fdid identify`` (``method``, ``search``, ``seed``,
``maxiter``, ``v_tilde``, ``no_integral_action``, ``n_real``... : the option name with ``_`` for
``-``; ``true`` for a flag; a list for a repeatable option) and ``range`` (data ranges of the
identification trace). They are checked with the ``fdid identify`` parser and its checks of the
option combination (``check_arguments``: ``v_tilde`` with ``v_tilde_range``, an option the method
does not read, ...) when the manifest is loaded, and the data with its ``check_data_range`` (:mod:`fdid_fmi.pipeline.identify`) before
the identification, so an entry is identified exactly as ``fdid identify`` would, or refused as it
would refuse it; messages name the options as the manifest spells them (``options.v_tilde_range``,
``map``, ``units = { t_s = "ms" }``), not as command-line flags. ``axis`` may only name the entry's
own axis. Fleet options:

``diagnose``   (bool, default true) run ``fdid diagnose`` on the identified model (the slowest
               stage: ~2-3x the identification; switch it off for speed);
``detectors``  (list of str) diagnosis detector families (default all);
``fmi``        (2 or 3, default 2) FMI version of the exported FMU.

A manifest entry that cannot be used (missing machine/axis, an unknown option, a bad value)
becomes an :class:`EntrySpec` with ``error`` set: the fleet reports it with that one line and
runs the others.
"""
from __future__ import annotations

import argparse
import csv
import functools
import hashlib
import io
import json
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError

FLEET_OPTIONS = ("diagnose", "detectors", "fmi")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_ENTRY_KEYS = {"machine", "axis", "traces", "trace", "map", "units", "options"}
# machine and axis become file names (entries/<machine>__<axis>/, <machine>_<axis>.fmu): a file
# name is at most 255 bytes, and one entry's too long name must not stop the others
MAX_NAME = 100
# fdid identify options an entry cannot set: the fleet writes the model into the entry's folder
_NOT_OPTIONS = {"output": "the fleet writes the model to entries/<machine>__<axis>/model.json",
                "trace": "the traces are the entry's 'traces'"}

__all__ = ["EntrySpec", "Manifest", "load_manifest", "parse_manifest_text", "entry_hash", "software_version",
           "identify_args", "manifest_words", "FLEET_OPTIONS"]


@dataclass(frozen=True)
class EntrySpec:
    """One unit of work: one axis of one machine.

    Attributes
    ----------
    machine, axis : str
    traces : tuple of str     absolute paths; the first identifies, the others are held out
    mapping : dict            reader mapping ``{"t": col, "x.cmd": col, ...}`` (``--map``)
    units : dict              ``{col: unit}`` (``--unit``)
    identify : tuple of str   ``fdid identify`` option tokens (``("--seed", "0", ...)``)
    diagnose : bool
    detectors : tuple of str or None
    fmi : int                 2 or 3
    row : int                 position in the manifest (1-based entry number / CSV line)
    error : str or None       why the entry cannot run (manifest problem), one line
    names : tuple of str      the trace files as the manifest gives them (relative to its folder):
                              how messages and reports name them (``night1/m01_x.csv`` and
                              ``night2/m01_x.csv`` were both ``m01_x.csv``); see :meth:`trace_name`
    """

    machine: str
    axis: str
    traces: tuple = ()
    mapping: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)
    identify: tuple = ()
    diagnose: bool = True
    detectors: tuple | None = None
    fmi: int = 2
    row: int = 0
    error: str | None = None
    names: tuple = ()

    @property
    def key(self):
        """``machine/axis``: the entry's name in reports and in the previous fleet result."""
        return f"{self.machine}/{self.axis}"

    def trace_name(self, k):
        """Name of trace ``k`` in messages and reports: as the manifest gives it (the full path for an
        entry made without one)."""
        return self.names[k] if k < len(self.names) else str(self.traces[k])

    @property
    def dirname(self):
        """Folder of the entry's outputs under ``OUT/entries/``."""
        return f"{self.machine}__{self.axis}"

    def to_dict(self):
        return {"machine": self.machine, "axis": self.axis, "traces": list(self.traces),
                "mapping": dict(self.mapping), "units": dict(self.units), "identify": list(self.identify),
                "diagnose": self.diagnose, "detectors": list(self.detectors) if self.detectors else None,
                "fmi": self.fmi, "row": self.row, "error": self.error, "names": list(self.names)}


@dataclass
class Manifest:
    """A parsed manifest: entries (in file order), change thresholds, where it came from."""

    entries: list
    thresholds: dict = field(default_factory=dict)
    source: str = "<manifest>"


# ----------------------------------------------------------------------------- option checking
class _RaisingParser(argparse.ArgumentParser):
    """An ArgumentParser that raises InputError instead of printing usage and exiting, and takes
    no abbreviation of an option (``--max`` is not read as ``--maxiter``); the ``fdid identify``
    sub-parser is of this class too (``add_subparsers`` makes its parsers of the parent's class)."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise InputError(message, column="options")

    def exit(self, status=0, message=None):  # --help etc. never reach here from a manifest
        raise InputError((message or "bad options").strip(), column="options")


def _identify_parser():
    from ..pipeline.identify import add_identify_parser
    root = _RaisingParser(prog="fdid", add_help=False)
    sub = root.add_subparsers(dest="command")
    add_identify_parser(sub)
    return root


def identify_args(trace_path, spec: EntrySpec):
    """The ``argparse`` namespace ``fdid identify TRACE <options>`` would build for ``spec``.

    Raises
    ------
    InputError  an unknown option or a bad value (argparse's message, one line)
    """
    tokens = ["identify", str(trace_path), *spec.identify]
    if spec.mapping:
        tokens += ["--map", *[f"{k}={v}" for k, v in spec.mapping.items()]]
    if spec.units:
        tokens += ["--unit", *[f"{k}={v}" for k, v in spec.units.items()]]
    args = _identify_parser().parse_args(tokens)
    return args


def _repeatable_options():
    """Destinations of the ``fdid identify`` options that may be given several times."""
    sub = next(a for a in _identify_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest for a in sub.choices["identify"]._actions
            if isinstance(a, (argparse._AppendAction, argparse._ExtendAction))}


@functools.lru_cache(maxsize=1)
def _long_options():
    """Every long option string of ``fdid identify`` (``--maxiter``, ``--map``, ...)."""
    sub = next(a for a in _identify_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return frozenset(s for a in sub.choices["identify"]._actions for s in a.option_strings if s.startswith("--"))


def _refuse_abbreviations(options: dict, where, entry):
    """An option key that only begins an ``fdid identify`` option's name (``max`` for ``maxiter``)
    is refused naming the options it abbreviates (the parser refuses it as well, less clearly)."""
    names = None
    for k in options:
        if k in FLEET_OPTIONS or k in _NOT_OPTIONS:
            continue
        flag = "--" + str(k).replace("_", "-")
        names = _long_options() if names is None else names
        if flag in names:
            continue
        full = sorted(n[2:].replace("-", "_") for n in names if n.startswith(flag))
        if full:
            raise InputError(f"{entry}: option '{k}' is not an option of fdid identify but abbreviates "
                             f"{' or '.join(repr(f) for f in full)}: write the option name in full "
                             f"(abbreviations are not accepted)", source=where, column=k)


def _option_tokens(options: dict, where, axis=None):
    """``fdid identify`` tokens from an options table (fleet options removed)."""
    tokens = []
    repeatable = None
    for k, v in options.items():
        if k in FLEET_OPTIONS:
            continue
        if k in _NOT_OPTIONS:
            raise InputError(f"option '{k}' cannot be set in a manifest ({_NOT_OPTIONS[k]})",
                             source=where, column=k)
        if k == "axis" and axis is not None:
            # exactly the entry's axis: a list with another axis identified a two-axis model of
            # which only the entry's axis was validated and compared
            given = [v] if isinstance(v, str) else list(v) if isinstance(v, (list, tuple)) else [v]
            if [str(a) for a in given] != [axis]:
                what = "does not include" if axis not in [str(a) for a in given] else "names other axes than"
                raise InputError(f"option 'axis' = {v!r} {what} the entry's axis '{axis}' (an entry identifies "
                                 f"its own axis only; leave 'axis' out, or give each axis its own entry)",
                                 source=where, column=k)
        flag = "--" + str(k).replace("_", "-")
        if isinstance(v, (list, tuple)) and len(v) > 1:
            if repeatable is None:
                repeatable = _repeatable_options()
            if k not in repeatable:     # argparse would keep the last value without a word
                raise InputError(f"option '{k}' takes one value, got the list {list(v)!r}",
                                 source=where, column=k)
        values = v if isinstance(v, (list, tuple)) else [v]
        for item in values:
            if isinstance(item, bool):
                if item:
                    tokens.append(flag)
                elif k not in ("no_friction", "no_integral_action", "coupled"):
                    raise InputError(f"option '{k}' = false is not understood (leave it out)",
                                     source=where, column=k)
            elif isinstance(item, (int, float, str)):
                tokens += [flag, str(item)]
            else:
                raise InputError(f"option '{k}' has an unsupported value {item!r}", source=where, column=k)
    return tuple(tokens)


def _fleet_options(options, where):
    diagnose = options.get("diagnose", True)
    if not isinstance(diagnose, bool):
        raise InputError(f"'diagnose' must be true or false, got {diagnose!r}", source=where, column="diagnose")
    det = options.get("detectors")
    if det is not None:
        if isinstance(det, str):
            det = [d.strip() for d in det.split(",") if d.strip()]
        if not isinstance(det, (list, tuple)) or not det:
            raise InputError(f"'detectors' must name one or more detector families (a list or a comma "
                             f"list), got {options.get('detectors')!r}; leave it out for all",
                             source=where, column="detectors")
        from ..diagnose.loop import DETECTORS
        bad = [d for d in det if d not in DETECTORS]
        if bad:
            raise InputError(f"unknown detector(s) {bad}; expected some of {sorted(DETECTORS)}",
                             source=where, column="detectors")
        det = tuple(det)
    fmi = options.get("fmi", 2)
    if str(fmi) not in ("2", "3"):
        raise InputError(f"'fmi' must be 2 or 3, got {fmi!r}", source=where, column="fmi")
    return diagnose, det, int(fmi)


def _build_entry(raw: dict, defaults: dict, base: Path, row: int, where: str) -> EntrySpec:
    """One EntrySpec from a raw table; problems become ``error`` (never raised)."""
    machine = str(raw.get("machine", "") or "").strip()
    axis = str(raw.get("axis", "") or "").strip()
    try:
        for name, value in (("machine", machine), ("axis", axis)):
            if not value:
                raise InputError(f"entry {row} has no '{name}'", source=where, column=name)
            if not _NAME.match(value):
                raise InputError(f"'{value}' is not a usable {name} name (letters, digits, _ . -)",
                                 source=where, column=name)
            if len(value) > MAX_NAME:
                raise InputError(f"the {name} name is {len(value)} characters long; at most {MAX_NAME} "
                                 f"(it becomes a file name)", source=where, column=name)
        unknown = sorted(set(raw) - _ENTRY_KEYS)
        if unknown:
            raise InputError(f"unknown key(s) {unknown} in entry {row}; expected {sorted(_ENTRY_KEYS)}",
                             source=where, column=unknown[0])
        if "traces" in raw and "trace" in raw:    # one would be dropped without a word
            raise InputError(f"entry {row} ({machine}/{axis}) gives both 'traces' and 'trace' "
                             f"({raw['traces']!r} and {raw['trace']!r}); give the trace files once, "
                             f"as 'traces'", source=where, column="trace")
        traces = raw.get("traces", raw.get("trace"))
        if isinstance(traces, str):
            traces = [t.strip() for t in traces.split(";") if t.strip()]
        if not traces or not all(isinstance(t, str) for t in traces):
            raise InputError(f"entry {row} needs 'traces' (a list of trace files)", source=where,
                             column="traces")
        for t in traces:
            if not t.strip() or "\0" in t:
                raise InputError(f"entry {row}: {t!r} is not a trace file name", source=where, column="traces")
        paths = tuple(str((base / t).resolve()) if not Path(t).is_absolute() else t for t in traces)
        if len(set(paths)) < len(paths):       # a held-out trace that is the training trace
            raise InputError(f"entry {row} lists a trace file twice ({list(traces)})", source=where,
                             column="traces")
        for name in ("map", "units", "options"):     # checked before they are merged
            for what, tbl in (("the entry's", raw.get(name) or {}), ("[defaults]'", defaults.get(name, {}))):
                if not isinstance(tbl, dict):
                    raise InputError(f"{what} '{name}' must be a table of KEY = VALUE (e.g. "
                                     f"{name} = {{ ... }}), got {type(tbl).__name__}", source=where, column=name)
        mapping = {**defaults.get("map", {}), **(raw.get("map") or {})}
        units = {**defaults.get("units", {}), **(raw.get("units") or {})}
        options = {**defaults.get("options", {}), **(raw.get("options") or {})}
        mapping = {str(k): str(v) for k, v in mapping.items()}
        units = {str(k): str(v) for k, v in units.items()}
        diagnose, det, fmi = _fleet_options(options, where)
        _refuse_abbreviations(options, where, f"entry {row} ({machine}/{axis})")
        spec = EntrySpec(machine, axis, paths, mapping, units, _option_tokens(options, where, axis), diagnose,
                         det, fmi, row, names=tuple(traces))
        # the fdid identify parser checks option names and values (not the files)
        from ..pipeline.identify import check_arguments
        from ..pipeline.traces import parse_mapping, parse_units
        try:
            args = identify_args(paths[0], spec)
        except InputError as exc:
            raise InputError(f"entry {row}: {manifest_words(exc.message)}", source=where,
                             column="options") from None
        try:
            parse_mapping(args.map)
            parse_units(args.unit)
            # and fdid identify's checks of the option combination, before any trace is read (a
            # v_tilde with v_tilde_range, an option the method does not read, ...): the fleet ran
            # them silently ignored where the CLI refuses them
            check_arguments(args)
        except InputError as exc:
            raise InputError(f"entry {row} ({machine}/{axis}): {manifest_words(exc.message)}", source=where,
                             column=manifest_words(str(exc.source or exc.column or "options"))) from None
        return spec
    except InputError as exc:
        return EntrySpec(machine or f"entry{row}", axis or f"?{row}", row=row, error=_one_line(exc))


def _one_line(exc):
    return " ".join(str(exc).split())


_FLAG = re.compile(r"(?<![\w-])--([a-z][a-z0-9]*(?:-[a-z0-9]+)*)(?: ([^\s=,;:()']+)=([^\s,;()']+))?")


def _toml_key(k):
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def manifest_words(text):
    """``text`` (a message of ``fdid identify``'s checks or of the trace reader) with its command-line
    flags spelled the way a manifest sets them: ``--v-tilde-range`` -> ``options.v_tilde_range``,
    ``--map`` -> ``map``, ``--unit`` -> ``units``, ``--unit t_s=ms`` -> ``units = { t_s = "ms" }``.
    Flags that are not ``fdid identify`` options (``--tolerance`` of ``fdid validate``) are kept."""
    names = _long_options()

    def word(m):
        flag, key, value = "--" + m.group(1), m.group(2), m.group(3)
        table = {"--map": "map", "--unit": "units"}.get(flag)
        if table is not None:
            return f'{table} = {{ {_toml_key(key)} = "{value}" }}' if key else table
        if flag in names:
            return "options." + m.group(1).replace("-", "_") + (f" {key}={value}" if key else "")
        return m.group(0)
    return _FLAG.sub(word, str(text))


def _kv_tokens(text, where, column):
    out = {}
    for tok in (text or "").split():
        if "=" not in tok:
            raise InputError(f"'{tok}' is not KEY=VALUE", source=where, column=column)
        k, v = tok.split("=", 1)
        if k.strip() in out:             # the later one would win without a word
            raise InputError(f"'{k.strip()}' is given twice ({out[k.strip()]} and {v.strip()})",
                             source=where, column=column)
        out[k.strip()] = v.strip()
    return out


def _csv_value(v):
    low = v.lower()
    if low in ("true", "yes"):
        return True
    if low in ("false", "no"):
        return False
    return v


def parse_manifest_text(text, fmt, base=".", source="<manifest>") -> Manifest:
    """Parse manifest text (``fmt`` = ``toml`` or ``csv``); trace paths resolve against ``base``.

    Raises
    ------
    InputError  the file as a whole cannot be read (bad TOML/CSV syntax, no entries, two entries
                for the same machine/axis, or for names that differ only in upper/lower case);
                problems of one entry go to its ``error`` instead.
    """
    base = Path(base)
    if text.startswith("\ufeff"):      # a byte-order mark (a spreadsheet's "CSV UTF-8")
        text = text[1:]
    raws, defaults, thresholds = [], {}, {}
    if fmt == "toml":
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"not valid TOML ({exc})", source=source) from None
        unknown = sorted(set(doc) - {"entry", "defaults", "thresholds"})
        if unknown:
            raise InputError(f"unknown table(s) {unknown}; expected [[entry]], [defaults], [thresholds]",
                             source=source)
        raws = doc.get("entry", [])
        if not isinstance(raws, list):
            raise InputError("'entry' must be an array of tables ([[entry]])", source=source)
        defaults = doc.get("defaults", {})
        if not isinstance(defaults, dict) or set(defaults) - {"map", "units", "options"}:
            raise InputError(f"[defaults] holds only the tables map, units and options; got "
                             f"{sorted(defaults) if isinstance(defaults, dict) else type(defaults).__name__}",
                             source=source, column="defaults")
        thresholds = doc.get("thresholds", {})
        if not isinstance(thresholds, dict):
            raise InputError(f"[thresholds] must be a table of NAME = NUMBER, got {type(thresholds).__name__}",
                             source=source, column="thresholds")
        rows = list(range(1, len(raws) + 1))
    elif fmt == "csv":
        reader = csv.DictReader(io.StringIO(text))
        if not reader.fieldnames or not {"machine", "axis"} <= {f.strip() for f in reader.fieldnames}:
            raise InputError("the CSV manifest needs a header with at least machine, axis, traces",
                             source=source)
        names = [f.strip() for f in reader.fieldnames]
        twice = sorted({f for f in names if names.count(f) > 1 and f})
        if twice:                        # DictReader would keep the last column of a name
            raise InputError(f"the header names the column(s) {twice} twice", source=source, column=twice[0])
        rows = []
        for rec in reader:
            extra = rec.pop(None, None)  # fields beyond the header (DictReader's restkey)
            if extra is not None and any(str(x).strip() for x in extra):
                rows.append(reader.line_num)
                raws.append({"machine": rec.get("machine"), "axis": rec.get("axis"),
                             "_bad": f"line {reader.line_num} has {len(names) + len(extra)} fields, the header "
                                     f"{len(names)} (quote a field holding a comma)"})
                continue
            rec = {(k or "").strip(): (v or "").strip() for k, v in rec.items()}
            if not any(rec.values()):
                continue
            rows.append(reader.line_num)
            raw = {k: v for k, v in rec.items() if k in ("machine", "axis", "traces", "trace") and v}
            extra = sorted(k for k, v in rec.items() if k not in _ENTRY_KEYS and v)
            if extra:
                raw[extra[0]] = rec[extra[0]]     # reported as an unknown key of this entry
            try:
                raw["map"] = _kv_tokens(rec.get("map"), source, "map")
                raw["units"] = _kv_tokens(rec.get("units"), source, "units")
                raw["options"] = {k: _csv_value(v) for k, v in _kv_tokens(rec.get("options"), source,
                                                                          "options").items()}
            except InputError as exc:
                raw = {"machine": rec.get("machine"), "axis": rec.get("axis"), "_bad": str(exc)}
            raws.append(raw)
    else:
        raise InputError(f"manifest format must be toml or csv, got {fmt!r}", source=source)
    if not raws:
        raise InputError("the manifest lists no entries", source=source)
    entries = []
    for row, raw in zip(rows, raws):
        if not isinstance(raw, dict):
            raise InputError(f"entry {row} is not a table", source=source)
        if "_bad" in raw:
            entries.append(EntrySpec(str(raw.get("machine") or f"entry{row}"), str(raw.get("axis") or f"?{row}"),
                                     row=row, error=" ".join(raw["_bad"].split())))
            continue
        entries.append(_build_entry(raw, defaults, base, row, source))
    seen, folders, cased = {}, {}, {}
    for e in entries:       # a repeated key would share one result and one output folder
        if e.key in seen:
            raise InputError(f"{e.key} is listed twice (entries {seen[e.key]} and {e.row})", source=source)
        if e.dirname in folders:
            raise InputError(f"{e.key} and {folders[e.dirname]} would write the same folder "
                             f"entries/{e.dirname}; rename one (no '__' in names)", source=source)
        # M01/x and m01/x: one folder on a case-insensitive file system (macOS, Windows), where the
        # second entry would overwrite the first's model and FMU
        first = cased.get(e.dirname.casefold())
        if first is not None:
            raise InputError(f"{first[0]} and {e.key} (entries {first[1]} and {e.row}) would write the folders "
                             f"entries/{first[2]} and entries/{e.dirname}, which differ only in upper/lower "
                             f"case: one folder on macOS and Windows; rename one", source=source)
        seen[e.key], folders[e.dirname] = e.row, e.key
        cased[e.dirname.casefold()] = (e.key, e.row, e.dirname)
    return Manifest(entries, dict(thresholds), source)


def load_manifest(path) -> Manifest:
    """Read a ``.toml`` or ``.csv`` manifest file (see the module docstring)."""
    p = Path(path)
    if p.is_dir():          # not "manifest file not found", though the path exists
        try:
            inside = sorted(f.name for f in p.iterdir() if f.suffix.lower() == ".toml" and f.is_file())
        except OSError:
            inside = []
        hint = f" (TOML files there: {', '.join(inside[:3])}{', ...' if len(inside) > 3 else ''})" if inside else ""
        raise InputError(f"is a directory, not a manifest file; give the .toml or .csv manifest{hint}",
                         source=str(p))
    if not p.is_file():
        raise InputError("manifest file not found" if not p.exists() else "is not a regular file, "
                         "not a manifest file", source=str(p))
    fmt = {".toml": "toml", ".csv": "csv"}.get(p.suffix.lower())
    if fmt is None:
        raise InputError(f"a manifest is .toml or .csv, not '{p.suffix}'", source=str(p))
    try:
        text = p.read_text(encoding="utf-8-sig")     # a spreadsheet's "CSV UTF-8" starts with a BOM
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read ({exc})", source=str(p)) from None
    return parse_manifest_text(text, fmt, base=p.parent, source=str(p))


# ----------------------------------------------------------------------------- content hash
def file_digest(path):
    """sha256 of a file's bytes, or ``missing:<path>`` when it cannot be read (so that the hash
    changes once the file appears)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return f"missing:{path}"
    return h.hexdigest()


# the parts of the package an entry's results depend on (reading, identification, model and
# simulation, FMU generation and validation, diagnosis, the fleet itself); kernel.py and the C of
# the compiled extension (kernel_ext: the pole search's regressor filter) run in identification
# and simulation; pipeline/ holds the identification options, their value parsers and the trace
# options; api.py is what an entry calls (it imports the planner, and the planner the virtual
# machine's S-curves); report.py writes entry.html, with the column labels of labels.py
PIPELINE_SOURCES = ("io", "identify", "fmu", "fmu_templates", "diagnose", "fleet", "trace.py", "units.py",
                    "signals.py", "model.py", "simulate.py", "metrics.py", "errors.py", "outputs.py",
                    "kernel.py", "kernel_ext", "report.py", "labels.py", "workers.py", "pipeline", "api.py",
                    "plan", "virtual")


def pipeline_files():
    """The source files :func:`software_version` hashes (absolute paths, sorted per part)."""
    root = Path(__file__).resolve().parents[1]
    files = []
    for part in PIPELINE_SOURCES:
        p = root / part
        files += [p] if p.is_file() else sorted(p.rglob("*"))
    return [f for f in files if f.is_file() and f.suffix in (".py", ".c", ".h") and "__pycache__" not in f.parts]


def software_version() -> str:
    """``<package version>+src.<digest>``: the version string and a sha256 of the package's source
    files the results depend on (``PIPELINE_SOURCES``: Python modules and the FMU C templates), so
    that a rerun after a change of that code (a new release, or a development commit) redoes the
    work instead of reusing results the current code would not produce."""
    from .. import __version__
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for f in pipeline_files():
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return f"{__version__}+src.{h.hexdigest()[:12]}"


def entry_hash(spec: EntrySpec, version: str) -> str:
    """Content hash of a unit of work: trace file bytes, options and software version.

    Equal hashes mean equal inputs, so a finished result with the same hash can be reused.
    """
    d = spec.to_dict()
    d.pop("row")
    d["traces"] = [file_digest(p) for p in spec.traces]
    d["trace_names"] = [Path(p).name for p in spec.traces]
    d["version"] = version
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()
