"""The command line: an option that is given but not read is refused
(``fdid diagnose --val-range`` without ``--val``, ``--exclude`` of a channel no trace has), a
held-out trace that is the training trace is refused, ... Each refusal is one error line, exit 2,
before any fit (a guard replaces the diagnosis, so a regression fails fast instead of fitting)."""
import importlib
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_diagnose_inputs import _ramp_trace  # noqa: E402


def _exit_code(argv):
    try:
        return main([str(a) for a in argv])
    except SystemExit as exc:       # argparse
        return exc.code


def _one_error(capsys, prog):
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith(f"{prog}: error: "), err
    return err[0]


def _csv(path, tr):
    np.savetxt(path, np.column_stack([tr.t, tr.cmd("x"), tr.act("x")]), delimiter=",",
               header="t_s,x_cmd_mm,x_mm", comments="", fmt="%.12g")
    return path


@pytest.fixture(scope="module")
def diag_files(tmp_path_factory):
    from fdid_fmi.identify import identify_siso
    d = tmp_path_factory.mktemp("diag")
    tr = _ramp_trace()
    identify_siso(tr, maxiter=1, friction=False).save(d / "m.json")
    _csv(d / "train.csv", tr)
    _csv(d / "val.csv", _ramp_trace(seed=1))
    shutil.copy(d / "train.csv", d / "train_copy.csv")
    return d


@pytest.fixture
def no_fit(monkeypatch):
    """The diagnosis itself must not be reached: each case is refused before it."""
    def reached(*a, **k):
        raise AssertionError("the diagnosis started: the input was not refused")
    # fdid_fmi.diagnose names the API function; the subpackage's diagnose is what it runs
    monkeypatch.setattr(importlib.import_module("fdid_fmi.diagnose"), "diagnose", reached)


# ------------------------------------------------------------------ 1. --val-range without --val
def test_diagnose_val_range_without_val_is_refused(diag_files, no_fit, capsys):
    d = diag_files
    # not read only `if args.val`, which would run the diagnosis on the split --train
    code = _exit_code(["diagnose", d / "m.json", "--train", d / "train.csv", "--val-range", "0:1"])
    line = _one_error(capsys, "fdid diagnose")
    assert code == 2
    assert "'--val-range'" in line and "no --val is given" in line and "--train-range" in line, line


# ------------------------------------------------------------------ 2. --exclude of no channel
def test_diagnose_exclude_of_a_channel_no_trace_has_is_refused(diag_files, no_fit, capsys):
    d = diag_files
    # not compared with the candidates, matching none without a word
    code = _exit_code(["diagnose", d / "m.json", "--train", d / "train.csv", "--val", d / "val.csv",
                       "--exclude", "x_mm", "nosuch"])
    line = _one_error(capsys, "fdid diagnose")
    assert code == 2
    assert "'--exclude'" in line and "no channel 'nosuch'" in line, line
    assert "['x_cmd_mm', 'x_mm']" in line, line        # the channels there are


# ------------------------------------------------------------------ 3. --val is the training data
@pytest.mark.parametrize("val, said", [("train.csv", "is the --train file itself"),
                                       ("./train.csv", "is the --train file itself"),
                                       ("train_copy.csv", "holds the same data as the --train file")])
def test_diagnose_val_that_is_the_training_data_is_refused(diag_files, no_fit, capsys, val, said):
    d = diag_files
    # else the held-out error is measured in-sample, without a word
    code = _exit_code(["diagnose", d / "m.json", "--train", d / "train.csv", "--val", f"{d}/{val}"])
    line = _one_error(capsys, "fdid diagnose")
    assert code == 2
    assert "'--val'" in line and said in line and "held-out" in line, line


def test_diagnose_same_file_with_overlapping_ranges_is_refused(diag_files, no_fit, capsys):
    d = diag_files
    code = _exit_code(["diagnose", d / "m.json", "--train", d / "train.csv", "--train-range", "0:2",
                       "--val", d / "train.csv", "--val-range", "1.5:2.9"])
    assert code == 2 and "is the --train file itself" in _one_error(capsys, "fdid diagnose")


def test_diagnose_same_file_with_disjoint_ranges_is_held_out(diag_files, no_fit, capsys):
    d = diag_files
    # disjoint ranges of one recording are a true held-out test: not refused (the guard is reached)
    _exit_code(["diagnose", d / "m.json", "--train", d / "train.csv", "--train-range", "0:1.4",
                "--val", d / "train.csv", "--val-range", "1.5:2.9"])
    assert "the diagnosis started" in capsys.readouterr().err


# ------------------------------------------------------------------ 4. manifest: traces and trace
@pytest.mark.parametrize("text, fmt", [
    ('[[entry]]\nmachine="m01"\naxis="x"\ntraces=["a.csv"]\ntrace=["b.csv"]\n', "toml"),
    ("machine,axis,traces,trace\nm01,x,a.csv,b.csv\n", "csv"),
])
def test_manifest_entry_with_both_traces_and_trace_is_refused(text, fmt):
    from fdid_fmi.fleet import parse_manifest_text
    # raw.get("traces", raw.get("trace")) would keep 'traces' and drop b.csv without a word
    m = parse_manifest_text(text, fmt, source=f"both.{fmt}")
    (e,) = m.entries
    assert e.error and "\n" not in e.error, e.error
    assert "entry" in e.error and "m01/x" in e.error and "'traces' and 'trace'" in e.error, e.error
    assert "b.csv" in e.error


def test_manifest_entry_with_trace_alone_still_works():
    from fdid_fmi.fleet import parse_manifest_text
    m = parse_manifest_text('[[entry]]\nmachine="m01"\naxis="x"\ntrace=["b.csv"]\n', "toml")
    assert m.entries[0].error is None and m.entries[0].traces[0].endswith("b.csv")


# ------------------------------------------------------------------ 5. fleet: no output folder left
_ENTRY = ('[[entry]]\nmachine="m01"\naxis="x"\ntraces=["x.csv"]\n'
          'map = { t = "t_s", "x.cmd" = "x_cmd_mm", "x.act" = "x_mm" }\n')


@pytest.mark.parametrize("out", ["new", "new/deeper/still"])
def test_fleet_unreachable_scheduler_leaves_no_output_folder(tmp_path, capsys, out):
    pytest.importorskip("distributed")
    (tmp_path / "m.toml").write_text(_ENTRY)
    _csv(tmp_path / "x.csv", _ramp_trace(n=300))
    # the error, and no OUT/entries/ (empty) left behind
    code = _exit_code(["fleet", "run", tmp_path / "m.toml", "--out", tmp_path / out, "--scheduler", "bogus"])
    line = _one_error(capsys, "fdid fleet")
    assert code == 2 and "Dask scheduler" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml", "x.csv"]


def test_fleet_failure_keeps_what_existed_before(tmp_path, capsys):
    pytest.importorskip("distributed")
    (tmp_path / "m.toml").write_text(_ENTRY)
    _csv(tmp_path / "x.csv", _ramp_trace(n=300))
    out = tmp_path / "out"
    (out / "entries" / "old").mkdir(parents=True)
    (out / "notes.txt").write_text("mine")
    empty = tmp_path / "empty"
    empty.mkdir()
    for o in (out, empty):
        assert _exit_code(["fleet", "run", tmp_path / "m.toml", "--out", o, "--scheduler", "bogus"]) == 2
        assert "Dask scheduler" in _one_error(capsys, "fdid fleet")
    assert (out / "notes.txt").read_text() == "mine" and (out / "entries" / "old").is_dir()
    assert empty.is_dir() and list(empty.iterdir()) == []      # existed: kept; its entries/ was new


def test_fleet_bad_previous_leaves_no_output_folder(tmp_path, capsys):
    (tmp_path / "m.toml").write_text(_ENTRY)
    code = _exit_code(["fleet", "run", tmp_path / "m.toml", "--out", tmp_path / "o", "--previous", tmp_path / "o"])
    assert code == 2 and "--previous" in _one_error(capsys, "fdid fleet")
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ 6. fleet run DIR
def test_fleet_run_of_a_directory_says_it_is_a_directory(tmp_path, capsys):
    d = tmp_path / "night1"
    d.mkdir()
    (d / "plant.toml").write_text(_ENTRY)
    # not "night1: manifest file not found", though night1 exists
    code = _exit_code(["fleet", "run", d, "--out", tmp_path / "o"])
    line = _one_error(capsys, "fdid fleet")
    assert code == 2 and "is a directory, not a manifest file" in line and "plant.toml" in line, line
    assert "not found" not in line
    code = _exit_code(["fleet", "run", tmp_path / "none.toml", "--out", tmp_path / "o"])
    assert code == 2 and "manifest file not found" in _one_error(capsys, "fdid fleet")
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ 7. fdid align messages
@pytest.fixture
def align_files(tmp_path):
    """Two small files standing for the controller trace and a sensor (every case here is
    refused before either is read)."""
    ctrl, acc = tmp_path / "ctrl.csv", tmp_path / "acc.csv"
    ctrl.write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n0.001,0,0\n")
    acc.write_text("t_s,ax_g,ay_g,az_g\n0,0,0,1\n0.001,0,0,1\n")
    return tmp_path, ctrl, acc


def test_align_without_a_sensor_names_the_command_once(align_files, capsys):
    d, ctrl, _ = align_files
    # not "fdid align: error: fdid align: give at least one sensor: ..."
    assert _exit_code(["align", ctrl, "-o", d / "o.csv"]) == 2
    line = _one_error(capsys, "fdid align")
    assert line.count("fdid align") == 1 and "give at least one sensor" in line, line


def test_align_json_and_output_on_one_file_says_so(align_files, capsys):
    d, ctrl, acc = align_files
    # not "the JSON file would overwrite the input file X" (X is no input; it does not exist)
    assert _exit_code(["align", ctrl, "--acc", acc, "-o", d / "x.out", "--json", d / "x.out"]) == 2
    line = _one_error(capsys, "fdid align")
    assert "the JSON file and the aligned trace (-o) are the same file" in line, line
    assert "input" not in line and not (d / "x.out").exists()
    # an input named as --json is still an input
    assert _exit_code(["align", ctrl, "--acc", acc, "-o", d / "o.csv", "--json", acc]) == 2
    assert "would overwrite the input file" in _one_error(capsys, "fdid align")


@pytest.mark.parametrize("setting", ["name=a\nb", "name=a\tb", "axes=x,\ny"])
def test_align_setting_with_a_control_character_is_refused(align_files, capsys, setting):
    d, ctrl, acc = align_files
    # name=a<newline>b is refused: its newline would split the table rows and messages
    assert _exit_code(["align", ctrl, "--acc", acc, setting, "-o", d / "o.csv"]) == 2
    line = _one_error(capsys, "fdid align")
    assert "control character" in line and "column '" + setting.split("=")[0] + "'" in line, line
    assert not (d / "o.csv").exists()


def test_align_file_name_with_a_line_break_needs_a_name(align_files, capsys):
    d, ctrl, acc = align_files
    odd = d / "head\nacc.csv"
    odd.write_bytes(acc.read_bytes())
    assert _exit_code(["align", ctrl, "--acc", odd, "-o", d / "o.csv"]) == 2
    line = _one_error(capsys, "fdid align")
    assert "give name=" in line and "head\\nacc" in line, line


def test_align_unit_message_uses_an(tmp_path):
    from fdid_fmi.align import read_accelerometer
    from fdid_fmi.errors import InputError
    f = tmp_path / "acc.csv"
    f.write_text("t,ax,ay,az\n0,0,0,1\n0.001,0,0,1\n0.002,0,0,1\n")
    # not "a accelerometer column needs a acceleration unit"
    with pytest.raises(InputError, match="an accelerometer column needs an acceleration unit"):
        read_accelerometer(f)


def test_no_common_motion_within_max_offset_names_the_bound():
    from fdid_fmi.align.timing import coarse_offset
    from fdid_fmi.errors import InputError
    Ts = 1e-3
    t = np.arange(0, 8, Ts)
    env = np.zeros(t.size)
    for a in (1.0, 2.5, 4.5, 6.0):               # four moves of the controller
        env[(t > a) & (t < a + 0.4)] = 1.0
    tau = t.copy()
    sens = np.interp(tau + 1.24, t, env, right=0.0)   # the sensor's clock is 1.24 s behind
    off, rho = coarse_offset(t, env, tau, sens)
    assert off == pytest.approx(1.24, abs=2 * Ts) and rho > 0.9
    # more than "... the records do not overlap in time, or the sensor did not see the moves"
    with pytest.raises(InputError) as ei:
        coarse_offset(t, env, tau, sens, max_offset_s=0.5, what="accelerometer 'acc'")
    msg = str(ei.value)
    assert "no common motion" in msg and "--max-offset" in msg and "0.5 s" in msg, msg
    unrelated = (tau % 0.9 < 0.05).astype(float)     # short blips every 0.9 s: another run
    with pytest.raises(InputError) as ei:      # no common motion without a bound: no word of it
        coarse_offset(t, env, tau, unrelated)
    assert "no common motion" in str(ei.value)
    assert "--max-offset" not in str(ei.value)


def test_identify_summary_covers_the_ranges_given(diag_files, capsys):
    """With --range the free-run table covers the ranges, each run from its own start as fdid
    simulate runs them, not the whole record."""
    import re
    from fdid_fmi.io import read_trace
    d = diag_files
    out = d / "q.json"
    code = _exit_code(["identify", d / "train.csv", "--method", "quasi-static", "--range", "0.2:1.4,1.6:2.8",
                       "-o", out])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "free run on " in text and "ranges 0.2:1.4, 1.6:2.8 s:" in text
    row = next(ln for ln in text.splitlines() if ln.strip().startswith("x "))
    e_rms = float(re.split(r"\s+", row.strip())[1])
    pieces = read_trace(d / "train.csv").select([(0.2, 1.4), (1.6, 2.8)])
    e = np.concatenate([p.cmd("x") - p.act("x") for p in pieces])
    assert e_rms == pytest.approx(np.sqrt(np.mean(e ** 2)) * 1e3, abs=1e-3)


def test_identify_notes_a_position_that_does_not_follow_its_command(diag_files, tmp_path, capsys):
    """A command in m beside a position in mm (tracking error 99 % of the motion) is identified
    with a note. The same file with matching units gets no note."""
    d = diag_files
    text = (d / "train.csv").read_text().replace("t_s,x_cmd_mm,x_mm", "t_s,x_cmd_m,x_mm")
    (tmp_path / "m_mm.csv").write_text(text)
    code = _exit_code(["identify", tmp_path / "m_mm.csv", "--method", "quasi-static", "-o", tmp_path / "q.json"])
    out = capsys.readouterr().out
    assert code == 0 and "note: " in out and "of the commanded motion's" in out and "x_cmd_m and x_mm" in out
    code = _exit_code(["identify", d / "train.csv", "--method", "quasi-static", "-o", tmp_path / "q2.json"])
    out = capsys.readouterr().out
    assert code == 0 and "commanded motion" not in out and "runs ahead" not in out


def test_identify_notes_a_command_swapped_with_the_position(diag_files, tmp_path, capsys):
    """A command swapped with the measured position (the header's names exchanged) was identified
    without a word: the position then leads the command (correlation -0.99 here)."""
    d = diag_files
    text = (d / "train.csv").read_text().replace("t_s,x_cmd_mm,x_mm", "t_s,x_mm,x_cmd_mm")
    (tmp_path / "swapped.csv").write_text(text)
    code = _exit_code(["identify", tmp_path / "swapped.csv", "--method", "quasi-static", "-o", tmp_path / "q.json"])
    out = capsys.readouterr().out
    note = next((ln for ln in out.splitlines() if "runs ahead" in ln), "")
    assert code == 0 and note.startswith("note: ") and "x_mm runs ahead of x_cmd_mm" in note and "swapped" in note
