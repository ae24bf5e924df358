"""A second co-simulation engine: the FMI 2 FMU run by libcosim (through ``libcosimpy``).

libcosim is the engine of the Open Simulation Platform; it keeps its clock in integer
nanoseconds and drives each FMU with a fixed step: inputs are set (an override manipulator)
before each ``doStep``, outputs are read (a last-value observer) after it. Run that way, every
position, velocity and tool output read after ``doStep(t_k, Ts)`` equals ``fdid simulate``'s
prediction at t_k+1 on the same commands within 1e-9 mm, and the error output is the command
the FMU held minus that position.

The value references are read by name from the FMU's modelDescription.xml, never assumed.
libcosim loads FMI 2 only (``libcosimpy`` 0.0.6 crashes the process on an FMI 3 FMU instead of
raising), so only FMI 2 FMUs are handed to it, and the version is checked before loading.
"""
import numpy as np
import pytest
from fmpy import read_model_description

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.layout import build_layout
from fdid_fmi.simulate import simulate

TOL_MM = 1e-9
ROLE_KEY = {"pos": "position", "vel": "velocity", "tool": "tool_position"}


def _libcosim():
    try:
        from libcosimpy.CosimEnums import CosimExecutionState
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except (ImportError, OSError) as exc:
        pytest.skip(f"libcosimpy is not usable ({exc}); pip install libcosimpy")
    log_output_level(CosimLogLevel.WARNING)            # libcosim traces every FMI call otherwise
    return CosimExecution, CosimLocalSlave, CosimManipulator, CosimObserver, CosimExecutionState


def run_libcosim(fmu, n, Ts, inputs, outputs):
    """Run ``n - 1`` fixed steps of ``Ts`` in libcosim.

    Parameters
    ----------
    fmu : path of an FMI 2 co-simulation FMU
    inputs : dict FMU input name -> (n,) values; value k is set before the step from t_k
             (value 0 is also the start value, set before initialisation)
    outputs : list of FMU output names

    Returns
    -------
    dict name -> (n - 1,) values read after each step: row k is the output at t_k+1
    """
    md = read_model_description(str(fmu))
    assert md.fmiVersion == "2.0", "libcosim loads FMI 2 FMUs only (libcosimpy crashes on FMI 3)"
    vr = {v.name: v.valueReference for v in md.modelVariables}
    Execution, LocalSlave, Manipulator, Observer, State = _libcosim()
    ns = round(Ts * 1e9)
    assert ns == Ts * 1e9, "the step must be a whole number of nanoseconds"
    ex = Execution.from_step_size(step_size=ns)
    slave = ex.add_local_slave(LocalSlave(fmu_path=str(fmu), instance_name="drive"))
    assert slave >= 0, "libcosim could not load the FMU"
    override = Manipulator.create_override()
    last = Observer.create_last_value()
    assert ex.add_manipulator(override) and ex.add_observer(last)
    in_vr = [vr[k] for k in inputs]
    out_vr = [vr[k] for k in outputs]
    values = np.column_stack([np.asarray(v, float) for v in inputs.values()])
    for r, v0 in zip(in_vr, values[0]):
        assert ex.real_initial_value(slave, r, float(v0))
    got = np.empty((n - 1, len(out_vr)))
    for k in range(n - 1):
        assert override.slave_real_values(slave, in_vr, [float(v) for v in values[k]])
        assert ex.step(), f"libcosim's step from t = {k * Ts:g} s failed"
        got[k] = last.last_real_values(slave, out_vr)
    st = ex.status()
    assert st.current_time == (n - 1) * ns and st.error_code == 0
    return {name: got[:, i] for i, name in enumerate(outputs)}


@pytest.fixture(scope="module")
def fmi2(tmp_path_factory):
    d = tmp_path_factory.mktemp("libcosim")
    models = {"siso": fs.siso_model(), "two axes": fs.coupled_model(), "tool": fs.flexible_model(),
              "features": fs.feature_model()}
    return {k: (m, export_fmu(m, d / f"{i}.fmu", fmi_version=2)) for i, (k, m) in enumerate(models.items())}


@pytest.mark.parametrize("name", ["siso", "two axes", "tool", "features"])
def test_libcosim_runs_the_fmi2_fmu_as_simulate(fmi2, name):
    m, fmu = fmi2[name]
    n = 1500
    rng = np.random.default_rng(3)
    cmds = {a: fs.smooth_moves(n, rng, start=1.0 + k) for k, a in enumerate(m.axes)}
    lay = build_layout(m)
    names = {(v.role, v.index): v.name for v in lay.variables}
    ins = {names[("cmd", k)]: cmds[a] for k, a in enumerate(lay.axes)}
    exts = {}
    for v in lay.inputs:
        if v.role == "ext":      # an external force: a slow sine, set before each step as the commands
            exts[m.inputs[v.index].name] = ins[v.name] = 50.0 * np.sin(np.arange(n) * m.Ts * 2 * np.pi * 3)
    outs = [v.name for v in lay.variables if v.causality == "output"]
    assert outs and all(v.role in ROLE_KEY for v in lay.variables if v.causality == "output")
    got = run_libcosim(fmu, n, m.Ts, ins, outs)
    ref = simulate(m, cmds, Ts=m.Ts, externals=exts or None)
    checked = set()
    for v in lay.variables:
        if v.causality != "output":
            continue
        a = lay.axes[v.index]
        r = ref.axes[a]
        want = r[ROLE_KEY[v.role]][1:]
        tol = TOL_MM / m.Ts if v.role == "vel" else TOL_MM        # mm/s: a position difference over Ts
        assert np.abs(got[v.name] - want).max() <= tol, (v.name, np.abs(got[v.name] - want).max())
        checked.add(v.role)
    # the run is not trivial: the axes move, and friction sticks the model at rest in between
    pos = ref.axes[m.axes[0]]["position"]
    assert np.ptp(pos) > 1.0 and (np.abs(np.diff(pos)) < 1e-9).sum() > 50
    assert {"pos", "vel"} <= checked
    # the tracking error at each recorded time: the command of that time minus the position
    for k, a in enumerate(lay.axes):
        e = cmds[a][1:] - got[names[("pos", k)]]
        assert np.abs(e - ref.axes[a]["error"][1:]).max() <= TOL_MM
