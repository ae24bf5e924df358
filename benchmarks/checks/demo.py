"""``fdid demo`` end to end, as a user runs it (a subprocess, real files)."""
import json
import subprocess
import sys

from checks import check

FDID = [sys.executable, "-m", "fdid_fmi.cli"]


@check("tests/test_cli.py::test_demo_end_to_end")
def demo_end_to_end(tmp):
    r = subprocess.run(FDID + ["demo", "--out", str(tmp / "demo")], capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-2000:]
    out = tmp / "demo"
    for f in ("model.json", "drive.fmu", "report.html", "report.json", "summary.json", "plan.html"):
        assert (out / f).is_file(), f
    s = json.loads((out / "summary.json").read_text())
    # both held-out traces, both axes (README's table); the loops below then check every one
    assert sorted(s["validation"]) == ["circle", "diamond"]
    assert sorted((r["trace"], r["axis"]) for r in s["table"]) == [(t, a) for t in ("circle", "diamond")
                                                                   for a in "xy"]
    for name, v in s["validation"].items():
        assert v["problems"] == [] and v["max_abs_diff_reference_mm"] <= 1e-9, name
    for row in s["table"]:
        assert row["FMU RMS [µm]"] < 0.3 * row["Full LS RMS [µm]"]
    assert "<img" in (out / "report.html").read_text()


@check("tests/test_install.py::test_export_and_demo_outside_the_source_tree (its demo)")
def demo_outside_the_source_tree(tmp):
    """A plain, non-editable install (``pip install --no-deps --target DIR .``, as a wheel would put
    it) runs ``fdid demo`` outside the source tree, with no environment variable and no checkout."""
    import os
    from checks import ROOT
    installed = tmp / "site"
    res = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                          "--target", str(installed), str(ROOT)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    work = tmp / "work"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("FDID")}
    env["PYTHONPATH"] = str(installed)
    res = subprocess.run(FDID + ["demo", "--out", "demo"], cwd=work, env=env, capture_output=True, text=True,
                         timeout=1800)
    assert res.returncode == 0, res.stderr[-3000:]
    assert (work / "demo").is_dir() and any((work / "demo").rglob("*.fmu"))
