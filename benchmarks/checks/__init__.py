"""End-to-end checks that ``benchmarks/bench_end_to_end.py`` runs and reports pass/fail on.

Each check is a function of the modules in this folder, registered with :func:`check`: a full
default identification, a diagnosis run, the demo -- minutes of CPU each, too long for
``./run.sh test``. Their assertions are those of the test each check names (``origin``); a
check fails by raising (``AssertionError`` with its message, or any error).

A check that takes a ``tmp`` argument gets a fresh empty folder (a ``pathlib.Path``).
"""
from dataclasses import dataclass, field
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parents[2]
for p in (ROOT / "tests",):          # plant2, plant2_fits, cli_support: the tests' support code
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

REGISTRY = []


@dataclass
class Check:
    fn: object
    origin: str                 # the test (file::name[params]) these assertions come from
    params: dict = field(default_factory=dict)

    @property
    def name(self):
        base = f"{self.fn.__module__.rsplit('.', 1)[-1]}::{self.fn.__name__}"
        return base + (f"[{'-'.join(str(v) for v in self.params.values())}]" if self.params else "")


def check(origin, *params):
    """Register the decorated function as a check (once per dict in ``params``, called with it as
    keyword arguments; once without arguments when there is none). ``origin``: the test id, with
    ``{name}``-style fields filled from each dict."""
    def deco(fn):
        for p in params or ({},):
            REGISTRY.append(Check(fn, origin.format(**p), dict(p)))
        return fn
    return deco


def load_all():
    """Import every check module of this folder (registration order: file name, then source)."""
    import importlib
    for f in sorted(Path(__file__).parent.glob("[a-z]*.py")):
        importlib.import_module(f"checks.{f.stem}")
    return REGISTRY
