"""``fdid export MODEL.json -o X.fmu``: a model as an FMI Co-Simulation FMU."""
from __future__ import annotations

from pathlib import Path

from ..errors import InputError, naming
from ..model import load_model
from ..outputs import check_output


def register(sub):
    p = sub.add_parser(
        "export", help="export a model as an FMI co-simulation FMU",
        description="Export a state-space model as an FMI 2.0 (or 3.0) Co-Simulation FMU: C code "
                    "generated from fmu_templates/, compiled with gcc (linux64) and, if asked, "
                    "x86_64-w64-mingw32-gcc (win64); sources/ always shipped. Quasi-static models "
                    "cannot be exported.")
    p.add_argument("model", help="model JSON written by fdid identify")
    p.add_argument("-o", "--output", default=None, help="FMU file to write (default: MODEL.fmu)")
    p.add_argument("--fmi", choices=("2", "3"), default="2", help="FMI version (default 2)")
    p.add_argument("--platforms", default="linux64", metavar="P[,P]",
                   help="binaries to build: linux64, win64 (default linux64)")
    p.add_argument("--backend", choices=("c", "python"), default="c",
                   help="c (default; no Python at run time) or python (pythonfmu prototype, FMI 2 only: "
                        "needs pip install 'fdid-fmi[python-backend]', and the importer needs Python "
                        "with fdid-fmi installed)")
    p.add_argument("--name", default=None, help="model identifier (default: from the FMU file name)")
    p.set_defaults(func=run)


def run(args):
    from ..api import export_fmu
    platforms = [s.strip() for s in args.platforms.split(",") if s.strip()]
    if not platforms:
        raise InputError(f"--platforms '{args.platforms}' names no platform (linux64, win64)",
                         source="--platforms")
    if args.backend == "python" and args.platforms != "linux64":
        raise InputError("--platforms applies to --backend c; pythonfmu builds its own binaries",
                         source="--platforms")
    out = Path(args.output) if args.output else Path(args.model).with_suffix(".fmu")
    check_output(out, inputs=[args.model], what="FMU", suffix=".fmu")
    model = load_model(args.model)
    with naming(args.model):
        res = export_fmu(model, out, fmi=int(args.fmi), platforms=platforms, backend=args.backend,
                         name=args.name)
    what = "pythonfmu" if args.backend == "python" else ", ".join(platforms)
    print(f"FMI {args.fmi} co-simulation FMU written to {res.path} ({res.size_bytes / 1024:.1f} KiB; {what})")
    return 0
