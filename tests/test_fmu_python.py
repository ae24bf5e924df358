"""pythonfmu backend: builds, validates and runs in fmpy with the reference semantics."""
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.validate import run_fmu
from fdid_fmi.simulate import simulate

pytest.importorskip("pythonfmu", reason="the python backend needs pythonfmu (pip install pythonfmu)")


def test_python_backend_runs_in_fmpy_like_the_reference(tmp_path):
    from fmpy.validation import validate_fmu as fmpy_validate
    m = fs.feature_model()
    fmu = export_fmu(m, tmp_path / "py.fmu", backend="python")
    assert fmpy_validate(str(fmu)) == []
    with zipfile.ZipFile(fmu) as zf:
        names = zf.namelist()
    assert "resources/fdid_layout.json" in names and "binaries/linux64/py.so" in names
    rng = np.random.default_rng(9)
    n = 1500
    cmds = {"x": fs.smooth_moves(n, rng, start=2.0, v_start=20.0)}
    ext = {"force_N": np.cos(np.arange(n) * 0.02)}
    v0 = {"x": (cmds["x"][1] - cmds["x"][0]) / m.Ts}
    ref = simulate(m, cmds, Ts=m.Ts, start_velocity=v0, externals=ext)
    out = run_fmu(fmu, cmds, m.Ts, start_velocity=v0, externals=ext, comm_step=1)
    assert np.abs(out["x_x"] - ref.axes["x"]["position"]).max() <= 1e-9
    assert np.abs((cmds["x"] - out["x_x"]) - ref.axes["x"]["error"]).max() <= 1e-9
    c_fmu = export_fmu(m, tmp_path / "c.fmu")
    out_c = run_fmu(c_fmu, cmds, m.Ts, start_velocity=v0, externals=ext)
    assert np.abs(out["x_x"] - out_c["x_x"]).max() <= 1e-9


def test_python_and_c_fmus_agree_bit_for_bit_even_in_stick_slip(tmp_path):
    """Both backends run the same C core: identical outputs, even on a trace whose
    friction stick-slip amplifies any rounding difference (a 1e-12 mm change of the commands
    moves the result by more than 1e-6 mm)."""
    m = fs.coupled_model(vt_y=0.3)
    n = 1500
    rng = np.random.default_rng(4)
    cmds = {a: fs.smooth_moves(n, rng, start=2.0 + i) for i, a in enumerate(m.axes)}
    outs = ["x_x", "x_v", "y_x", "y_v", "x_dnf", "y_dnf"]
    py = run_fmu(export_fmu(m, tmp_path / "py.fmu", backend="python"), cmds, m.Ts, outputs=outs)
    c = run_fmu(export_fmu(m, tmp_path / "c.fmu"), cmds, m.Ts, outputs=outs)
    for k in outs:
        assert np.array_equal(py[k], c[k]), k
    c_fmu = tmp_path / "c.fmu"
    bumped = {a: v + 1e-12 * rng.standard_normal(n) for a, v in cmds.items()}
    c2 = run_fmu(c_fmu, bumped, m.Ts, outputs=["y_x"])
    assert np.abs(c2["y_x"] - c["y_x"]).max() > 1e-6            # the regime is chaotic


def test_python_backend_is_fmi2_only(tmp_path):
    with pytest.raises(InputError, match="FMI 2.0"):
        export_fmu(fs.siso_model(), tmp_path / "p.fmu", backend="python", fmi_version=3)


def test_python_backend_steps_like_the_c_fmu_on_long_runs_and_off_grid_stops(tmp_path):
    """The step rule of the C FMU (test_fmu_master_calls.py): the end of a step is put on the
    sample grid from its end time, and the FMU steps in whole samples only."""
    from fmpy import read_model_description, simulate_fmu
    m = fs.siso_model()
    fmu = str(export_fmu(m, tmp_path / "p.fmu", backend="python"))
    assert read_model_description(fmu).coSimulation.canHandleVariableCommunicationStepSize is False
    res = simulate_fmu(fmu, start_time=8192.0, stop_time=8192.02, output_interval=m.Ts, output=["x_x"])
    assert len(res) == 21 and np.isfinite(res["x_x"]).all()
    res = simulate_fmu(fmu, stop_time=10.5 * m.Ts, output_interval=m.Ts, output=["x_x"])
    assert res["time"][-1] == pytest.approx(10 * m.Ts)
    # refusals (off grid, wrong time, past the stop time) in a child process: pythonfmu turns
    # the slave's exception into fmi2Fatal, and after freeing such an instance a later garbage
    # collection crashed the host (pythonfmu 0.7.0), so the child leaves with os._exit
    child = f"""
import os
import shutil
from fdid_fmi.fmu.validate import FmuRunner
for t, h, stop in ((0.0, 1.45 * {m.Ts!r}, None), (1.0, {m.Ts!r}, None), (0.0, 3 * {m.Ts!r}, 2 * {m.Ts!r})):
    r = FmuRunner({fmu!r})
    r.start(0.0, stop)
    r.fmu.exitInitializationMode()
    try:
        r.fmu.doStep(t, h)
        print("stepped", flush=True)
    except Exception as exc:
        print("refused", getattr(exc, "status", None), flush=True)
    shutil.rmtree(r._dir, ignore_errors=True)   # the extracted FMU (its library stays mapped)
os._exit(0)
"""
    out = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, timeout=120)
    assert out.stdout.split() == ["refused", "4"] * 3, (out.stdout, out.stderr[-2000:])


def test_python_backend_refuses_a_v_tilde_the_friction_solve_cannot_resolve(tmp_path, capfd):
    # as the C FMU does: checked where the solve runs; pythonfmu reports the
    # refusal as fmi2Fatal (any exception of the slave), the C FMU as fmi2Error
    from fmpy import simulate_fmu
    from fmpy.fmi1 import FMICallException
    from test_model_json import LO, TS, two_axis
    from fdid_fmi.model import DriveModel
    fmu = str(export_fmu(DriveModel.from_dict(two_axis()), tmp_path / "p.fmu", backend="python"))
    with pytest.raises(FMICallException, match="status 4"):
        simulate_fmu(fmu, stop_time=0.01, output_interval=TS, start_values={"y_v_tilde": 1e-20},
                     debug_logging=True)
    assert "v_tilde must be at least 1e-13 mm/s at friction level 1, got 1e-20" in capfd.readouterr().out
    r = simulate_fmu(fmu, stop_time=0.01, output_interval=TS,
                     start_values={"x_v_tilde": 0.5 * LO, "x_friction_level": 0.1})
    assert np.isfinite(r["x_x"]).all()
