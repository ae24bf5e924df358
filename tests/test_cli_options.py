"""The command line as a user meets it: abbreviated options refused, the
``fdid identify`` summary's v_tilde line, plain numbers from ``examples/emps_identify.py``, and a
failed ``fdid demo`` that leaves no empty or half-filled output folder behind."""
import argparse
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fdid_fmi.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]


def _all_parsers(parser):
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sp in action.choices.values():
                yield from _all_parsers(sp)


def _exit_code(argv):
    try:
        return main(argv)
    except SystemExit as exc:       # argparse
        return exc.code


# ------------------------------------------------------------------ 1. no abbreviated options
def test_every_fdid_parser_refuses_abbreviations():
    parsers = list(_all_parsers(build_parser()))
    names = {p.prog for p in parsers}
    assert {"fdid", "fdid identify", "fdid demo", "fdid fleet", "fdid fleet run"} <= names
    assert [p.prog for p in parsers if p.allow_abbrev] == []


@pytest.mark.parametrize("argv, unknown", [
    (["identify", "{d}/t.csv", "--meth", "pole-search", "-o", "{d}/m.json"], "--meth"),  # --method
    # (--emps --data: a quick failure, not the whole demo, where an abbreviation is accepted)
    (["demo", "--em", "--data", "{d}/none", "--out", "{d}/demo"], "--em"),               # --emps
    (["--deb", "demo", "--emps", "--data", "{d}/none", "--out", "{d}/demo"], "--deb"),   # --debug
    (["demo", "--emps", "--data", "{d}/none", "--out", "{d}/demo", "--deb"], "--deb"),   # sub-parser's
    (["fleet", "run", "{d}/m.toml", "--wor", "2"], "--wor"),                             # --workers
])
def test_abbreviated_long_option_is_one_error_line(capsys, tmp_path, argv, unknown):
    # `--meth pole-search` is not taken as --method, nor `--em` as --emps (and the demo does not run)
    code = _exit_code([a.format(d=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "error: unrecognized arguments: " + unknown in lines[0], err
    assert list(tmp_path.iterdir()) == []          # nothing ran, nothing written


@pytest.mark.parametrize("argv, prog, bad", [
    (["--vers"], "fdid", "--vers; before the command fdid takes only"),   # was: "COMMAND is required"
    (["--method", "mimo", "identify", "t.csv"], "fdid", "--method; before the command"),
    (["identify", "t.csv", "--bogus"], "fdid identify", "--bogus"),   # was: "see fdid --help"
    (["fleet", "run", "m.toml", "--bogus"], "fdid fleet run", "--bogus"),
    (["fleet", "--bogus", "run", "m.toml"], "fdid fleet", "--bogus"),  # given to fleet, not to run
])
def test_an_unknown_option_is_named_where_it_was_given(capsys, argv, prog, bad):
    assert _exit_code(argv) == 2
    (line,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert line.startswith(f"{prog}: error: unrecognized arguments: {bad}") and line.endswith(f"(see {prog} --help)")


def test_help_and_debug_where_they_were_accepted():
    assert _exit_code(["--bogus", "--help"]) == 0          # help still wins over an unknown option
    a = build_parser().parse_args(["fleet", "run", "m.toml", "--debug"])     # after a nested command
    assert a.debug is True


def test_abbreviation_refused_by_the_installed_command(tmp_path):
    r = subprocess.run([sys.executable, "-m", "fdid_fmi.cli", "identify", str(tmp_path / "t.csv"),
                        "--meth", "pole-search", "-o", str(tmp_path / "m.json")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith("fdid identify: error: unrecognized arguments: --meth pole-search")
    assert r.stderr.rstrip().endswith("(see fdid identify --help)")        # the command's options


def test_full_option_names_still_parse():
    a = build_parser().parse_args(["identify", "t.csv", "--method", "pole-search", "--jobs=2",
                                   "-o", "m.json", "--map", "t=a", "x.cmd=b"])
    assert (a.method, a.jobs, a.output, a.map) == ("pole-search", 2, "m.json", ["t=a", "x.cmd=b"])
    a = build_parser().parse_args(["--debug", "demo", "--emps", "--out", "o"])
    assert a.debug and a.emps and a.out == "o"


def test_readme_commands_use_full_option_names():
    # an abbreviation in the README or the docs would now be refused
    known = {o for p in _all_parsers(build_parser()) for a in p._actions for o in a.option_strings}
    used = set()
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    for page in pages:
        for line in page.read_text(encoding="utf-8").splitlines():
            if line.lstrip().startswith("fdid ") or "`fdid " in line:
                for cmd in re.findall(r"fdid [^`]*", line):
                    used.update(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", cmd))
    assert len(used) > 20
    assert sorted(used - known) == []


# ------------------------------------------------------------------ 2./3. the printed numbers
@pytest.fixture(scope="module")
def siso_fits():
    """Two small real pole searches (x and y of the virtual drive; 3 DE iterations)."""
    from fdid_fmi.identify import identify_siso
    from fdid_fmi.virtual import MachineConfig, presets, simulate_machine
    from fdid_fmi.virtual import trajectories as tj
    cfg = presets.deckel_maho_like()
    fits = {}
    for ax in ("x", "y"):
        tr = simulate_machine(MachineConfig(axes=[cfg.axis(ax)], Ts=cfg.Ts),
                              tj.linear_moves(n_moves=2, axes=(ax,), Ts=cfg.Ts, seed=1), seed=1)
        fits[ax] = identify_siso(tr, ax, seed=0, maxiter=3, same_sample="hold")
    return fits


def _vt(v):
    return f"{v:.3f}" if abs(v) >= 0.1 else f"{v:.3g}"


def test_identify_summary_prints_v_tilde_with_unit_and_axis(siso_fits):
    from fdid_fmi.cli.identify import summary
    from fdid_fmi.model import DriveModel
    m = DriveModel.combine([siso_fits["x"], siso_fits["y"]], method="pole-search")
    lines = summary(m)
    # not "poles: ...  v_tilde {'x': 0.013374773828375852} mm/s"
    assert not any("{" in ln or "}" in ln for ln in lines), lines
    vt = [ln for ln in lines if ln.startswith("v_tilde")]
    assert vt == [f"v_tilde [mm/s]: {ax} {_vt(siso_fits[ax].identification['v_tilde_mm_s'][ax])}"
                  for ax in ("x", "y")]
    # one block with two axes (a coupled model): both on one line, fixed decimals
    two = siso_fits["x"].copy()
    two.identification["v_tilde_mm_s"] = {"x": 0.2, "y": np.float64(0.18)}
    assert "v_tilde [mm/s]: x 0.200, y 0.180" in summary(two)
    two.identification["v_tilde_mm_s"] = {"x": 0.00223456}
    assert "v_tilde [mm/s]: x 0.00223" in summary(two)        # never "0.002" or "0.000"


def test_emps_identify_prints_plain_numbers(siso_fits, monkeypatch, tmp_path):
    # the example ran its job on import (and so does not import without its data: exit);
    # its last line printed np.float64(7.046...) reprs under numpy 2
    monkeypatch.setattr(sys, "argv", ["emps_identify.py", str(tmp_path / "none")])
    spec = importlib.util.spec_from_file_location("emps_identify_example", ROOT / "examples/emps_identify.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ident = siso_fits["x"].identification
    assert isinstance(ident["real_hz"][0], np.float64)      # what the record holds
    line = mod.pole_search_line(ident)
    assert "np." not in line and "float64" not in line and "{" not in line
    (w, z), = ident["complex_hz_zeta"]
    assert line.startswith(f"pole search: real [{ident['real_hz'][0]:.3f}] Hz  "
                           f"complex [{w:.3f} Hz / zeta {z:.4f}]  v_tilde [mm/s]: x ")
    ch = ident["friction_refinement"]["chosen"]
    assert line.endswith(f"refinement: band {ch['band']:g}, {ch['iterations']} iterations, "
                         f"free-run objective {ch['free_run_objective']:.4g}")


# ------------------------------------------------------------------ 4. fdid demo's output folder
def _listing(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


def test_failed_demo_emps_leaves_no_output_folder(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # out/demo/emps/ is not created, empty, before the data are read
    assert _exit_code(["demo", "--emps", "--data", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "DATA_EMPS.mat" in err
    assert _listing(tmp_path) == []
    assert _exit_code(["demo", "--emps", "--data", str(tmp_path / "missing"),
                       "--out", str(tmp_path / "new" / "deep" / "emps")]) == 2
    assert _listing(tmp_path) == []


def test_failed_demo_keeps_an_existing_folder_and_its_files(capsys, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    (out / "model.json").write_text("an earlier run's model")
    bad = tmp_path / "data"
    bad.mkdir()
    (bad / "DATA_EMPS.mat").write_bytes(b"not a mat file")
    before = _listing(tmp_path)
    assert _exit_code(["demo", "--emps", "--data", str(bad), "--out", str(out)]) == 2
    assert "Traceback" not in capsys.readouterr().err
    assert _listing(tmp_path) == before                    # no staging folder left either
    assert (out / "notes.txt").read_text() == "the user's"
    assert (out / "model.json").read_text() == "an earlier run's model"


def test_staged_output_moves_files_only_when_the_run_succeeds(tmp_path):
    from fdid_fmi.cli.demo import staged_output
    out = tmp_path / "a" / "b" / "demo"
    with pytest.raises(RuntimeError):                       # a failure after files were written
        with staged_output(out) as work:
            (work / "model.json").write_text("half a run")
            raise RuntimeError("the FMU build failed")
    assert _listing(tmp_path) == []                         # neither out nor a/b/ stay
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "keep.txt").write_text("x")
    with pytest.raises(KeyboardInterrupt):
        with staged_output(out) as work:
            (work / "report.html").write_text("partial")
            raise KeyboardInterrupt
    assert _listing(tmp_path) == ["a", "a/keep.txt"]        # a/ existed: kept, as is
    out.mkdir(parents=True)
    (out / "model.json").write_text("old")
    (out / "notes.txt").write_text("the user's")
    with staged_output(out) as work:
        assert work.parent == out.parent and work != out
        (work / "model.json").write_text("new")
        (work / "report.html").write_text("report")
    assert _listing(out) == ["model.json", "notes.txt", "report.html"]
    assert (out / "model.json").read_text() == "new" and (out / "notes.txt").read_text() == "the user's"
    assert _listing(out.parent) == ["demo", "demo/model.json", "demo/notes.txt", "demo/report.html"]
    (tmp_path / "file").write_text("")
    from fdid_fmi.errors import InputError
    with pytest.raises(InputError, match="not a folder"):
        with staged_output(tmp_path / "file"):
            pass


def test_an_axis_without_its_measured_position_is_named_not_dropped(capsys, tmp_path):
    """A trace whose y axis has its command column but not its measured one is identified on x
    alone, and the summary says y is not identified."""
    lines = (ROOT / "examples" / "virtual_circle.csv").read_text().splitlines()
    (tmp_path / "nocol.csv").write_text("\n".join(",".join(ln.split(",")[:4]) for ln in lines) + "\n")
    assert main(["identify", str(tmp_path / "nocol.csv"), "--method", "quasi-static",
                 "-o", str(tmp_path / "q.json")]) == 0
    out = capsys.readouterr().out
    assert "note: axis y has no measured position" in out and "--map y.act=COLUMN" in out
    assert "axis x" not in out


def test_every_option_with_a_default_shows_it_in_help():
    """``fdid CMD --help``: each option that takes a value and may be left out says what is used
    then ("default: ..."), also when that is no value at all (a file not written, all detectors);
    a required option, or one of a required choice (``--model`` / ``--fmu``), need not."""
    import argparse

    from fdid_fmi.cli import _command_parsers, build_parser
    parser = build_parser()
    missing = []
    for sp in _command_parsers(parser.commands.values()):
        fmt = sp._get_formatter()
        required = {id(a) for g in sp._mutually_exclusive_groups if g.required for a in g._group_actions}
        for action in sp._actions:
            if (not action.option_strings or action.required or id(action) in required
                    or action.default is argparse.SUPPRESS):
                continue
            if action.nargs == 0 and action.default in (None, False):      # a flag, off unless given
                continue
            if "default" not in fmt._format_action(action).lower():
                missing.append(f"{sp.prog} {action.option_strings[-1]}")
    assert not missing, missing
