"""README contract review: the commands and scripts the README names do what it says.

Found by a review of the README as a new user meets it.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# scripts that had no argument parser: ``--help`` was taken as the output folder (files written
# into ./--help/), ran the whole job (bench_rest, diagnose_scenarios: minutes), rewrote the
# tracked example traces (make_example_traces) or ended in a traceback (emps_identify)
NO_PARSER_BEFORE = ["examples/align_virtual.py", "examples/diagnose_scenarios.py",
                    "examples/emps_identify.py", "examples/make_example_traces.py",
                    "examples/fleet/write_traces.py", "benchmarks/bench_rest.py"]


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
