"""Careless and hostile inputs to the core modules (trace, model, simulate, signals, metrics,
outputs, report): each test fails without the code it guards."""
import json
import os

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.identify import regressors as rg
from fdid_fmi.identify.lsfit import Fit
from fdid_fmi.identify.pole_search import assemble
from fdid_fmi.identify.structure import siso_structure
from fdid_fmi.model import DriveModel, QuasiStaticModel, load_model
from fdid_fmi.trace import Channel, Trace

TS = 1e-3


def siso_model():
    a = rg.characteristic_polynomial([40.0], [(12.0, 0.9)])
    b = {("x_error", "x_cmd"): np.array([0.05, 0.7 * a[1], 0.9 * a[2], 0.0]),
         ("x_error", "x_dnf"): np.array([0.0, 0.0, 800.0, 0.0])}
    return assemble(siso_structure("x", same_sample="hold"),
                    Fit(J=0, a=a, b=b, rms=None, feasible=True, v_tilde={"x": 0.5}), TS)


def saved(tmp_path, model=None):
    p = tmp_path / "m.json"
    (model or siso_model()).save(p)
    return p, json.loads(p.read_text())


def rewrite(tmp_path, d, name="bad.json"):
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return p


# ------------------------------------------------------------------------------ trace
def test_slice_of_epoch_time_stamps_keeps_its_range():
    t = 1.7e9 + np.arange(2001) * 0.001          # absolute time stamps: 1e-9 |t| was 1.7 s
    x = np.sin(t - t[0])
    tr = Trace.from_arrays(t, {"x": {"cmd": x, "act": x}})
    s = tr.slice(t[500], t[600])
    assert s.n == 101 and s.t[0] == t[500] and s.t[-1] == t[600]


def test_trace_refuses_2d_time_and_channels_in_one_line():
    t, x = np.arange(10) * 0.001, np.arange(10.0)
    with pytest.raises(InputError, match="time must be one column.*shape \\(10, 1\\)"):
        Trace.from_arrays(t.reshape(10, 1), {"x": {"cmd": x, "act": x}})
    with pytest.raises(InputError, match="x_cmd.*one column of numbers.*shape \\(10, 1\\)"):
        Trace.from_arrays(t, {"x": {"cmd": x.reshape(10, 1), "act": x}})


def test_trace_refuses_two_channels_of_one_name():
    t = np.arange(10) * 0.001
    with pytest.raises(InputError, match="'x_mm'.*two channels have this name"):
        Trace(t, [Channel("x_mm", "mm", np.zeros(10)), Channel("x_mm", "mm", np.ones(10))])


def test_short_slice_keeps_the_sample_time_of_its_trace():
    t = np.arange(200) * 0.00105
    tr = Trace.from_arrays(t, {"x": {"cmd": t, "act": t}})
    assert tr.Ts == 0.00105
    assert tr.slice(t[10], t[14]).Ts == 0.00105     # not 0.001


# ------------------------------------------------------------------------------ model files
def test_model_file_with_transposed_B_is_refused(tmp_path):
    m = siso_model()
    _, d = saved(tmp_path, m)
    d["B"] = np.array(d["B"]).T.tolist()
    with pytest.raises(InputError, match=f"column 'B'.*{m.n_states} x k matrix, got shape"):
        load_model(rewrite(tmp_path, d))
    d = json.loads((tmp_path / "m.json").read_text())
    d["A"] = [d["A"][0]]
    with pytest.raises(InputError, match="column 'A'.*square"):
        load_model(rewrite(tmp_path, d))


def test_model_matrices_given_as_vectors_still_load():
    m = siso_model()
    m1 = DriveModel(Ts=m.Ts, A=m.A, B=m.B.ravel(), C=m.C.ravel(), D=m.D.ravel(), inputs=m.inputs,
                    outputs=m.outputs)
    assert np.array_equal(m1.B, m.B) and np.array_equal(m1.C, m.C) and np.array_equal(m1.D, m.D)


@pytest.mark.parametrize("key,value", [("order", 2.7), ("order", "3"), ("order", True),
                                       ("cutoff_hz", True), ("cutoff_hz", "50")])
def test_quasi_static_order_and_cutoff_are_not_coerced(tmp_path, key, value):
    q = QuasiStaticModel(Ts=0.001, gains={"x": {"K_vel": 0.01, "K_acc": 1e-5, "K_jerk": 0.0}},
                         cutoff_hz=50)
    _, d = saved(tmp_path, q)
    assert load_model(rewrite(tmp_path, d, "ok.json")).order == 2
    d[key] = value
    with pytest.raises(InputError, match=f"column '{key}'"):
        load_model(rewrite(tmp_path, d))


def test_model_file_with_a_key_twice_is_refused(tmp_path):
    p, _ = saved(tmp_path)
    text = p.read_text().rstrip().rstrip("}") + ', "Ts": 0.002\n}'
    bad = tmp_path / "dup.json"
    bad.write_text(text)
    with pytest.raises(InputError, match="column 'Ts'.*given twice"):
        load_model(bad)


@pytest.mark.parametrize("key,value", [("effects", ["stribeck"]), ("effects", "stribeck"),
                                       ("identification", [1]), ("metrics", "x"), ("provenance", [])])
def test_model_file_metadata_of_the_wrong_type_is_refused(tmp_path, key, value):
    _, d = saved(tmp_path)
    d[key] = value
    with pytest.raises(InputError, match=f"column '{key}'"):
        load_model(rewrite(tmp_path, d))


@pytest.mark.parametrize("value", ["0.5", {"a": 1}, None])
def test_friction_v_tilde_that_is_no_number_names_the_parameter(tmp_path, value):
    _, d = saved(tmp_path)
    i = [p["kind"] for p in d["inputs"]].index("friction")
    d["inputs"][i]["params"]["v_tilde"] = value
    with pytest.raises(InputError, match="x_dnf.v_tilde"):
        load_model(rewrite(tmp_path, d))


def test_model_with_numpy_scalar_parameters_saves_and_loads(tmp_path):
    m = siso_model()
    m.inputs[m.input_index("friction")].params["level"] = np.float32(0.75)
    m.inputs[m.input_index("friction")].params["v_tilde"] = np.int64(2)
    m.validate()                                  # accepted here, so save must write it
    m.save(tmp_path / "np.json")
    p = load_model(tmp_path / "np.json").inputs[m.input_index("friction")].params
    assert p == {"level": 0.75, "v_tilde": 2}


# ------------------------------------------------------------------------------ simulate
def _trace():
    t = np.arange(500) * TS
    xr = 5 * np.sin(2 * np.pi * 2 * t)
    return Trace.from_arrays(t, {"x": {"cmd": xr, "act": xr}})


def test_simulate_refuses_a_ts_that_contradicts_the_trace():
    from fdid_fmi.simulate import simulate
    m, tr = siso_model(), _trace()
    assert np.array_equal(simulate(m, tr, Ts=TS).y, simulate(m, tr).y)
    for Ts in (2e-3, "abc"):
        with pytest.raises(InputError, match="column 'Ts'"):
            simulate(m, tr, Ts=Ts)


@pytest.mark.parametrize("v0", ["a", None, True])
def test_start_velocity_that_is_no_number_is_named(v0):
    from fdid_fmi.simulate import simulate
    with pytest.raises(InputError, match="start_velocity.*axis 'x'"):
        simulate(siso_model(), {"x": np.zeros(50)}, Ts=TS, start_velocity={"x": v0})


# ------------------------------------------------------------------------------ signals, metrics
def test_prediction_table_refuses_arrays_of_other_shapes():
    from fdid_fmi.metrics import prediction_table
    e = np.linspace(-0.01, 0.01, 100)
    assert prediction_table(e, e)["discrepancy"]["rms_um"] == 0.0
    for p in (e[:, None], e[:1]):
        with pytest.raises(InputError, match="predicted_error"):
            prediction_table(e, p)


def test_contour_error_window_zero_is_finite_at_the_last_point():
    from fdid_fmi.metrics import contour_error
    P = np.c_[np.arange(5.0), np.zeros(5)]
    assert np.allclose(contour_error(P, P + [0.0, 0.001], window=0), 0.001)
    with pytest.raises(ValueError, match="window"):
        contour_error(P, P, window=-1)


# ------------------------------------------------------------------------------ outputs, report
def test_atomic_write_keeps_the_permissions_of_an_existing_file(tmp_path):
    from fdid_fmi.outputs import atomic_write
    p = tmp_path / "model.json"
    p.write_text("old")
    os.chmod(p, 0o600)
    old = os.umask(0o022)
    try:
        atomic_write(p, "new")
        atomic_write(tmp_path / "fresh.json", "new")
    finally:
        os.umask(old)
    assert p.read_text() == "new" and os.stat(p).st_mode & 0o777 == 0o600
    assert os.stat(tmp_path / "fresh.json").st_mode & 0o777 == 0o644


def test_longest_legal_file_name_is_written_and_a_longer_one_refused(tmp_path):
    from fdid_fmi.outputs import atomic_write, check_output
    name = tmp_path / ("c" * 251 + ".csv")         # 255 characters: legal
    check_output(name)
    atomic_write(name, "data")
    assert name.read_text() == "data" and not list(tmp_path.glob(".*.part"))
    with pytest.raises(InputError, match="cannot write"):
        check_output(tmp_path / ("c" * 300 + ".csv"))


def test_report_with_a_file_name_that_is_not_utf8_is_written(tmp_path):
    from fdid_fmi.report import Report
    name = os.fsdecode(b"prog\xff.nc")             # how sys.argv carries such a name
    rep = Report(f"Process plan: {name}")
    rep.add_text(f"program {name}")
    assert "prog\\udcff.nc" in rep.html().encode("utf-8").decode("utf-8")    # fdid plan's writer
    p = rep.write(tmp_path / "plan.html")
    text = p.read_text(encoding="utf-8")
    assert "prog\\udcff.nc" in text


def test_report_keeps_both_tables_and_figures_of_one_name():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from fdid_fmi.report import Report
    rep = Report("r")
    rep.add_table("errors", [{"trace": "a", "rms": 1.0}])
    rep.add_table("errors", [{"trace": "b", "rms": 2.0}])
    for v in (1, 2):
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, v])
        rep.add_figure("fig", fig, data={"v": v})
    d = rep.to_dict()
    assert [t["rows"][0][0] for t in d["tables"].values()] == ["a", "b"]
    assert [f["data"]["v"] for f in d["figures"].values()] == [1, 2]
    h = rep.html()
    assert h.count("id='table-errors'") == 1 and h.count("id='figure-fig'") == 1


@pytest.mark.parametrize("where, unit, message", [
    ("inputs", "m", "command input has unit 'm'; expected mm or deg"),
    ("inputs", "um", "command input has unit 'um'"),
    ("outputs", "m", "position output has unit 'm'"),
])
def test_port_units_are_the_cnc_convention(where, unit, message):
    """Port units were free text: a command declared in m was simulated as mm and exported with
    unit "m" in the modelDescription, 1000x off for any master that believes it."""
    d = _unit_model_dict()
    d[where][0]["unit"] = unit
    with pytest.raises(InputError, match=message):
        DriveModel.from_dict(d)


def test_an_axis_keeps_one_position_unit():
    d = _unit_model_dict()
    d["inputs"][0]["unit"] = "deg"                 # a rotary command, position still in mm
    with pytest.raises(InputError, match=r"axis 'x' mixes position units \['deg', 'mm'\]"):
        DriveModel.from_dict(d)
    for p in d["inputs"][:1] + d["outputs"]:
        p["unit"] = "deg"                          # a rotary axis throughout: accepted
    assert DriveModel.from_dict(d).inputs[0].unit == "deg"


def _unit_model_dict():
    return {"format": "fdid-fmi-model", "format_version": 2, "kind": "state_space", "Ts": 1e-3,
            "method": "hand-built", "A": [[0.9]], "B": [[0.1, 1e-4]], "C": [[1.0], [-1.0]],
            "D": [[0.0, 0.0], [1.0, 0.0]],
            "inputs": [{"name": "x_cmd", "unit": "mm", "kind": "command", "axis": "x"},
                       {"name": "x_dnf", "unit": "1", "kind": "friction", "axis": "x",
                        "params": {"v_tilde": 1.0}}],
            "outputs": [{"name": "x_pos", "unit": "mm", "kind": "position", "axis": "x"},
                        {"name": "x_err", "unit": "mm", "kind": "error", "axis": "x"}]}


def test_validation_json_of_several_ranges_is_json_and_keeps_a_failure():
    """Several ranges: max() of [1e-15, nan] is 1e-15 (a failed range hidden), and an inf must
    not be written as the token Infinity, which JSON readers refuse."""
    from fdid_fmi.cli.validate import results_json
    from fdid_fmi.fmu.validate import ValidationResult
    for bad in (float("nan"), float("inf")):
        rs = [ValidationResult("a.fmu", max_abs_diff_reference_mm=1e-15),
              ValidationResult("a.fmu", max_abs_diff_reference_mm=bad, problems=["fmpy: x"])]
        data = json.loads(json.dumps(results_json(rs), allow_nan=False))
        assert data["max_abs_diff_reference_mm"] is None and data["ok"] is False
        assert data["problems"] == ["fmpy: x"] and data["ranges"][1]["max_abs_diff_reference_mm"] is None
    rs = [ValidationResult("a.fmu", max_abs_diff_reference_mm=v) for v in (1e-15, 3e-15)]
    assert results_json(rs)["max_abs_diff_reference_mm"] == 3e-15 and results_json(rs)["ok"] is True


def test_combine_owns_its_ports_and_records():
    """combine() shared Port objects and record dicts with its blocks: a change to the combined
    model's friction port or identification record changed the block it came from."""
    a, b = DriveModel.from_dict(_unit_model_dict()), DriveModel.from_dict(_renamed_y(_unit_model_dict()))
    a.identification = {"real_hz": [10.0]}
    both = DriveModel.combine([a, b])
    both.inputs[1].params["v_tilde"] = 5.0
    both.identification["blocks"][0]["real_hz"].append(20.0)
    assert a.inputs[1].params["v_tilde"] == 1.0 and a.identification == {"real_hz": [10.0]}


def _renamed_y(d):
    return json.loads(json.dumps(d).replace('"x_', '"y_').replace('"axis": "x"', '"axis": "y"'))
