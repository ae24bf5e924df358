"""FMU export: fmpy validation, agreement with the reference simulator, FMI behaviour."""
import json
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu as fmpy_validate

import fmu_support as fs
from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import compiler_available
from fdid_fmi.fmu.validate import FmuRunner, run_fmu, run_master
from fdid_fmi.model import QuasiStaticModel
from fdid_fmi.simulate import simulate

MODELS = {"siso": fs.siso_model, "coupled": fs.coupled_model, "flexible": fs.flexible_model,
          "feature": fs.feature_model}
N = 3000


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmus")
    out = {}
    for name, make in MODELS.items():
        m = make()
        out[name] = (m, export_fmu(m, d / f"{name}.fmu"))
    return out


def _commands(model, seed, v_start):
    rng = np.random.default_rng(seed)
    cmds = {a: fs.smooth_moves(N, rng, start=7.5 * i + 3.0, v_start=v_start) for i, a in enumerate(model.axes)}
    ext = {}
    if any(p.kind == "external" for p in model.inputs):
        ext = {"force_N": 5.0 * np.sin(np.arange(N) * 0.013) + rng.normal(0, 0.5, N)}
    return cmds, ext


def _max_diff(model, cmds, out, ref):
    """Largest differences of the FMU's outputs read before each step (row k: t_k) from the
    reference: positions, the tracking error x_cmd(t_k) - <axis>_x(t_k), tool side; velocities."""
    d, dv = 0.0, 0.0
    for a in model.axes:
        r = ref.axes[a]
        d = max(d, np.abs(out[f"{a}_x"] - r["position"]).max(),
                np.abs((cmds[a] - out[f"{a}_x"]) - r["error"]).max())
        if "tool_position" in r:
            d = max(d, np.abs(out[f"{a}_x_tool"] - r["tool_position"]).max())
        dv = max(dv, np.abs(out[f"{a}_v"] - r["velocity"]).max())
    return d, dv


@pytest.mark.parametrize("name", list(MODELS))
def test_fmpy_validation_reports_no_problem(fmus, name):
    assert fmpy_validate(str(fmus[name][1])) == []


@pytest.mark.parametrize("name", list(MODELS))
def test_friction_feed_through_is_significant(fmus, name):
    """The exact friction solve matters: loop gain L*|beta|/v_tilde >> 1 on every test model."""
    m = fmus[name][0]
    for i, p in enumerate(m.inputs):
        if p.kind == "friction":
            o = m.output_index("velocity", p.axis)
            beta = m.D[o, i] if o is not None else m.D[m.output_index("position", p.axis), i] / m.Ts
            assert p.params["level"] * abs(beta) / p.params["v_tilde"] > 10


@pytest.mark.parametrize("v_start", [0.0, 35.0], ids=["at-rest", "in-motion"])
@pytest.mark.parametrize("name", list(MODELS))
def test_fmu_equals_reference_simulator(fmus, name, v_start):
    m, fmu = fmus[name]
    cmds, ext = _commands(m, seed=11, v_start=v_start)
    v0 = {a: (c[1] - c[0]) / m.Ts for a, c in cmds.items()}
    if v_start:
        assert all(abs(v) > 30 for v in v0.values())
    ref = simulate(m, cmds, Ts=m.Ts, start_velocity=v0, externals=ext)
    out = run_fmu(fmu, cmds, m.Ts, start_velocity=v0, externals=ext)
    d, dv = _max_diff(m, cmds, out, ref)
    assert d <= 1e-9, f"max |FMU - reference| = {d} mm"
    assert dv <= 1e-9 / m.Ts
    # the applied friction inputs are exposed as locals and match too
    fr = [i for i, p in enumerate(m.inputs) if p.kind == "friction"]
    dnf = run_fmu(fmu, cmds, m.Ts, start_velocity=v0, externals=ext,
                  outputs=[m.inputs[i].name for i in fr])
    for i in fr:
        assert np.abs(dnf[m.inputs[i].name] - ref.u[:, i]).max() <= 1e-9
    # both friction branches and the linear region are visited
    u = ref.u[:, fr]
    lev = np.array([m.inputs[i].params["level"] for i in fr])
    assert (np.abs(u) < 0.999 * lev).any() and (np.isclose(np.abs(u), lev)).any()


def test_two_friction_inputs_use_mixed_branches(fmus):
    """The coupled model visits mixed branches (one friction saturated, one linear)."""
    m, fmu = fmus["coupled"]
    cmds, _ = _commands(m, seed=3, v_start=0.0)
    ref = simulate(m, cmds, Ts=m.Ts)
    fr = [i for i, p in enumerate(m.inputs) if p.kind == "friction"]
    lev = np.array([m.inputs[i].params["level"] for i in fr])
    sat = np.isclose(np.abs(ref.u[:, fr]), lev)
    assert (sat[:, 0] != sat[:, 1]).any() and (~sat).all(axis=1).any()
    out = run_fmu(fmu, cmds, m.Ts)
    assert _max_diff(m, cmds, out, ref)[0] <= 1e-9


def test_parameters_match_reference_overrides(fmus):
    m, fmu = fmus["coupled"]
    cmds, _ = _commands(m, seed=5, v_start=0.0)
    params = {"x_friction_level": 0.6, "y_v_tilde": 2.5}
    ref = simulate(m, cmds, Ts=m.Ts, params={**params, "y_friction_on": False})
    out = run_fmu(fmu, cmds, m.Ts, parameters=params, booleans={"y_friction_on": False})
    assert _max_diff(m, cmds, out, ref)[0] <= 1e-9
    base = run_fmu(fmu, cmds, m.Ts)
    assert np.abs(base["y_x"] - out["y_x"]).max() > 1e-4   # the parameters do something


def test_communication_step_of_three_samples(fmus):
    """h = 3 Ts runs three internal steps with the input held: equal to the reference on held input.

    The command moves without stopping (40 mm/s plus a sine): a held (staircase) command
    that stops makes the friction stick and slip every few samples, a chaotic regime where
    rounding differences grow, whatever the implementation.
    """
    m, fmu = fmus["flexible"]
    t = np.arange(N) * m.Ts
    cmd = 3.0 + 40.0 * t + 2.0 * np.sin(2 * np.pi * 3 * t)
    held = {"x": np.repeat(cmd[::3], 3)[:N]}
    ref = simulate(m, held, Ts=m.Ts, start_velocity={"x": 40.0})
    out3 = run_fmu(fmu, held, m.Ts, comm_step=3, start_velocity={"x": 40.0})
    for key, var in (("position", "x_x"), ("tool_position", "x_x_tool")):
        assert np.abs(out3[var] - ref.axes["x"][key][::3]).max() <= 1e-9
    assert np.abs((held["x"][::3] - out3["x_x"]) - ref.axes["x"]["error"][::3]).max() <= 1e-9
    out1 = run_fmu(fmu, held, m.Ts, start_velocity={"x": 40.0})
    assert np.array_equal(out1["x_x"][::3], out3["x_x"])
    assert len(out3["x_x"]) == N // 3


def test_initial_state_follows_inputs_set_before_the_first_step(fmus):
    """Inputs changed after exitInitializationMode but before the first doStep re-initialise."""
    m, fmu = fmus["siso"]
    cmds, _ = _commands(m, seed=4, v_start=20.0)
    v0 = (cmds["x"][1] - cmds["x"][0]) / m.Ts
    ref = simulate(m, cmds, Ts=m.Ts, start_velocity={"x": v0})
    r = FmuRunner(fmu)
    try:
        f = r.fmu
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.setReal([r.vr("x_x_cmd")], [123.0])            # a stale value
        f.setReal([r.vr("x_v0")], [v0])
        f.exitInitializationMode()
        assert abs(f.getReal([r.vr("x_x")])[0] - 123.0) < 0.1   # lags by K_vel * v0
        out = []
        for k in range(200):
            f.setReal([r.vr("x_x_cmd")], [cmds["x"][k]])
            out.append(f.getReal([r.vr("x_x")])[0])
            f.doStep(k * m.Ts, m.Ts)
        assert np.abs(np.array(out) - ref.axes["x"]["position"][:200]).max() <= 1e-9
    finally:
        r.close()


def _logged_runner(fmu):
    msgs = []

    def logger(env, name, status, category, message):
        msgs.append((status, category.decode(), message.decode()))

    from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2CallbackAllocateMemoryTYPE, \
        fmi2CallbackFreeMemoryTYPE, fmi2StepFinishedTYPE
    from fmpy import calloc, free
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    cb.stepFinished = fmi2StepFinishedTYPE()
    cb.componentEnvironment = None
    r = FmuRunner(fmu)
    r.fmu.instantiate(callbacks=cb)
    r._cb = cb
    return r, msgs


def test_a_drifting_master_clock_is_named_not_the_step_size(fmus):
    """A master that keeps its clock by adding its steps (t += h) from a wall-clock start time
    drifts off the sample grid by their rounding (ulp(1.7e9 s) = 2.4e-7 s) and is refused after
    about 140 steps of h = Ts = 1 ms; the message must say that its time drifted, not that h = Ts is
    not a multiple of Ts."""
    m, fmu = fmus["siso"]
    r, msgs = _logged_runner(fmu)
    f = r.fmu
    try:
        t = 1.7e9
        f.setupExperiment(startTime=t)
        f.enterInitializationMode()
        f.exitInitializationMode()
        with pytest.raises(FMICallException):
            for _ in range(100_000):
                f.doStep(t, m.Ts)
                t += m.Ts
        assert abs(t - 1.7e9) < 1000 * m.Ts, "refused only after more than 1000 steps"
        text = msgs[-1][2]
        assert "currentCommunicationPoint" in text and "drifted" in text, text
        assert "not an integer multiple" not in text, text
    finally:
        r.close()


@pytest.mark.parametrize("case", ["step_size", "nan_input", "unknown_vr", "order", "cancel", "v0_fixed",
                                  "negative_vtilde", "output_set"])
def test_misuse_returns_error_with_a_clear_message(fmus, case):
    m, fmu = fmus["siso"]
    r, msgs = _logged_runner(fmu)
    f = r.fmu
    try:
        if case == "order":
            with pytest.raises(FMICallException):
                f.doStep(0.0, m.Ts)
            assert "fmi2DoStep may not be called in the instantiated state" in msgs[-1][2]
            return
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        # 2.5 samples end half a sample before the third (the distance is not printed as negative)
        want = {"step_size": f"not an integer multiple of the model sample time Ts = {m.Ts!r} s (the step would "
                             f"end {0.5 * m.Ts:.3g} s before the nearest sample time)",
                "nan_input": "must be finite", "unknown_vr": "unknown value reference 999",
                "cancel": "no step is pending", "v0_fixed": "fixed parameter",
                "negative_vtilde": "must be > 0", "output_set": "cannot be set"}[case]
        with pytest.raises(FMICallException) as exc:
            if case == "step_size":
                f.doStep(0.0, 2.5 * m.Ts)
            elif case == "nan_input":
                f.setReal([r.vr("x_x_cmd")], [float("nan")])
            elif case == "unknown_vr":
                f.getReal([999])
            elif case == "cancel":
                f.cancelStep()
            elif case == "v0_fixed":
                f.setReal([r.vr("x_v0")], [1.0])
            elif case == "negative_vtilde":
                f.setReal([r.vr("x_v_tilde")], [-1.0])
            elif case == "output_set":
                f.setReal([r.vr("x_x")], [1.0])
        assert exc.value.status == 3  # fmi2Error
        assert msgs and msgs[-1][0] == 3 and want in msgs[-1][2], msgs
        assert msgs[-1][1] == "logStatusError"
        # the instance is in the error state until reset
        with pytest.raises(FMICallException):
            f.doStep(0.0, m.Ts)
        f.reset()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        f.doStep(0.0, 3 * m.Ts)
        assert f.getRealStatus(2) == pytest.approx(3 * m.Ts)   # fmi2LastSuccessfulTime
    finally:
        r.close()


def test_debug_logging_follows_the_categories(fmus):
    m, fmu = fmus["siso"]
    r, msgs = _logged_runner(fmu)
    f = r.fmu
    try:
        f.setupExperiment(startTime=0.0)
        assert msgs == []                                   # loggingOn=false: no call trace
        f.setDebugLogging(True, ["logCalls"])
        f.enterInitializationMode()
        assert msgs[-1][1] == "logCalls" and "fmi2EnterInitializationMode" in msgs[-1][2]
        f.setDebugLogging(False, [])
        n = len(msgs)
        f.exitInitializationMode()
        assert len(msgs) == n
        f.setDebugLogging(True, ["logStatusWarning"])
        f.setDebugLogging(True, ["noSuchCategory"])       # fmi2Warning (test_fmu_master_calls.py)
        assert msgs[-1][0] == 1 and "unknown log category 'noSuchCategory' ignored" in msgs[-1][2]
    finally:
        r.close()


def test_fmu_state_round_trip_through_fmpy(fmus):
    m, fmu = fmus["coupled"]
    cmds, _ = _commands(m, seed=8, v_start=10.0)
    r = FmuRunner(fmu)
    f = r.fmu
    try:
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.setReal([r.vr("x_x_cmd"), r.vr("y_x_cmd")], [cmds["x"][0], cmds["y"][0]])
        f.exitInitializationMode()
        vrs = [r.vr("x_x"), r.vr("y_x"), r.vr("y_v")]

        def run(k0, k1):
            for k in range(k0, k1):
                f.setReal([r.vr("x_x_cmd"), r.vr("y_x_cmd")], [cmds["x"][k], cmds["y"][k]])
                f.doStep(k * m.Ts, m.Ts)
            return f.getReal(vrs)

        run(0, 500)
        state = f.getFMUstate()
        blob = f.serializeFMUstate(state)
        a = run(500, 900)
        f.setFMUstate(state)
        b = run(500, 900)
        f.setFMUstate(f.deSerializeFMUstate(blob))
        c = run(500, 900)
        assert a == b == c
        f.freeFMUstate(state)
    finally:
        r.close()


def test_model_description_contents(fmus):
    m, fmu = fmus["flexible"]
    md = read_model_description(str(fmu))
    units = {u.name: u for u in md.unitDefinitions}
    assert {"mm", "mm/s", "s"} <= set(units)
    assert units["mm"].baseUnit.m == 1 and units["mm"].baseUnit.factor == 1e-3
    v = {x.name: x for x in md.modelVariables}
    assert v["x_x_cmd"].causality == "input" and v["x_x_cmd"].unit == "mm"
    for name in ("x_x", "x_x_tool"):
        assert v[name].causality == "output" and v[name].unit == "mm" and v[name].description
    assert v["x_v"].unit == "mm/s"
    assert v["x_v0"].variability == "fixed" and float(v["x_v0"].start) == 0.0
    assert v["x_friction_on"].type == "Boolean" and v["x_v_tilde"].variability == "tunable"
    assert md.defaultExperiment.stepSize == repr(m.Ts) or float(md.defaultExperiment.stepSize) == m.Ts
    deps = {u.variable.name: [d.name for d in u.dependencies] for u in md.outputs}
    # causal: the position answers the command one sample later
    assert deps["x_x"] == [] and deps["x_x_tool"] == []
    # no tracking-error output: neither <axis>_e nor the model's error output (x_err)
    assert sorted(deps) == ["x_v", "x_x", "x_x_tool"]
    assert "x_e" not in v and "x_err" not in v
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and cs.modelIdentifier == "flexible"
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
        assert {"sources/fdid_core.c", "sources/fmi2Functions.c", "sources/model_data.c",
                "binaries/linux64/flexible.so", "resources/model.json"} <= names
        assert json.loads(zf.read("resources/model.json"))["format"] == "fdid-fmi-model"


def test_guid_is_a_hash_of_the_model(tmp_path):
    m = fs.siso_model()
    a = read_model_description(str(export_fmu(m, tmp_path / "a.fmu", model_identifier="same"))).guid
    b = read_model_description(str(export_fmu(m, tmp_path / "b.fmu", model_identifier="same"))).guid
    c = read_model_description(str(export_fmu(fs.siso_model(v_tilde=2.0), tmp_path / "c.fmu",
                                              model_identifier="same"))).guid
    assert a == b != c


def test_no_libm_unless_features_need_it(fmus):
    if shutil.which("readelf") is None:
        pytest.skip("readelf (binutils) is not installed")

    def needed(fmu, ident):
        with zipfile.ZipFile(fmu) as zf:
            data = zf.read(f"binaries/linux64/{ident}.so")
        p = fmu.with_suffix(".so")
        p.write_bytes(data)
        out = subprocess.run(["readelf", "-d", "--dyn-syms", str(p)], capture_output=True, text=True).stdout
        return out

    plain = needed(fmus["coupled"][1], "coupled")
    assert "libm.so" not in plain and "fmi2DoStep" in plain
    assert " fdid_initialize" not in plain   # internal symbols are hidden
    assert "libm.so" in needed(fmus["feature"][1], "feature")


def test_quasi_static_models_are_refused(tmp_path):
    qs = QuasiStaticModel(Ts=1e-3, gains={"x": {"K_vel": 1e-3, "K_acc": 0.0, "K_jerk": 0.0}}, cutoff_hz=50.0)
    with pytest.raises(InputError, match="quasi-static"):
        export_fmu(qs, tmp_path / "q.fmu")


def test_bad_export_options(tmp_path):
    m = fs.siso_model()
    with pytest.raises(InputError, match="FMI version"):
        export_fmu(m, tmp_path / "a.fmu", fmi_version=4)
    with pytest.raises(InputError, match="unknown platform"):
        export_fmu(m, tmp_path / "a.fmu", platforms=("mac64",))
    with pytest.raises(InputError, match=".fmu"):
        export_fmu(m, tmp_path / "a.zip")


def test_export_cli(tmp_path):
    from fdid_fmi.cli import main
    m = fs.siso_model()
    m.save(tmp_path / "m.json")
    assert main(["export", str(tmp_path / "m.json"), "-o", str(tmp_path / "cli.fmu")]) == 0
    assert fmpy_validate(str(tmp_path / "cli.fmu")) == []
    assert main(["export", str(tmp_path / "m.json"), "--platforms", "solaris"]) == 2


def test_win64_dll_is_built(tmp_path):
    if not compiler_available("win64"):
        pytest.skip("x86_64-w64-mingw32-gcc is not installed (apt-get install gcc-mingw-w64-x86-64)")
    fmu = export_fmu(fs.coupled_model(), tmp_path / "w.fmu", platforms=("linux64", "win64"))
    assert fmpy_validate(str(fmu)) == []
    with zipfile.ZipFile(fmu) as zf:
        dll = zf.read("binaries/win64/w.dll")
    assert dll[:2] == b"MZ"
    p = tmp_path / "w.dll"
    p.write_bytes(dll)
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(p)], capture_output=True, text=True).stdout
    assert "fmi2DoStep" in dump and "fmi2Instantiate" in dump
    dlls = {line.split(":")[1].strip() for line in dump.splitlines() if "DLL Name" in line}
    assert dlls <= {"KERNEL32.dll", "msvcrt.dll"}, dlls


def test_fmi3_fmu_validates_and_equals_the_reference(tmp_path):
    from fmpy.fmi3 import FMU3Slave  # noqa: F401  (fmpy with FMI 3.0 support)
    m = fs.coupled_model()
    fmu = export_fmu(m, tmp_path / "c3.fmu", fmi_version=3)
    assert fmpy_validate(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.fmiVersion == "3.0" and float(md.coSimulation.fixedInternalStepSize) == m.Ts
    with zipfile.ZipFile(fmu) as zf:
        names = set(zf.namelist())
        assert {"binaries/x86_64-linux/c3.so", "sources/buildDescription.xml",
                "sources/fmi3Functions.c"} <= names
    cmds, _ = _commands(m, seed=11, v_start=35.0)
    v0 = {a: (c[1] - c[0]) / m.Ts for a, c in cmds.items()}
    ref = simulate(m, cmds, Ts=m.Ts, start_velocity=v0)
    out = run_fmu(fmu, cmds, m.Ts, start_velocity=v0)
    assert _max_diff(m, cmds, out, ref)[0] <= 1e-9
    out3 = run_fmu(fmu, cmds, m.Ts, comm_step=3, outputs=["x_x"])
    assert len(out3["x_x"]) == N // 3
    # a step size that is not a multiple of Ts is refused
    r = FmuRunner(fmu)
    try:
        f = r.fmu
        f.instantiate()
        f.enterInitializationMode(startTime=0.0)
        f.exitInitializationMode()
        with pytest.raises(Exception):
            f.doStep(0.0, 1.5 * m.Ts)
    finally:
        r.close()


@pytest.mark.parametrize("name", list(MODELS))
def test_masters_see_the_model(fmus, name):
    """fmpy.simulate_fmu with an input table and step_size = Ts written as a decimal (what every
    master does: set inputs, doStep, read): positions, velocities and tool positions at each time
    stamp equal the in-process prediction, and x_cmd(t) - <axis>_x(t) is the tracking error."""
    m, fmu = fmus[name]
    n = 600
    cmds, ext = _commands(m, seed=11, v_start=0.0)
    cmds = {a: c[:n] for a, c in cmds.items()}
    ext = {k: v[:n] for k, v in ext.items()}
    t = 0.25 + 0.001 * np.arange(n)                       # an ordinary decimal grid, t0 != 0
    inputs = {f"{a}_x_cmd": c for a, c in cmds.items()} | ext
    outs = [v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"]
    res = run_master(fmu, t, inputs, outs, step_size=0.001)
    ref = simulate(m, cmds, Ts=m.Ts, externals=ext)
    for a in m.axes:
        r = ref.axes[a]
        assert np.abs(res[f"{a}_x"] - r["position"]).max() <= 1e-9
        assert np.abs(res[f"{a}_v"] - r["velocity"]).max() <= 1e-6
        if "tool_position" in r:
            assert np.abs(res[f"{a}_x_tool"] - r["tool_position"]).max() <= 1e-9
        # the tracking error at the master's time stamps: the command of that time stamp
        # minus the position recorded at it (docs/fmu-interface.md)
        assert np.abs((cmds[a] - res[f"{a}_x"]) - r["error"]).max() <= 1e-9
    assert not any(name.endswith("_e") or name.endswith("_err") for name in outs)
