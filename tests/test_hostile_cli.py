"""Hostile command lines and files: one clear line for every failure, no traceback, no input file
changed, no partial output left.

Most cases run the real ``fdid`` entry point in-process (``fdid_fmi.cli.main``, the same code the
console script runs) to keep the suite fast; a few run it as a subprocess, as a user does.
"""
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.outputs import atomic_path, atomic_write, check_output, remove_orphan_temp_files
from cli_support import run_cli as run

TS = 1e-3
FDID = [sys.executable, "-m", "fdid_fmi.cli"]


def small_model(path):
    """A causal one-axis model JSON (position and error outputs, friction input)."""
    a = 0.9
    d = {"format": "fdid-fmi-model", "format_version": 1, "kind": "state_space", "Ts": TS,
         "method": "hand-built", "A": [[a]], "B": [[1 - a, 1e-4]], "C": [[1.0], [-1.0]],
         "D": [[0.0, 0.0], [1.0, 0.0]],
         "inputs": [{"name": "x_cmd", "unit": "mm", "kind": "command", "axis": "x"},
                    {"name": "x_dnf", "unit": "1", "kind": "friction", "axis": "x",
                     "params": {"v_tilde": 1.0, "level": 0.5}}],
         "outputs": [{"name": "x_pos", "unit": "mm", "kind": "position", "axis": "x"},
                     {"name": "x_err", "unit": "mm", "kind": "error", "axis": "x"}]}
    path.write_text(json.dumps(d))
    return path


def trace_csv(path, n=2000, scale=1.0, encoding="utf-8"):
    """t_s, x_cmd_mm, x_mm of smooth back-and-forth moves (x lags the command)."""
    t = np.arange(n) * TS
    cmd = 5.0 * (1 - np.cos(2 * np.pi * t / (n * TS / 2)))
    act = np.concatenate([[cmd[0]] * 3, cmd[:-3]])
    rows = ["t_s,x_cmd_mm,x_mm"] + [f"{a:.6g},{float(b * scale)!r},{float(c * scale)!r}" for a, b, c in zip(t, cmd, act)]
    path.write_bytes(("\n".join(rows) + "\n").encode(encoding))
    return path


def assert_one_line(code, err, *words, rc=2):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == rc, (code, err)
    assert len(lines) == 1, err
    assert "Traceback" not in err and "np.float64" not in err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def snapshot(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


@pytest.fixture
def files(tmp_path):
    return small_model(tmp_path / "m.json"), trace_csv(tmp_path / "run.csv")


# ----------------------------------------------------------------------------- outputs
@pytest.mark.parametrize("cmd", ["identify", "simulate-trace", "simulate-model", "export"])
def test_output_onto_an_input_is_refused(capsys, files, cmd):
    model, csv = files
    json_fmu = small_model(model.with_name("model.fmu"))    # a model file named like an FMU
    before = snapshot(csv.parent)
    args = {"identify": ["identify", csv, "-o", csv],
            "simulate-trace": ["simulate", model, csv, "-o", csv],
            "simulate-model": ["simulate", model, csv, "-o", model],
            "export": ["export", json_fmu]}[cmd]          # default output: model.fmu itself
    code, _, err = run(capsys, *args)
    assert_one_line(code, err, "overwrite the input")
    assert snapshot(csv.parent) == before


@pytest.mark.parametrize("where", ["missing", "directory"])
@pytest.mark.parametrize("cmd", ["identify", "simulate", "export", "diagnose-o", "diagnose-report",
                                 "diagnose-json"])
def test_bad_output_path_is_refused_before_the_work(capsys, files, tmp_path, cmd, where):
    model, csv = files
    out = {"missing": tmp_path / "no" / "such" / "out", "directory": tmp_path}[where]
    if cmd == "export" and where == "missing":
        out = out.with_suffix(".fmu")
    args = {"identify": ["identify", csv, "-o", out], "simulate": ["simulate", model, csv, "-o", out],
            "export": ["export", model, "-o", out if where == "missing" else tmp_path / "d.fmu"],
            "diagnose-o": ["diagnose", model, "--train", csv, "-o", out],
            "diagnose-report": ["diagnose", model, "--train", csv, "--report", out],
            "diagnose-json": ["diagnose", model, "--train", csv, "--json", out]}[cmd]
    if cmd == "export" and where == "directory":
        (tmp_path / "d.fmu").mkdir()
    before = snapshot(tmp_path)
    t0 = time.process_time()
    code, _, err = run(capsys, *args)
    assert time.process_time() - t0 < 2.0          # refused before identification / diagnosis
    assert_one_line(code, err)
    assert ("does not exist" in err) if where == "missing" else ("directory" in err)
    assert snapshot(tmp_path) == before


def test_disk_full_leaves_no_partial_file(files, tmp_path):
    """Writing fails half-way (file-size limit: EFBIG, as a full disk gives ENOSPC): one line, the
    old output kept, no temporary file left."""
    model, csv = files
    out = tmp_path / "pred.csv"
    out.write_text("old prediction\n")
    before = snapshot(tmp_path)

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    r = subprocess.run(FDID + ["simulate", str(model), str(csv), "-o", str(out)], capture_output=True,
                       text=True, preexec_fn=limit, timeout=300)
    assert_one_line(r.returncode, r.stderr, "pred.csv", "cannot write")
    assert snapshot(tmp_path) == before


def test_failed_export_leaves_nothing(files, tmp_path):
    model, _ = files
    out = tmp_path / "drive.fmu"
    out.write_bytes(b"previous fmu")
    before = snapshot(tmp_path)
    r = subprocess.run(FDID + ["export", str(model), "-o", str(out)], capture_output=True, text=True,
                       env={**os.environ, "CC": "false"}, timeout=300)   # the compiler fails
    assert_one_line(r.returncode, r.stderr, "failed")
    assert snapshot(tmp_path) == before


def test_atomic_helpers(tmp_path):
    p = tmp_path / "a.txt"
    atomic_write(p, "one")
    with pytest.raises(RuntimeError):
        with atomic_path(p) as tmp:
            tmp.write_text("half")
            raise RuntimeError("writer failed")
    assert p.read_text() == "one" and sorted(os.listdir(tmp_path)) == ["a.txt"]
    with pytest.raises(InputError, match="overwrite the input"):
        check_output(tmp_path / "." / "a.txt", inputs=[p])
    os.symlink(p, tmp_path / "link.txt")
    with pytest.raises(InputError, match="overwrite the input"):
        check_output(tmp_path / "link.txt", inputs=[p])


def test_orphan_temp_file_of_a_killed_writer_is_removed(tmp_path):
    """A writer killed with SIGKILL inside ``atomic_path`` leaves its ``.part`` file; the fleet
    runner sweeps such files once all its workers have stopped."""
    p = tmp_path / "entry.json"
    code = ("import os, signal, sys; from fdid_fmi.outputs import atomic_path\n"
            "with atomic_path(sys.argv[1]) as tmp:\n"
            "    tmp.write_text('half'); os.kill(os.getpid(), signal.SIGKILL)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(p)], check=False)
    assert proc.returncode == -9
    left = list(tmp_path.glob(".entry.json.*.part"))
    assert len(left) == 1 and not p.exists()
    (tmp_path / "keep.part").write_text("a user's file")
    assert remove_orphan_temp_files(tmp_path) == left
    assert sorted(os.listdir(tmp_path)) == ["keep.part"]


# ----------------------------------------------------------------------------- option values
@pytest.mark.parametrize("opts,words", [
    (["--method", "mimo", "--dc-gain", "error=abc"], ["--dc-gain", "Q:VALUE"]),
    (["--method", "mimo", "--dc-gain", "error=1:x"], ["--dc-gain"]),
    (["--method", "mimo", "--dc-gain", "positon=1:1.0"], ["--dc-gain", "positon"]),
    (["--method", "mimo", "--integrators", "acceleration=2"], ["--integrators", "acceleration"]),
    (["--method", "mimo", "--integrators", "error=two"], ["--integrators", "integer"]),
    (["--method", "mimo", "--integrators", "error"], ["--integrators", "OUTPUT=VALUE"]),
    (["--method", "mimo", "--outputs", "error,bogus"], ["--outputs", "bogus"]),
    (["--seed", str(2 ** 32)], ["--seed", "4294967295"]),
    (["--seed", "-1"], ["--seed"]),
    (["--method", "mimo", "--n-complex", "40"], ["--n-complex"]),
    (["--maxiter", "0"], ["--maxiter"]),
    (["--v-tilde", "nan"], ["--v-tilde"]),
    (["--real-hz", "5:1"], ["--real-hz", "LO < HI"]),
    (["--lock-complex", "abc"], ["--lock-complex"]),
    (["--external", "a b"], ["--external", "not a name"]),
    # an option the method does not read would be silently ignored: refused instead
    (["--external", "pulses_N"], ["--external", "mimo"]),
    (["--coupled"], ["--coupled", "mimo"]),
    (["--lock-complex", "30:0.1"], ["--lock-complex", "mimo"]),
    (["--method", "mimo", "--structure", "rigid"], ["--structure", "pole-search"]),
    (["--method", "quasi-static", "--seed", "3"], ["--seed", "quasi-static"]),
    (["--method", "full-ls", "--no-friction"], ["--no-friction", "full-ls"]),
    (["--method", "mimo", "--cutoff-hz", "50"], ["--cutoff-hz", "mimo"]),
    (["--structure", "rigid", "--jobs", "2"], ["--jobs", "pinned"]),
])
def test_bad_option_values_give_one_line(capsys, files, tmp_path, opts, words):
    _, csv = files
    code, _, err = run(capsys, "identify", csv, *opts, "-o", tmp_path / "out.json")
    assert_one_line(code, err, *words)
    assert not (tmp_path / "out.json").exists()


@pytest.mark.parametrize("argv,words", [
    # a NaN gain can never be met and a negative one keeps what does not help: both refused
    (["diagnose", "m.json", "--train", "t.csv", "--min-gain", "nan"], ["--min-gain", "[0, 1)"]),
    (["diagnose", "m.json", "--train", "t.csv", "--max-loss", "-5"], ["--max-loss", "[0, 1)"]),
    (["diagnose", "m.json", "--train", "t.csv", "--max-steps", "-1"], ["--max-steps"]),
    (["diagnose", "m.json", "--train", "t.csv", "--maxiter", "0"], ["--maxiter"]),
    (["diagnose", "m.json", "--train", "t.csv", "--jobs", "0"], ["--jobs"]),
    (["plan", "p.nc", "--model", "m.json", "--tol", "nan"], ["--tol", "> 0"]),
    (["plan", "p.nc", "--model", "m.json", "--margin", "-3"], ["--margin", "[0, 1)"]),
    (["validate", "d.fmu", "t.csv", "--tolerance", "nan"], ["--tolerance", "> 0"]),
    (["align", "c.csv", "--window", "0", "-o", "a.csv"], ["--window", "> 0"]),
    (["align", "c.csv", "--lowpass", "-3", "-o", "a.csv"], ["--lowpass", "> 0"]),     # refused, not taken
    (["align", "c.csv", "--lowpass", "nan", "-o", "a.csv"], ["--lowpass", "> 0"]),
    # a trace whose time starts before its trigger: argparse takes '-0.5:2' for an option
    (["diagnose", "m.json", "--train", "t.csv", "--train-range", "-0.5:2"], ["--train-range", "--option=VALUE"]),
    (["simulate", "m.json", "t.csv", "--range", "-0.5:2"], ["--range", "--option=VALUE"]),
    # an FMU with no binaries was exported as success; pythonfmu ignored --platforms
    (["export", "m.json", "--platforms", ","], ["--platforms", "no platform"]),
    (["export", "m.json", "--backend", "python", "--platforms", "win64"], ["--platforms", "--backend c"]),
])
def test_bad_numbers_of_other_commands_give_one_line(capsys, argv, words):
    code, _, err = run(capsys, *argv)
    assert_one_line(code, err, *words)


# ----------------------------------------------------------------------------- data
@pytest.mark.parametrize("scale,word", [(1e300, "positions reach"), (1e-300, "moves by only")])
def test_absurdly_scaled_data_is_refused(capsys, tmp_path, scale, word):
    csv = trace_csv(tmp_path / "scaled.csv", n=500, scale=scale)
    code, _, err = run(capsys, "identify", csv, "-o", tmp_path / "m.json")
    assert_one_line(code, err, "scaled.csv", "x_cmd_mm", word)
    assert not (tmp_path / "m.json").exists()


def test_utf16_files(capsys, tmp_path):
    model = small_model(tmp_path / "m.json")
    csv = trace_csv(tmp_path / "u16.csv", n=300, encoding="utf-16")     # with BOM
    code, out, err = run(capsys, "simulate", model, csv, "-o", tmp_path / "p.csv")
    assert code == 0, err
    assert np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1).shape == (300, 3)
    raw = trace_csv(tmp_path / "u16le.csv", n=300, encoding="utf-16-le")  # no BOM
    code, _, err = run(capsys, "simulate", model, raw, "-o", tmp_path / "q.csv")
    assert_one_line(code, err, "u16le.csv", "UTF-16")


def test_simulate_honours_range(capsys, files, tmp_path):
    model, csv = files
    code, out, err = run(capsys, "simulate", model, csv, "--range", "0.2:0.5", "-o", tmp_path / "p.csv")
    assert code == 0, err
    data = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    assert data.shape[0] == 301 and abs(data[0, 0] - 0.2) < 1e-9 and abs(data[-1, 0] - 0.5) < 1e-9
    code, out, err = run(capsys, "simulate", model, csv, "--range", "0.1:0.2,0.3:0.4", "-o",
                         tmp_path / "q.csv")
    assert code == 0, err
    assert np.loadtxt(tmp_path / "q.csv", delimiter=",", skiprows=1).shape[0] == 202


@pytest.mark.parametrize("extra", [["--range", "0.1:0.5,0.6:0.9"], ["--range", "0.1:0.5", "--train-range", "0:1"]])
def test_diagnose_takes_one_range_per_trace(capsys, files, extra):
    model, csv = files
    code, _, err = run(capsys, "diagnose", model, "--train", csv, *extra)
    assert_one_line(code, err, "one data range per trace")


def test_plan_takes_one_range(capsys, files, tmp_path):
    model, csv = files
    nc = tmp_path / "p.nc"
    nc.write_text("G21 G90 G94\nG1 X5 F3000\nM30\n")
    code, _, err = run(capsys, "plan", nc, "--model", model, "--limits-from", csv, "--range", "0.1:0.5,0.6:0.9")
    assert_one_line(code, err, "one --range for fdid plan's trace")


def test_short_trace_to_diagnose(capsys, files, tmp_path):
    model, _ = files
    five = trace_csv(tmp_path / "five.csv", n=5)
    code, _, err = run(capsys, "diagnose", model, "--train", five)
    assert_one_line(code, err, "five.csv", "samples")


def test_random_bytes_fmu(capsys, files, tmp_path):
    _, csv = files
    fmu = tmp_path / "random.fmu"
    fmu.write_bytes(np.random.default_rng(0).bytes(5000))
    code, _, err = run(capsys, "validate", fmu, csv)
    assert_one_line(code, err, "random.fmu")


def test_wide_header_is_refused_quickly(capsys, files, tmp_path):
    model, _ = files
    wide = tmp_path / "wide.csv"
    n = 200000
    wide.write_text("t_s," + ",".join(f"c{i}" for i in range(n)) + "\n0," + ",".join(["1"] * n) + "\n")
    t0 = time.process_time()
    code, _, err = run(capsys, "simulate", model, wide, "-o", tmp_path / "p.csv")
    assert time.process_time() - t0 < 5.0
    assert_one_line(code, err, "wide.csv", "columns")


def test_time_error_has_no_numpy_repr(capsys, files, tmp_path):
    model, _ = files
    bad = tmp_path / "back.csv"
    bad.write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.049,1,1\n0.049,2,2\n")
    code, _, err = run(capsys, "simulate", model, bad, "-o", tmp_path / "p.csv")
    assert_one_line(code, err, "back.csv", "0.049 s")


# ----------------------------------------------------------------------------- the boundary
def test_unexpected_exception_is_one_line_naming_a_bug(capsys, files, monkeypatch, tmp_path):
    """A failure nobody foresaw (here: a command handler that raises) is reported as a bug in
    one line; the traceback only with --debug."""
    import fdid_fmi.cli.simulate as sim
    model, csv = files

    def broken(args):
        raise KeyError("surprise")

    monkeypatch.setattr(sim, "run", broken)
    code, _, err = run(capsys, "simulate", model, csv, "-o", tmp_path / "p.csv")
    line = assert_one_line(code, err, "internal error", "KeyError", "bug", rc=3)
    assert "--debug" in line
    code, _, err = run(capsys, "--debug", "simulate", model, csv, "-o", tmp_path / "p.csv")
    assert code == 3 and "Traceback" in err and "surprise" in err
    code, _, err = run(capsys, "simulate", model, csv, "-o", tmp_path / "p.csv", "--debug")
    assert code == 3 and "Traceback" in err


def test_subprocess_error_is_one_line_without_traceback(tmp_path):
    """The console entry point as a user runs it."""
    csv = tmp_path / "bad.csv"
    csv.write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.001,abc,0\n0.002,1,1\n")
    r = subprocess.run(FDID + ["identify", str(csv), "-o", str(tmp_path / "m.json")], capture_output=True,
                       text=True, timeout=300)
    assert_one_line(r.returncode, r.stderr, "bad.csv", "x_cmd_mm", "row 3")


def test_errors_name_the_file(capsys, tmp_path):
    """A model refused by export (quasi-static: no state space) names the model file."""
    qs = tmp_path / "qs.json"
    qs.write_text(json.dumps({"format": "fdid-fmi-model", "format_version": 1, "kind": "quasi_static",
                              "Ts": TS, "gains": {"x": {"K_vel": 1e-3, "K_acc": 1e-6, "K_jerk": 1e-9}},
                              "cutoff_hz": 50.0, "order": 2}))
    code, _, err = run(capsys, "export", qs, "-o", tmp_path / "q.fmu")
    assert_one_line(code, err, "qs.json", "quasi-static")
    qs.write_text(json.dumps({"format": "fdid-fmi-model", "format_version": 1, "kind": "quasi_static",
                              "Ts": TS, "gains": {"x": {"K_vel": "fast", "K_acc": 1e-6, "K_jerk": 1e-9}},
                              "cutoff_hz": 50.0, "order": 2}))
    code, _, err = run(capsys, "simulate", qs, trace_csv(tmp_path / "r.csv", n=100), "-o", tmp_path / "p.csv")
    assert_one_line(code, err, "qs.json", "K_vel")


def test_search_refuses_when_no_objective_is_finite():
    from fdid_fmi.identify.search import run_search
    for method in ("de", "multistart"):
        with pytest.raises(InputError, match="no candidate with a finite prediction error"):
            run_search(lambda x: float("nan"), [0.0, 0.0], [1.0, 1.0], method=method, maxiter=2, starts=2)
    res = run_search(lambda x: float(np.sum((x - 0.3) ** 2)) if x[0] > 0.1 else float("nan"),
                     [0.0, 0.0], [1.0, 1.0], method="de", maxiter=20)
    assert np.isfinite(res.fun) and np.allclose(res.x, 0.3, atol=1e-3)


@pytest.mark.parametrize("extra,word", [(["--limits-from", "{tr}", "--csv", "{tr}"], "tr.csv"),
                                        (["--commands", "{tr}", "--json", "{tr}"], "tr.csv"),
                                        (["--limits", "100,2000,1e5", "--csv", "{out}", "--json", "{out}"],
                                         "same file")])
def test_plan_never_writes_over_its_inputs(capsys, tmp_path, extra, word):
    """fdid plan's outputs are checked against every input (the program, the twin, --limits-from,
    --commands) and against each other before any work: a trace given as --limits-from and --csv
    would be overwritten by the prediction."""
    tr = tmp_path / "tr.csv"
    tr.write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.001,1,1\n")
    before = tr.read_bytes()
    argv = ["plan", tmp_path / "p.nc", "--model", tmp_path / "m.json"] + \
        [a.format(tr=tr, out=tmp_path / "o.csv") for a in extra]
    code, _, err = run(capsys, *argv)
    assert_one_line(code, err, word)
    assert "p.nc" not in err                            # refused before the program is read
    assert tr.read_bytes() == before and not (tmp_path / "o.csv").exists()
