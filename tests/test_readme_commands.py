"""The README contract: the commands and scripts the README names do what it says.

The README as a new user meets it.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# every script parses its arguments: without a parser ``--help`` would be taken as the output
# folder (files written into ./--help/), run the whole job (bench_rest, diagnose_scenarios:
# minutes), rewrite the tracked example traces (make_example_traces) or end in a traceback
# (emps_identify)
NO_PARSER_BEFORE = ["examples/align_virtual.py", "examples/diagnose_scenarios.py",
                    "examples/emps_identify.py", "examples/make_example_traces.py",
                    "examples/fleet/write_traces.py", "benchmarks/bench_rest.py",
                    "benchmarks/probe_presliding.py"]


@pytest.mark.parametrize("script", NO_PARSER_BEFORE)
def test_script_help_prints_usage_and_does_nothing(script, tmp_path):
    examples = sorted((ROOT / "examples").glob("virtual_*.csv"))
    before = {p: p.stat().st_mtime_ns for p in examples}
    env = dict(os.environ, PYTHONPATH=str(ROOT / "tests"))
    try:
        r = subprocess.run([sys.executable, str(ROOT / script), "--help"], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{script} --help ran the job instead of printing its usage")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("usage:"), r.stdout[:300]
    assert "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []                      # nothing written
    assert {p: p.stat().st_mtime_ns for p in examples} == before  # example traces untouched


def test_emps_identify_missing_folder_is_one_line(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "examples/emps_identify.py"), str(tmp_path / "none")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0 and "DATA_EMPS.mat" in r.stderr


def test_export_help_says_what_the_python_backend_needs(capsys):
    # the help said the importer needs "Python with numpy"; the FMU's slave imports fdid_fmi
    # (its compiled core steps the model), as the README and fmu/python_backend.py say
    from fdid_fmi.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["export", "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "importer needs Python with fdid-fmi installed" in out
    assert "fdid-fmi[python-backend]" in out
    slave = (ROOT / "src/fdid_fmi/fmu/python_slave_template.py").read_text()
    assert "from fdid_fmi.kernel import" in slave


def test_demo_pocket_corner_is_the_example_program():
    from fdid_fmi.cli.demo import POCKET_CORNER_NC
    assert POCKET_CORNER_NC == (ROOT / "examples" / "pocket_corner.nc").read_text()


_PLAN_IN_INSTALLED = """
import sys
from pathlib import Path
import fdid_fmi
assert Path(fdid_fmi.__file__).resolve().parents[1] == Path(sys.argv[1]).resolve(), fdid_fmi.__file__
from fdid_fmi.identify import identify_full_ls
from fdid_fmi.cli.demo import _plan_example
from fdid_fmi.model import DriveModel
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
cfg = presets.deckel_maho_like()
ms = [identify_full_ls(simulate_machine(MachineConfig(axes=[cfg.axis(a)], Ts=cfg.Ts),
      tj.linear_moves(n_moves=4, axes=(a,), Ts=cfg.Ts, seed=1), seed=1), a) for a in ("x", "y")]
_plan_example(DriveModel.combine(ms, method="full-ls"), Path(sys.argv[2]))
"""


def test_demo_plans_the_example_in_an_installed_package(tmp_path):
    # README: `fdid demo` writes plan.html of examples/pocket_corner.nc, and a plain (not editable)
    # install gives a working fdid; the demo looked for ROOT/examples and silently skipped the plan
    # when the package was installed (no examples/ next to site-packages)
    import shutil
    site = tmp_path / "site"
    shutil.copytree(ROOT / "src" / "fdid_fmi", site / "fdid_fmi",
                    ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path / "out"
    out.mkdir()
    r = subprocess.run([sys.executable, "-c", _PLAN_IN_INSTALLED, str(site), str(out)],
                       cwd=tmp_path, env=dict(os.environ, PYTHONPATH=str(site)),
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "plan of pocket_corner.nc" in r.stdout and "cycle time 2.836 s" in r.stdout, r.stdout
    assert (out / "plan.html").stat().st_size > 0


def test_demo_emps_finds_the_data_from_an_installed_package(tmp_path):
    # `fdid demo --emps` took ../shared/data/emps relative to the package file: in an installed
    # package that is <venv>/lib/shared/data/emps ("file not found" naming a path in the venv);
    # now: next to the source checkout, else ../shared/data/emps from the working directory,
    # else one line asking for --data
    import shutil
    site = tmp_path / "site"
    shutil.copytree(ROOT / "src" / "fdid_fmi", site / "fdid_fmi",
                    ignore=shutil.ignore_patterns("__pycache__"))
    # one process, two working directories: without and with ../shared/data/emps
    code = ("import os, sys\nfrom fdid_fmi.cli import main\n"
            "for d in sys.argv[1:]:\n"
            "    os.chdir(d)\n"
            "    print('rc', main(['demo', '--emps', '--out', 'o']), file=sys.stderr, flush=True)\n")
    (tmp_path / "a" / "work").mkdir(parents=True)
    emps = tmp_path / "b" / "shared" / "data" / "emps"
    emps.mkdir(parents=True)
    (emps / "DATA_EMPS.mat").write_bytes(b"not a mat file")
    (tmp_path / "b" / "work").mkdir()
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a" / "work"), str(tmp_path / "b" / "work")],
                       env=dict(os.environ, PYTHONPATH=str(site)), capture_output=True, text=True, timeout=60)
    assert "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 4 and lines[1] == "rc 2" and lines[3] == "rc 2", r.stderr
    assert lines[0].startswith("fdid demo: error:") and "--data" in lines[0]
    # the data folder at ../shared/data/emps from the working directory is the one read
    assert lines[2].startswith("fdid demo: error:") and "../shared/data/emps/DATA_EMPS.mat" in lines[2]
