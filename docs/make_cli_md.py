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

EXAMPLES = """\
fdid identify examples/virtual_xy_moves.csv -o model.json                     # structure chosen from the data
fdid identify examples/virtual_xy_moves.csv --structure rigid --jobs 1 -o model.json
fdid identify run.csv --map t=time x.cmd=pos_set x.act=pos_enc --unit pos_set=um pos_enc=um --range 0.5:3.2,4:6 -o model.json
fdid identify run.csv --method mimo --n-real 2 --n-complex 1 --same-sample quadratic -o model.json
fdid identify DATA_EMPS.mat --no-integral-action -o emps.json
fdid simulate model.json examples/virtual_circle.csv --at-rest -o prediction.csv
fdid export model.json -o drive.fmu --fmi 3 --platforms linux64,win64
fdid validate drive.fmu examples/virtual_circle.csv --model model.json --json validation.json
fdid diagnose model.json --train train.csv --val val.csv -o model_plus.json --report diagnose.html --json diagnose.json --fmu --jobs 2
fdid plan examples/pocket_corner.nc --model model.json --limits 100,2000,1e5 --tol 0.02 --report plan.html --json plan.json --csv plan.csv
fdid plan examples/pocket_corner.nc --fmu drive.fmu --limits-from examples/virtual_xy_moves.csv --tol 0.02 --optimize -o pocket_opt.nc
fdid plan examples/circle.nc --model model.json --commands examples/virtual_circle.csv
fdid plan examples/slot_tangent.nc --model model.json --limits 100,2000,1e5 --corner-angle 1
fdid align controller.csv --acc acc_tool.csv axes=x,y --kgm kgm.csv -o aligned.csv --json calib.json
fdid align run2.csv --acc acc2.csv axes=x,y name=acc_tool --orientation calib.json -o aligned2.csv
fdid fleet run night2.toml --out fleet/night2 --previous fleet/night1
fdid fleet run plant.csv --out fleet/today --scheduler tcp://HOST:8786
fdid demo --out out/demo --emps"""


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
             "## Examples", "", "```bash", EXAMPLES, "```", "",
             "## fdid", "", "```text", help_text([]), "```", ""]
    for c in COMMANDS:
        parts += [f"## fdid {' '.join(c)}", "", "```text", help_text(c), "```", ""]
    Path(__file__).with_name("cli.md").write_text("\n".join(parts), encoding="utf-8")


if __name__ == "__main__":
    main()
