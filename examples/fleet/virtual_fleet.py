"""A virtual plant fleet run for two nights: which axes changed?

Run:  .venv/bin/python examples/fleet/virtual_fleet.py OUT_DIR [--machines 20] [--workers 2]
      [--no-diagnose] [--scheduler tcp://...]

1. writes the traces of ``--machines`` two-axis machines (m02, m04, ... with feed-forward) for
   night 1 and night 2 plus one manifest per night (``OUT_DIR/data/night<N>.toml``); in night 2
   every 5th axis has a plant change (friction x2, 20 µm backlash, a 30 Hz tool-side mode),
   listed in ``OUT_DIR/data/truth.json``;
2. ``fdid fleet run`` night 1, then night 2 against night 1, then night 2 again (nothing to do);
3. prints the flagged axes against the truth and writes ``OUT_DIR/acceptance.json``.

The same from the command line::

    fdid fleet run OUT_DIR/data/night1.toml --out OUT_DIR/night1
    fdid fleet run OUT_DIR/data/night2.toml --out OUT_DIR/night2 --previous OUT_DIR/night1
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fdid_fmi.fleet import run_fleet
from fdid_fmi.fleet.virtual import write_virtual_fleet


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--machines", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--no-diagnose", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    t0 = time.perf_counter()
    man = write_virtual_fleet(out / "data", n_machines=args.machines, diagnose=not args.no_diagnose)
    truth = json.loads((out / "data" / "truth.json").read_text())
    print(f"traces and manifests written in {time.perf_counter() - t0:.1f} s: {man}")
    runs = {}
    kw = dict(workers=args.workers, scheduler=args.scheduler)
    runs["night1"] = run_fleet(man[1], out / "night1", **kw)
    runs["night2"] = run_fleet(man[2], out / "night2", previous=out / "night1", **kw)
    runs["night2_rerun"] = run_fleet(man[2], out / "night2", previous=out / "night1", **kw)
    for name, fr in runs.items():
        print(f"\n## {name}")
        print("\n".join(fr.summary()))
    fr = runs["night2"]
    flagged = {e.key: e.change.kinds for e in fr.changed}
    true = {f"{a['machine']}/{a['axis']}": a["change"] for a in truth["axes"] if a["change"]}
    rows = []
    print("\n| axis | preset | truth | flagged | named |")
    print("|---|---|---|---|---|")
    for a in truth["axes"]:
        k = f"{a['machine']}/{a['axis']}"
        if a["change"] or k in flagged:
            named = fr.entry(k).change.summary if k in flagged else ""
            print(f"| {k} | {a['preset']} | {a['change'] or 'none'} | {'yes' if k in flagged else 'no'} | {named} |")
            rows.append({"axis": k, "truth": a["change"], "flagged": k in flagged, "kinds": flagged.get(k, [])})
    tp = sum(1 for k in true if k in flagged)
    fp = sum(1 for k in flagged if k not in true)
    named_right = sum(1 for k, v in true.items() if v in flagged.get(k, []))
    res = {"axes": len(truth["axes"]), "true_changes": len(true), "flagged": len(flagged), "true_positive": tp,
           "false_positive": fp, "named_right": named_right, "rows": rows,
           "wall_s": {n: r.wall_s for n, r in runs.items()},
           "executed": {n: len(r.executed) for n, r in runs.items()},
           "failed": {n: len(r.failed) for n, r in runs.items()},
           "executor": runs["night1"].executor}
    print(f"\n{tp}/{len(true)} changed axes flagged, {fp} false alarm(s), {named_right} named right; "
          f"wall {res['wall_s']}; rerun executed {res['executed']['night2_rerun']} entries")
    (out / "acceptance.json").write_text(json.dumps(res, indent=1))
    return 0 if (tp == len(true) and fp == 0) else 1


if __name__ == "__main__":
    raise SystemExit(main())
