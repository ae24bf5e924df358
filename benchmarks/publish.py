"""The one writer of ``docs/results/``: a benchmark run with its default (publishable) options
writes its tables there as ``<name>.md`` (a heading, the command that produced it, the machine and
code state, the tables) and the figures behind them as ``<name>.json``; runs with other options
write only to ``benchmarks/results/``.

    from publish import publish
    publish("simulate", "Simulation speed", [table_md, ...], "./run.sh bench simulate", data)
"""
import json
import os
import platform
import sys
from pathlib import Path

from timing import ROOT, code_state

DOCS = ROOT / "docs" / "results"


def command(name, *args):
    """The command line of ``./run.sh bench NAME ARGS``."""
    return " ".join(["./run.sh bench", name, *map(str, args)])


def about(doc):
    """A benchmark's docstring without its first line and from its "Writes ..." or usage paragraph
    on: what it measures, for its page."""
    keep = []
    for para in doc.split("\n\n")[1:]:
        if para.startswith("Writes ") or para.startswith("    ") or para.startswith("Run:"):
            break
        keep.append(para)
    return "\n\n".join(keep)


def printed(fn, *args):
    """What ``fn(*args)`` prints, as one string (tables a benchmark prints, for its page)."""
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        fn(*args)
    return buf.getvalue()


def publishable(ap, args):
    """Whether every option of ``args`` (parsed by ``ap``) has its default value: only such a run
    writes docs/results/."""
    return all(getattr(args, k) == ap.get_default(k) for k in vars(args))


def md_table(header, rows, align=None):
    """A markdown table: ``header`` (column titles), ``rows`` (lists of cells, already formatted);
    ``align``: one of "l" / "r" per column (default: first column left, the others right)."""
    align = align or ["l"] + ["r"] * (len(header) - 1)
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def machine():
    """Where the figures were measured: CPU count and model, Python, numpy."""
    import numpy as np
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu_count": os.cpu_count(), "cpu": cpu or platform.processor(), "python": platform.python_version(),
            "numpy": np.__version__, "platform": platform.platform()}


def _atomic(path, text):
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def report(path, data, tables):
    """A benchmark's own output: ``data`` as JSON at ``path`` (written atomically, its folder made),
    then ``tables`` (markdown strings) and the path printed."""
    import json
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _atomic(path, json.dumps(data, indent=1))
    for t in tables:
        print(t + "\n")
    print(f"written {path}")


def publish(name, title, tables, cmd, data, notes="", state=None, folder=None):
    """Write ``docs/results/<name>.md`` and ``docs/results/<name>.json`` atomically.

    ``tables``: markdown strings (tables, each with its caption line if any), in order; ``cmd``:
    the exact command that produced them (:func:`command`); ``data``: the figures (JSON-able) the
    tables were made from; ``notes``: text placed after the command line; ``state``: the code state
    (default :func:`timing.code_state` now). Returns the markdown file's path."""
    folder = Path(folder) if folder else DOCS
    folder.mkdir(parents=True, exist_ok=True)
    state = state or code_state()
    mach = machine()
    commit = state.get("commit", "")[:12] or "unknown"
    dirty = " with uncommitted changes in " + ", ".join(state["paths"]) if state.get("dirty") else ""
    lines = [f"# {title}", "",
             f"Produced by `{cmd}` (generated file: edit the benchmark, not this page).", "",
             f"Measured on {mach['cpu_count']} × {mach['cpu']}, Python {mach['python']}, numpy "
             f"{mach['numpy']}; code at commit {commit}{dirty}.", ""]
    if notes:
        lines += [notes.strip(), ""]
    for t in tables:
        lines += [t.strip(), ""]
    _atomic(folder / f"{name}.md", "\n".join(lines).rstrip() + "\n")
    from fdid_fmi.model import jsonable          # non-finite figures as null: strict JSON
    _atomic(folder / f"{name}.json", json.dumps(jsonable({"command": cmd, "code_state": state, "machine": mach,
                                                           "data": data}), indent=1, allow_nan=False) + "\n")
    print(f"published {folder / (name + '.md')}", file=sys.stderr)
    return folder / f"{name}.md"
