"""The compiled core (fdid_fmi._kernel, the FMUs' fdid_core.c) against the pure-Python oracle
(tests/sim_oracle.py): the same doubles, on every hand-built model."""
import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.simulate import simulate
from sim_oracle import oracle_simulate

MODELS = {"siso": fs.siso_model, "coupled": fs.coupled_model, "flexible": fs.flexible_model}


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("v_start", [0.0, 35.0])
def test_kernel_equals_oracle(name, v_start):
    m = MODELS[name]()
    rng = np.random.default_rng(21)
    n = 2500
    cmds = {a: fs.smooth_moves(n, rng, start=3.0 + i, v_start=v_start) for i, a in enumerate(m.axes)}
    v0 = {a: (c[1] - c[0]) / m.Ts for a, c in cmds.items()}
    k = simulate(m, cmds, Ts=m.Ts, start_velocity=v0)
    o = oracle_simulate(m, cmds, Ts=m.Ts, start_velocity=v0)
    assert np.array_equal(k.y, o.y) and np.array_equal(k.u, o.u)
    for a in m.axes:
        assert np.array_equal(k.axes[a]["velocity"], o.axes[a]["velocity"])


def test_kernel_equals_oracle_with_features_externals_and_parameters():
    m = fs.feature_model()
    rng = np.random.default_rng(5)
    n = 2000
    cmds = {"x": fs.smooth_moves(n, rng, start=1.0)}
    ext = {"force_N": 3.0 * np.sin(np.arange(n) * 0.01)}
    params = {"x_friction_level": 0.7, "x_v_tilde": 0.3}
    k = simulate(m, cmds, Ts=m.Ts, externals=ext, params=params)
    from sim_oracle import _Plan, _run
    o = _run(_Plan(m, params), cmds, ext, np.arange(n) * m.Ts, {})
    assert np.array_equal(k.y, o.y) and np.array_equal(k.u, o.u)
    off = simulate(m, cmds, Ts=m.Ts, externals=ext, params={"x_friction_on": False})
    assert np.all(off.u[:, 1] == 0.0) and not np.array_equal(off.y, k.y)


def test_kernel_refuses_non_finite_outputs():
    from fdid_fmi.errors import InputError
    m = fs.siso_model()
    with pytest.raises(InputError, match="finite|command"):
        simulate(m, {"x": np.array([0.0, 1.0, np.inf, 2.0] * 10)}, Ts=m.Ts)


def test_a_copied_stepper_continues_as_the_original():
    """Stepper.copy (the planner's in-position probe): stepped on, the copy gives the original's
    outputs to the bit, and the original stays where it was."""
    from fdid_fmi import kernel
    m = fs.coupled_model()
    st = kernel.Stepper(kernel.CompiledModel(m))
    st.set_parameters({}, m.axes)
    rng = np.random.default_rng(3)
    cmds = np.cumsum(rng.normal(0.0, 0.02, (300, 2)), axis=0)

    def run(s, rows, initial=False):
        out = []
        for k, r in enumerate(rows):
            s.views["cmd"][:] = r
            s.touch(initial=initial and k == 0)
            out.append(s.outputs().copy())
            s.advance()
        return np.array(out)

    run(st, cmds[:150], initial=True)
    probe = st.copy()
    held = run(probe, np.repeat(cmds[149:150], 50, axis=0))
    assert np.array_equal(run(st.copy(), np.repeat(cmds[149:150], 50, axis=0)), held)
    whole = kernel.Stepper(kernel.CompiledModel(m))
    whole.set_parameters({}, m.axes)
    assert np.array_equal(run(whole, cmds, initial=True)[150:], run(st, cmds[150:]))
