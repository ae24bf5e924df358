"""The README's short results table, made from the figures the benchmarks published in
docs/results/*.json; rewrites README.md between ``<!-- results:begin -->`` and
``<!-- results:end -->`` (``./run.sh bench`` runs it after the benchmarks).

    .venv/bin/python benchmarks/readme_table.py [--check]

``--check``: exit with status 1 when the README's table is not the one the published figures give.
"""
import argparse
import json
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs" / "results"
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
SOURCES = ("demo", "emps", "simulate")


def _load(folder, name):
    path = Path(folder) / f"{name}.json"
    if not path.is_file():
        raise SystemExit(f"readme_table.py: {path} is missing: run ./run.sh bench {name}")
    return json.loads(path.read_text())["data"]


def _span(values, fmt):
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else f"{fmt.format(lo)}–{fmt.format(hi)}"


def _link(name):
    return f"[{name}](docs/results/{name}.md)"


def render(folder=DOCS):
    """The markdown block (without the markers) from docs/results/{demo,emps,simulate}.json."""
    demo, emps, sim = (_load(folder, n) for n in SOURCES)
    t = demo["table"]
    virtual = ["virtual two-axis machine, circle and diamond, tracking-error discrepancy",
               _span([r["FMU RMS [µm]"] for r in t], "{:.3f}"), _span([r["Full LS RMS [µm]"] for r in t], "{:.2f}"),
               _span([r["quasi-static RMS [µm]"] for r in t], "{:.1f}"), "", _link("demo")]
    rows = {r["model"]: r for r in emps["rows"]}
    default = next(r for r in emps["rows"] if r["kind"] == "default")
    full_ls = next(r for r in emps["rows"] if r["model"].startswith("Full LS"))
    qs = rows["quasi-static"]
    narx = next((r for r in emps["rows"] if r.get("tuned")), None)
    pub = emps["published_um"]

    def emps_row(what, key, published):
        peer = f"NARX {narx[key]:.2f}" if narx else ""
        peer += (", " if peer else "") + f"physics model ≈ {published}" if published else ""
        return [what, f"{default[key]:.2f}", f"{full_ls[key]:.2f}", f"{qs[key]:.1f}", peer, _link("emps")]
    fmu = max(demo["fmu_max_abs_diff_mm"].values())
    speed = {r["states"]: r for r in sim["rows"]}
    fast, coupled = speed[min(speed)], speed[max(speed)]
    runs = {r["command"]: r for r in demo["runs"]}
    ident = next((r for c, r in runs.items() if c.startswith("fdid identify") and "--structure" not in c), None)
    demo_run = next(r for c, r in runs.items() if c.startswith("fdid demo"))
    lines = ["| measured (free-run RMS in µm unless stated) | fdid-fmi | Full LS | quasi-static | peer | page |",
             "|---|---:|---:|---:|---|---|",
             "| " + " | ".join(virtual) + " |",
             "| " + " | ".join(emps_row("EMPS (real data), training record DATA_EMPS, position",
                                         "train_all_um", pub["train"])) + " |",
             "| " + " | ".join(emps_row("EMPS, validation: DATA_EMPS_PULSES before the first force pulse",
                                         "pulses_before_1st_um", None)) + " |",
             f"| FMU through fmpy against the model, max \\|difference\\| [mm] | {fmu:.2g} | | | | {_link('demo')} |",
             f"| simulation core, M samples per CPU-s: 3rd-order axis / coupled X/Y ({coupled['states']} states) | "
             f"{fast['compiled_cpu_samples_per_s'] / 1e6:.1f} / {coupled['compiled_cpu_samples_per_s'] / 1e6:.1f} "
             f"| | | Python loop {fast['python_cpu_samples_per_s'] / 1e6:.3f} / "
             f"{coupled['python_cpu_samples_per_s'] / 1e6:.3f} | {_link('simulate')} |"]
    if ident:
        lines.append(f"| `fdid identify examples/virtual_xy_moves.csv`, wall / CPU [s] | {ident['wall_s']:.1f} / "
                     f"{ident['cpu_s']:.1f} | | | | {_link('demo')} |")
    lines.append(f"| `fdid demo`, wall / CPU [s] | {demo_run['wall_s']:.1f} / {demo_run['cpu_s']:.1f} | | | | {_link('demo')} |")
    return "\n".join(lines)


def current(text):
    """The block between the markers of a README text."""
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[a:b].strip("\n")


def update(readme=README, folder=DOCS):
    """Rewrite the block in ``readme``; True when it changed."""
    text = Path(readme).read_text()
    new = render(folder)
    if current(text) == new:
        return False
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    tmp = Path(readme).with_name(f".{Path(readme).name}.{os.getpid()}.tmp")
    tmp.write_text(text[:a] + "\n" + new + "\n" + text[b:])
    os.replace(tmp, readme)
    return True


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="only check that the README's table is current")
    a = ap.parse_args(argv)
    if a.check:
        ok = current(README.read_text()) == render()
        print("README results table is current" if ok else "README results table differs: run "
              ".venv/bin/python benchmarks/readme_table.py")
        return 0 if ok else 1
    print("README.md results table " + ("rewritten" if update() else "unchanged"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
