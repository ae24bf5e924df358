"""fdid validate: fmpy checks, FMU vs reference simulator, FMU vs measurement."""
import json

import numpy as np
import pytest

import fmu_support as fs
from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu, validate_fmu
from fdid_fmi.simulate import simulate
from fdid_fmi.trace import Trace

N = 3000
NOISE_MM = 0.002


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    d = tmp_path_factory.mktemp("val")
    m = fs.coupled_model()
    fmu = export_fmu(m, d / "coupled.fmu")
    rng = np.random.default_rng(7)
    cmds = {a: fs.smooth_moves(N, rng, start=10.0 + 5 * i, v_start=25.0) for i, a in enumerate(m.axes)}
    sim = simulate(m, cmds, Ts=m.Ts, start_velocity={a: (c[1] - c[0]) / m.Ts for a, c in cmds.items()})
    t = np.arange(N) * m.Ts
    axes = {a: {"cmd": cmds[a], "act": sim.axes[a]["position"] + rng.normal(0, NOISE_MM, N)} for a in m.axes}
    trace = Trace.from_arrays(t, axes, source="synthetic")
    cols = [t]
    header = ["t_s"]
    for a in m.axes:
        cols += [axes[a]["cmd"], axes[a]["act"]]
        header += [f"{a}_cmd_mm", f"{a}_act_mm"]
    csv = d / "trace.csv"
    np.savetxt(csv, np.column_stack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    return {"dir": d, "model": m, "fmu": fmu, "trace": trace, "csv": csv}


def test_validate_fmu_against_reference_and_measurement(case):
    res = validate_fmu(case["fmu"], case["trace"])
    assert res.problems == []
    assert res.max_abs_diff_reference_mm <= 1e-9
    assert res.ok
    for a in ("x", "y"):
        # the "measurement" is the model plus white noise: the discrepancy is the noise
        assert res.axes[a]["rms_um"] == pytest.approx(NOISE_MM * 1e3, rel=0.1)
        assert res.axes[a]["max_um"] > 3 * res.axes[a]["rms_um"]
    assert res.contour["axes"] == ["x", "y"] and 0 < res.contour["rms_um"] < 2 * NOISE_MM * 1e3
    # a measurement anywhere on the commanded path has no contour error, so its contour
    # discrepancy is the FMU's own contour error whatever its lag along the path (a tracking
    # error is not: it passed for the contour error before)
    t, cmd = case["trace"].t[:1000], {a: case["trace"].cmd(a)[:1000] for a in ("x", "y")}
    on_path = [validate_fmu(case["fmu"], Trace.from_arrays(t, {a: {"cmd": c, "act": np.r_[np.full(d, c[0]), c[:1000 - d]]}
                                                              for a, c in cmd.items()})) for d in (0, 5)]
    assert on_path[0].contour == on_path[1].contour and on_path[0].contour["rms_um"] > 1.0
    assert on_path[0].axes["x"]["rms_um"] != on_path[1].axes["x"]["rms_um"]
    d = res.to_dict()
    assert {"problems", "max_abs_diff_reference_mm", "axes", "contour", "ok"} <= set(d)
    json.dumps(d)
    assert "| x |" in res.table()


def test_validate_detects_a_different_reference(case):
    other = fs.coupled_model(vt_y=4.0)
    res = validate_fmu(case["fmu"], case["trace"], model=other)
    assert not res.ok and res.max_abs_diff_reference_mm > 1e-6
    assert any("differ" in p for p in res.problems)


def test_a_reference_model_of_another_sample_time_is_named_not_the_trace(case):
    """A wrong --model is named, not the trace ("the trace is sampled at 0.0006 s but the model at
    0.001 s" would blame the trace)."""
    import dataclasses
    other = dataclasses.replace(case["model"], Ts=2 * case["model"].Ts)
    other.save(case["dir"] / "other.json")
    with pytest.raises(InputError) as e:
        validate_fmu(case["fmu"], case["trace"], model=case["dir"] / "other.json")
    msg = str(e.value)
    assert "coupled.fmu" in msg and "the reference model" in msg and "other.json at 0.002 s" in msg, msg
    assert "the trace is sampled" not in msg


def test_validate_refuses_a_trace_without_the_axes(case):
    t = np.arange(100) * 1e-3
    tr = Trace.from_arrays(t, {"z": {"cmd": t, "act": t}})
    with pytest.raises(InputError, match="no commanded position"):
        validate_fmu(case["fmu"], tr)


def test_validate_cli_writes_json(case, capsys):
    from fdid_fmi.cli import main
    out = case["dir"] / "v.json"
    args = ["validate", str(case["fmu"]), str(case["csv"]), "--map", "t=t_s", "x.cmd=x_cmd_mm",
            "x.act=x_act_mm", "y.cmd=y_cmd_mm", "y.act=y_act_mm", "--json", str(out)]
    assert main(args) == 0
    d = json.loads(out.read_text())
    assert d["problems"] == [] and d["max_abs_diff_reference_mm"] <= 1e-9
    assert set(d["axes"]) == {"x", "y"} and d["contour"]["axes"] == ["x", "y"]
    assert d["inputs"] == {"fmu": str(case["fmu"]), "trace": str(case["csv"]), "ranges_s": None,
                           "model": "the model.json inside the FMU"}
    text = capsys.readouterr().out
    assert "max |FMU - reference|" in text and "contour x/y" in text
    # a wrong reference model: exit code 1
    fs.coupled_model(vt_y=4.0).save(case["dir"] / "other.json")
    assert main(args[:-2] + ["--model", str(case["dir"] / "other.json")]) == 1


def test_validate_reports_an_fmu_without_a_binary_for_this_platform(case, tmp_path):
    import zipfile
    src = case["fmu"]
    dst = tmp_path / "nobin.fmu"
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for item in zi.infolist():
            if not item.filename.startswith("binaries/"):
                zo.writestr(item, zi.read(item.filename))
    with pytest.raises(InputError, match="could not be run"):
        validate_fmu(dst, case["trace"])
