"""Identified twins run the way co-simulation masters run them.

Virtual drive without and with feed-forward, plant2's Stribeck axis with the play friction law
and its breakaway term (two play states run in the FMU) and the real EMPS drive: the pole-search model is
exported, then driven (a) by ``fdid validate``, i.e. ``fmpy.simulate_fmu`` with an input table of
the measured commands and ``step_size`` = the nominal Ts as a decimal, and (b) by the ecos
co-simulation engine (set inputs, step, read). Either gives ``fdid simulate``'s positions at the
same time stamps to 1e-9 mm, and the same RMS against the measurement. The same-sample form is
pinned to what ``identify`` chooses for these drives (tested in test_pole_search_virtual), which
halves the identification time.
"""
import numpy as np
import pytest

from fdid_fmi.fmu import export_fmu, validate_fmu
from fdid_fmi.identify import identify_mimo, identify_siso, mimo_structure
from fdid_fmi.identify.structure import InputSpec
from fdid_fmi.metrics import rms
from fdid_fmi.simulate import run_up, simulate
from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj


def _virtual(cfg, ident):
    one = MachineConfig(axes=[cfg.axis("x")], Ts=cfg.Ts)
    train = simulate_machine(one, tj.linear_moves(n_moves=8, axes=("x",), Ts=cfg.Ts, seed=1), seed=1)
    val = simulate_machine(one, tj.linear_moves(n_moves=4, axes=("x",), Ts=cfg.Ts, seed=7), seed=4)
    return ident(train), val


@pytest.fixture(scope="module", params=["no feed-forward", "feed-forward", "play law", "EMPS"])
def twin(request, tmp_path_factory, shared_data_optional):
    if request.param == "no feed-forward":
        m, val = _virtual(presets.deckel_maho_like(), lambda tr: identify_siso(tr, "x", seed=0, maxiter=30,
                                                                              same_sample="hold"))
    elif request.param == "feed-forward":
        m, val = _virtual(presets.with_feedforward(),
                          lambda tr: identify_mimo(tr, mimo_structure(("x",), ("error",), 2, 1,
                                                                 same_sample="cubic"), seed=0,
                                                   maxiter=30))
    elif request.param == "play law":      # presliding friction: the play's state runs in the FMU
        from plant2 import scenarios as p2
        train, vals, _ = p2.scenario("stribeck")
        st = mimo_structure(("x",), ("error",), 1, 2, friction=False, play_mm=0.002, same_sample="quadratic")
        # and its breakaway (what diagnosis adds on this axis: augment.add_stribeck), on the play's terms
        brk = InputSpec("feature", "x", params={"function": "play_stribeck", "width_mm": 0.002, "v_s": 3.0,
                                                "source": "position"})
        st.inputs.append(brk)
        st.mask.update({(o, brk.name): t for (o, i), t in list(st.mask.items()) if i == "x_play"})
        m, val = identify_mimo(train, st, seed=0, maxiter=30), vals[0]
        assert [p.params["function"] for p in m.inputs if p.kind == "feature"] == ["play", "play_stribeck"]
    else:
        if shared_data_optional is None:
            pytest.skip("real data folder ../shared/data is absent")
        from fdid_fmi.io import read_trace
        val = read_trace(shared_data_optional / "emps" / "DATA_EMPS.mat")
        m = identify_siso(val, "x", integral_action=False, seed=0, maxiter=30, same_sample="hold")
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
