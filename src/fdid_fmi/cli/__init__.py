"""``fdid`` command line: one sub-module per command group, each registering its parsers.

Every command module exposes ``register(subparsers)``; the handler it sets as ``func``
receives the parsed args and returns an exit code.

The boundary (:func:`main`) turns every failure into one line on stderr:

* expected errors (``FdidError``: bad input, a failed build) -> ``fdid CMD: error: ...``
  naming file, column/row or parameter; exit code 2;
* file-system errors (``OSError``: disk full, permission) -> one line with the file name; 2;
* out of memory -> one line; 2;  Ctrl-C -> ``interrupted``; 130;
* anything else is a bug -> one line saying so and where to report it; exit code 3.

The traceback is printed only with the global ``--debug`` flag (``fdid --debug CMD ...`` or
``fdid CMD ... --debug``).
"""
from __future__ import annotations

import argparse
import copy
import importlib
import itertools
import os
import sys
import traceback

from ..errors import FdidError
from ..workers import one_blas_thread

# command modules, in the order their commands are listed in --help
MODULES = ("identify", "simulate", "export", "validate", "diagnose", "plan", "align", "fleet", "demo")

BUG_REPORT = ("this is a bug in fdid-fmi; please report it to the fdid-fmi maintainers (issue "
              "tracker of the project) with the command line and the output of the same command "
              "with --debug")


class _Formatter(argparse.HelpFormatter):
    """Help lines that end with the option's default where it has one (not None, not a flag's
    False) and the help text does not already say it."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (not action.option_strings or action.default in (None, False, argparse.SUPPRESS)
                or "%(default)" in text or "default" in text.lower()):
            return text
        return f"{text} (default: %(default)s)" if text else "default: %(default)s"

    def _format_action(self, action):
        if not action.help and self._get_help_string(action):    # a default but no help text
            action = copy.copy(action)
            action.help = self._get_help_string(action)
        return super()._format_action(action)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage block): ``fdid CMD: error: ... (see --help)``,
    and no abbreviation of a long option (``--meth`` for ``--method`` would silently change
    meaning once another ``--meth...`` option is added). ``add_subparsers`` makes every command's
    parser (and ``fdid fleet``'s nested ones) of this class, so the rule holds for all of them."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)


    def error(self, message):
        if message.endswith("expected one argument"):   # argparse reads '-0.5:2' as an option
            message += "; a value that starts with '-' is given as --option=VALUE (--range=-0.5:2)"
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser():
    parser = _Parser(
        prog="fdid", description="Feed-drive digital twins from CNC servo traces, as FMI FMUs.")
    from .. import __version__
    parser.add_argument("--version", action="version", version=f"fdid-fmi {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="print the Python traceback of an error (for bug reports)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in MODULES:
        try:
            mod = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # command not built yet
            raise
        mod.register(sub)
    for sp in _command_parsers(sub.choices.values()):    # --debug also after the command name
        try:
            sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                            help="print the Python traceback of an error (for bug reports)")
        except argparse.ArgumentError:
            pass  # the command defines its own --debug
    parser.commands = sub.choices
    return parser


def _nested(p):
    """The sub-command action of parser ``p`` (``fdid fleet``'s ``run``), or None."""
    return next((a for a in p._actions if isinstance(a, argparse._SubParsersAction)), None)


def _command_parsers(parsers):
    """The given command parsers and every nested one below them."""
    for p in parsers:
        yield p
        act = _nested(p)
        if act is not None:
            yield from _command_parsers(act.choices.values())


TOP_OPTIONS = ("--version", "--debug", "-h", "--help")


def _parse(parser, argv):
    """``parser.parse_args`` whose unknown options are named where they were given: before the
    command (``fdid --vers``: not "a command is required"), or after it, with that command's help
    to look up (``see fdid identify --help``)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    lead = list(itertools.takewhile(lambda a: a.startswith("-"), argv))
    unknown = [a for a in lead if a not in TOP_OPTIONS]
    if unknown and not {"-h", "--help", "--version"} & set(lead):     # help and version still win
        parser.error(f"unrecognized arguments: {' '.join(unknown)}; before the command fdid takes "
                     f"only {', '.join(TOP_OPTIONS)} (a command's options go after its name)")
    args, extra = parser.parse_known_args(argv)
    if extra:
        p, rest = parser.commands[args.command], argv[argv.index(args.command) + 1:]
        # the parser of a nested command (fdid fleet run) when the extras were given after its name
        while (act := _nested(p)) is not None and (name := getattr(args, act.dest, None)) in rest \
                and extra[0] in rest[rest.index(name) + 1:]:
            p, rest = act.choices[name], rest[rest.index(name) + 1:]
        p.error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def _one_line(text):
    """First line of a message; the rest is available with --debug."""
    lines = [ln for ln in str(text).splitlines() if ln.strip()]
    if not lines:
        return "(no message)"
    return lines[0] + (" (details with --debug)" if len(lines) > 1 else "")


def _oserror_text(exc):
    name = exc.filename if exc.filename is not None else None
    what = exc.strerror or str(exc)
    return f"{name}: {what}" if name is not None else what


def main(argv=None):
    for stream in (sys.stdout, sys.stderr):   # file names that are not valid UTF-8 print escaped
        try:
            stream.reconfigure(errors="backslashreplace")
        except (AttributeError, ValueError):
            pass
    parser = build_parser()
    args = _parse(parser, argv)
    debug = bool(getattr(args, "debug", False))
    cmd = f"fdid {args.command}"
    try:
        with one_blas_thread():     # as fdid's worker processes (fdid_fmi.workers: why)
            return int(args.func(args) or 0)
    except FdidError as exc:
        if debug:
            traceback.print_exc()
        print(f"{cmd}: error: {exc if debug else _one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout has gone (`fdid plan ... | head`): stop quietly, as a Unix tool
        # killed by SIGPIPE does; stdout goes to /dev/null so the exit's flush cannot fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141          # 128 + SIGPIPE, what a shell reports for such a tool
    except MemoryError:
        if debug:
            traceback.print_exc()
        print(f"{cmd}: error: out of memory (the input is too large for this machine)", file=sys.stderr)
        return 2
    except OSError as exc:
        if debug:
            traceback.print_exc()
        print(f"{cmd}: error: {_one_line(_oserror_text(exc))}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the boundary: one line, never a bare traceback
        import zipfile
        if isinstance(exc, zipfile.BadZipFile):
            # a file that should be an FMU (zip archive) is not one
            if debug:
                traceback.print_exc()
            where = getattr(args, "fmu", None) or getattr(args, "model", None)
            print(f"{cmd}: error: {where + ': ' if where else ''}is not an FMU (not a zip archive: {exc})",
                  file=sys.stderr)
            return 2
        if debug:
            traceback.print_exc()
        print(f"{cmd}: internal error: {type(exc).__name__}: {_one_line(exc)} -- {BUG_REPORT}",
              file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
