"""End-to-end checks too long for the test suite: full default identifications (``identify_auto``),
diagnosis runs on the virtual drive, plant2 and EMPS, and the demo -- each with the assertions of
the test it was (``benchmarks/checks/``; tests/README.md lists them), run one after the other in
this process, BLAS on one thread.

    .venv/bin/python benchmarks/bench_end_to_end.py [--checks SUBSTR,...] [--list] [--out NAME.json]

``--checks``: only the checks whose name or origin test contains one of the comma-separated
substrings (e.g. ``--checks diagnose_virtual,demo``). Writes benchmarks/results/bench_end_to_end.json
(per check: pass / fail, the failure's message, wall s, CPU s of this process and its finished
child processes) and prints a markdown table; exits with status 1 when a check fails.
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import inspect  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from checks import load_all  # noqa: E402
from publish import command, publish, publishable  # noqa: E402
from timing import cpu_s  # noqa: E402

OUT = HERE / "results"


def run(chk):
    """Run one check; its row of the results."""
    row = {"check": chk.name, "origin": chk.origin}
    t0, c0 = time.perf_counter(), cpu_s()
    with tempfile.TemporaryDirectory(prefix="fdid-e2e-") as tmp:
        kw = dict(chk.params)
        if "tmp" in inspect.signature(chk.fn).parameters:
            kw["tmp"] = Path(tmp)
        try:
            chk.fn(**kw)
            row["passed"], row["message"] = True, ""
        except Exception as e:          # noqa: BLE001 -- every failure is reported, the next check runs
            row["passed"] = False
            tb = traceback.extract_tb(e.__traceback__)[-1]
            row["message"] = f"{type(e).__name__}: {str(e)[:400]} ({Path(tb.filename).name}:{tb.lineno})"
    row["wall_s"], row["cpu_s"] = time.perf_counter() - t0, cpu_s() - c0
    return row


def table(rows):
    lines = ["| check | test it was | result | wall s | CPU s |", "|---|---|---|---:|---:|"]
    for r in rows:
        res = "pass" if r["passed"] else f"FAIL: {r['message']}".replace("|", "/")
        lines.append(f"| {r['check']} | {r['origin']} | {res} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} |")
    ok = sum(r["passed"] for r in rows)
    lines.append(f"| all | | {ok} / {len(rows)} passed | {sum(r['wall_s'] for r in rows):.1f} | "
                 f"{sum(r['cpu_s'] for r in rows):.1f} |")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checks", default=None, help="comma-separated substrings of check names or origin tests")
    ap.add_argument("--list", action="store_true", help="list the checks (name, origin test) and exit")
    ap.add_argument("--out", default="bench_end_to_end.json", help="file name in benchmarks/results/")
    args = ap.parse_args(argv)
    checks = load_all()
    if args.checks:
        keys = [k for k in args.checks.split(",") if k]
        checks = [c for c in checks if any(k in c.name or k in c.origin for k in keys)]
        if not checks:
            ap.error(f"no check matches {args.checks!r} (--list shows them)")
    if args.list:
        for c in checks:
            print(f"{c.name}  <-  {c.origin}")
        return 0
    rows = []
    for c in checks:
        rows.append(run(c))
        r = rows[-1]
        print(f"{'pass' if r['passed'] else 'FAIL'} {r['check']} ({r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} CPU-s)"
              + (f": {r['message']}" if not r["passed"] else ""), flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    out = OUT / args.out
    out.write_text(json.dumps({"cpu_count": os.cpu_count(), "checks": rows,
                               "passed": sum(r["passed"] for r in rows), "total": len(rows)}, indent=1))
    print()
    print("\n".join(table(rows)))
    print(f"wrote {out}")
    if publishable(ap, args):
        publish("end_to_end", "End-to-end checks", ["\n".join(table(rows))], command("end_to_end"),
                json.loads(out.read_text()), notes=__doc__.split("\n\n")[0])
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
