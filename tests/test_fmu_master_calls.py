"""Calls the FMI 2.0 / 3.0 specifications allow a co-simulation master to make, on both FMU
versions: long runs, stop times off the sample grid, getting start values before
initialisation (FMI 3), freeing a NULL state, the stop time, an unknown log category."""
import ctypes

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.validate import FmuRunner, run_master
from fdid_fmi.simulate import simulate


@pytest.fixture(scope="module")
def siso(tmp_path_factory):
    d = tmp_path_factory.mktemp("master_calls")
    m = fs.siso_model()
    return m, {v: export_fmu(m, d / f"s{v}.fmu", fmi_version=v) for v in (2, 3)}


@pytest.fixture(params=[2, 3])
def runner(request, siso):
    m, fmus = siso
    r = FmuRunner(fmus[request.param])
    yield m, r, request.param
    r.close()


def _start(r, start=0.0, stop=None):
    r.start(start, stop)
    r.fmu.exitInitializationMode()
    return r.fmu


@pytest.mark.parametrize("version", [2, 3])
def test_long_runs_keep_stepping(siso, version):
    """fmpy computes each step as the difference of two grid times; at t = 8192 s their rounding
    (~1e-12 s) must not exceed the FMU's tolerance relative to h, or the step is refused. Run the
    way masters run it (fmpy.simulate_fmu with an input table, outputs read after doStep): the
    positions equal the in-process prediction at the same time stamps (measured: 0 mm)."""
    m, fmus = siso
    n = 600
    cmd = fs.smooth_moves(n, np.random.default_rng(11), start=3.0, v_start=0.0)
    t = 8192.25 + 0.001 * np.arange(n)
    res = run_master(fmus[version], t, {"x_x_cmd": cmd}, ["x_x"], step_size=0.001)
    ref = simulate(m, {"x": cmd}, Ts=m.Ts)
    assert len(res["x_x"]) == n
    assert np.abs(res["x_x"] - ref.axes["x"]["position"]).max() <= 1e-9


@pytest.mark.parametrize("version", [2, 3])
def test_stop_time_off_the_grid_ends_at_the_last_full_step(siso, version):
    """The FMU declares canHandleVariableCommunicationStepSize = false (it steps in whole
    samples), so fmpy does not shorten the last step to reach a stop time between samples."""
    m, fmus = siso
    md = read_model_description(str(fmus[version]))
    assert md.coSimulation.canHandleVariableCommunicationStepSize is False
    res = simulate_fmu(str(fmus[version]), stop_time=10.5 * m.Ts, output_interval=m.Ts, output=["x_x"])
    assert res["time"][-1] == pytest.approx(10 * m.Ts)
    cmd = np.zeros(11)   # the FMU's command stays at its start value 0: the model at rest
    ref = simulate(m, {"x": cmd}, Ts=m.Ts)
    assert np.abs(res["x_x"] - ref.axes["x"]["position"]).max() <= 1e-12


@pytest.mark.parametrize("start", [0.0, 1e5, 1.7e9])     # 1.7e9 s: a wall-clock start time
def test_off_grid_steps_are_refused_at_any_time(runner, start):
    """The tolerance for the rounding of grid times grows with |t| but stays below a hundredth
    of a sample, so a step that is not a whole number of samples is refused at any time."""
    m, r, version = runner
    f = _start(r, start=start)
    f.doStep(start, m.Ts)
    t = start + m.Ts
    save, restore = (f.getFMUState, f.setFMUState) if version == 3 else (f.getFMUstate, f.setFMUstate)
    state = save()
    for h in (0.6 * m.Ts, 1.09 * m.Ts, 1.45 * m.Ts, 2e7 * m.Ts):   # the last: more than 1e7 steps
        with pytest.raises(FMICallException):
            f.doStep(t, h)
        restore(state)                           # leaves the error state
    with pytest.raises(FMICallException):
        f.doStep(t + 1.0, m.Ts)                  # not the FMU's time
    restore(state)
    f.doStep(t, 3 * m.Ts)


def test_step_past_the_stop_time_is_an_error(runner):
    m, r, version = runner
    f = _start(r, stop=2 * m.Ts)
    f.doStep(0.0, m.Ts)
    f.doStep(m.Ts, m.Ts)
    with pytest.raises(FMICallException):
        f.doStep(2 * m.Ts, m.Ts)


def test_fmi3_gives_start_values_before_initialisation(siso):
    m, fmus = siso
    r = FmuRunner(fmus[3])
    try:
        f = r.fmu
        f.instantiate()
        vt = f.getFloat64([r.vr("x_v_tilde")])[0]
        assert vt == m.inputs[m.input_index("friction", "x")].params["v_tilde"]
        f.enterInitializationMode(startTime=0.0)   # the instance is still usable
        f.exitInitializationMode()
        f.doStep(0.0, m.Ts)
    finally:
        r.close()


def test_freeing_a_null_state_is_ignored(runner):
    m, r, version = runner
    f = _start(r)
    free = getattr(f.dll, "fmi2FreeFMUstate" if version == 2 else "fmi3FreeFMUState")
    free.restype = ctypes.c_int
    free.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    assert free(f.component, None) == 0
    held = ctypes.c_void_p(None)
    assert free(f.component, ctypes.byref(held)) == 0
    f.doStep(0.0, m.Ts)                          # not in the error state


def test_an_unknown_log_category_is_a_warning(runner):
    m, r, version = runner
    f = _start(r)
    fn = getattr(f.dll, f"fmi{version}SetDebugLogging")
    fn.restype = ctypes.c_int
    fn.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t, ctypes.POINTER(ctypes.c_char_p)]
    cats = (ctypes.c_char_p * 1)(b"noSuchCategory")
    assert fn(f.component, 1, 1, cats) == 1      # fmi2Warning / fmi3Warning
    f.doStep(0.0, m.Ts)                          # not in the error state
