"""The ``fdid`` command line end to end, as a user runs it (subprocess, real files). ``fdid demo``
end to end is a check of ``benchmarks/bench_end_to_end.py`` (``checks/demo.py``)."""
import json
import subprocess
import sys

import numpy as np
import pytest

FDID = [sys.executable, "-m", "fdid_fmi.cli"]


def fdid(*args, cwd=None):
    return subprocess.run(FDID + [str(a) for a in args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def test_identify_simulate_on_emps(shared_data, tmp_path):
    mat = shared_data / "emps" / "DATA_EMPS.mat"
    # a short search: this is the command line's path, not the search's result (bench_end_to_end.py)
    r = fdid("identify", mat, "--no-integral-action", "--maxiter", "3", "-o", tmp_path / "m.json")
    assert r.returncode == 0, r.stderr
    assert "pred-err RMS um" in r.stdout and (tmp_path / "m.json").is_file()
    r = fdid("simulate", tmp_path / "m.json", shared_data / "emps" / "DATA_EMPS_PULSES.mat",
             "-o", tmp_path / "p.csv")
    assert r.returncode == 0, r.stderr
    head = (tmp_path / "p.csv").read_text().splitlines()[0]
    assert head == "t_s,x_x_pred_mm,x_e_pred_mm"
    data = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    assert data.shape == (24841, 3) and np.all(np.isfinite(data))


@pytest.mark.parametrize("method", ["quasi-static", "full-ls"])
def test_baseline_methods_from_csv(tmp_path, method):
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    tr = simulate_machine(MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts),
                          tj.linear_moves(n_moves=6, axes=("x",), Ts=cfg.Ts, seed=1), seed=1)
    csv = tmp_path / "run.csv"
    np.savetxt(csv, np.column_stack([tr.t, tr.cmd("x"), tr.act("x")]), delimiter=",",
               header="t_s,x_cmd_mm,x_motor_mm", comments="", fmt="%.10g")
    before = csv.read_bytes()
    r = fdid("identify", csv, "--method", method, "-o", tmp_path / "m.json",
             "--map", "t=t_s", "x.cmd=x_cmd_mm", "x.act=x_motor_mm")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "m.json").read_text())["format"] == "fdid-fmi-model"
    assert csv.read_bytes() == before                     # the user's file is untouched


def test_bad_input_is_one_clear_line(tmp_path):
    csv = tmp_path / "bad.csv"
    csv.write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.001,abc,0\n0.002,1,1\n")
    r = fdid("identify", csv, "-o", tmp_path / "m.json")
    assert r.returncode == 2
    assert "bad.csv" in r.stderr and "x_cmd_mm" in r.stderr and "Traceback" not in r.stderr
    r = fdid("simulate", tmp_path / "nope.json", csv)
    assert r.returncode == 2 and "nope.json" in r.stderr and "Traceback" not in r.stderr

