"""Peak resident memory and time of `fdid identify --method quasi-static` on long traces.

A controller trace of 10^7 rows and 3 columns (time, commanded and measured position) is 320 MB
of CSV and 240 MB of float64 numbers; identification should hold a small multiple of that, not
twenty times it. Each run is a fresh `fdid` process measured with `/usr/bin/time -v` (maximum
resident set size, wall and CPU time); with `--other VENV` the same traces go through another
version's `fdid` in the same run, side by side:

    .venv/bin/python benchmarks/bench_memory.py [--rows 1e6,1e7] [--other OLD/.venv]

Writes benchmarks/results/bench_memory.json and prints a table.
"""
import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from publish import command, md_table, publish, publishable

OUT = Path(__file__).resolve().parent / "results"


def write_trace(path, n, seed=0):
    """A random-walk command and a measurement 0.1 um off it, 1 kHz, ``n`` rows, in blocks."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as fh:
        fh.write("t_s,x_cmd_mm,x_mm\n")
        x0 = 0.0
        for k0 in range(0, n, 10 ** 6):
            k = np.arange(k0, min(n, k0 + 10 ** 6))
            x = x0 + np.cumsum(rng.normal(0.0, 0.01, k.size))
            x0 = x[-1]
            a = x + rng.normal(0.0, 1e-4, k.size)
            np.savetxt(fh, np.column_stack([k * 1e-3, x, a]), delimiter=",", fmt="%.9g")


def measure(fdid, trace, out):
    """(peak RSS in MB, wall s, CPU s) of one `fdid identify --method quasi-static` run."""
    res = subprocess.run(["/usr/bin/time", "-v", str(fdid), "identify", str(trace), "--method", "quasi-static",
                          "-o", str(out)], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"{fdid} failed on {trace}:\n{res.stdout}\n{res.stderr}")

    def field(name):
        return re.search(rf"{re.escape(name)}: (.*)", res.stderr).group(1).strip()
    wall = field("Elapsed (wall clock) time (h:mm:ss or m:ss)").split(":")
    wall_s = sum(float(v) * 60 ** i for i, v in enumerate(reversed(wall)))
    cpu_s = float(field("User time (seconds)")) + float(field("System time (seconds)"))
    return int(field("Maximum resident set size (kbytes)")) * 1024 / 1e6, wall_s, cpu_s


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", default="1e6,1e7", help="trace lengths, comma separated (default 1e6,1e7)")
    ap.add_argument("--other", help="another version's virtual environment (its bin/fdid is run too)")
    ap.add_argument("--out", default=str(OUT / "bench_memory.json"))
    a = ap.parse_args()
    versions = {"this": Path(sys.executable).parent / "fdid"}
    if a.other:
        versions["other"] = Path(a.other) / "bin" / "fdid"
    rows = [int(float(r)) for r in a.rows.split(",")]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in rows:
            trace = Path(tmp) / f"trace_{n}.csv"
            write_trace(trace, n)
            for label, fdid in versions.items():
                rss, wall, cpu = measure(fdid, trace, Path(tmp) / f"{label}_{n}.json")
                results.append({"rows": n, "file_mb": trace.stat().st_size / 1e6, "version": label,
                                "peak_rss_mb": rss, "wall_s": wall, "cpu_s": cpu})
            trace.unlink()
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps({"command": "fdid identify TRACE --method quasi-static",
                                       "runs": results}, indent=1))
    res = json.loads(Path(a.out).read_text())
    print(tables(res)[0])
    print(f"written {a.out}")
    if publishable(ap, a):
        publish("memory", "Memory of a long identification", tables(res), command("memory"), res,
                notes="`fdid identify TRACE --method quasi-static` on a generated controller trace (time, "
                      "commanded and measured position; 1 kHz random walk), each a fresh `fdid` process "
                      "measured with `/usr/bin/time -v`: maximum resident set size, wall and CPU time.")


def tables(res):
    """The markdown table of a run's result."""
    return [md_table(["rows", "CSV [MB]", "version", "peak RSS [MB]", "wall [s]", "CPU [s]"],
                     [[f"{r['rows']:.0e}", f"{r['file_mb']:.0f}", r["version"], f"{r['peak_rss_mb']:.0f}",
                       f"{r['wall_s']:.1f}", f"{r['cpu_s']:.1f}"] for r in res["runs"]],
                     ["r", "r", "l", "r", "r", "r"])]

if __name__ == "__main__":
    main()
