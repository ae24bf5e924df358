"""fdid align keeps the controller trace's channels without a role (a spindle load, a status
word, a DC-link voltage) in the aligned CSV, not dropped without a word: same rows,
names and the file's units, values read back bitwise; the role columns are unchanged."""
import numpy as np
import pytest

from fdid_fmi.align.writer import write_trace_csv
from fdid_fmi.cli import main
from fdid_fmi.io import read_trace
from fdid_fmi.trace import Channel, Trace
from fdid_fmi.virtual import presets, simulate_machine
from fdid_fmi.virtual import trajectories as tj
from fdid_fmi.virtual.sensors import GridEncoderTruth, write_raw_run

EXTRA_HEADER = ["spindle_load_pct", "status", "dc_link [V]", "spindle_rpm"]
EXTRAS = ["spindle_load_pct", "status", "dc_link", "spindle_rpm"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One short two-axis run with a grid encoder, aligned by the CLI twice: the controller file
    as written by the trace tool (plain) and the same file with four channels without a role."""
    d = tmp_path_factory.mktemp("r4align")
    cfg = presets.flexible_y()
    sim = simulate_machine(cfg, tj.linear_moves(n_moves=8, axes=("x", "y"), Ts=cfg.Ts, seed=4,
                                                d_max=20.0), seed=4)
    run = write_raw_run(sim, d, accelerometers=[], grid_encoders=[GridEncoderTruth()])
    lines = run["controller"].read_text().splitlines()
    n = len(lines) - 1
    rng = np.random.default_rng(7)
    cols = [np.round(rng.uniform(0, 100, n), 1), (np.arange(n) // 500) % 4 * 1.0,
            rng.normal(560.0, 3.0, n), np.round(rng.uniform(0, 12000, n), 2)]
    text = [lines[0] + "," + ",".join(EXTRA_HEADER)]
    text += [ln + "," + ",".join(repr(float(c[k])) for c in cols) for k, ln in enumerate(lines[1:])]
    extra = d / "ctrl_extra.csv"
    extra.write_text("\n".join(text) + "\n")
    out = {}
    for key, ctrl in (("plain", run["controller"]), ("extra", extra)):
        o = d / f"aligned_{key}.csv"
        assert main(["align", str(ctrl), "--kgm", str(run["sensors"]["kgm"]), "-o", str(o)]) == 0
        out[key] = o
    return {"ctrl": extra, "run": run, "out": out, "d": d}


def test_channels_without_a_role_survive_bitwise(runs):
    ctrl, back = read_trace(runs["ctrl"]), read_trace(runs["out"]["extra"])
    assert ctrl.extra_channels == EXTRAS
    assert back.extra_channels == EXTRAS
    k0 = int(np.searchsorted(ctrl.t, back.t[0]))
    rows = slice(k0, k0 + back.n)
    np.testing.assert_array_equal(back.t, ctrl.t[rows])       # the controller's own rows
    for name in EXTRAS:     # bitwise: the controller's samples are cropped, never resampled
        np.testing.assert_array_equal(back.extra(name), ctrl.extra(name)[rows], err_msg=name)
        assert back.channels[name].unit == ctrl.channels[name].unit, name
    # the file holds the user's numbers in the user's units (50.4 %, 1234.5 rpm), not 0.504 / deg/s
    head = runs["out"]["extra"].read_text().splitlines()[0].split(",")
    assert head[-4:] == EXTRA_HEADER
    raw = np.loadtxt(runs["out"]["extra"], delimiter=",", skiprows=1)[:, -4:]
    src = np.loadtxt(runs["ctrl"], delimiter=",", skiprows=1)[rows, -4:]
    np.testing.assert_array_equal(raw, src)


def test_cli_says_which_channels_it_kept(runs, capsys):
    d = runs["d"]
    rc = main(["align", str(runs["ctrl"]), "--kgm", str(runs["run"]["sensors"]["kgm"]),
               "-o", str(d / "again.csv")])
    printed = capsys.readouterr().out
    assert rc == 0
    assert "kept 4 controller channel(s) without a role: spindle_load_pct, status, dc_link, spindle_rpm" \
        in printed
    assert (d / "again.csv").read_bytes() == runs["out"]["extra"].read_bytes()


def test_role_columns_unchanged_and_round_trip(runs):
    """The role columns are byte for byte those of the same run without the extra channels,
    and read back with the same roles; the extras get none."""
    plain = runs["out"]["plain"].read_text().splitlines()
    extra = runs["out"]["extra"].read_text().splitlines()
    assert len(plain) == len(extra)
    w = len(plain[0].split(","))
    assert extra[0].split(",")[w:] == EXTRA_HEADER
    for p, e in zip(plain, extra):
        assert e.split(",")[:w] == p.split(","), p
    a, b = read_trace(runs["out"]["plain"]), read_trace(runs["out"]["extra"])
    assert b.roles == a.roles
    assert not set(b.extra_channels) & {c for r in b.roles.values() for c in r.values()}
    for ax, rm in a.roles.items():
        for role in rm:
            np.testing.assert_array_equal(b.get(ax, role), a.get(ax, role))


def test_extra_named_like_a_role_is_kept_under_a_name_without_one(runs, tmp_path, capsys):
    """With --map naming the positions only, the velocities x_v_mm_s / y_v_mm_s are channels
    without a role; under their names they would read back as vel: written as ctrl_<name>,
    said in one line each, and the roles read back are the aligned trace's."""
    out = tmp_path / "mapped.csv"
    m = ["x.cmd=x_cmd_mm", "x.act=x_mm", "y.cmd=y_cmd_mm", "y.act=y_mm"]
    rc = main(["align", str(runs["ctrl"]), "--kgm", str(runs["run"]["sensors"]["kgm"]), "-o", str(out),
               "--map"] + m)
    printed = capsys.readouterr().out
    assert rc == 0
    for v in ("x_v_mm_s", "y_v_mm_s"):
        assert f"controller channel '{v}' (no role) written as 'ctrl_{v}'" in printed
    ctrl = read_trace(runs["ctrl"], mapping=dict(s.split("=") for s in m))
    back = read_trace(out)
    assert {a: sorted(r) for a, r in back.roles.items()} == {"x": ["act", "cmd", "tool"],
                                                           "y": ["act", "cmd", "tool"]}
    k0 = int(np.searchsorted(ctrl.t, back.t[0]))
    for name in ctrl.extra_channels:
        kept = name if name in back.channels else f"ctrl_{name}"
        np.testing.assert_array_equal(back.extra(kept), ctrl.extra(name)[k0:k0 + back.n], err_msg=name)


def test_writer_keeps_a_replaced_role_and_a_time_like_channel(tmp_path):
    """A Trace built in Python: a replaced tool channel named y_tool and a second clock named time
    would read back as y.tool / as time; both are kept, without a role."""
    t = np.arange(40) * 1e-3
    rng = np.random.default_rng(1)
    ch = {n: Channel(n, u, rng.normal(size=40)) for n, u in
          (("y_c", "mm"), ("y_a", "mm"), ("y_tool_mm", "mm"), ("y_tool", "mm"), ("time", "s"), ("i_q", "A"))}
    tr = Trace(t=t, channels=ch, roles={"y": {"cmd": "y_c", "act": "y_a", "tool": "y_tool_mm"}})
    back = read_trace(write_trace_csv(tr, tmp_path / "w.csv"))
    assert back.roles == {"y": {"cmd": "y_cmd_mm", "act": "y_mm", "tool": "y_tool_mm"}}
    assert sorted(back.extra_channels) == ["ctrl_time", "ctrl_y_tool", "i_q"]
    for old, new in (("y_tool", "ctrl_y_tool"), ("time", "ctrl_time"), ("i_q", "i_q")):
        np.testing.assert_array_equal(back.extra(new), tr.extra(old))
        assert back.channels[new].unit == tr.channels[old].unit
    notes = []      # one line per channel written under another name
    write_trace_csv(tr, tmp_path / "w2.csv", notes=notes)
    assert (tmp_path / "w2.csv").read_bytes() == (tmp_path / "w.csv").read_bytes()
    assert len(notes) == 2 and all("written as 'ctrl_" in n for n in notes)
