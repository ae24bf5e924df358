"""FMUs of IDENTIFIED models: a flexible-mode model and a coupled two-axis model
(the SISO EMPS model is in test_fmu_validate.py) exported as FMUs, validated through fmpy on a
held-out trace, equal to the reference simulator and to a C host run, and as good against the
measurement as the model itself. The models are stored (``tests/data/make_fitted_models.py``)."""
import shutil
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.fmu import export_fmu, validate_fmu
from fdid_fmi.fmu.validate import run_fmu
from fdid_fmi.metrics import rms
from fdid_fmi.model import load_model
from fdid_fmi.simulate import simulate
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fmu_support.host import build_host, run_host


DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def flexible(tmp_path_factory):
    """The flexible Y axis fitted on velocity and tool position; a held-out trace of 6 moves."""
    cfg = presets.flexible_y()
    m = load_model(DATA / "flexible_tool_model.json")
    val = simulate_machine(MachineConfig(axes=[cfg.axis("y")], Ts=cfg.Ts),
                           tj.linear_moves(n_moves=6, axes=("y",), Ts=cfg.Ts, seed=9), seed=9)
    fmu = export_fmu(m, tmp_path_factory.mktemp("flex") / "flex.fmu")
    return m, val, fmu


@pytest.fixture(scope="module")
def coupled(tmp_path_factory):
    """The coupled two-axis model (one 6th-order denominator) fitted on a spiral; a circle held out."""
    cfg = presets.coupled_xy()
    Ts = cfg.Ts
    m = load_model(DATA / "coupled_xy_model.json")
    val = simulate_machine(cfg, tj.circle(Ts=Ts), seed=3)
    d = tmp_path_factory.mktemp("coupled")
    return m, val, export_fmu(m, d / "coupled.fmu"), d


def _check(model, trace, fmu):
    res = validate_fmu(fmu, trace, model=model)
    assert res.problems == []
    assert res.max_abs_diff_reference_mm <= 1e-9
    sim = simulate(model, trace)
    for ax in model.axes:
        # a tool-side model is compared with the tool-side measurement (read here, not through
        # metrics.measured_position, which validate_fmu uses too: ignoring the side passed)
        side = model.position_side(ax)
        e = trace.cmd(ax) - (trace.get(ax, "tool") if side == "tool" else trace.act(ax))
        own = rms(sim.axes[ax]["error"] - e) * 1e3
        assert res.axes[ax]["rms_um"] == pytest.approx(own, rel=1e-6, abs=1e-9)
    return res


def test_flexible_mode_model_fmu(flexible):
    m, val, fmu = flexible
    assert any(p.kind == "tool_position" for p in m.outputs) and m.position_side("y") == "tool"
    _check(m, val, fmu)


def test_coupled_model_fmu_in_fmpy_and_c_host(coupled):
    m, val, fmu, d = coupled
    assert sum(p.kind == "friction" for p in m.inputs) == 2   # the 2-input exact friction solve
    res = _check(m, val, fmu)
    assert res.contour is not None
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed")
    n = 1500
    cmds = {a: val.cmd(a)[:n] for a in m.axes}
    outs = [f"{a}_{k}" for a in m.axes for k in ("x", "v")]
    proc, Y = run_host(build_host(d), fmu, {f"{a}_x_cmd": c for a, c in cmds.items()}, outs, m.Ts)
    assert proc.returncode == 0, proc.stderr
    ref = run_fmu(fmu, cmds, m.Ts, outputs=outs)
    for j, name in enumerate(outs):
        assert np.array_equal(Y[0, :, j], ref[name]), name
