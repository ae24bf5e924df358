"""``fdid fleet run MANIFEST``: identify, export, validate and diagnose every axis of a fleet.

    fdid fleet run night1.toml --out fleet/night1
    fdid fleet run night2.toml --out fleet/night2 --previous fleet/night1     # which axes changed?
    fdid fleet run plant.csv --out fleet/today --scheduler tcp://10.0.0.5:8786

Writes ``OUT/fleet.json`` (one row per axis), ``OUT/fleet.html`` and per axis
``OUT/entries/<machine>__<axis>/`` (model, FMU, validation, diagnosis, report). A rerun skips
every entry whose inputs did not change. Exit code 0 when every entry completed, 1 when some
failed (each is listed with its one-line reason).
"""
from __future__ import annotations

import sys


def register(sub):
    p = sub.add_parser("fleet", help="run a fleet manifest: many axes, local pool or Dask cluster",
                       description=__doc__.split("\n\n")[0])
    fs = p.add_subparsers(dest="fleet_command", required=True, metavar="ACTION")
    r = fs.add_parser("run", help="identify -> export -> validate -> diagnose every manifest entry",
                      description="Run every entry of a TOML/CSV manifest (machine, axis, trace files, "
                                  "column map, options) as an independent unit of work; skip entries "
                                  "already done with the same inputs; compare with a previous run.")
    r.add_argument("manifest", help="fleet manifest (.toml or .csv)")
    r.add_argument("--out", default="fleet_out", help="output folder (default fleet_out)")
    r.add_argument("--previous", default=None, metavar="DIR",
                   help="a previous fleet output folder: list the axes whose plant changed since (default: none)")
    r.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (tcp://host:8786); default: a local process pool")
    r.add_argument("--workers", type=int, default=None,
                   help="processes of the local pool (default: the machine's cores)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.set_defaults(func=run)


def run(args):
    from ..errors import InputError
    from ..fleet import run_fleet
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}", column="--workers")
    if args.workers is not None and args.scheduler:
        raise InputError("--workers sets the local pool; with --scheduler the cluster's workers are used",
                         column="--workers")
    fr = run_fleet(args.manifest, args.out, previous=args.previous, scheduler=args.scheduler,
                   workers=args.workers, progress=not args.no_progress and sys.stderr.isatty())
    for line in fr.summary():
        print(line)
    print(f"report: {fr.out}/fleet.html (+ fleet.json)")
    return 1 if fr.failed else 0
