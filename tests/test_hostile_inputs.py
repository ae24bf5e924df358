"""Property-based hostile inputs: random bytes as trace / model / FMU files, random JSON shapes as
models. Each ends in a result or an ``FdidError`` (one line at the CLI) -- never another exception
-- and the input file is never changed."""
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from fdid_fmi.errors import FdidError
from fdid_fmi.io import read_trace
from fdid_fmi.model import DriveModel, QuasiStaticModel, load_model
from fdid_fmi.trace import Trace

SETTINGS = settings(max_examples=30, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _read_or_refuse(fn, path):
    before = path.read_bytes()
    try:
        out = fn(path)
    except FdidError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg and "np.float64" not in msg, msg
        out = None
    assert path.read_bytes() == before
    return out


@SETTINGS
@pytest.mark.parametrize("ext", [".csv", ".txt", ".mat", ".xml"])
@given(data=st.binary(min_size=1, max_size=2000))
def test_random_bytes_as_trace(tmp_path, ext, data):
    p = tmp_path / f"r{ext}"
    p.write_bytes(data)
    out = _read_or_refuse(read_trace, p)
    assert out is None or isinstance(out, Trace)


_cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=6),
                  st.integers().map(str), st.just(""))


@SETTINGS
@given(header=st.lists(st.text(max_size=8), min_size=1, max_size=5),
       rows=st.lists(st.lists(_cell, min_size=1, max_size=5), max_size=8),
       delim=st.sampled_from([",", ";", "\t", " "]))
def test_random_csv_shapes(tmp_path, header, rows, delim):
    p = tmp_path / "t.csv"
    p.write_text("\n".join(delim.join(r) for r in [header] + rows) + "\n", encoding="utf-8",
                 errors="surrogatepass")
    out = _read_or_refuse(read_trace, p)
    if out is not None:
        assert np.all(np.isfinite(out.t)) and np.all(np.diff(out.t) > 0)


_json = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
                     lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=5), kids,
                                                                               max_size=4),
                     max_leaves=20)
_model_keys = ("Ts", "A", "B", "C", "D", "inputs", "outputs", "method", "poles", "gains", "cutoff_hz",
               "order", "kind")


@SETTINGS
@given(extra=st.dictionaries(st.sampled_from(_model_keys), _json, max_size=8))
def test_random_json_shapes_as_model(tmp_path, extra):
    d = {"format": "fdid-fmi-model", "format_version": 1, **extra}
    p = tmp_path / "m.json"
    p.write_text(json.dumps(d))
    out = _read_or_refuse(load_model, p)
    assert out is None or isinstance(out, (DriveModel, QuasiStaticModel))


@SETTINGS
@given(port=st.dictionaries(st.sampled_from(["name", "unit", "kind", "axis", "params", "description"]),
                            _json, max_size=6),
       which=st.sampled_from(["inputs", "outputs"]))
def test_random_port_fields(tmp_path, port, which):
    """One port of a valid model replaced by random fields."""
    d = {"format": "fdid-fmi-model", "format_version": 1, "kind": "state_space", "Ts": 1e-3,
         "A": [[0.9]], "B": [[0.1, 1e-4]], "C": [[1.0], [-1.0]], "D": [[0.0, 0.0], [1.0, 0.0]],
         "inputs": [{"name": "x_cmd", "unit": "mm", "kind": "command", "axis": "x"},
                    {"name": "x_dnf", "unit": "1", "kind": "friction", "axis": "x",
                     "params": {"v_tilde": 1.0, "level": 0.5}}],
         "outputs": [{"name": "x_pos", "unit": "mm", "kind": "position", "axis": "x"},
                     {"name": "x_err", "unit": "mm", "kind": "error", "axis": "x"}]}
    d[which][1] = port
    p = tmp_path / "m.json"
    p.write_text(json.dumps(d))
    _read_or_refuse(load_model, p)


@SETTINGS
@given(data=st.binary(min_size=1, max_size=3000))
def test_random_bytes_as_model_file(tmp_path, data):
    p = tmp_path / "m.json"
    p.write_bytes(data)
    assert _read_or_refuse(load_model, p) is None


@SETTINGS
@given(tokens=st.lists(st.text(max_size=12), max_size=4))
@example(tokens=["\n"])              # found by this test: the token was echoed with its line break
def test_random_map_tokens(tokens):
    """--map tokens: a mapping whose axis names are identifiers, or one-line InputError."""
    import re

    from fdid_fmi.pipeline.traces import parse_mapping
    try:
        out = parse_mapping(tokens)
    except FdidError as exc:
        assert "\n" not in str(exc)
        return
    for key in out:
        assert key == "t" or re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*\.(cmd|act|tool|vel|acc|cur|err)", key)


def test_xml_entity_bomb_is_refused(tmp_path):
    p = tmp_path / "bomb.xml"
    ents = "".join(f'<!ENTITY l{k} "{("&l%d;" % (k - 1)) * 10 if k else "lol" * 20}">' for k in range(10))
    p.write_text(f'<?xml version="1.0"?><!DOCTYPE b [{ents}]><b>&l9;</b>')
    with pytest.raises(FdidError, match="bomb.xml"):
        read_trace(p)
