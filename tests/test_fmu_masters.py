"""Identified twins run the way co-simulation masters run them.

Virtual drive without and with feed-forward, plant2's Stribeck axis with the play friction law
and its breakaway term (two play states run in the FMU) and the real EMPS drive: the pole-search model is
exported, then driven (a) by ``fdid validate``, i.e. ``fmpy.simulate_fmu`` with an input table of
the measured commands and ``step_size`` = the nominal Ts as a decimal, and (b) by the ecos
co-simulation engine (set inputs, step, read). Either gives ``fdid simulate``'s positions at the
same time stamps to 1e-9 mm, and the same RMS against the measurement. The twins are stored
(``tests/data/make_fitted_models.py``: the pole search with seed 0 and 30 generations, the
same-sample form pinned to what ``identify`` chooses for these drives, which the pole-search
checks of ``benchmarks/bench_end_to_end.py`` assert).
"""
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.fmu import export_fmu, validate_fmu
from fdid_fmi.metrics import rms
from fdid_fmi.model import load_model
from fdid_fmi.simulate import run_up, simulate
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj

DATA = Path(__file__).parent / "data"


def _virtual_val(cfg):
    """Four moves of X (seed 7), not the twin's training moves."""
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    return simulate_machine(one, tj.linear_moves(n_moves=4, axes=("x",), Ts=cfg.Ts, seed=7), seed=4)


@pytest.fixture(scope="module", params=["no feed-forward", "feed-forward", "play law", "EMPS"])
def twin(request, tmp_path_factory, shared_data_optional):
    if request.param == "no feed-forward":
        m, val = load_model(DATA / "twin_no_feedforward_model.json"), _virtual_val(presets.deckel_maho_like())
    elif request.param == "feed-forward":
        m, val = load_model(DATA / "twin_feedforward_model.json"), _virtual_val(presets.with_feedforward())
    elif request.param == "play law":      # presliding friction: the play's state runs in the FMU
        from plant2 import scenarios as p2
        _, vals, _ = p2.scenario("stribeck")
        # and its breakaway (what diagnosis adds on this axis: augment.add_stribeck), on the play's terms
        m, val = load_model(DATA / "twin_play_law_model.json"), vals[0]
        assert [p.params["function"] for p in m.inputs if p.kind == "feature"] == ["play", "play_stribeck"]
    else:
        if shared_data_optional is None:
            pytest.skip("real data folder ../shared/data is absent")
        from fdid_fmi.io import read_trace
        val = read_trace(shared_data_optional / "emps" / "DATA_EMPS.mat")
        m = load_model(DATA / "twin_emps_model.json")
    return request.param, m, val, export_fmu(m, tmp_path_factory.mktemp("twin") / "twin.fmu")


def test_fmpy_simulate_fmu_gives_the_model(twin):
    name, m, val, fmu = twin
    assert repr(m.Ts) in ("0.0006", "0.001")               # the nominal sample time, a decimal
    res = validate_fmu(fmu, val)
    assert res.problems == [], res.problems
    assert res.max_abs_diff_reference_mm <= 1e-9
    own = rms(simulate(m, val).axes["x"]["position"] - val.act("x")) * 1e3
    assert res.axes["x"]["rms_um"] == pytest.approx(own, rel=1e-6)
    if name == "EMPS":
        assert "run-up" in res.start and own < 3.5          # measured 2.7 um


def test_ecos_engine_gives_the_model(twin):
    """ecos: set x_cmd(t_k), step, read: the position read is the model's at t_k+1."""
    try:
        from ecospy import EcosSimulation, EcosSimulationStructure
    except (ImportError, OSError) as exc:  # OSError: libtbb12 missing
        pytest.skip(f"ecospy is not usable ({exc}); pip install ecospy and apt-get install libtbb12")
    name, m, val, fmu = twin
    n = min(val.n, 4000)
    cmd = val.cmd("x")[:n]
    R, ext, _ = run_up({"x": cmd}, m.Ts)                      # as fdid simulate starts the record
    drive = ext["x"]
    ref = simulate(m, val.slice(val.t[0], val.t[n - 1])).axes["x"]["position"]
    ss = EcosSimulationStructure()
    ss.add_model("drive", str(fmu))
    sim = EcosSimulation(structure=ss, step_size=m.Ts)
    got = np.empty(len(drive))
    try:
        sim.set_real("drive::x_x_cmd", drive[0])
        if not R:
            sim.set_real("drive::x_v0", (cmd[1] - cmd[0]) / m.Ts)
        sim.init()
        got[0] = sim.get_real("drive::x_x")
        for k in range(len(drive) - 1):
            sim.set_real("drive::x_x_cmd", drive[k])
            sim.step()
            got[k + 1] = sim.get_real("drive::x_x")
    finally:
        sim.terminate()
        sim.free()
    assert np.abs(got[R:] - ref).max() <= 1e-9
