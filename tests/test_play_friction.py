"""The play feature (presliding friction, ``model.FEATURE_FUNCTIONS``): the identification's
regressor is the input the simulator applies."""
import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.identify.lsfit import play_signal
from fdid_fmi.simulate import simulate


@pytest.mark.parametrize("v_start", [0.0, 35.0, -20.0])
def test_regressor_is_the_input_the_simulator_applies(v_start):
    m = fs.feature_model()
    n = 2000
    cmds = {"x": fs.smooth_moves(n, np.random.default_rng(11), start=1.0, v_start=v_start)}
    v0 = {"x": (cmds["x"][1] - cmds["x"][0]) / m.Ts}
    sim = simulate(m, cmds, Ts=m.Ts, start_velocity=v0, externals={"force_N": np.zeros(n)})
    i = [p.name for p in m.inputs].index("x_play")
    w = play_signal(sim.axes["x"]["position"], m.inputs[i].params["width_mm"], np.sign(v0["x"]))
    assert np.array_equal(w, sim.u[:, i])
    assert np.any((np.abs(w) > 0.01) & (np.abs(w) < 0.99)) and np.any(np.abs(w) == 1.0)   # ramps, saturates


def test_play_signal_by_hand():
    x = np.array([0.0, 1.0, 2.0, 1.5, 0.0, 0.2])
    # b = 1, starting at rest: h follows x - 1 while rising, holds on the way back until x - h = -1
    assert np.array_equal(play_signal(x, 1.0, 0.0), [0.0, 0.0, 1.0, 1.0, 0.5, -1.0])
