"""A plain, non-editable install works outside the source tree: the wheel carries the
compiled simulation core and the C templates, so `fdid export` needs no environment variable and
no checkout (`fdid demo` from such an install: a check of benchmarks/bench_end_to_end.py)."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """`pip install --no-deps --target DIR .`: the package as a wheel would put it (its
    dependencies come from this environment)."""
    target = tmp_path_factory.mktemp("site")
    res = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps",
                          "--no-build-isolation", "--target", str(target), str(ROOT)],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    return target


def _run(installed, cwd, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith("FDID")}
    env["PYTHONPATH"] = str(installed)
    return subprocess.run([sys.executable, "-m", "fdid_fmi.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_installed_package_is_not_the_source_tree(installed, tmp_path):
    res = subprocess.run([sys.executable, "-c", "import fdid_fmi, fdid_fmi._kernel as k; "
                          "print(fdid_fmi.__file__); print(k.__file__)"], cwd=tmp_path,
                         env={**os.environ, "PYTHONPATH": str(installed)}, capture_output=True, text=True)
    pkg, ext = res.stdout.split()
    assert pkg.startswith(str(installed)) and ext.startswith(str(installed)), res.stdout
    assert (installed / "fdid_fmi" / "fmu_templates" / "fdid_core.c").is_file()
    assert (installed / "fdid_fmi" / "fmu_templates" / "include" / "fmi3Functions.h").is_file()


def test_export_outside_the_source_tree(installed, tmp_path):
    import fmu_support as fs
    model = tmp_path / "m.json"
    fs.siso_model().save(model)
    res = _run(installed, tmp_path, "export", str(model), "-o", "drive.fmu")
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "drive.fmu").stat().st_size > 1000
