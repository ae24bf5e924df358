"""Hostile model files and FMU calls: code injection, broken numbers, unbounded steps, forged states.

Model JSON files and FMUs are exchanged between companies; whatever a model file holds must
either be refused with one line naming the field, or end up in the FMU only as escaped data.
The injection payload below is proved live first (compiled as C it creates a marker file the
moment the library is loaded); then it is pushed through every free-form field of a model and
the FMU built from it is loaded and stepped: the marker file must not appear.
"""
import ctypes
import json
import struct
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu as fmpy_validate
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu
from fdid_fmi.fmu.build import CFLAGS, compiler_available
from fdid_fmi.fmu.description import model_description_fmi2, model_description_fmi3
from fdid_fmi.fmu.layout import build_layout
from fdid_fmi.model import BIDI_CONTROLS, DriveModel, load_model

pytestmark = pytest.mark.skipif(not compiler_available("linux64"), reason="gcc is not installed")

TS = 1e-3
FDID = [sys.executable, "-m", "fdid_fmi.cli"]


def model_dict(axis="x", method="hand-built", unit="mm", description="", ext_name="force_N",
               ext_unit="N", Ts=TS, friction=None, features=()):
    """JSON dict of a small causal model: x[k+1] = a x[k] + (1-a) x_cmd[k] + b d[k] (+ externals,
    features); outputs position and error (e = x_cmd - x, D = 1 on its own command)."""
    a = 0.9
    fr = {"v_tilde": 1.0, "level": 0.5} if friction is None else friction
    ins = [{"name": f"{axis}_cmd", "unit": unit, "kind": "command", "axis": axis},
           {"name": f"{axis}_dnf", "unit": "1", "kind": "friction", "axis": axis, "params": fr},
           {"name": ext_name, "unit": ext_unit, "kind": "external", "axis": axis,
            "description": description}]
    for k, params in enumerate(features):
        ins.append({"name": f"{axis}_feat{k}", "unit": "1", "kind": "feature", "axis": axis,
                    "params": params})
    B = [[1 - a, 1e-4, 1e-5] + [1e-6] * len(features)]
    D = [[0.0] * len(ins), [1.0] + [0.0] * (len(ins) - 1)]
    return {"format": "fdid-fmi-model", "format_version": 1, "kind": "state_space", "Ts": Ts,
            "method": method, "A": [[a]], "B": B, "C": [[1.0], [-1.0]], "D": D, "inputs": ins,
            "outputs": [{"name": f"{axis}_pos", "unit": unit, "kind": "position", "axis": axis,
                         "description": description},
                        {"name": f"{axis}_err", "unit": unit, "kind": "error", "axis": axis}]}


def write_json(path, d):
    path.write_text(json.dumps(d))
    return path


def payload(marker):
    """C that creates ``marker`` when the shared library holding it is loaded, wrapped so that
    it closes a C comment before and opens one after (the reported injection)."""
    return (f'x */ __attribute__((constructor)) static void fdid_pwn(void) {{ '
            f'extern int creat(const char *, unsigned); creat("{marker}", 420u); }} /*')


def fdid(*args):
    return subprocess.run(FDID + [str(a) for a in args], capture_output=True, text=True, timeout=300)


def one_line_error(r, *words):
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert len(lines) == 1 and "error:" in lines[0] and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def run_fmu_steps(fmu, n=20, instance="i"):
    """Load an FMU with fmpy (FMI 2 or 3), step it n times from a ramp; returns the x outputs."""
    md = read_model_description(str(fmu))
    d = extract(str(fmu))
    three = md.fmiVersion.startswith("3")
    cls = FMU3Slave if three else FMU2Slave
    kw = dict(unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance)
    f = cls(guid=md.guid, **kw)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    f.instantiate(loggingOn=False)
    if three:
        f.enterInitializationMode(startTime=0.0)
    else:
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
    f.exitInitializationMode()
    out = []
    setr, getr = (f.setFloat64, f.getFloat64) if three else (f.setReal, f.getReal)
    for k in range(n):
        setr([vr["x_x_cmd"]], [0.01 * k])
        f.doStep(k * TS, TS)
        out.append(getr([vr["x_x"]])[0])
    f.terminate()
    f.freeInstance()
    return np.array(out)


# ----------------------------------------------------------------------------- the payload is live
def test_payload_runs_when_compiled_as_code(tmp_path):
    """Control: the payload, written unescaped into a C comment, compiles under the FMU's flags
    and creates its marker file when the library is loaded. (The tests below would prove
    nothing with a dead payload.)"""
    marker = tmp_path / "pwned_control"
    src = tmp_path / "evil.c"
    src.write_text(f"/* model: {payload(marker)} */\nint fdid_dummy;\n")
    lib = tmp_path / "libevil.so"
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", str(src), "-o", str(lib)], check=True)
    assert not marker.exists()
    ctypes.CDLL(str(lib))
    assert marker.exists()


# ----------------------------------------------------------------------------- injection, names
@pytest.mark.parametrize("field", ["axis", "port", "external"])
def test_injection_through_a_name_is_refused(tmp_path, field):
    marker = tmp_path / "pwned"
    evil = payload(marker)
    d = {"axis": lambda: model_dict(axis=evil), "port": lambda: model_dict(),
         "external": lambda: model_dict(ext_name=evil)}[field]()
    if field == "port":
        d["outputs"][0]["name"] = evil
    src = write_json(tmp_path / "evil.json", d)
    before = src.read_bytes()
    with pytest.raises(InputError, match="is not a name"):
        load_model(src)
    r = fdid("export", src, "-o", tmp_path / "evil.fmu")
    one_line_error(r, "evil.json", "is not a name")
    assert not (tmp_path / "evil.fmu").exists() and not marker.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["evil.json"]   # nothing half-written
    assert src.read_bytes() == before


@pytest.mark.parametrize("fmi", [2, 3])
def test_injection_through_free_text_stays_escaped_data(tmp_path, fmi):
    """method and description are free text: they may hold the payload, but the FMU carries it
    only as escaped XML; no C source holds it and loading the FMU runs nothing. A unit is one of
    the canonical units: the payload there is refused when the model is read."""
    marker = tmp_path / "pwned"
    evil = payload(marker)
    with pytest.raises(InputError, match="external input has unit 'x \\*/ __attr"):
        load_model(write_json(tmp_path / "unit.json", model_dict(ext_unit=evil[:64])))
    d = model_dict(method=evil[:200], description=evil)
    src = write_json(tmp_path / "evil.json", d)
    fmu = export_fmu(load_model(src), tmp_path / "evil.fmu", fmi_version=fmi)
    with zipfile.ZipFile(fmu) as zf:
        sources = {n: zf.read(n).decode() for n in zf.namelist() if n.startswith("sources/")}
        xml = zf.read("modelDescription.xml").decode()
    for name, text in sources.items():
        assert "constructor" not in text and "creat" not in text, name
    root = ET.fromstring(xml)                       # well-formed; the payload is attribute data
    descs = [e.get("description") for e in root.iter() if e.get("description")]
    assert evil in descs
    assert fmpy_validate(str(fmu)) == []
    x = run_fmu_steps(fmu)
    assert np.all(np.isfinite(x)) and x[-1] > 0
    assert not marker.exists()


def test_injection_through_map_axis_is_refused(tmp_path):
    marker = tmp_path / "pwned"
    csv = tmp_path / "run.csv"
    t = np.arange(400) * TS
    np.savetxt(csv, np.column_stack([t, np.sin(t), np.sin(t)]), delimiter=",",
               header="t_s,c,a", comments="")
    r = fdid("identify", csv, "--map", "t=t_s", f"{payload(marker)}.cmd=c", "x.act=a",
             "-o", tmp_path / "m.json")
    one_line_error(r, "--map", "is not a name")
    assert not (tmp_path / "m.json").exists() and not marker.exists()


@pytest.mark.parametrize("bad", ["", "1x", "x y", "x\ty", "x\ny", "a-b", "é", "x\x00", "\ud800",
                                 "x" * 129])
def test_bad_port_names_are_refused(bad):
    d = model_dict()
    d["inputs"][2]["name"] = bad
    with pytest.raises(InputError, match="input 3 name"):
        DriveModel.from_dict(d)


@pytest.mark.parametrize("field,value", [("unit", "m\x01m"), ("unit", "mm\n"), ("description", "a\x1bb"),
                                         ("description", "x\ud800"), ("description", "a\u2028b"),
                                         ("unit", "\ufffe")])
def test_control_characters_in_text_are_refused(field, value):
    d = model_dict()
    d["inputs"][2][field] = value
    with pytest.raises(InputError, match="non-printable character"):
        DriveModel.from_dict(d)


@pytest.mark.parametrize("field,value,words", [("format_version", True, "format version True"),
                                               ("format_version", 0, "format version 0"),
                                               ("Ts", True, "Ts must be a number"),
                                               ("Ts", "0.001", "Ts must be a number")])
def test_header_numbers_are_numbers(field, value, words):
    """JSON true read as 1 (Ts = 1 s), format version 0 or True: refused."""
    d = model_dict()
    d[field] = value
    with pytest.raises(InputError, match=words):
        DriveModel.from_dict(d)


@pytest.mark.parametrize("axis", ["x", None])
def test_one_command_per_axis(axis):
    """A second command on axis x (never fed: the simulation would ignore it) or a command without an
    axis (exported as 'None_x_cmd') is refused when the model is built."""
    d = model_dict()
    d["inputs"][2].update(kind="command", axis=axis, unit="mm")
    with pytest.raises(InputError, match="exactly one command input"):
        DriveModel.from_dict(d)


def test_duplicate_names_are_refused():
    d = model_dict()
    d["inputs"][2]["name"] = "x_cmd"
    with pytest.raises(InputError, match="named 'x_cmd'"):
        DriveModel.from_dict(d)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.one_of(st.text(max_size=12), st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,11}", fullmatch=True)),
       unit=st.one_of(st.sampled_from(["N", "A", "1", "mm"]), st.text(max_size=12)),
       desc=st.text(max_size=30))
def test_random_names_refused_or_valid_xml(tmp_path_factory, name, unit, desc):
    """Any string as port name, unit and description: the model is refused with InputError, or
    both modelDescription.xml versions pass fmpy's validator and keep the text exactly."""
    d = model_dict(ext_name=name, ext_unit=unit, description=desc)
    try:
        m = DriveModel.from_dict(d)
    except InputError:
        return
    lay = build_layout(m)
    guid = "{00000000-0000-0000-0000-000000000000}"
    for k, xml in ((2, model_description_fmi2(lay, guid, "m", source_files=["a.c"])),
                   (3, model_description_fmi3(lay, guid, "m"))):
        folder = tmp_path_factory.mktemp(f"md{k}")
        (folder / "modelDescription.xml").write_text(xml, encoding="utf-8")
        assert fmpy_validate(str(folder)) == [], xml
        root = ET.fromstring(xml.encode("utf-8"))
        names = [e.get("name") for e in root.iter() if e.get("causality") == "input"]
        assert name in names
        if desc:
            assert desc in [e.get("description") for e in root.iter()]


def test_a_port_named_time_does_not_clash_with_fmi3_time(tmp_path):
    """FMI 3 declares the independent variable ``time``: a port of that name gets another
    variable name, and both model descriptions pass fmpy's validator."""
    lay = build_layout(DriveModel.from_dict(model_dict(ext_name="time")))
    guid = "{00000000-0000-0000-0000-000000000000}"
    for k, xml in ((2, model_description_fmi2(lay, guid, "m", source_files=["a.c"])),
                   (3, model_description_fmi3(lay, guid, "m"))):
        folder = tmp_path / f"md{k}"
        folder.mkdir()
        (folder / "modelDescription.xml").write_text(xml, encoding="utf-8")
        assert fmpy_validate(str(folder)) == [], xml
        names = [e.get("name") for e in ET.fromstring(xml.encode("utf-8")).iter() if e.get("name")]
        assert len(names) == len(set(names))


@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,20}", fullmatch=True),
       desc=st.text(st.characters(blacklist_categories=("Cc", "Cs", "Zl", "Zp"),
                                  blacklist_characters="".join(map(chr, BIDI_CONTROLS))), max_size=40))
def test_random_valid_names_export_and_load(tmp_path_factory, name, desc):
    """Random legal names and descriptions through the whole export, then loaded by fmpy."""
    if name in ("x_cmd", "x_dnf"):
        return
    d = model_dict(ext_name=name, description=desc)
    fmu = export_fmu(DriveModel.from_dict(d), tmp_path_factory.mktemp("fmu") / "r.fmu")
    md = read_model_description(str(fmu), validate=True)
    assert name in [v.name for v in md.modelVariables]
    assert np.all(np.isfinite(run_fmu_steps(fmu, n=5)))


# ----------------------------------------------------------------------------- numbers
@pytest.mark.parametrize("edit,column", [
    (lambda d: d["inputs"].append({"name": "x_sin", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "sin_position", "period_mm": 0}}), "period_mm"),
    (lambda d: d["inputs"].append({"name": "x_str", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "stribeck", "v_tilde": 1.0, "v_s": 0}}), "v_s"),
    (lambda d: d["inputs"].append({"name": "x_sat", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "sat", "v_tilde": -1}}), "v_tilde"),
    (lambda d: d["inputs"].append({"name": "x_play", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play", "width_mm": 0.0,
                                              "source": "position"}}), "width_mm"),
    (lambda d: d["inputs"].append({"name": "x_play", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play", "width_mm": float("nan"),
                                              "source": "position"}}), "width_mm"),
    (lambda d: d["inputs"].append({"name": "x_play", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play", "width_mm": 0.01}}), "x_play.source"),
    (lambda d: d["inputs"].append({"name": "x_ps", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play_stribeck", "width_mm": 0.01,
                                              "source": "position"}}), "v_s"),
    (lambda d: d["inputs"].append({"name": "x_ps", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play_stribeck", "width_mm": -1, "v_s": 2.0,
                                              "source": "position"}}), "width_mm"),
    (lambda d: d["inputs"].append({"name": "x_ps", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play_stribeck", "width_mm": 0.01, "v_s": 2.0,
                                              "source": "command"}}), "x_ps.source"),
    # a number the function does not use still reaches the C model data: checked like the others
    (lambda d: d["inputs"].append({"name": "x_play", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play", "width_mm": 0.01, "v_tilde": "abc",
                                              "source": "position"}}), "x_play.v_tilde"),
    (lambda d: d["inputs"].append({"name": "x_play", "unit": "1", "kind": "feature", "axis": "x",
                                   "params": {"function": "play", "width_mm": 0.01, "period_mm": float("nan"),
                                              "source": "position"}}), "x_play.period_mm"),
    (lambda d: d["inputs"][1]["params"].update(level=float("nan")), "level"),
    (lambda d: d["inputs"][1]["params"].update(level=float("inf")), "level"),
    (lambda d: d["inputs"][1]["params"].update(level="x"), "level"),
    (lambda d: d["inputs"][1]["params"].update(level=-1), "level"),
    (lambda d: d.update(Ts=1e-300), "Ts"),
    (lambda d: d.update(Ts=100.0), "Ts"),
    (lambda d: d.update(A=[[1e200]]), "A"),
])
def test_numbers_a_simulation_uses_are_checked(tmp_path, edit, column):
    d = model_dict()
    edit(d)
    if d["inputs"][-1]["kind"] == "feature":
        for row in d["B"]:
            row.append(0.0)
        for row in d["D"]:
            row.append(0.0)
    src = write_json(tmp_path / "nan.json", d)     # json writes NaN/Infinity literals
    with pytest.raises(InputError) as exc:
        load_model(src)
    assert column in str(exc.value) and "nan.json" in str(exc.value)


def test_nan_model_gives_no_fmu_and_no_csv(tmp_path):
    d = model_dict(friction={"v_tilde": 1.0, "level": float("nan")})
    src = write_json(tmp_path / "nan.json", d)
    one_line_error(fdid("export", src, "-o", tmp_path / "n.fmu"), "nan.json", "level")
    csv = tmp_path / "run.csv"
    t = np.arange(50) * TS
    np.savetxt(csv, np.column_stack([t, t, t]), delimiter=",", header="t_s,x_cmd_mm,x_mm", comments="")
    one_line_error(fdid("simulate", src, csv, "-o", tmp_path / "p.csv"), "nan.json", "level")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nan.json", "run.csv"]


def test_wrong_types_and_deep_nesting_give_one_line(tmp_path):
    cases = {"axis7": lambda d: d["inputs"][0].update(axis=7),
             "params_list": lambda d: d["inputs"][1].update(params=[1, 2]),
             "inputs_str": lambda d: d.update(inputs="abc"),
             "A_text": lambda d: d.update(A=[["a"]]),
             "big_int": lambda d: d.update(A=[[10 ** 400]])}
    for name, edit in cases.items():
        d = model_dict()
        edit(d)
        src = write_json(tmp_path / f"{name}.json", d)
        with pytest.raises(InputError, match=name):
            load_model(src)
    deep = tmp_path / "deep.json"
    deep.write_text('{"format": "fdid-fmi-model", "format_version": 1, "A": ' + "[" * 100000 + "]" * 100000 + "}")
    one_line_error(fdid("export", deep, "-o", tmp_path / "d.fmu"), "deep.json")


# ----------------------------------------------------------------------------- FMU run time
@pytest.fixture(scope="module")
def fmu2(tmp_path_factory):
    return export_fmu(DriveModel.from_dict(model_dict()), tmp_path_factory.mktemp("f") / "h.fmu")


def _slave(fmu, logs):
    md = read_model_description(str(fmu))
    f = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="h")
    f.instantiate(callbacks=None)
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    return f


def test_do_step_with_1e10_steps_is_refused_fast(fmu2):
    f = _slave(fmu2, [])
    t0 = time.perf_counter()
    with pytest.raises(FMICallException):
        f.doStep(0.0, 1e10 * TS)
    assert time.perf_counter() - t0 < 1.0
    f.reset()                                           # the instance is usable afterwards
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    f.doStep(0.0, 1000 * TS)                            # a large legal step still runs
    f.freeInstance()


def test_forged_serialized_states_are_refused(fmu2):
    f = _slave(fmu2, [])
    f.doStep(0.0, TS)
    state = f.getFMUstate()
    good = bytes(f.serializeFMUstate(state))
    f.deSerializeFMUstate(good, state)                  # the genuine state is accepted
    # layout after the 64-byte GUID: magic (4), mode (4), start time (8), ...
    forged = []
    b = bytearray(good)
    struct.pack_into("<i", b, 68, 2 | 4)               # two states at once (bypasses checks)
    forged.append(bytes(b))
    b = bytearray(good)
    struct.pack_into("<i", b, 68, 32)                  # the fatal state
    forged.append(bytes(b))
    b = bytearray(good)
    struct.pack_into("<d", b, 72, float("nan"))        # start time
    forged.append(bytes(b))
    b = bytearray(good)
    struct.pack_into("<d", b, len(b) - 8 * 3, float("nan"))   # a value in the state buffer
    forged.append(bytes(b))
    forged.append(good[:-1])
    b = bytearray(good)
    b[1:6] = b"\x1b[2J%"                                # another FMU's GUID, with control bytes
    forged.append(bytes(b))
    for k, bad in enumerate(forged):
        f.reset()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        with pytest.raises(FMICallException):
            f.deSerializeFMUstate(bad, state)
    f.freeInstance()


def test_a_non_finite_output_is_an_error_not_a_value(fmu2):
    """A state whose values are finite but huge (a forged state here; a diverged model alike)
    makes an output infinite: fmi2GetReal refuses it (status error) instead of returning inf with
    OK, and the instance recovers by reset."""
    import ctypes as ct
    from fdid_fmi import kernel
    m = DriveModel.from_dict(model_dict())
    nbuf = kernel._lib().fdid_buffer_size(ct.byref(kernel.CompiledModel(m).c))
    outs = [v.valueReference for v in read_model_description(str(fmu2)).modelVariables
            if v.causality == "output"]
    f = _slave(fmu2, [])
    f.doStep(0.0, TS)
    state = f.getFMUstate()
    b = bytearray(f.serializeFMUstate(state))
    for i in range(m.n_states):                         # the model's states, at the buffer's start
        struct.pack_into("<d", b, len(b) - 8 * (nbuf - i), 1.7e308)
    f.deSerializeFMUstate(bytes(b), state)              # finite: accepted
    f.setFMUstate(state)
    with pytest.raises(FMICallException):
        f.getReal(outs)
    f.reset()
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    f.doStep(0.0, TS)
    assert np.all(np.isfinite(f.getReal(outs)))
    f.freeInstance()


def test_fmi3_logs_nothing_with_logging_off(tmp_path):
    """FMI 3: with loggingOn = false the FMU never calls logMessage, not even for an error; with
    it on, the error is logged."""
    fmu = export_fmu(DriveModel.from_dict(model_dict()), tmp_path / "l3.fmu", fmi_version=3)
    md = read_model_description(str(fmu))
    unzipped = extract(str(fmu))
    for on in (False, True):
        logged = []
        f = FMU3Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="l3")
        f.instantiate(loggingOn=on, logMessage=lambda env, status, cat, msg: logged.append(msg))
        f.enterInitializationMode(startTime=0.0)
        f.exitInitializationMode()
        with pytest.raises(FMICallException):
            f.doStep(0.0, 0.5 * TS)                     # not a whole number of samples
        f.freeInstance()
        assert bool(logged) == on, logged


def test_fmi3_do_step_with_1e10_steps_is_refused_fast(tmp_path):
    fmu = export_fmu(DriveModel.from_dict(model_dict()), tmp_path / "h3.fmu", fmi_version=3)
    md = read_model_description(str(fmu))
    f = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="h3")
    f.instantiate(loggingOn=False)
    f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    t0 = time.perf_counter()
    with pytest.raises(FMICallException):
        f.doStep(0.0, 1e10 * TS)
    assert time.perf_counter() - t0 < 1.0
    f.freeInstance()
