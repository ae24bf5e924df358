"""The play feature (presliding friction, ``model.FEATURE_FUNCTIONS``): the identification's
regressor is the input the simulator applies."""
import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.identify.lsfit import feature_signal, play_signal
from fdid_fmi.simulate import simulate


@pytest.mark.parametrize("start", [1.0, 123.457, -71.3])     # positions whose x - (x - b) rounds
@pytest.mark.parametrize("v_start", [0.0, 35.0, -20.0])
def test_regressor_is_the_input_the_simulator_applies(v_start, start):
    m = fs.feature_model()
    n = 2000
    cmds = {"x": fs.smooth_moves(n, np.random.default_rng(11), start=start, v_start=v_start)}
    v0 = {"x": (cmds["x"][1] - cmds["x"][0]) / m.Ts}
    sim = simulate(m, cmds, Ts=m.Ts, start_velocity=v0, externals={"force_N": np.zeros(n)})
    i = [p.name for p in m.inputs].index("x_play")
    w = play_signal(sim.axes["x"]["position"], m.inputs[i].params["width_mm"], np.sign(v0["x"]))
    assert np.array_equal(w, sim.u[:, i])
    assert np.all(np.abs(w[np.abs(w) > 1 - 1e-9]) == 1.0)      # slid through: exactly +-1
    assert np.any((np.abs(w) > 0.01) & (np.abs(w) < 0.99)) and np.any(np.abs(w) == 1.0)   # ramps, saturates


def test_play_stribeck_regressor_is_the_input_the_simulator_applies():
    """The play's Stribeck term: the play times exp(-(v / v_s)^2) of the previous step's velocity,
    as the simulator applies it (to libm's last bit, after the start sample)."""
    m = fs.feature_model()
    n = 2000
    cmds = {"x": fs.smooth_moves(n, np.random.default_rng(12), v_start=30.0)}
    v0 = {"x": (cmds["x"][1] - cmds["x"][0]) / m.Ts}
    sim = simulate(m, cmds, Ts=m.Ts, start_velocity=v0, externals={"force_N": np.zeros(n)})
    i = [p.name for p in m.inputs].index("x_play_stribeck")
    w = feature_signal(m.inputs[i].params, sim.axes["x"]["velocity"], sim.axes["x"]["position"], np.sign(v0["x"]))
    np.testing.assert_allclose(w[1:], sim.u[1:, i], rtol=0, atol=1e-15)
    assert sim.u[0, i] == pytest.approx(np.exp(-(v0["x"] / 3.0) ** 2), rel=1e-15)    # slid through at the start
    assert np.any(np.abs(w) > 0.9) and np.any((np.abs(w) > 0.01) & (np.abs(w) < 0.5))   # breakaway, decay


def test_play_signal_by_hand():
    x = np.array([0.0, 1.0, 2.0, 1.5, 0.0, 0.2])
    # b = 1, starting at rest: h follows x - 1 while rising, holds on the way back until x - h = -1
    assert np.array_equal(play_signal(x, 1.0, 0.0), [0.0, 0.0, 1.0, 1.0, 0.5, -1.0])


def test_cli_identify_with_the_play_law_then_export_and_validate(tmp_path):
    """``fdid identify --method mimo --play-width`` on plant2 data written as a CSV: the model
    carries the play at that width, says so, and its FMU validates through fmpy."""
    import subprocess
    import sys

    from plant2 import scenarios as p2
    train, vals, _ = p2.scenario("clean_rigid")
    csv = tmp_path / "run.csv"
    tr = train[0]
    np.savetxt(csv, np.column_stack([tr.t, tr.cmd("x"), tr.act("x")]), delimiter=",",
               header="t_s,x_cmd_mm,x_mm", comments="", fmt="%.12g")

    def fdid(*args):
        return subprocess.run([sys.executable, "-m", "fdid_fmi.cli", *map(str, args)], capture_output=True,
                              text=True, timeout=600)

    r = fdid("identify", csv, "--method", "mimo", "--n-complex", "2", "--play-width", "0.004",
             "--same-sample", "quadratic", "--maxiter", "3", "-o", tmp_path / "m.json")
    assert r.returncode == 0, r.stderr
    assert "play (presliding friction) half-width [mm]: x 0.004" in r.stdout
    from fdid_fmi.model import load_model
    m = load_model(tmp_path / "m.json")
    assert [p.params for p in m.inputs if p.kind == "feature"] == \
        [{"function": "play", "width_mm": 0.004, "source": "position"}]
    assert not any(p.kind == "friction" for p in m.inputs)
    r = fdid("export", tmp_path / "m.json", "-o", tmp_path / "m.fmu")
    assert r.returncode == 0, r.stderr
    r = fdid("validate", tmp_path / "m.fmu", csv, "--model", tmp_path / "m.json", "--json", tmp_path / "v.json")
    assert r.returncode == 0, r.stderr + r.stdout
    import json
    v = json.loads((tmp_path / "v.json").read_text())
    assert v["ok"] is True


def test_the_play_law_recipe_keeps_the_friction_terms_and_sign():
    """``augment.to_play_law``: the sat friction input becomes the play with its numerator terms
    and sign; the Stribeck term of a play-law axis is the play's (``play_stribeck``), the same
    width, the friction path's terms."""
    from fdid_fmi.diagnose import augment as ag
    from fdid_fmi.identify import identify_mimo, mimo_structure
    from plant2 import scenarios as p2
    train, _, _ = p2.scenario("clean_rigid")
    m = identify_mimo(train[0], mimo_structure(("x",), ("error",), 1, 1, same_sample="hold"), seed=0, maxiter=2)
    r = ag.recipe_from_model(m)
    p = ag.to_play_law(r, "x", 0.002)
    (o,) = [o.name for o in r.outputs]
    assert [s.kind for s in p.inputs] == ["command", "feature"] and p.inputs[1].name == "x_play"
    assert p.inputs[1].params == {"function": "play", "width_mm": 0.002, "source": "position"}
    assert p.masks[(o, "x_play")] == r.masks[(o, "x_dnf")] and p.friction_sign == {(o, "x_play"): 1}
    assert "x" not in p.v_tilde and "x" in r.v_tilde and r.inputs[1].kind == "friction"   # r unchanged
    s = ag.add_stribeck(p, "x", 3.0)
    assert s.inputs[-1].params == {"function": "play_stribeck", "width_mm": 0.002, "v_s": 3.0,
                                   "source": "position"}
    assert s.masks[(o, s.inputs[-1].name)] == r.masks[(o, "x_dnf")]
    assert ag.add_stribeck(r, "x", 3.0).inputs[-1].params["function"] == "stribeck"     # the sat law's


def test_diagnosis_reads_the_play_as_the_friction_path():
    """A play-law axis: its friction path is the play input; a motor-only axis gets one note, the
    travel its friction builds up over (not also 'lost motion was not checked')."""
    from fdid_fmi.diagnose.augment import friction_path
    from fdid_fmi.diagnose.limits import NoteKind, data_limits
    from fdid_fmi.identify.structure import mimo_structure
    st = mimo_structure(("x",), ("error",), 1, 2, friction=False, play_mm=0.008)
    assert st.inputs[friction_path(st.inputs, "x")].params["function"] == "play"
    assert friction_path(mimo_structure(("x",), ("error",), play_mm=0.008).inputs, "x") == 1   # sat first
    notes = data_limits(["x", "y"], set(), {"x": 30.0, "y": 30.0}, [], None, {"x": 0.008})
    assert [(n.axis, n.kind) for n in notes] == [("x", NoteKind.CARRIED), ("y", NoteKind.SUSPECTED)]
    assert "16 µm of travel" in notes[0].text
    small = data_limits(["x"], set(), {"x": 1.0}, [], None, {"x": 0.002})   # 4 µm: below the 5 µm
    assert [n.kind for n in small] == [NoteKind.NOT_OBSERVABLE]
