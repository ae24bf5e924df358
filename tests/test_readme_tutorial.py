"""The README's tutorial, run as a user runs it: every bash and python block of the section
"Tutorial", in order, in a fresh folder holding a copy of the bundled examples.

The python block runs the exported FMU in ``fmpy.simulate_fmu`` fed every sample; its positions
must equal ``fdid simulate``'s (prediction.csv, written by an earlier block) to 1e-9 mm.
"""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
EXAMPLES = ("virtual_xy_moves.csv", "virtual_circle.csv", "pocket_corner.nc")


def section_blocks(heading):
    """The bash and python blocks of the README section whose heading starts with ``heading``."""
    text = README.read_text(encoding="utf-8")
    start = text.index(f"\n## {heading}")
    end = text.index("\n## ", start + 1)
    return re.findall(r"^```(bash|python)\n(.*?)^```", text[start:end], flags=re.S | re.M)


def tutorial_blocks():
    return section_blocks("Tutorial")


def test_readme_is_a_short_guide_with_the_two_setup_commands():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 300
    blocks = "".join(re.findall(r"^```bash\n(.*?)^```", text, flags=re.S | re.M))
    assert re.search(r"^\./run\.sh demo\b", blocks, flags=re.M)
    assert re.search(r"^\./run\.sh test\b", blocks, flags=re.M)
    assert re.search(r"^pip install \.", blocks, flags=re.M)


@pytest.mark.slow   # about 45 CPU-s: identify (rigid, twice: command line and API), export, validate, a short diagnose, plan
def test_tutorial_runs_and_the_fmu_in_fmpy_equals_fdid_simulate(tmp_path, monkeypatch):
    blocks = tutorial_blocks()
    kinds = [k for k, _ in blocks]
    assert "python" in kinds and kinds.count("bash") >= 4, kinds
    (tmp_path / "examples").mkdir()
    for name in EXAMPLES:
        shutil.copy(ROOT / "examples" / name, tmp_path / "examples" / name)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    monkeypatch.chdir(tmp_path)
    ns = {}
    for kind, code in blocks:
        if kind == "bash":
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=tmp_path, env=env,
                               capture_output=True, text=True, timeout=600)
            assert r.returncode == 0, f"{code}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
            assert "Traceback" not in r.stderr
        else:
            exec(compile(code, "README tutorial", "exec"), ns)

    for f in ("model.json", "prediction.csv", "drive.fmu", "model_plus.json", "diagnose.html", "plan.html"):
        assert (tmp_path / f).stat().st_size > 0, f
    pred = np.genfromtxt(tmp_path / "prediction.csv", delimiter=",", names=True)
    res = ns["res"]
    assert len(res) == len(pred)
    assert np.max(np.abs(res["time"] - pred["t_s"])) < 1e-12
    for ax in ("x", "y"):
        assert np.max(np.abs(res[f"{ax}_x"] - pred[f"{ax}_x_pred_mm"])) <= 1e-9, ax
    # the tracking error the tutorial computes is the command minus that position
    d = np.genfromtxt(tmp_path / "examples" / "virtual_circle.csv", delimiter=",", names=True)
    assert np.array_equal(ns["e_x"], d["x_cmd_mm"] - res["x_x"])
    assert np.max(np.abs(ns["e_x"] - pred["x_e_pred_mm"])) <= 1e-9

    # the Python API section, in the same folder: the model the command line identified
    api = section_blocks("Python API")
    assert [k for k, _ in api] == ["python"], api
    ns = {}
    exec(compile(api[0][1], "README Python API", "exec"), ns)
    from fdid_fmi import DriveModel
    cli_model = DriveModel.load(tmp_path / "model.json")
    assert np.array_equal(ns["model"].A, cli_model.A) and np.array_equal(ns["model"].C, cli_model.C)
    assert ns["check"].ok, ns["check"].problems
    assert ns["check"].max_abs_diff_reference_mm <= 1e-9


def test_cli_reference_is_generated_from_the_help_pages(tmp_path):
    # docs/cli.md is written by docs/make_cli_md.py; a changed option must be regenerated there
    script = tmp_path / "make_cli_md.py"
    shutil.copy(ROOT / "docs" / "make_cli_md.py", script)
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "cli.md").read_text(encoding="utf-8") == \
        (ROOT / "docs" / "cli.md").read_text(encoding="utf-8"), \
        "docs/cli.md is out of date: run .venv/bin/python docs/make_cli_md.py"


def test_cli_reference_examples_parse():
    import shlex
    from fdid_fmi.cli import build_parser
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    block = re.search(r"^## Examples\n\n```bash\n(.*?)^```", text, flags=re.S | re.M).group(1)
    parser = build_parser()
    lines = [ln for ln in block.splitlines() if ln.strip()]
    assert len(lines) >= 10
    for line in lines:
        parser.parse_args(shlex.split(line.split("  #")[0])[1:])
