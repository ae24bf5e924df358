"""Write the traces the example fleet manifests (plant.toml, plant.csv) read.

Run:  .venv/bin/python examples/fleet/write_traces.py [OUT_DIR]     (default out/fleet_example)

Writes ``OUT_DIR/night1/`` and ``OUT_DIR/night2/`` (two machines, m02 with feed-forward; in
night 2 the friction of m01/x doubles and m02/y gets 20 µm backlash), the generated manifests
``OUT_DIR/night1.toml`` / ``night2.toml`` and a copy of ``plant.toml`` / ``plant.csv``. Then::

    fdid fleet run OUT_DIR/plant.toml  --out OUT_DIR/result_plant
    fdid fleet run OUT_DIR/night1.toml --out OUT_DIR/night1_result
    fdid fleet run OUT_DIR/night2.toml --out OUT_DIR/night2_result --previous OUT_DIR/night1_result
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from fdid_fmi.fleet.virtual import write_virtual_fleet

HERE = Path(__file__).resolve().parent


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", default="out/fleet_example",
                    help="output folder (default out/fleet_example)")
    out = Path(ap.parse_args(sys.argv[1:] if argv is None else argv).out)
    man = write_virtual_fleet(out, n_machines=2, changes={("m01", "x"): "friction", ("m02", "y"): "backlash"},
                              diagnose=False)
    for f in ("plant.toml", "plant.csv"):
        shutil.copy(HERE / f, out / f)
    print(f"traces in {out}/night1, {out}/night2; manifests {', '.join(str(m) for m in man.values())}, "
          f"{out / 'plant.toml'}, {out / 'plant.csv'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
