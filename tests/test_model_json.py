"""Damaged model JSON files and file names -- one clear line (exit 2) naming the file, the
key or parameter and what was expected; never an internal error, never a silently wrong model.

Cases run the real ``fdid`` entry point in-process (``fdid_fmi.cli.main``), like
tests/test_hostile_cli.py, on small hand-built models (no identification: fast)."""
import copy
import json

import numpy as np
import pytest

from fdid_fmi.cli import main
from fdid_fmi.errors import InputError
from fdid_fmi.model import DriveModel, load_model
from fdid_fmi.simulate import simulate
from cli_support import one_line, run_cli

TS = 1e-3
D_FRIC = -1e-4      # same-sample response of a position to its friction input (as identified)


def run(capsys, *args):
    """``fdid ARGS`` in-process: (exit code, stderr)."""
    code, _, err = run_cli(capsys, *args)
    return code, err


def two_axis(v_tilde=1.0, level=1.0):
    """A causal two-axis model dict (one state per axis, friction on both axes, positions and
    errors respond to the friction in the same sample as an identified model's do)."""
    a, f = 0.9, D_FRIC
    return {"format": "fdid-fmi-model", "format_version": 2, "kind": "state_space", "Ts": TS,
            "method": "hand-built", "A": [[a, 0.0], [0.0, a]],
            "B": [[1 - a, 1e-4, 0.0, 0.0], [0.0, 0.0, 1 - a, 1e-4]],
            "C": [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]],
            "D": [[0.0, f, 0.0, 0.0], [1.0, -f, 0.0, 0.0], [0.0, 0.0, 0.0, f], [0.0, 0.0, 1.0, -f]],
            "inputs": [{"name": "x_cmd", "unit": "mm", "kind": "command", "axis": "x"},
                       {"name": "x_dnf", "unit": "1", "kind": "friction", "axis": "x",
                        "params": {"v_tilde": v_tilde, "level": level}},
                       {"name": "y_cmd", "unit": "mm", "kind": "command", "axis": "y"},
                       {"name": "y_dnf", "unit": "1", "kind": "friction", "axis": "y",
                        "params": {"v_tilde": v_tilde, "level": level}}],
            "outputs": [{"name": "x_pos", "unit": "mm", "kind": "position", "axis": "x"},
                        {"name": "x_err", "unit": "mm", "kind": "error", "axis": "x"},
                        {"name": "y_pos", "unit": "mm", "kind": "position", "axis": "y"},
                        {"name": "y_err", "unit": "mm", "kind": "error", "axis": "y"}]}


def trace_csv(path, n=3000):
    """t_s, x/y commands and actual positions: back-and-forth moves with reversals."""
    t = np.arange(n) * TS
    x = 5.0 * (1 - np.cos(2 * np.pi * t / 1.5))
    y = 3.0 * np.sin(2 * np.pi * t / 1.0)
    rows = ["t_s,x_cmd_mm,x_mm,y_cmd_mm,y_mm"] + [
        f"{a:.6g},{b!r},{b!r},{c!r},{c!r}" for a, b, c in zip(t, x.tolist(), y.tolist())]
    path.write_text("\n".join(rows) + "\n")
    return path


def write(path, d):
    path.write_text(json.dumps(d))
    return path


@pytest.fixture
def model(tmp_path):
    return write(tmp_path / "m.json", two_axis())


# ------------------------------------------------------------ 1. an integer too long for a number
@pytest.mark.parametrize("cmd", ["export", "simulate"])
def test_huge_integer_names_the_key(capsys, tmp_path, model, cmd):
    text = model.read_text().replace(f'"Ts": {TS}', '"Ts": 1' + "0" * 5000)
    assert '"Ts": 1000' in text
    bad = tmp_path / "bigint.json"
    bad.write_text(text)
    before = bad.read_bytes()
    argv = ["export", bad, "-o", tmp_path / "d.fmu"] if cmd == "export" else \
        ["simulate", bad, trace_csv(tmp_path / "run.csv"), "-o", tmp_path / "p.csv"]
    line = one_line(*run(capsys, *argv), "bigint.json", "column 'Ts'", "5001 digits", "too long")
    assert "4300" not in line and "ValueError" not in line
    assert bad.read_bytes() == before
    assert not (tmp_path / "d.fmu").exists() and not (tmp_path / "p.csv").exists()


def test_long_integer_inside_a_matrix_or_params_names_its_key(tmp_path):
    """400 digits (past 1e308, within Python's int-string limit) was float()'s OverflowError."""
    d = two_axis()
    d["A"][1][1] = 10 ** 400
    with pytest.raises(InputError, match=r"column 'A': .*401 digits"):
        load_model(write(tmp_path / "a.json", d))
    d = two_axis()
    d["inputs"][1]["params"]["v_tilde"] = 10 ** 400
    with pytest.raises(InputError, match=r"column 'v_tilde': .*401 digits"):
        load_model(write(tmp_path / "v.json", d))
    d = two_axis()
    d["A"][1][1] = 0                        # an ordinary integer still reads as a number
    assert load_model(write(tmp_path / "ok.json", d)).A[1, 1] == 0.0


# ----------------------------------------------------------------- 5. a directory is not missing
@pytest.mark.parametrize("cmd", ["simulate", "validate", "export", "validate-model"])
def test_directory_is_not_a_regular_file(capsys, tmp_path, model, cmd):
    adir = tmp_path / "adir"
    adir.mkdir()
    csv = trace_csv(tmp_path / "run.csv", n=200)
    argv = {"simulate": ["simulate", adir, csv, "-o", tmp_path / "p.csv"],
            "validate": ["validate", adir, csv],
            "export": ["export", adir, "-o", tmp_path / "d.fmu"],
            "validate-model": ["validate", tmp_path / "none.fmu", csv, "--model", adir]}[cmd]
    if cmd == "validate-model":     # a real FMU, so the --model directory is what is refused
        assert main(["export", str(model), "-o", str(tmp_path / "none.fmu")]) == 0
        capsys.readouterr()
    line = one_line(*run(capsys, *argv), "adir", "is a directory, not a regular file")
    assert "not found" not in line


def test_missing_and_empty_model_files(capsys, tmp_path):
    csv = trace_csv(tmp_path / "run.csv", n=200)
    one_line(*run(capsys, "simulate", tmp_path / "nope.json", csv, "-o", tmp_path / "p.csv"),
             "nope.json", "model file not found")
    one_line(*run(capsys, "validate", tmp_path / "nope.fmu", csv), "nope.fmu", "FMU file not found")
    (tmp_path / "empty.json").write_text("")
    one_line(*run(capsys, "export", tmp_path / "empty.json", "-o", tmp_path / "d.fmu"),
             "empty.json", "model file is empty (0 bytes)")


def test_an_fmu_given_as_the_model_says_so(capsys, tmp_path, model):
    """An FMU where the model JSON belongs is named as an FMU, not 'not a JSON model file
    ('utf-8' codec can't decode byte 0xbe ...)'."""
    csv = trace_csv(tmp_path / "run.csv", n=200)
    assert main(["export", str(model), "-o", str(tmp_path / "drive.fmu")]) == 0
    capsys.readouterr()
    line = one_line(*run(capsys, "simulate", tmp_path / "drive.fmu", csv, "-o", tmp_path / "p.csv"),
                    "drive.fmu", "is a zip archive (an FMU?), not a model file: give the model JSON")
    assert "codec" not in line


# -------------------------------------------------- 2./4. damaged shapes and types name their key
def _damaged(change):
    d = two_axis()
    change(d)
    return d


@pytest.mark.parametrize("change, words", [
    (lambda d: d["B"].__setitem__(0, d["B"][0][:-1]),
     ["column 'B'", "B must be a 2 x k matrix of numbers in rows of one length", "row 1 has 3 entries"]),
    (lambda d: d.__setitem__("inputs", {"a": 1}),
     ["column 'inputs'", "inputs must be a JSON array of port objects", "got dict"]),
    (lambda d: d["outputs"].__setitem__(1, "x_err"),
     ["column 'outputs'", "output 2 must be a JSON object", "got str 'x_err'"]),
    (lambda d: d["inputs"][0].pop("unit"), ["column 'inputs'", "input 1 lacks 'unit'"]),
    (lambda d: d["inputs"][0].__setitem__("gain", 2), ["column 'inputs'", "unknown key 'gain'"]),
    (lambda d: d.__setitem__("poles", "x"),
     ["column 'poles'", "poles must be a JSON array of [real, imag] pairs", "got str 'x'"]),
    (lambda d: d.__setitem__("poles", "12"), ["column 'poles'", "got str '12'"]),   # not poles 1, 2
    (lambda d: d.__setitem__("poles", [[1.0, 2.0, 3.0]]), ["column 'poles'", "pole 1 must be"]),
    (lambda d: d["A"][0].__setitem__(0, "0.9"),
     ["column 'A'", "A must be a square matrix of numbers, got str '0.9' at A[0][0]"]),
    (lambda d: d["A"][1].__setitem__(1, True), ["column 'A'", "got bool True at A[1][1]"]),
    (lambda d: d["D"][1].__setitem__(0, "1"), ["column 'D'", "got str '1' at D[1][0]"]),
    (lambda d: d["C"][0].__setitem__(0, None), ["column 'C'", "got NoneType None at C[0][0]"]),
    (lambda d: d["A"][0].__setitem__(0, 1e308), ["column 'A'", "magnitude 1e+308 (at most 1e+150)"]),
    (lambda d: d.__setitem__("Ts", float("inf")), ["column 'Ts'", "must be a finite number > 0, got inf"]),
])
def test_damaged_model_names_the_key(capsys, tmp_path, change, words):
    bad = write(tmp_path / "bad.json", _damaged(change))
    line = one_line(*run(capsys, "export", bad, "-o", tmp_path / "d.fmu"), "bad.json", *words)
    assert "sequence" not in line and "argument after" not in line and "malformed" not in line
    assert not (tmp_path / "d.fmu").exists()


def test_string_in_a_matrix_is_not_blamed_on_stability(tmp_path):
    """'1.0' for A[0][0] is refused as a string, not read as 1.0 and refused as 'the model is not
    stable'."""
    with pytest.raises(InputError) as exc:
        load_model(write(tmp_path / "m.json", _damaged(lambda d: d["A"][0].__setitem__(0, "1.0"))))
    assert "stable" not in str(exc.value) and "got str '1.0'" in str(exc.value)


def test_unstable_model_prints_a_readable_spectral_radius(tmp_path):
    d = _damaged(lambda d: d["A"][0].__setitem__(0, 1e149))
    with pytest.raises(InputError, match=r"spectral radius of A = 1e\+149\)"):
        load_model(write(tmp_path / "m.json", d))
    d = _damaged(lambda d: d["A"][0].__setitem__(0, 1.5))
    with pytest.raises(InputError, match=r"spectral radius of A = 1\.500000\)"):
        load_model(write(tmp_path / "m.json", d))


def test_valid_shapes_still_load(tmp_path):
    d = two_axis()
    d["poles"] = [[-10.0, 5.0], [-10.0, -5.0], -3.0]
    d["A"] = [[0.9, 0], [0, 0.9]]           # integers are numbers
    m = load_model(write(tmp_path / "m.json", d))
    assert m.poles == [complex(-10, 5), complex(-10, -5), complex(-3, 0)]
    assert m.A.dtype == float and m.A[0, 1] == 0.0
    m2 = DriveModel(Ts=TS, A=np.array([[0.5]]), B=np.array([[0.5, 1e-4]]), C=np.array([[1.0], [-1.0]]),
                    D=np.array([[0.0, 0.0], [1.0, 0.0]]), inputs=copy.deepcopy(m.inputs[:2]),
                    outputs=copy.deepcopy(m.outputs[:2]), poles=np.array([-1 + 2j]))
    assert m2.poles == [complex(-1, 2)] and m2.copy().A[0, 0] == 0.5


# ------------------------------------------------- 6. an FMU name with nothing before .fmu
@pytest.mark.parametrize("name", [".fmu", ".FMU"])
def test_stemless_fmu_name_says_what_is_wrong(capsys, tmp_path, model, name):
    """'x/.fmu' is a hidden file without a name (a script's empty $NAME.fmu, most likely): it is
    refused, saying so -- it was 'the FMU must end in .fmu', which it does."""
    line = one_line(*run(capsys, "export", model, "-o", tmp_path / name), name,
                    "has nothing before .fmu", "drive.fmu")
    assert "must end in" not in line
    assert not (tmp_path / name).exists()
    one_line(*run(capsys, "export", model, "-o", tmp_path / "d.txt"), "the FMU must end in .fmu")


# ----------------------------------------- 3. a v_tilde below what the friction solve resolves
# two_axis: beta = |D_FRIC| / TS = 0.1 mm/s per unit friction, so the smallest v_tilde is
# 1e-12 x level x 0.1 mm/s (model.FRICTION_RATIO_MAX)
BETA = abs(D_FRIC) / TS


def _commands(n=3000):
    t = np.arange(n) * TS
    return {"x": 5.0 * (1 - np.cos(2 * np.pi * t / 1.5)), "y": 3.0 * np.sin(2 * np.pi * t / 1.0)}


@pytest.mark.parametrize("v_tilde", [1e-20, 1e-100, 1e-200, 1e-310])
def test_tiny_v_tilde_is_refused_naming_it(capsys, tmp_path, v_tilde):
    """Was accepted and simulated to 1e193 mm (exit 0) or to 'the model's outputs are not finite',
    blamed on the trace."""
    d = two_axis()
    d["inputs"][1]["params"]["v_tilde"] = v_tilde
    bad = write(tmp_path / "m.json", d)
    csv = trace_csv(tmp_path / "run.csv")
    for argv in (["simulate", bad, csv, "-o", tmp_path / "p.csv"], ["export", bad, "-o", tmp_path / "d.fmu"]):
        line = one_line(*run(capsys, *argv), "m.json", "column 'x_dnf.v_tilde'",
                        "v_tilde must be at least 1e-13 mm/s", "friction inputs")
        assert "run.csv" not in line
    assert not (tmp_path / "p.csv").exists() and not (tmp_path / "d.fmu").exists()


@pytest.mark.parametrize("level", [1.0, 10.0])
def test_v_tilde_bound_just_below_and_above(level):
    lo = 1e-12 * level * BETA
    with pytest.raises(InputError, match=r"column .x_dnf.v_tilde.: v_tilde must be at least"):
        DriveModel.from_dict(two_axis(v_tilde=0.99 * lo, level=level))
    d = two_axis(v_tilde=1.0, level=level)
    d["inputs"][3]["params"]["v_tilde"] = 0.99 * lo          # the other axis is checked too
    with pytest.raises(InputError, match=r"column 'y_dnf.v_tilde'"):
        DriveModel.from_dict(d)
    m = DriveModel.from_dict(two_axis(v_tilde=1.01 * lo, level=level))
    r = simulate(m, _commands(), Ts=TS)
    assert np.isfinite(r.y).all()
    d_fric = np.abs(r.u[:, [1, 3]])
    assert d_fric.max() <= level * (1 + 1e-3), d_fric.max()    # the friction keeps to its level
    assert d_fric.max() >= 0.99 * level                         # and reaches it (slides)


# A v_tilde given as a parameter (simulate's params, the FMU's tunable <axis>_v_tilde) is held to
# the same bound, checked where the friction solve runs: before, only > 0 was checked, and
# 1e-20 mm/s ran to outputs of 1e193 mm (the model file's bound above does not reach it).
LO = 1e-12 * BETA          # the least v_tilde at level 1


def test_tiny_v_tilde_parameter_is_refused_in_simulate():
    m = DriveModel.from_dict(two_axis())
    with pytest.raises(InputError, match=r"column 'y_v_tilde': v_tilde must be at least 1e-13 mm/s at friction "
                                         r"level 1, got 1e-20"):
        simulate(m, _commands(), Ts=TS, params={"y_v_tilde": 1e-20})
    # the bound scales with the level set beside it, in any order, and a friction switched off has none
    for params in ({"x_v_tilde": 0.5 * LO, "x_friction_level": 0.1}, {"x_v_tilde": 1e-20, "x_friction_on": False}):
        assert np.isfinite(simulate(m, _commands(), Ts=TS, params=params).y).all(), params


def _fmu2_in_step_mode(fmu):
    """An FMI 2 instance of ``fmu`` after ExitInitializationMode, as a master has it, and its
    value references by name (fmpy's simulate_fmu applies start values in its own order)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="i")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s, {v.name: v.valueReference for v in md.modelVariables}


def test_tiny_v_tilde_parameter_is_refused_by_the_fmu(tmp_path, capfd):
    # fmpy's default logger prints the FMU's messages (a logger= of simulate_fmu is not used: fmpy's
    # logger proxy is global, and a later FMU's message then calls the freed callback: a crash)
    import fmpy
    from fmpy.fmi1 import FMICallException
    from fdid_fmi.fmu import export_fmu
    m = DriveModel.from_dict(two_axis())
    fmu = str(export_fmu(m, tmp_path / "d.fmu"))
    with pytest.raises(FMICallException, match="status 3"):
        fmpy.simulate_fmu(fmu, stop_time=0.05, output_interval=TS, start_values={"y_v_tilde": 1e-20})
    assert "y_v_tilde = 1e-20 mm/s is below 1e-13 mm/s" in capfd.readouterr().out
    # doStep itself says fmi2Error, not only a logged refusal with fmi2OK
    s, vr = _fmu2_in_step_mode(fmu)
    s.setReal([vr["y_v_tilde"]], [1e-20])
    with pytest.raises(FMICallException) as ei:
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=TS)
    assert ei.value.status == 3 and "fmi2DoStep: y_v_tilde = 1e-20 mm/s" in capfd.readouterr().out
    s.freeInstance()
    # level and v_tilde set in either order, each alone below the other's old value's floor
    for order in (("x_v_tilde", "x_friction_level"), ("x_friction_level", "x_v_tilde")):
        values = {"x_v_tilde": 0.5 * LO, "x_friction_level": 0.1}
        s, vr = _fmu2_in_step_mode(fmu)
        for k in order:
            s.setReal([vr[k]], [values[k]])
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=TS)     # raises unless fmi2OK
        assert np.isfinite(s.getReal([vr["x_x"], vr["y_x"]])).all()
        s.terminate()
        s.freeInstance()


def test_v_tilde_without_feed_through_keeps_its_gain_a_model_number(tmp_path):
    """beta = 0: g = level / v_tilde overflowed from 1e-308 mm/s on (NaN outputs); the bound is
    then level / MAX_ABS."""
    d = two_axis(v_tilde=1e-310)
    for row in d["D"]:
        row[1] = row[3] = 0.0
    with pytest.raises(InputError, match=r"x_dnf.v_tilde.*at least 1e-150 mm/s"):
        DriveModel.from_dict(d)
    for p in d["inputs"][1::2]:
        p["params"]["v_tilde"] = 1.01e-150
    r = simulate(DriveModel.from_dict(d), _commands(), Ts=TS)
    assert np.isfinite(r.y).all() and np.abs(r.u[:, [1, 3]]).max() <= 1.0


def test_one_friction_input_keeps_any_positive_v_tilde():
    """One friction input is solved in closed form: |d| <= level at any v_tilde > 0 (kept)."""
    d = two_axis(v_tilde=1e-300)
    keep = [0, 1]
    d["A"], d["B"], d["C"] = [[0.9]], [d["B"][0][:2]], [[1.0], [-1.0]]
    d["D"] = [r[:2] for r in d["D"][:2]]
    d["inputs"], d["outputs"] = [d["inputs"][k] for k in keep], [d["outputs"][k] for k in keep]
    m = DriveModel.from_dict(d)
    r = simulate(m, {"x": _commands()["x"]}, Ts=TS)
    assert np.isfinite(r.y).all() and np.abs(r.u[:, 1]).max() <= 1.0


def test_simulate_to_standard_output(capsys, tmp_path, model, monkeypatch):
    """``-o -`` writes no file named '-': the CSV alone goes to standard
    output (the reader's notes and the summary line to standard error)."""
    monkeypatch.chdir(tmp_path)
    text = trace_csv(tmp_path / "run.csv", n=200).read_text().replace("t_s,x_cmd_mm,x_mm", "t_s,x_cmd,x_mm")
    (tmp_path / "bare.csv").write_text(text)           # x_cmd states no unit: a note
    code, out, err = run_cli(capsys, "simulate", model, tmp_path / "bare.csv", "-o", "-")
    assert code == 0 and not (tmp_path / "-").exists()
    lines = out.splitlines()
    assert lines[0] == "t_s,x_x_pred_mm,x_e_pred_mm,y_x_pred_mm,y_e_pred_mm" and len(lines) == 201
    assert np.isfinite(np.loadtxt(lines[1:], delimiter=",")).all()
    assert "note: " in err and "written to standard output" in err
