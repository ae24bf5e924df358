"""A small virtual fleet end to end: local process pool, Dask LocalCluster, a killed worker, reruns.

Four axes (two machines, one with feed-forward), short traces (4 moves, ~2 s at 1 ms), diagnosis
off (the fleet option; diagnosis itself is tested in test_diagnose_*). Night 2 doubles the friction
of m01/x and adds 20 µm backlash to m02/y.
"""
import json
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.cli import main as cli_main
from fdid_fmi.fleet import load_fleet_result, run_fleet
from fdid_fmi.fleet.virtual import write_virtual_fleet
from fdid_fmi.model import load_model

CHANGES = {("m01", "x"): "friction", ("m02", "y"): "backlash"}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    # the fleet, not the identification, is under test: the rigid structure and a short search
    man = write_virtual_fleet(root / "data", n_machines=2, changes=CHANGES, n_moves=4, diagnose=False,
                              extra_options={"structure": "rigid", "maxiter": 8})
    # night 1 plus three broken entries: a missing file, an unknown column, a bad option
    text = man[1].read_text() + """
[[entry]]
machine = "m09"
axis = "x"
traces = ["night1/no_such_file.csv"]

[[entry]]
machine = "m01"
axis = "z"
traces = ["night1/m01_x.csv"]
map = { t = "t_s", "z.cmd" = "x_cmd_mm", "z.act" = "x_position_mm" }

[[entry]]
machine = "m02"
axis = "z"
traces = ["night1/m02_x.csv"]
options = { search = "random-walk" }
"""
    broken = root / "data" / "night1_broken.toml"
    broken.write_text(text)
    out1 = root / "local1"
    night1 = run_fleet(broken, out1, workers=2, progress=False)
    return {"root": root, "man": man, "broken": broken, "out1": out1, "night1": night1}


def _no_temp_files(folder):
    return [p for p in Path(folder).rglob("*") if p.name.endswith(".part") or p.name.startswith(".")]


def test_night1_local_pool_with_broken_entries(fleet):
    fr = fleet["night1"]
    assert fr.executor.startswith("local pool")
    ok = {e.key for e in fr.entries if e.ok}
    assert ok == {"m01/x", "m01/y", "m02/x", "m02/y"}
    errors = {e.key: e.error for e in fr.failed}
    assert set(errors) == {"m09/x", "m01/z", "m02/z"}
    assert "no_such_file.csv" in errors["m09/x"] and "not found" in errors["m09/x"]
    assert "x_position_mm" in errors["m01/z"]
    assert "random-walk" in errors["m02/z"]
    assert all("\n" not in e for e in errors.values())
    for e in fr.entries:
        if e.ok:
            d = fleet["out1"] / "entries" / f"{e.machine}__{e.axis}"
            assert {"model.json", "validation.json", "entry.json", "entry.html"} <= {p.name for p in d.iterdir()}
            assert (d / e.outputs["fmu"]).stat().st_size > 1000
            assert all(v.max_abs_diff_reference_mm <= 1e-9 and not v.problems for v in e.validation)
            assert e.timings.identify_s > 0 and e.timings.export_s > 0 and e.timings.validate_s > 0
    assert not _no_temp_files(fleet["out1"])
    # the fleet report: a JSON table (one row per entry) and the HTML with the one-line reasons
    d = json.loads((fleet["out1"] / "fleet.json").read_text())
    assert [r["machine"] + "/" + r["axis"] for r in d["table"]] == [e.key for e in fr.entries]
    assert d["counts"] == {"entries": 7, "ok": 4, "failed": 3, "validation_failed": 0, "changed": 0}
    html = (fleet["out1"] / "fleet.html").read_text()
    assert "no_such_file.csv" in html and "random-walk" in html


def test_night2_flags_exactly_the_changed_axes_and_rerun_does_nothing(fleet):
    out2 = fleet["root"] / "local2"
    fr = run_fleet(fleet["man"][2], out2, previous=fleet["out1"], workers=2, progress=False)
    assert not fr.failed
    flagged = {e.key: e.change.kinds for e in fr.changed}
    assert flagged == {"m01/x": ["friction"], "m02/y": ["backlash"]}
    assert "friction level up" in fr.entry("m01/x").change.summary
    assert fr.entry("m01/x").change.friction_rel > 0.4            # truth: Coulomb x 2
    assert 12 < fr.entry("m02/y").change.estimates["backlash_um"] < 28     # truth: 20 µm
    for k in ("m01/y", "m02/x"):
        assert fr.entry(k).change is not None and not fr.entry(k).change.changed
    summary = "\n".join(fr.summary())
    assert "CHANGED m01/x" in summary and "CHANGED m02/y" in summary and "m01/y" not in summary
    # nothing changed: no work, same report
    again = run_fleet(fleet["man"][2], out2, previous=fleet["out1"], workers=2, progress=False)
    assert again.executed == [] and sorted(again.skipped) == sorted(e.key for e in fr.entries)
    assert {e.key for e in again.changed} == set(flagged)
    assert load_fleet_result(out2).executed == []
    # the CLI over the same folder: nothing to do, exit 0, the changed axes listed
    rc = cli_main(["fleet", "run", str(fleet["man"][2]), "--out", str(out2), "--previous",
                   str(fleet["out1"]), "--no-progress"])
    assert rc == 0
    # a changed trace file redoes that entry only
    f = fleet["root"] / "data" / "night2" / "m02_x.csv"
    f.write_text(f.read_text() + "\n")
    third = run_fleet(fleet["man"][2], out2, previous=fleet["out1"], workers=1, progress=False)
    assert third.executed == ["m02/x"]


def test_dask_cluster_same_results_and_killed_worker(fleet):
    """Night 1 on a LocalCluster with 2 workers; one worker process is killed (SIGKILL) while it runs an
    entry. The run plus one rerun complete every entry exactly once, with the local pool's results."""
    from distributed import Client, LocalCluster
    out = fleet["root"] / "dask1"
    man = fleet["man"][1]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=40) as cluster, Client(cluster) as client:
        box = {}
        th = threading.Thread(target=lambda: box.setdefault("r", run_fleet(man, out, client=client,
                                                                           progress=False)))
        th.start()
        victim, key = None, None
        t_end = time.time() + 120
        while time.time() < t_end and victim is None:
            # kill a worker after the first entry finished, while it is running another one
            if any((out / "entries").glob("*/entry.json")):
                busy = {w: ks for w, ks in client.processing().items() if ks}
                if busy:
                    victim, keys = next(iter(busy.items()))
                    key = next(iter(keys))
                    pid = client.run(os.getpid, workers=[victim])[victim]
                    os.kill(pid, signal.SIGKILL)       # the worker process dies mid-entry
            time.sleep(0.05)
        th.join(300)
        assert victim is not None, "no worker was busy after the first entry"
        first = box["r"]
        rerun = run_fleet(man, out, client=client, progress=False)
    assert first.executor.startswith("dask")
    lost = {e.key for e in first.failed}
    assert set(rerun.executed) == lost                   # the rerun does exactly what was lost
    assert all(e.ok for e in rerun.entries) and len(rerun.entries) == 4
    assert sorted(e.key for e in rerun.entries) == sorted({e.key for e in rerun.entries})
    # the entry in flight on the killed worker was finished by another process
    dirname = key.split("fdid-fleet-")[1].rsplit("-", 2)[0]
    done = next(e for e in rerun.entries if f"{e.machine}__{e.axis}" == dirname)
    assert done.worker.split(":")[1] != str(pid)
    assert not _no_temp_files(out)
    assert len(list((out / "entries").glob("*/entry.json"))) == 4
    # same results as on the local pool: identical models and figures
    for e in rerun.entries:
        loc = fleet["night1"].entry(e.key)
        a = load_model(out / "entries" / f"{e.machine}__{e.axis}" / "model.json")
        b = load_model(fleet["out1"] / "entries" / f"{e.machine}__{e.axis}" / "model.json")
        for m in "ABCD":
            np.testing.assert_array_equal(getattr(a, m), getattr(b, m))
        assert e.errors_um == loc.errors_um
        assert [v.rms_um for v in e.validation] == [v.rms_um for v in loc.validation]


def test_local_pool_killed_worker(fleet):
    """A local pool process killed (SIGKILL) mid-run: the broken pool is replaced, the entries that
    were not finished are resubmitted, and every entry is done exactly once."""
    import psutil
    out = fleet["root"] / "killed_local"
    box = {}
    th = threading.Thread(target=lambda: box.setdefault("r", run_fleet(fleet["man"][1], out, workers=2,
                                                                       progress=False)))
    th.start()
    killed = None
    t_end = time.time() + 120
    while time.time() < t_end and killed is None:
        if any((out / "entries").glob("*/entry.json")):
            pool = [p for p in psutil.Process().children()
                    if "spawn_main" in " ".join(p.cmdline()) and p.is_running()]
            if pool:
                killed = pool[0].pid
                os.kill(killed, signal.SIGKILL)
        time.sleep(0.05)
    th.join(300)
    assert killed is not None
    fr = box["r"]
    assert all(e.ok for e in fr.entries), [e.error for e in fr.entries]
    pids = {e.worker.split(":")[1] for e in fr.entries}
    assert len(pids) >= 2          # the work was spread over the pool (and its replacement)
    assert len(list((out / "entries").glob("*/entry.json"))) == 4
    assert not _no_temp_files(out)
    assert run_fleet(fleet["man"][1], out, workers=2, progress=False).executed == []


def test_ctrl_c_stops_the_local_pool_now(fleet):
    """Ctrl-C (SIGINT to the command's process group, as a terminal sends it) during the first
    entry: the command stops within seconds and no entry is finished after it (a plain shutdown
    of the pool waits for the running entry and runs the one queued behind it in full)."""
    import subprocess
    import sys
    out = fleet["root"] / "interrupted"
    p = subprocess.Popen([sys.executable, "-m", "fdid_fmi.cli", "fleet", "run", str(fleet["man"][1]), "--out",
                          str(out), "--workers", "1", "--no-progress"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True,
                         # SIGINT at its default (pytest-xdist's workers ignore it, and the child
                         # would inherit that: Python then never raises KeyboardInterrupt)
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t_end = time.time() + 120
    while time.time() < t_end and not any((out / "entries").glob("*/*")):    # the first entry at work
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGINT)
    t0 = time.time()
    _, err = p.communicate(timeout=60)
    stopped = time.time() - t0
    time.sleep(3)                   # nothing goes on behind the command's back
    assert p.returncode == 130 and "interrupted" in err, err
    assert stopped < 5, stopped     # measured: 0.3 s (6-9 s with an entry more run in full)
    assert not list((out / "entries").glob("*/entry.json"))
    assert not _no_temp_files(out)
