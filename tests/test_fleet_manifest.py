"""Fleet manifests, content hashes and the change comparison (no identification: fast)."""
import numpy as np
import pytest

from fdid_fmi import __version__
from fdid_fmi.errors import InputError
from fdid_fmi.fleet import Thresholds, entry_hash, load_manifest, parse_manifest_text
from fdid_fmi.fleet.compare import ModelSignature, compare_models, direction_of_motion, residual_signature

TOML = """
[defaults]
map = { t = "t_s" }
options = { diagnose = false }

[thresholds]
error_ratio = 3.0

[[entry]]
machine = "m01"
axis = "x"
traces = ["a.csv", "b.csv"]
map = { "x.cmd" = "x_cmd_mm", "x.act" = "x_mm" }
options = { seed = 3, no_integral_action = true, maxiter = 5 }

[[entry]]
machine = "m01"
axis = "y"
traces = ["c.csv"]
options = { method = "magic" }

[[entry]]
machine = "m02"
axis = "x"
traces = ["d.csv"]
options = { colour = "red" }

[[entry]]
machine = "m02"
axis = "y"
traces = ["e.csv"]
options = { diagnose = "yes" }

[[entry]]
axis = "z"
traces = ["f.csv"]
"""


def test_toml_entries_defaults_and_option_checks(tmp_path):
    m = parse_manifest_text(TOML, "toml", base=tmp_path, source="plant.toml")
    assert [e.key for e in m.entries] == ["m01/x", "m01/y", "m02/x", "m02/y", "entry5/z"]
    e = m.entries[0]
    assert e.error is None
    assert e.traces == (str(tmp_path / "a.csv"), str(tmp_path / "b.csv"))
    assert e.mapping == {"t": "t_s", "x.cmd": "x_cmd_mm", "x.act": "x_mm"}
    assert e.diagnose is False
    assert e.identify == ("--seed", "3", "--no-integral-action", "--maxiter", "5")
    assert m.thresholds == {"error_ratio": 3.0}
    # bad entries carry one line naming the problem; they do not stop the manifest
    errs = {x.key: x.error for x in m.entries[1:]}
    assert "magic" in errs["m01/y"] and "\n" not in errs["m01/y"]
    assert "--colour" in errs["m02/x"]
    assert "diagnose" in errs["m02/y"]
    assert "machine" in errs["entry5/z"]


def test_csv_manifest(tmp_path):
    text = ("machine,axis,traces,map,units,options\n"
            "m01,x,a.csv;b.csv,t=t_s x.cmd=x_cmd_mm x.act=x_mm,x_mm=um,diagnose=false seed=2\n"
            "m01,y,c.csv,y.cmd=yc,,fmi=4\n"
            "m02,x,d.csv,nonsense,,\n")
    (tmp_path / "plant.csv").write_text(text)
    m = load_manifest(tmp_path / "plant.csv")
    a, b, c = m.entries
    assert a.error is None and a.units == {"x_mm": "um"} and a.identify == ("--seed", "2")
    assert len(a.traces) == 2 and not a.diagnose
    assert "fmi" in b.error
    assert "KEY=VALUE" in c.error


def test_manifest_file_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_manifest(tmp_path / "none.toml")
    (tmp_path / "bad.toml").write_text("[[entry]\nmachine=")
    with pytest.raises(InputError, match="not valid TOML"):
        load_manifest(tmp_path / "bad.toml")
    (tmp_path / "x.yaml").write_text("a: 1")
    with pytest.raises(InputError, match=r"\.toml or \.csv"):
        load_manifest(tmp_path / "x.yaml")
    dup = '[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\n' * 2
    with pytest.raises(InputError, match="listed twice"):
        parse_manifest_text(dup, "toml")
    with pytest.raises(InputError, match="no entries"):
        parse_manifest_text("", "toml")
    # a bad second entry of the same machine/axis may not hide behind the good first one: both
    # would share one result (the good one's) and one output folder
    bad_dup = ('[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\n'
               '[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\noptions={bogus=3}\n')
    with pytest.raises(InputError, match="listed twice"):
        parse_manifest_text(bad_dup, "toml")
    clash = ('[[entry]]\nmachine="a__b"\naxis="c"\ntraces=["1.csv"]\n'
             '[[entry]]\nmachine="a"\naxis="b__c"\ntraces=["1.csv"]\n')
    with pytest.raises(InputError, match="same folder"):
        parse_manifest_text(clash, "toml")


@pytest.mark.parametrize("text,words", [
    ('[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\nmap="x.cmd=x_cmd_mm"\n', ["map", "table", "str"]),
    ('[defaults]\nmap="t=t_s"\n[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\n', ["map", "[defaults]"]),
    ('[defaults]\ncolour="red"\n[[entry]]\nmachine="a"\naxis="x"\ntraces=["1.csv"]\n', ["[defaults]", "colour"]),
])
def test_tables_that_are_not_tables(text, words):
    """A CSV-style string where TOML wants a table: one line naming it (not a TypeError), in an
    entry (that entry fails) or in [defaults] (the manifest is refused)."""
    try:
        m = parse_manifest_text(text, "toml")
    except InputError as exc:
        msg = str(exc)
    else:
        msg = m.entries[0].error
    assert msg and "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_entry_hash_follows_bytes_options_and_version(tmp_path):
    (tmp_path / "a.csv").write_text("t_s,x_cmd_mm,x_mm\n0,0,0\n")
    text = '[[entry]]\nmachine="m"\naxis="x"\ntraces=["a.csv"]\noptions={seed=1}\n'
    spec = parse_manifest_text(text, "toml", base=tmp_path).entries[0]
    h = entry_hash(spec, __version__)
    assert h == entry_hash(parse_manifest_text(text, "toml", base=tmp_path).entries[0], __version__)
    assert h != entry_hash(spec, "9.9.9")
    assert h != entry_hash(parse_manifest_text(text.replace("seed=1", "seed=2"), "toml", base=tmp_path)
                           .entries[0], __version__)
    (tmp_path / "a.csv").write_text("t_s,x_cmd_mm,x_mm\n0,0,1\n")
    assert h != entry_hash(spec, __version__)
    (tmp_path / "a.csv").unlink()
    assert entry_hash(spec, __version__) != h      # a missing file has its own hash


def test_thresholds_checked():
    assert Thresholds.from_dict({"error_ratio": 3}).error_ratio == 3.0
    with pytest.raises(InputError, match="unknown threshold"):
        Thresholds.from_dict({"eror_ratio": 3})
    with pytest.raises(InputError, match="non-negative"):
        Thresholds.from_dict({"pole_rel": "a lot"})


def _sig(peak=10.0, vt=0.5, poles=((-10.0, 0.0), (-5.0, 20.0)), effects=()):
    return ModelSignature(poles_hz=[list(p) for p in poles], friction_peak_um=peak, v_tilde_mm_s=vt,
                          effects=list(effects), Ts=1e-3)


def _moves(n=3000, Ts=1e-3):
    t = np.arange(n) * Ts
    cmd = 10 * np.sin(2 * np.pi * 0.7 * t)          # reverses every ~0.7 s
    return t, cmd


def test_compare_names_friction_backlash_resonance_and_no_change():
    th = Thresholds()
    t, cmd = _moves()
    flat = {"motor": {"old_on_old": 0.5, "old_on_new": 0.55, "new_on_new": 0.5}}
    rep = compare_models(_sig(), _sig(peak=10.5), flat, {}, th)
    assert not rep.changed and rep.kinds == []
    rep = compare_models(_sig(), _sig(peak=19.0), {"motor": {"old_on_old": 0.5, "old_on_new": 3.0,
                                                             "new_on_new": 0.6}}, {}, th)
    assert rep.changed and rep.kinds == ["friction"] and "up 90%" in rep.summary
    # a tool-side residual that is a direction-dependent offset of +-10 µm: 20 µm backlash
    r = 0.010 * direction_of_motion(cmd) + 1e-5 * np.random.default_rng(0).standard_normal(t.size)
    errs = {"motor": {"old_on_old": 0.5, "old_on_new": 0.5, "new_on_new": 0.5},
            "tool": {"old_on_old": 0.5, "old_on_new": 10.0, "new_on_new": 10.0}}
    rep = compare_models(_sig(), _sig(), errs, {"tool": (r, cmd, 1e-3)}, th)
    assert rep.kinds == ["backlash"] and rep.estimates["backlash_um"] == pytest.approx(20, rel=0.05)
    # a 30 Hz ringing instead
    r = 0.01 * np.sin(2 * np.pi * 30 * t) * np.exp(-((t % 0.7) / 0.1))
    rep = compare_models(_sig(), _sig(), errs, {"tool": (r, cmd, 1e-3)}, th)
    assert rep.kinds == ["resonance"] and rep.estimates["resonance_hz"] == pytest.approx(30, rel=0.05)
    # parameters that move while the old model still predicts the new traces: evidence, no flag
    rep = compare_models(_sig(), _sig(peak=19.0, poles=((-10.0, 0.0), (-5.0, 60.0))), flat, {}, th)
    assert not rep.changed and len(rep.evidence) == 2 and "not flagged" in rep.evidence[1]
    # the prediction got worse, poles moved, no friction change, no shape: "dynamics"
    grown = {"motor": {"old_on_old": 0.5, "old_on_new": 3.0, "new_on_new": 0.6}}
    rep = compare_models(_sig(), _sig(poles=((-10.0, 0.0), (-5.0, 60.0))), grown, {}, th)
    assert rep.kinds == ["dynamics"] and any("poles moved" in e for e in rep.evidence)
    # an effect diagnosis added
    rep = compare_models(_sig(), _sig(effects=["mode@31.0Hz"]), flat, {}, th)
    assert rep.kinds == ["resonance"] and rep.estimates["resonance_hz"] == 31.0


def test_residual_signature_separates_shapes():
    t, cmd = _moves()
    s = residual_signature(0.01 * direction_of_motion(cmd), cmd, 1e-3)
    assert s["direction_r2"] > 0.99
    s = residual_signature(0.01 * np.sin(2 * np.pi * 30 * t), cmd, 1e-3)
    assert s["direction_r2"] < 0.1 and abs(s["peak_hz"] - 30) < 1 and s["peak_fraction"] > 0.5
