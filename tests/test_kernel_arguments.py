"""Hostile arguments at the compiled core's Python entry points (fdid_fmi.kernel): each call
either gives the documented doubles or a clear error, never a read or write outside its arrays,
into a read-only array, or through memory that was freed."""
import gc

import numpy as np
import pytest
import scipy.signal as ss

import fmu_support as fs
from fdid_fmi import kernel
from fdid_fmi.errors import InputError


@pytest.fixture(scope="module")
def siso():
    return kernel.CompiledModel(fs.siso_model())


def test_stepper_outputs_stay_valid_after_the_stepper_is_gone(siso):
    st = kernel.Stepper(siso)
    nbuf = st._buf.size
    expected = st.outputs().copy()
    del st
    y = kernel.Stepper(siso).outputs()       # the Stepper is dropped at once
    gc.collect()
    # arrays of the buffer's size take the freed block if it was freed
    others = [np.full(nbuf, 123.0) for _ in range(8)]
    assert np.array_equal(y, expected), y
    assert all(np.all(o == 123.0) for o in others)


@pytest.fixture(scope="module")
def coupled():
    return kernel.CompiledModel(fs.coupled_model())


@pytest.mark.parametrize("shape", [(400,), (400, 1), (400, 3), (1,)])
def test_run_refuses_commands_of_another_shape(coupled, shape):
    # two axes: the C reads N x 2 doubles; a shorter array would be read past its end
    with pytest.raises(InputError, match="cmds.*expected \\(N, 2\\)"):
        kernel.run(coupled, np.zeros(shape), np.zeros((400, 4)), np.zeros(2))


def test_run_refuses_externals_and_start_velocities_of_another_shape():
    cm = kernel.CompiledModel(fs.feature_model())          # m inputs, one of them external
    m = len(cm.model.inputs)
    c = np.zeros((300, 1))
    for bad in (np.zeros(300), np.zeros((300, 1)), np.zeros((30, m))):
        with pytest.raises(InputError, match="exts"):
            kernel.run(cm, c, bad, np.zeros(1))
    with pytest.raises(InputError, match="v0"):
        kernel.run(cm, c, np.zeros((300, m)), np.zeros(2))
    with pytest.raises(InputError, match="cmds.*real"):
        kernel.run(cm, c + 1j, np.zeros((300, m)), np.zeros(1))


def test_run_takes_a_vector_for_one_axis_and_any_memory_order(siso, coupled):
    rng = np.random.default_rng(4)
    c = np.cumsum(rng.normal(size=300)) * 1e-3
    a = kernel.run(siso, c, np.zeros((300, 2)), np.zeros(1))
    b = kernel.run(siso, c[:, None], np.zeros((300, 2)), np.zeros(1))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    c2 = np.cumsum(rng.normal(size=(300, 2)), axis=0) * 1e-3
    a = kernel.run(coupled, c2, np.zeros((300, 4)), np.zeros(2))
    for view in (np.asfortranarray(c2), c2[::-1].copy()[::-1]):
        b = kernel.run(coupled, view, np.zeros((300, 4)), np.zeros(2))
        assert all(np.array_equal(x, y) for x, y in zip(a, b))


AN = np.array([1.0, -0.5, 0.2, -0.1])      # order 3


def test_allpole_refuses_a_read_only_output():
    rng = np.random.default_rng(6)
    W, zi = rng.normal(size=(2, 40)), rng.normal(size=(2, 3))
    buf = bytes(8 * 2 * 43)                  # immutable memory the C would have written
    R = np.frombuffer(buf, dtype=float).reshape(2, 43)
    with pytest.raises(ValueError, match="writeable"):
        kernel.allpole(1.0, AN, W, zi, R)
    assert buf == bytes(8 * 2 * 43)
    R = np.zeros((2, 43))
    R.flags.writeable = False
    with pytest.raises(ValueError, match="writeable"):
        kernel.allpole(1.0, AN, W, zi, R)
    assert not R.any()


@pytest.mark.parametrize("shift", [0, 1, 3])
def test_allpole_in_place_gives_lfilter_of_the_input_as_it_was(shift):
    # W a view into R (one row: contiguous, so it reached the C uncopied), shifted so that
    # W[k + 1] is the memory of the output y[k]
    rng = np.random.default_rng(7)
    n, N = 3, 60
    zi = rng.normal(size=(1, n))
    R = rng.normal(size=(1, N + n))
    W = R[:, n - shift:N + n - shift]
    expected = ss.lfilter([0.5], AN, W[0].copy(), zi=zi[0])[0]
    kernel.allpole(0.5, AN, W, zi, R)
    assert np.array_equal(R[0, n:], expected)


def _rows_reference(R, n, inputs, F):
    N = R.shape[1] - n
    return np.array([sum(F[r, j] * R[i, n - j:n - j + N] for j in range(n + 1))
                     for r, i in enumerate(inputs)])


def test_regressor_rows_equal_the_sums_for_good_arguments():
    rng = np.random.default_rng(8)
    R, F = rng.normal(size=(3, 42)), rng.normal(size=(4, 3))
    inputs = np.array([0, 2, 1, 2])
    ref = _rows_reference(R, 2, inputs, F)
    for Rv, inp in ((R, inputs), (np.asfortranarray(R), inputs.astype(np.uint8)),
                    (R.astype(np.float32).astype(float), inputs)):
        out = kernel.regressor_rows(Rv, 2, inp, F)
        assert np.allclose(out, _rows_reference(Rv, 2, inputs, F), rtol=0, atol=0)
    assert np.allclose(kernel.regressor_rows(R, 2, inputs, F), ref, rtol=0, atol=0)
    late = kernel.regressor_rows(R, 2, inputs, F, 5, np.array([0.0, 1.0, 0.0, 0.0]), np.full(4, 2.0),
                                 np.ones((3, 40)))
    assert np.array_equal(late[1], ref[1, 5:] - 2.0) and np.array_equal(late[0], ref[0, 5:])


@pytest.mark.parametrize("case", ["float inputs", "bool inputs", "inputs beyond int", "F columns",
                                  "F flat", "R 3-d", "negative order"])
def test_regressor_rows_refuse_arguments_they_would_reinterpret(case):
    rng = np.random.default_rng(9)
    R, F, inputs, n = rng.normal(size=(3, 42)), rng.normal(size=(2, 3)), np.array([0, 1]), 2
    if case == "float inputs":
        inputs = np.array([0.7, 1.9])               # not truncated to rows 0 and 1
    elif case == "bool inputs":
        inputs = np.array([True, False])
    elif case == "inputs beyond int":
        inputs = np.array([0, 2 ** 32 + 1])         # not wrapped to row 1
    elif case == "F columns":
        F = rng.normal(size=(3, 2))                 # not read as (2, 3)
    elif case == "F flat":
        F = rng.normal(size=6)
    elif case == "R 3-d":
        R = rng.normal(size=(3, 4, 42))             # not read as (3, 4) rows
    else:
        n, F = -1, np.zeros((2, 0))
    with pytest.raises(ValueError, match="regressor_rows"):
        kernel.regressor_rows(R, n, inputs, F)


def _moves(model, n=1500):
    rng = np.random.default_rng(10)
    return {a: fs.smooth_moves(n, rng, start=1.0 + i) for i, a in enumerate(model.axes)}


@pytest.mark.parametrize("on", ["false", "0", float("nan"), None, 2])
def test_friction_on_must_be_a_boolean(on):
    from fdid_fmi.simulate import simulate
    m = fs.siso_model()
    with pytest.raises(InputError, match="x_friction_on.*true or false"):
        simulate(m, _moves(m), Ts=m.Ts, params={"x_friction_on": on})


def test_friction_on_booleans_and_their_numbers_agree():
    from fdid_fmi.simulate import simulate
    m = fs.siso_model()
    c = _moves(m)
    off = simulate(m, c, Ts=m.Ts, params={"x_friction_on": False}).y
    on = simulate(m, c, Ts=m.Ts).y
    assert not np.array_equal(on, off)
    for v, ref in ((0, off), (0.0, off), (np.False_, off), (1, on), (np.True_, on), (True, on)):
        assert np.array_equal(simulate(m, c, Ts=m.Ts, params={"x_friction_on": v}).y, ref), v


def test_friction_parameters_of_an_axis_without_friction_are_refused():
    from fdid_fmi.model import DriveModel
    from fdid_fmi.simulate import simulate
    s = fs.siso_model()                      # the same drive without its friction input
    m = DriveModel(Ts=s.Ts, A=s.A, B=s.B[:, :1], C=s.C, D=s.D[:, :1], inputs=s.inputs[:1],
                   outputs=s.outputs, method="hand-built")
    c = _moves(m)
    for p in ({"x_friction_level": 5.0}, {"x_v_tilde": 0.1}, {"x_friction_on": False}):
        with pytest.raises(InputError, match="no friction input"):
            simulate(m, c, Ts=m.Ts, params=p)
    assert np.isfinite(simulate(m, c, Ts=m.Ts).y).all()


@pytest.mark.parametrize("v", [np.nan, np.inf, -np.inf])
def test_a_non_finite_start_velocity_is_named_not_blamed_on_the_model(v):
    from fdid_fmi.simulate import simulate
    m = fs.siso_model()
    with pytest.raises(InputError, match="v0.*start velocities must be finite"):
        simulate(m, _moves(m, 200), Ts=m.Ts, start_velocity={"x": v})
    with pytest.raises(InputError, match="v0.*finite"):
        kernel.run(kernel.CompiledModel(m), np.zeros((10, 1)), np.zeros((10, 2)), [v])


def test_run_and_stepper_name_a_model_that_was_not_compiled():
    m = fs.siso_model()
    with pytest.raises(InputError, match="expected a CompiledModel.*DriveModel"):
        kernel.run(m, np.zeros((5, 1)), np.zeros((5, 2)), [0.0])
    with pytest.raises(InputError, match="expected a CompiledModel"):
        kernel.Stepper(None)


def test_a_compiled_model_does_not_follow_later_changes_of_the_model():
    m = fs.siso_model()
    cm = kernel.CompiledModel(m)
    c = np.cumsum(np.full((400, 1), 0.05), axis=0)          # 50 mm/s: the friction is active
    before = kernel.run(cm, c, np.zeros((400, 2)), [50.0])
    m.C[:] *= 2.0                                             # the caller reuses its model
    m.D[:] *= 2.0
    after = kernel.run(cm, c, np.zeros((400, 2)), [50.0])
    assert all(np.array_equal(x, y) for x, y in zip(before, after))


def test_allpole_refuses_a_denominator_that_is_not_normalised():
    rng = np.random.default_rng(11)
    W, zi, R = rng.normal(size=(2, 30)), np.zeros((2, 3)), np.zeros((2, 33))
    with pytest.raises(ValueError, match="an\\[0\\] = 1"):
        kernel.allpole(1.0, 2.0 * AN, W, zi, R)         # not filtered as if an[0] were 1
    kernel.allpole(1.0, AN, W, zi, R)
    assert np.array_equal(R[:, 3:], ss.lfilter([1.0], AN, W, axis=1))
