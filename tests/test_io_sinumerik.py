"""SINUMERIK SAT servo-trace XML: base-85 decoding, time series, speed-loop FRF, stored spectra."""
import struct

import numpy as np
import pytest

from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.io.sinumerik import (ALPHABET, decode_base85, decode_base85_words, read_sinumerik_spectra,
                                   read_sinumerik_trace, speed_loop_frf)


def encode_word(w):
    digits = []
    for _ in range(5):
        w, d = divmod(w, 85)
        digits.append(ALPHABET[d])
    return "".join(reversed(digits))


def encode(values):
    words = struct.unpack(">%dI" % (2 * len(values)), struct.pack(">%dd" % len(values), *values))
    return "".join("." if w == 0 else encode_word(w) for w in words)


def test_alphabet():
    assert len(ALPHABET) == 85 and len(set(ALPHABET)) == 85 and "." not in ALPHABET


def test_base85_round_trip_and_zero_words():
    vals = [0.0, 1.0, -0.2094395102393195, 1e-300, 123456.789, 2.0 ** 40]
    text = encode(vals)
    assert text.startswith("..")                          # 0.0 = two zero words
    np.testing.assert_array_equal(decode_base85(text), vals)
    np.testing.assert_array_equal(decode_base85(" \n".join([text[:7], text[7:]])), vals)  # whitespace
    z = decode_base85(encode([1.5, -2.5, 0.0, 4.0]), complex_=True)
    np.testing.assert_array_equal(z, [1.5 - 2.5j, 4.0j])


def test_base85_errors():
    with pytest.raises(InputError, match="32 bits"):
        decode_base85_words("~~~~~")                      # 85^5 - 1 > 2^32 - 1
    with pytest.raises(InputError, match="incomplete group"):
        decode_base85("0000")
    with pytest.raises(InputError, match="not a multiple of 2"):
        decode_base85("00001")
    with pytest.raises(InputError, match="not in the base-85 alphabet"):
        decode_base85("00\"01..")
    with pytest.raises(InputError, match="not in the base-85 alphabet"):
        decode_base85("0\u00b5001..")


@pytest.fixture(scope="module")
def xml(shared_data):
    return shared_data / "sinumerik_trace" / "freq_trace.XML"


@pytest.fixture(scope="module")
def sat(xml):
    return read_trace(xml)


def test_time_series(sat):
    assert sat.n == 2047 and sat.Ts == pytest.approx(125e-6)
    assert sat.t[-1] == pytest.approx(0.25575)
    assert sat.roles == {}
    assert sorted(sat.channels) == ["speed_actual_neg", "speed_actual_pos",
                                    "speed_setpoint_neg", "speed_setpoint_pos"]
    assert all(c.unit == "rad_s" for c in sat.channels.values())
    assert (sat.meta["input_node"], sat.meta["output_node"]) == (62, 61)
    for d, sign in (("pos", 1), ("neg", -1)):
        u = sat.extra(f"speed_setpoint_{d}")
        # binary PRBS: two levels, 0.419 +- 0.209 rad/s (4 +- 2 rpm)
        np.testing.assert_allclose(np.unique(np.round(sign * u, 6)), [0.209442, 0.628316], atol=1e-6)
        y = sat.extra(f"speed_actual_{d}")
        assert np.mean(sign * y) == pytest.approx(0.419, abs=0.01)
    assert sat.meta["excitation"]["prbs_order"] == 11 and 2 ** 11 - 1 == sat.n


def test_speed_loop_gain_from_time_series(sat):
    frf = speed_loop_frf(sat, [20.0, 100.0])
    # nearest DFT bins of the 2047-sample record: k = 5, 26 -> 19.54 Hz, 101.61 Hz
    np.testing.assert_allclose(frf.freq_hz, np.array([5, 26]) * 8000 / 2047)
    # README: ~0.98 at 20 Hz, ~0.5 at 100 Hz. Tolerances = the precision those figures are
    # stated to (2 decimals: +-0.02; 1 decimal: +-0.05). Measured 0.976 and 0.498.
    assert frf.gain[0] == pytest.approx(0.98, abs=0.02)
    assert frf.gain[1] == pytest.approx(0.5, abs=0.05)
    assert -30 < frf.phase_deg[0] < -15 and -110 < frf.phase_deg[1] < -80   # a lag, as a loop must
    assert frf.n_avg == 2 and np.all(frf.coherence > 0.99)
    # all bins: a low-pass with ~55-60 Hz bandwidth (README). The raw gain is ragged from bin
    # to bin (SAT's own stored H is too), so take the -3 dB crossing of a 5-bin moving average.
    full = speed_loop_frf(sat)
    g = np.convolve(full.gain, np.ones(5) / 5, mode="same")
    bw = full.freq_hz[2 + np.argmax(g[2:] < 1 / np.sqrt(2))]   # measured: 54.7 Hz
    assert 45 < bw < 65


def test_speed_loop_gain_per_direction(sat):
    for d in ("pos", "neg"):
        from fdid_fmi.trace import Trace
        one = Trace(t=sat.t, channels={k: c for k, c in sat.channels.items() if k.endswith(d)})
        g = speed_loop_frf(one, [20.0, 100.0]).gain
        assert g[0] == pytest.approx(0.98, abs=0.02) and g[1] == pytest.approx(0.5, abs=0.05)


def test_stored_spectra_match_decoded_time_series(xml, sat):
    sp = read_sinumerik_spectra(xml)
    assert (sp.input_node, sp.output_node, sp.n_avg) == (62, 61, 2)
    assert sp.S_uu.size == 1023 and sp.freq_hz[-1] == pytest.approx(4000.0)
    # SAT's spectra = 4/N^2 * mean over the 2 runs of U conj(U), Y conj(Y), U conj(Y) at bins k
    N = sat.n
    U = [np.fft.rfft(sat.extra(f"speed_setpoint_{d}"))[:1023] for d in ("pos", "neg")]
    Y = [np.fft.rfft(sat.extra(f"speed_actual_{d}"))[:1023] for d in ("pos", "neg")]
    scale = 4 / N ** 2 / 2
    np.testing.assert_allclose(sp.S_uu, scale * sum(abs(u) ** 2 for u in U), rtol=1e-9)
    np.testing.assert_allclose(sp.S_yy, scale * sum(abs(y) ** 2 for y in Y), rtol=1e-9)
    np.testing.assert_allclose(sp.S_uy, scale * sum(u * np.conj(y) for u, y in zip(U, Y)),
                               rtol=1e-9, atol=1e-12 * np.max(np.abs(sp.S_uy)))
    frf = speed_loop_frf(sat)
    np.testing.assert_allclose(sp.H[1:1023], frf.H[:1022], rtol=1e-9)
    # SAT labels bin k as k*4000/1022 Hz; the DFT bin is k*8000/2047 Hz
    np.testing.assert_allclose(sp.bin_hz[26], 101.612, atol=1e-3)
    np.testing.assert_allclose(sp.freq_hz[26], 101.761, atol=1e-3)


def test_sinumerik_errors(tmp_path, sat):
    p = tmp_path / "other.xml"
    p.write_text("<?xml version='1.0'?><root><float name='a'>1</float></root>")
    with pytest.raises(InputError, match="not a SINUMERIK SAT"):
        read_sinumerik_trace(p)
    p.write_text("<root><unclosed></root>")
    with pytest.raises(InputError, match="not well-formed XML"):
        read_trace(p)
    with pytest.raises(InputError, match="Nyquist"):
        speed_loop_frf(sat, [5000.0])
    with pytest.raises(InputError, match="fixed channels"):
        read_trace(tmp_path / "other.xml", mapping={"x.cmd": "a"})


@pytest.mark.parametrize("edit,words", [
    (lambda t: t.replace('<unsigned_int name="m_uNodeId">61<', '<unsigned_int name="m_uNodeId">sixtyone<', 1),
     ["m_uNodeId", "'sixtyone'", "integer"]),
    (lambda t: t.replace('<float name="m_dProcessUpdateTime">0.000125<',
                         '<float name="m_dProcessUpdateTime">1,25e-4<', 1), ["m_dProcessUpdateTime", "number"]),
    (lambda t: t.replace('name="m_ValueVector"', 'name="m_Other"', 1), ["m_ValueVector", "missing"]),
    (lambda t: t.replace('encoding="ISO-8859-1"', 'encoding="x-bogus"', 1), ["cannot be decoded", "x-bogus"]),
    (lambda t: t.replace('<unsigned_int name="m_uNodeId">62<', '<unsigned_int name="m_uNodeId">61<', 1),
     ["node id 61", "twice"]),
])
def test_a_damaged_export_is_one_error_line(xml, tmp_path, edit, words):
    """Damage an export the reader does not expect (each one would escape as a
    ValueError, AttributeError or LookupError): one InputError naming what is wrong."""
    text = xml.read_bytes().decode("latin-1")
    damaged = edit(text)
    assert damaged != text
    p = tmp_path / "damaged.xml"
    p.write_bytes(damaged.encode("latin-1"))
    with pytest.raises(InputError) as exc:
        read_trace(p)
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_identify_on_the_frequency_response_trace_says_what_it_is(shared_data, capsys, tmp_path):
    """Not 'no axis with both cmd and act channels; use --map' (--map is refused for a SINUMERIK
    XML): the message says what the file is and what reads it."""
    from cli_support import one_line, run_cli
    xml = shared_data / "sinumerik_trace" / "freq_trace.XML"
    code, _, err = run_cli(capsys, "identify", xml, "-o", tmp_path / "m.json")
    line = one_line(code, err, "freq_trace.XML", "speed-loop frequency-response measurement", "speed_loop_frf")
    assert "--map" not in line
