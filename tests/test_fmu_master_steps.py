"""How masters step the FMU: clocks that add up their steps, coarse communication steps (held or
interpolated inputs), value references and dependencies as masters read them."""
import dataclasses
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu as fmpy_validate

import fmu_support as fs
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.validate import FmuRunner, coarse_step, run_coarse
from fdid_fmi.simulate import simulate

N = 3050          # the record length of the OMSimulator run: 3049 steps of 1 ms to 3.049 s


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The SISO model with friction (FMI 2 and 3), and without friction (FMI 2): the friction's
    stick-slip decisions amplify any change of the inputs, so the interpolation is measured
    on the linear model."""
    d = tmp_path_factory.mktemp("master_steps")
    m, lin = fs.siso_model(), fs.siso_model(level=0.0)
    return {"model": m, 2: export_fmu(m, d / "s2.fmu", fmi_version=2),
            3: export_fmu(m, d / "s3.fmu", fmi_version=3),
            "linear": lin, "linear2": export_fmu(lin, d / "l2.fmu", fmi_version=2)}


@pytest.fixture(scope="module")
def cmd():
    return fs.smooth_moves(N, np.random.default_rng(3), start=3.0)


def _table(cmd, Ts):
    sig = np.zeros(len(cmd), dtype=[("time", float), ("x_x_cmd", float)])
    sig["time"] = Ts * np.arange(len(cmd))
    sig["x_x_cmd"] = cmd
    return sig


@pytest.mark.parametrize("version", [2, 3])
def test_an_accumulating_master_runs_to_the_end_and_matches(fmus, cmd, version):
    """A master that keeps its time as t += h (OMSimulator) and shortens its last step to reach
    the stop time: after 3049 steps of 1 ms it stands at 3.0489999999997752 s, and its last
    doStep is a 2.2e-13 s sliver, which ends on the sample the FMU is at (a no-op, OK). Every
    call returns OK and the positions equal the per-sample prediction."""
    m = fmus["model"]
    Ts, stop = m.Ts, (N - 1) * m.Ts
    ref = simulate(m, {"x": cmd}, Ts=Ts).axes["x"]["position"]
    r = FmuRunner(fmus[version])
    try:
        f, three = r.fmu, version == 3
        setr, getr = (f.setFloat64, f.getFloat64) if three else (f.setReal, f.getReal)
        vi, vo = r.vr("x_x_cmd"), r.vr("x_x")
        r.start(0.0, stop)
        setr([vi], [cmd[0]])
        f.exitInitializationMode()
        t, k, got, steps = 0.0, 0, [], []
        while t < stop:
            h = min(Ts, stop - t)
            setr([vi], [cmd[k]])
            f.doStep(currentCommunicationPoint=t, communicationStepSize=h)   # raises unless OK/warning
            t += h
            steps.append(h)
            k += 1
            got.append(getr([vo])[0])
        assert steps[-1] < 1e-9 and t == stop and len(steps) == N       # the sliver was taken
        x = np.array(got[:N - 1])
        assert np.abs(x - ref[1:N]).max() <= 1e-9
        assert got[-1] == got[-2]                                        # the sliver changed nothing
        # a real off-grid step is still refused
        with pytest.raises(FMICallException):
            f.doStep(currentCommunicationPoint=t, communicationStepSize=0.5 * Ts)
    finally:
        r.close()


def test_fmpy_with_step_size_alone_runs_and_logs_the_held_input_note_once(fmus, cmd, capfd):
    """``simulate_fmu(fmu, stop_time, step_size=Ts, input=table)``: fmpy ignores ``step_size`` for a
    co-simulation FMU and steps at its own output interval (here 4 ms); the FMU runs it and says,
    once, through fmpy's default logger (debug logging off), what that means."""
    m = fmus["model"]
    res = simulate_fmu(str(fmus[2]), stop_time=(N - 1) * m.Ts, step_size=m.Ts, input=_table(cmd, m.Ts),
                       output=["x_x"])
    out = capfd.readouterr().out
    h, n = coarse_step((N - 1) * m.Ts, m.Ts)
    assert n == 4 and res["time"][1] == pytest.approx(h) and len(res) == 763
    note = [ln for ln in out.splitlines() if "communication step" in ln]
    assert len(note) == 1, out
    assert note[0].startswith("[WARNING]") and "0.004 s = 4 samples" in note[0] \
        and "held for 4 samples" in note[0] and "step at 0.001 s to feed every sample" in note[0], note
    # FMI 3: the FMU may call the logger only when logging is on (FMI 3.0 fmi3Instantiate*)
    simulate_fmu(str(fmus[3]), stop_time=(N - 1) * m.Ts, input=_table(cmd, m.Ts), output=["x_x"],
                 debug_logging=True)
    out = capfd.readouterr().out
    assert sum("0.004 s = 4 samples" in ln for ln in out.splitlines()) == 1, out


def test_input_derivatives_interpolate_within_a_coarse_step(fmus, cmd):
    """FMI 2 canInterpolateInputs: with the slopes fmpy computes from the input table, a step of 4
    samples is more than 10x closer to the per-sample prediction than with held inputs
    (measured on this record: 0.0034 mm against 0.082 mm)."""
    m, fmu = fmus["linear"], fmus["linear2"]
    ref = simulate(m, {"x": cmd}, Ts=m.Ts).axes["x"]["position"]
    t = m.Ts * np.arange(N)
    err = {}
    for deriv in (False, True):
        rows, got = run_coarse(fmu, t, {"x_x_cmd": cmd}, ["x_x"], {}, 4, derivatives=deriv)
        err[deriv] = np.abs(got["x_x"] - ref[rows]).max()
    assert err[True] * 10 <= err[False], err
    # fed every sample, a derivative changes nothing (sample 0 of a step is the value set)
    rows, got = run_coarse(fmu, t[:200], {"x_x_cmd": cmd[:200]}, ["x_x"], {}, 1, derivatives=True)
    assert np.abs(got["x_x"] - ref[rows]).max() == 0.0


def test_setting_an_input_again_clears_its_derivative(fmus, cmd):
    """FMI 2.0.4 section 4.2.1: inputs and their derivatives are set for the start of a
    communication step; a value set again without a derivative is held."""
    m, fmu = fmus["model"], fmus[2]
    outs = []
    for clear in (True, False):
        r = FmuRunner(fmu)
        try:
            f = r.fmu
            vi, vo = r.vr("x_x_cmd"), r.vr("x_x")
            r.start(0.0)
            f.setReal([vi], [cmd[0]])
            f.exitInitializationMode()
            for k in range(0, 400, 4):
                f.setRealInputDerivatives([vi], [1], [50.0])
                if clear:
                    f.setReal([vi], [cmd[k]])
                f.doStep(k * m.Ts, 4 * m.Ts)
                if not clear:
                    f.setReal([vi], [cmd[k + 4]])
            outs.append(f.getReal([vo])[0])
        finally:
            r.close()
    held = run_coarse(fmu, m.Ts * np.arange(401), {"x_x_cmd": cmd[:401]}, ["x_x"], {}, 4, derivatives=False)
    assert outs[0] == held[1]["x_x"][99]          # the cleared slope: exactly the held-input run
    assert outs[1] != outs[0]                     # a slope kept moves the inputs


def test_derivatives_of_order_two_are_refused_with_a_message(fmus):
    from test_fmu_export import _logged_runner
    r, msgs = _logged_runner(fmus[2])
    try:
        f = r.fmu
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        with pytest.raises(FMICallException):
            f.setRealInputDerivatives([r.vr("x_x_cmd")], [2], [1.0])
        assert "first derivatives (order 1) only" in msgs[-1][2], msgs
        f.reset()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        with pytest.raises(FMICallException):
            f.setRealInputDerivatives([r.vr("x_x")], [1], [1.0])
        assert "is not an input" in msgs[-1][2], msgs
    finally:
        r.close()


@pytest.mark.parametrize("version", [2, 3])
def test_value_references_start_at_1_and_dependencies_name_existing_variables(tmp_path, version):
    """Value references 1..n in both versions; FMI 3 dependencies are value references of
    existing variables, and read as 1-based indices into ModelVariables (as OMSimulator reads
    them) they name the same variables. fmpy's validation finds no problem. The position and
    velocity outputs answer the command one sample later: the model's error outputs, relabelled
    as outputs of kind 'other' (exported as such), give outputs with same-step dependencies."""
    m = fs.coupled_model()
    m.outputs = [dataclasses.replace(p, kind="other", name=p.name.replace("_err", "_dev"))
                 if p.kind == "error" else p for p in m.outputs]
    m.validate()
    fmu = export_fmu(m, tmp_path / "c.fmu", fmi_version=version)
    assert fmpy_validate(str(fmu)) == []
    md = read_model_description(str(fmu))
    vrs = [v.valueReference for v in md.modelVariables if v.causality != "independent"]
    assert sorted(vrs) == list(range(1, len(vrs) + 1))
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    mv = list(root.find("ModelVariables"))
    ms = root.find("ModelStructure")
    n_deps = 0
    if version == 3:
        by_vr = {int(e.get("valueReference")): e.get("name") for e in mv}
        for o in ms.findall("Output"):
            for dep in (o.get("dependencies") or "").split():
                n_deps += 1
                assert int(dep) in by_vr                                   # the standard's reading
                assert mv[int(dep) - 1].get("name") == by_vr[int(dep)]     # as a 1-based index
    else:
        mv = [e for e in mv if e.tag == "ScalarVariable"]
        for o in ms.find("Outputs"):
            for dep in (o.get("dependencies") or "").split():
                n_deps += 1
                assert mv[int(dep) - 1].get("causality") == "input"
    assert n_deps > 0


def _fmi3_slave(fmu, tmp_path, name="i"):
    from fmpy import extract
    from fmpy.fmi3 import FMU3Slave
    md = read_model_description(str(fmu))
    d = extract(str(fmu), str(tmp_path / name))
    f = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    return f, {v.name: v.valueReference for v in md.modelVariables}


def test_fmi3_intermediate_update_feeds_every_sample_of_a_coarse_step(fmus, cmd, tmp_path):
    """FMI 3.0 has no input derivatives; its counterpart is intermediate update mode
    (providesIntermediateUpdate): before each internal sample of a step the FMU asks the master
    for the inputs of that sample. A master that answers with its table steps at 4 samples and
    gets the per-sample prediction exactly, friction and all; one that sets a parameter there is
    refused."""
    m = fmus["model"]
    ref = simulate(m, {"x": cmd}, Ts=m.Ts).axes["x"]["position"]
    f, vr = _fmi3_slave(fmus[3], tmp_path)
    asked = []

    def update(env, t, set_requested, get_allowed, finished, can_return, early, early_time):
        k = int(round(t / m.Ts))
        asked.append(k)
        f.setFloat64([vr["x_x_cmd"]], [cmd[k]])

    f.instantiate(intermediateUpdate=update, requiredIntermediateVariables=[vr["x_x_cmd"]])
    try:
        f.enterInitializationMode(startTime=0.0)
        f.setFloat64([vr["x_x_cmd"]], [cmd[0]])
        f.exitInitializationMode()
        got = []
        for k in range(0, 400, 4):
            f.setFloat64([vr["x_x_cmd"]], [cmd[k]])
            f.doStep(k * m.Ts, 4 * m.Ts)
            got.append(f.getFloat64([vr["x_x"]])[0])
        assert asked[:6] == [1, 2, 3, 5, 6, 7] and len(asked) == 300
        assert np.abs(np.array(got) - ref[4:401:4]).max() == 0.0
        held = run_coarse(fmus[3], m.Ts * np.arange(401), {"x_x_cmd": cmd[:401]}, ["x_x"], {}, 4,
                          derivatives=False)[1]["x_x"]
        assert np.abs(held - ref[4:401:4]).max() > 1e-6      # held inputs are not the same run
    finally:
        f.freeInstance()
    g, _ = _fmi3_slave(fmus[3], tmp_path, "g")

    def bad_update(env, t, *rest):
        try:
            g.setFloat64([vr["x_friction_level"]], [0.5])
        except FMICallException:          # refused: the doStep that called back fails with it
            pass

    msgs = []
    g.instantiate(loggingOn=True, intermediateUpdate=bad_update, requiredIntermediateVariables=[vr["x_x_cmd"]],
                  logMessage=lambda env, status, cat, msg: msgs.append(msg.decode()))
    try:
        g.enterInitializationMode(startTime=0.0)
        g.exitInitializationMode()
        with pytest.raises(FMICallException):
            g.doStep(0.0, 4 * m.Ts)
        assert any("cannot be set in intermediate update mode (inputs only)" in s for s in msgs), msgs
    finally:
        g.freeInstance()
    # an output asked for as an intermediate variable: refused at instantiation, with a message
    h, _ = _fmi3_slave(fmus[3], tmp_path, "h")
    msgs.clear()
    with pytest.raises(Exception):
        h.instantiate(loggingOn=True, intermediateUpdate=update, requiredIntermediateVariables=[vr["x_x"]],
                      logMessage=lambda env, status, cat, msg: msgs.append(msg.decode()))
    assert any("is not an input" in s for s in msgs), msgs


def test_validate_reports_fed_every_sample_and_the_masters_coarse_step(fmus, cmd):
    """fdid validate gives both figures, in its text and its JSON: fed every sample, and at the
    step fmpy picks by itself with the inputs held and with the inputs passed within the step."""
    from fdid_fmi.fmu import validate_fmu
    from fdid_fmi.trace import Trace
    out = {}
    for key, m in (("linear2", fmus["linear"]), (3, fmus["model"])):
        x = simulate(m, {"x": cmd}, Ts=m.Ts).axes["x"]["position"]
        tr = Trace.from_arrays(m.Ts * np.arange(N), {"x": {"cmd": cmd, "act": x}}, source="synthetic")
        res = validate_fmu(fmus[key], tr)
        d, text = res.to_dict(), res.table()
        assert res.ok and d["coarse_step_s"] == pytest.approx(0.004) and d["coarse_samples"] == 4
        assert "fed every sample" in text and "held inputs at a master's step of 0.004 s (4 samples)" in text
        out[key] = d
    lin = out["linear2"]
    assert lin["max_abs_diff_reference_mm"] <= 1e-9 < lin["max_abs_diff_held_mm"]
    assert lin["max_abs_diff_interpolated_mm"] * 10 <= lin["max_abs_diff_held_mm"]
    assert out[3]["max_abs_diff_interpolated_mm"] == 0.0 < out[3]["max_abs_diff_held_mm"]
