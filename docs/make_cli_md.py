"""Write docs/cli.md from the `fdid <command> --help` pages (run after changing an option).

    .venv/bin/python docs/make_cli_md.py
"""
import argparse
import contextlib
import io
import os
from pathlib import Path

COMMANDS = [["identify"], ["simulate"], ["export"], ["validate"], ["diagnose"], ["plan"],
            ["align"], ["fleet", "run"], ["demo"]]


def help_text(argv):
    from fdid_fmi.cli import main
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            main([*argv, "--help"])
        except SystemExit:
            pass
    return out.getvalue().rstrip()


def main():
    argparse.ArgumentParser(description=__doc__).parse_args()
    os.environ["COLUMNS"] = "100"       # one width whatever the terminal
    parts = ["# Command-line reference", "",
             "Generated from `fdid <command> --help` by `docs/make_cli_md.py`; do not edit by hand.",
             "Exit codes: 0 done, 1 a check failed (`validate`, `diagnose --fmu`, `demo`, "
             "`plan --optimize` out of reach, a fleet entry failed), 2 bad input, 3 an internal "
             "error, 130 Ctrl-C.", "",
             "Commands: " + ", ".join(f"[`fdid {' '.join(c)}`](#fdid-{'-'.join(c)})" for c in COMMANDS), "",
             "## fdid", "", "```text", help_text([]), "```", ""]
    for c in COMMANDS:
        parts += [f"## fdid {' '.join(c)}", "", "```text", help_text(c), "```", ""]
    Path(__file__).with_name("cli.md").write_text("\n".join(parts), encoding="utf-8")


if __name__ == "__main__":
    main()
