"""``fdid`` command line: one sub-module per command group, each registering its parsers.

Every command module exposes ``register(subparsers)``; the handler it sets as ``func``
receives the parsed args and returns an exit code. Expected errors (``FdidError``) are
printed as one clear line, without a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import FdidError

# command modules, in the order their commands are listed in --help
MODULES = ("identify", "simulate", "export", "validate", "diagnose", "plan", "align", "fleet", "demo")


def build_parser():
    parser = argparse.ArgumentParser(
        prog="fdid", description="Feed-drive digital twins from CNC servo traces, as FMI FMUs.")
    from .. import __version__
    parser.add_argument("--version", action="version", version=f"fdid-fmi {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in MODULES:
        try:
            mod = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # command not built yet
            raise
        mod.register(sub)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except FdidError as exc:
        print(f"fdid {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
