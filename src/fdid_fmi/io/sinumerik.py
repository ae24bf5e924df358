"""Siemens SINUMERIK servo-trace XML (SAT frequency-response export) reader.

File layout (found by decoding ``freq_trace.XML``, SAT 4.7.6): XML elements carry typed
members (``<float name=...>``, ``<unsigned_int name=...>``, ...). Each
``PlatformSignalNode`` (``m_uNodeId``) holds a list of ``TimeSeries`` (one per run
direction), an auto-spectrum and cross-spectra. Numeric arrays (``NumericArray``,
``format="base85"``) are text in the 85-symbol alphabet ``ALPHABET``: 5 characters give
one 32-bit big-endian word (most significant digit first), a lone ``.`` is a zero word,
two words are one big-endian float64, and complex arrays interleave re, im.
``m_listPrimaryFreqRespSigNodeData`` says which node is the input (excitation) and which
the output, by ``m_iUniqueInstanceId``.

For the speed-loop measurement in the test data the input is node 62, the speed
setpoint (PRBS of order 11: one period = 2047 samples at 8 kHz, +-0.209 rad/s around
+-0.419 rad/s = 4 rpm), and the output node 61, the actual motor speed. Speeds are in
rad/s (SI, as SAT stores them: the offset 0.4189 is exactly 4 rpm).

``read_sinumerik_trace`` returns these as a ``Trace`` with **no axis roles** -- the file
holds motor speeds, not the positions the identifiers use -- and extra channels

* ``speed_setpoint_pos``, ``speed_actual_pos`` (run in + direction), rad/s
* ``speed_setpoint_neg``, ``speed_actual_neg`` (run in - direction), rad/s

on the common time base of both runs (0 ... 0.25575 s, Ts = 125 us). The direction is
taken from the sign of the setpoint's mean (``run1``, ``run2``, ... if that is ambiguous).

``speed_loop_frf`` estimates the closed speed-loop response actual/setpoint (H1, thesis
and SAT convention: averaged cross-spectrum over averaged input auto-spectrum, one average
per direction) at the DFT bins k * fs / N of the full record. Because the record is
exactly one PRBS period this estimate is free of leakage. ``read_sinumerik_spectra``
decodes the spectra SAT stored, for a cross-check: they equal 4/N^2 * mean over
directions of U conj(U), Y conj(Y) and U conj(Y) at bins k = 0..1022 of the N = 2047 point
DFT (note the conjugate order, and that SAT's stored frequency vector is
linspace(0, fs/2, 1023), which labels bin k as k*4000/1022 Hz instead of k*8000/2047 Hz,
up to 0.2 % off).
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..trace import Channel, Trace
from .common import check_file, file_sha256

ALPHABET = ("0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
            "!#$`()*+-/:;=?@[]^_{|}~")
_LUT = np.full(256, -1, dtype=np.int64)
for _i, _c in enumerate(ALPHABET):
    _LUT[ord(_c)] = _i
_TOKEN = re.compile(r"\.|[^.]{1,5}")


# ----------------------------------------------------------------------------- base-85
def decode_base85_words(text, *, source=None, name=None) -> np.ndarray:
    """Decode SAT base-85 text into 32-bit words (uint32).

    5 symbols of ``ALPHABET`` -> one word, value = sum d_i 85^(4-i); ``.`` -> 0.
    Whitespace is ignored.
    """
    s = "".join((text or "").split())
    toks = _TOKEN.findall(s)
    words = np.zeros(len(toks), dtype=np.uint64)
    full = [i for i, tok in enumerate(toks) if tok != "."]
    if full:
        bad = [toks[i] for i in full if len(toks[i]) != 5]
        if bad:
            raise InputError(f"base-85 array ends with an incomplete group '{bad[0]}' (5 symbols "
                             f"expected)", source=source, column=name)
        joined = "".join(toks[i] for i in full)
        codes = np.fromiter(map(ord, joined), dtype=np.int64, count=len(joined))
        digits = np.where(codes < 256, _LUT[np.minimum(codes, 255)], -1).reshape(-1, 5)
        if (digits < 0).any():
            ch = joined[int(np.argmax(digits.ravel() < 0))]
            raise InputError(f"symbol {ch!r} is not in the base-85 alphabet", source=source, column=name)
        vals = digits @ (85 ** np.arange(4, -1, -1, dtype=np.int64))
        if (vals > 0xFFFFFFFF).any():
            raise InputError("base-85 group exceeds 32 bits", source=source, column=name)
        words[full] = vals.astype(np.uint64)
    return words.astype(np.uint32)


def decode_base85(text, *, complex_=False, source=None, name=None) -> np.ndarray:
    """Decode a SAT base-85 numeric array into float64 (or complex128 when ``complex_``).

    Two big-endian 32-bit words -> one big-endian IEEE float64; complex arrays
    interleave real and imaginary parts.
    """
    words = decode_base85_words(text, source=source, name=name)
    per = 4 if complex_ else 2
    if words.size % per:
        raise InputError(f"base-85 array has {words.size} words, not a multiple of {per}",
                         source=source, column=name)
    vals = words.astype(">u4").tobytes()
    x = np.frombuffer(vals, dtype=">f8").astype(float)
    if complex_:
        return x[0::2] + 1j * x[1::2]
    return x


# ----------------------------------------------------------------------------- XML access
def _member(elem, tag, name, cast=float, default=None, source=None):
    m = elem.find(f"{tag}[@name='{name}']")
    if m is None or m.text is None:
        if default is not None:
            return default
        raise InputError(f"<{elem.tag}> has no member <{tag} name='{name}'>", source=source, column=name)
    try:
        return cast(m.text.strip())
    except ValueError:
        raise InputError(f"<{tag} name='{name}'> is {m.text.strip()[:40]!r}, not "
                         f"{'an integer' if cast is int else 'a number'}", source=source, column=name) from None


def _array(na, source, what="NumericArray"):
    """Decode one ``NumericArray`` element, checking its ``m_length``."""
    if na is None:
        raise InputError(f"a {what} element is missing", source=source, column=what)
    name = na.get("name")
    cplx = na.get("elementtype") == "ComplexNumber"
    if na.get("format", "base85") != "base85":
        raise InputError(f"array format '{na.get('format')}' is not supported (base85 only)",
                         source=source, column=name)
    length = _member(na, "unsigned_int", "m_length", int, source=source)
    raw = na.find("raw")
    x = decode_base85(raw.text if raw is not None else "", complex_=cplx, source=source, name=name)
    if x.size != length:
        raise InputError(f"decoded {x.size} values but m_length says {length}", source=source, column=name)
    return x


def _load_root(path):
    p = check_file(path)
    try:
        root = ET.parse(str(p)).getroot()
    except ET.ParseError as exc:
        raise InputError(f"is not well-formed XML ({exc})", source=str(p)) from None
    except (ValueError, LookupError) as exc:    # an encoding the parser does not know
        raise InputError(f"cannot be decoded as XML ({exc})", source=str(p)) from None
    if root.find(".//PlatformSignalNode") is None:
        raise InputError(f"is not a SINUMERIK SAT servo-trace export (root <{root.tag}> has no "
                         f"PlatformSignalNode)", source=str(p))
    return p, root


@dataclass
class _Node:
    node_id: int
    instance_id: int
    series: list          # list of (t_start, t_end, values)
    auto: np.ndarray = None
    freq: np.ndarray = None
    n_avg: int = 0
    cross: dict = field(default_factory=dict)  # other node id -> complex array


def _nodes(root, src):
    out = {}
    for n in root.iter("PlatformSignalNode"):
        nid = _member(n, "unsigned_int", "m_uNodeId", int, source=src)
        if nid in out:      # a later node would silently replace the earlier one
            raise InputError(f"signal node id {nid} appears twice", source=src, column=f"node{nid}")
        inst = _member(n, "integer", "m_iUniqueInstanceId", int, default=-1, source=src)
        series = []
        lst = n.find("LinkedList[@name='m_TimeSeriesList']")
        for ts in (lst if lst is not None else []):
            vals = _array(ts.find("NumericArray[@name='m_ValueVector']"), src, f"node {nid} m_ValueVector")
            t0 = _member(ts, "float", "m_TimeVector.start", source=src)
            t1 = _member(ts, "float", "m_TimeVector.end", source=src)
            tl = _member(ts, "unsigned_int", "m_TimeVector.length", int, source=src)
            if tl != vals.size:
                raise InputError(f"node {nid}: time vector length {tl} but {vals.size} values",
                                 source=src, column=f"node{nid}")
            series.append((t0, t1, vals))
        node = _Node(nid, inst, series)
        auto = n.find("SigNodeCrossSpectrumInfo[@name='m_autospectrumInfo']")
        if auto is not None:
            cs = auto.find("CrossSpectrum")
            if cs is None:
                raise InputError(f"node {nid}: its autospectrum has no <CrossSpectrum>", source=src,
                                 column=f"node{nid}")
            node.auto = _array(cs.find("NumericArray[@name='m_ValueVector']"), src, f"node {nid} autospectrum")
            node.freq = _array(cs.find("NumericArray[@name='m_FrequencyVector']"), src, f"node {nid} frequencies")
            node.n_avg = _member(auto, "unsigned_int", "m_uNumSpectraInAvg", int, default=0, source=src)
        cl = n.find("LinkedList[@name='m_crossSpecInfoList']")
        for el in (cl if cl is not None else []):
            other = _member(el, "unsigned_int", "m_uSignodeId", int, source=src)
            node.cross[other] = _array(el.find("CrossSpectrum/NumericArray[@name='m_ValueVector']"), src,
                                       f"node {nid} cross-spectrum")
        out[nid] = node
    return out


def _io_nodes(root, nodes, src):
    """(input node id, output node id) from m_listPrimaryFreqRespSigNodeData."""
    el = root.find(".//PrimaryFreqRespSigNodeData")
    by_inst = {n.instance_id: n.node_id for n in nodes.values()}
    if el is not None:
        i = _member(el, "integer", "m_iInputSigNodeUniqueInstanceID", int, source=src)
        o = _member(el, "integer", "m_iOutputSigNodeUniqueInstanceID", int, source=src)
        if i in by_inst and o in by_inst:
            return by_inst[i], by_inst[o]
    if {61, 62} <= set(nodes):
        return 62, 61
    raise InputError(f"cannot tell the input and output signal nodes apart (nodes {sorted(nodes)})",
                     source=src)


def _scalars(root):
    out = {}
    for m in root:
        if m.tag in ("float", "unsigned_int", "integer") and m.get("name") and m.text:
            try:
                out[m.get("name")] = float(m.text)
            except ValueError:
                pass
        elif m.tag in ("boolean", "string") and m.get("name"):
            out[m.get("name")] = (m.text or "").strip()
    return out


# ----------------------------------------------------------------------------- public API
def read_sinumerik_trace(path) -> Trace:
    """Read the time series of a SINUMERIK SAT frequency-response XML export.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Trace
        No axis roles; extra channels ``speed_setpoint_<dir>`` (input node) and
        ``speed_actual_<dir>`` (output node) in rad/s, ``<dir>`` = ``pos``/``neg``.
        ``meta``: ``sha256``, ``Ts_file`` (m_dProcessUpdateTime), ``input_node``,
        ``output_node``, ``directions``, ``excitation`` (offset, amplitude in rad/s,
        PRBS order), ``motor_to_axis_ratio`` (m_dMotorToAxisRatio as stored), ``members``
        (top-level scalar members), ``date``.
    """
    p, root = _load_root(path)
    src = str(p)
    nodes = _nodes(root, src)
    nin, nout = _io_nodes(root, nodes, src)
    sin, sout = nodes[nin].series, nodes[nout].series
    if not sin or len(sin) != len(sout):
        raise InputError(f"input node {nin} has {len(sin)} time series, output node {nout} has "
                         f"{len(sout)}; expected the same number (one per direction)", source=src)
    t0, t1, n = sin[0][0], sin[0][1], sin[0][2].size
    if n < 2:
        raise InputError(f"the time series have {n} sample(s); a trace needs at least 2", source=src)
    for k, (a, b) in enumerate(zip(sin, sout)):
        for s in (a, b):
            if s[2].size != n or not np.isclose(s[0], t0) or not np.isclose(s[1], t1):
                raise InputError(f"time series {k + 1} does not share the time base of the first "
                                 f"({t0}..{t1} s, {n} samples)", source=src)
    Ts_file = _member(root, "float", "m_dProcessUpdateTime", source=src)
    t = t0 + (t1 - t0) / (n - 1) * np.arange(n)
    if not np.isclose((t1 - t0) / (n - 1), Ts_file, rtol=1e-6):
        raise InputError(f"time vector step {float((t1 - t0) / (n - 1))!r} s differs from "
                         f"m_dProcessUpdateTime {float(Ts_file)!r} s", source=src)
    means = [float(np.mean(s[2])) for s in sin]
    if len(sin) == 2 and means[0] * means[1] < 0:
        dirs = ["pos" if m > 0 else "neg" for m in means]
    else:
        dirs = [f"run{k + 1}" for k in range(len(sin))]
    channels = {}
    for d, a, b in zip(dirs, sin, sout):
        channels[f"speed_setpoint_{d}"] = Channel(f"speed_setpoint_{d}", "rad_s", a[2])
        channels[f"speed_actual_{d}"] = Channel(f"speed_actual_{d}", "rad_s", b[2])
    members = _scalars(root)
    exc = root.find(".//ExcitationSource")
    excitation = {}
    if exc is not None:
        cond = exc.find(".//ExcitationSourceCondition")
        excitation = {
            "prbs_order": _member(exc, "unsigned_int", "m_uPrbsOrder", int, default=0, source=src),
            "offset_rad_s": _member(cond, "float", "m_dOffsetAmplitude", default=np.nan, source=src)
            if cond is not None else np.nan,
            "amplitude_rad_s": _member(cond, "float", "m_dExcitationAmplitude", default=np.nan,
                                       source=src) if cond is not None else np.nan,
        }
        ratio = _member(exc, "float", "m_dMotorToAxisRatio", default=np.nan, source=src)
    else:
        ratio = np.nan
    stamp = root.find("SatTimeStamp")
    meta = {
        "file": src, "sha256": file_sha256(p), "layout": "sinumerik-sat",
        "Ts_file": Ts_file, "input_node": nin, "output_node": nout, "directions": dirs,
        "excitation": excitation, "motor_to_axis_ratio": ratio, "members": members,
        "date": None if stamp is None else _member(stamp, "unsigned_int", "Date", int, default=0),
        "version": root.get("ver"),
    }
    return Trace(t=t, channels=channels, roles={}, source=src, meta=meta)


@dataclass
class FRF:
    """A frequency response estimate.

    Attributes
    ----------
    freq_hz : ndarray, Hz (the DFT bin frequencies actually used)
    H : ndarray, complex, output/input
    coherence : ndarray, in [0, 1] (1 when only one run is averaged)
    n_avg : int, number of runs averaged
    bins : ndarray of int, DFT bin index k (freq = k * fs / N)
    """

    freq_hz: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    n_avg: int
    bins: np.ndarray

    @property
    def gain(self):
        return np.abs(self.H)

    @property
    def phase_deg(self):
        return np.angle(self.H, deg=True)


def speed_loop_frf(source, freqs_hz=None, *, input="speed_setpoint", output="speed_actual") -> FRF:
    """Closed speed-loop frequency response actual/setpoint, H1 estimate over the runs.

    H1(f_k) = sum_d conj(U_d(k)) Y_d(k) / sum_d |U_d(k)|^2, with U_d, Y_d the DFTs of the
    whole record of run d (mean removed). The record must hold a whole number of
    excitation periods (true for SAT PRBS records: N = 2^order - 1), or the estimate leaks.

    Parameters
    ----------
    source : Trace or path
        A trace from ``read_sinumerik_trace`` (or any trace with channels
        ``<input>_<dir>`` / ``<output>_<dir>``), or the XML path.
    freqs_hz : sequence of float, optional
        Frequencies wanted; each gives the nearest DFT bin k * fs / N (see ``FRF.freq_hz``
        for the bins used). Default: all bins 1 .. N//2.
    input, output : str
        Channel name stems.

    Returns
    -------
    FRF
    """
    tr = source if isinstance(source, Trace) else read_sinumerik_trace(source)
    pairs = []
    for name in tr.channels:
        if name.startswith(input + "_"):
            d = name[len(input) + 1:]
            if f"{output}_{d}" not in tr.channels:
                raise InputError(f"channel '{name}' has no matching '{output}_{d}'", source=tr.source,
                                 column=name)
            pairs.append((tr.channels[name].data, tr.channels[f"{output}_{d}"].data))
    if not pairs:
        raise InputError(f"no channels named '{input}_<run>' (channels: {sorted(tr.channels)})",
                         source=tr.source, column=input)
    n = tr.n
    fs = 1.0 / tr.Ts
    if freqs_hz is None:
        bins = np.arange(1, n // 2 + 1)
    else:
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        if not np.all(np.isfinite(f)) or (f <= 0).any() or (f > fs / 2).any():
            raise InputError(f"frequencies must lie in (0, {fs / 2:g}] Hz (Nyquist), got {f.tolist()}",
                             source=tr.source, column="freqs_hz")
        bins = np.clip(np.rint(f * n / fs).astype(int), 1, n // 2)
    Suy = np.zeros(bins.size, complex)
    Suu = np.zeros(bins.size)
    Syy = np.zeros(bins.size)
    for u, y in pairs:
        U = np.fft.rfft(u - u.mean())[bins]
        Y = np.fft.rfft(y - y.mean())[bins]
        Suy += np.conj(U) * Y
        Suu += np.abs(U) ** 2
        Syy += np.abs(Y) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Suy / Suu
        coh = np.abs(Suy) ** 2 / (Suu * Syy)
    return FRF(freq_hz=bins * fs / n, H=H, coherence=coh, n_avg=len(pairs), bins=bins)


@dataclass
class StoredSpectra:
    """Spectra as SAT stored them in the XML.

    Attributes
    ----------
    freq_hz : ndarray, SAT's frequency vector (linspace(0, fs/2, 1023) in the test file)
    bin_hz : ndarray, true DFT bin frequencies k * fs / N of the time records
    S_uu, S_yy : ndarray, auto-spectra of input and output (real)
    S_uy : ndarray, complex, the stored cross-spectrum U conj(Y) (SAT's order)
    H : ndarray, complex, conj(S_uy) / S_uu = output/input (H1, causal phase sign)
    n_avg : int
    input_node, output_node : int
    """

    freq_hz: np.ndarray
    bin_hz: np.ndarray
    S_uu: np.ndarray
    S_yy: np.ndarray
    S_uy: np.ndarray
    H: np.ndarray
    n_avg: int
    input_node: int
    output_node: int


def read_sinumerik_spectra(path) -> StoredSpectra:
    """Decode the averaged spectra SAT stored in the XML (for cross-checks).

    The cross-spectrum of the output node with the input node is taken from the output
    node's ``m_crossSpecInfoList``.
    """
    p, root = _load_root(path)
    src = str(p)
    nodes = _nodes(root, src)
    nin, nout = _io_nodes(root, nodes, src)
    a, b = nodes[nin], nodes[nout]
    if a.auto is None or b.auto is None or nin not in b.cross:
        raise InputError(f"the file stores no spectra for nodes {nin}/{nout}", source=src)
    n = a.series[0][2].size if a.series else 2 * (a.auto.size - 1)
    Ts = _member(root, "float", "m_dProcessUpdateTime", source=src)
    S_uy = b.cross[nin]
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.conj(S_uy) / a.auto.real
    return StoredSpectra(freq_hz=a.freq, bin_hz=np.arange(a.auto.size) / (n * Ts),
                         S_uu=a.auto.real, S_yy=b.auto.real, S_uy=S_uy, H=H, n_avg=a.n_avg,
                         input_node=nin, output_node=nout)


def is_sinumerik_file(path) -> bool:
    return Path(path).suffix.lower() == ".xml"
