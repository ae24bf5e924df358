"""``DriveModel``: the identified drive as an unscaled discrete MIMO state space with friction.

The LTI part (thesis Eqn 5.18-5.25, returned UNSCALED) is

    xi[k+1] = A xi[k] + B u[k]
    y[k]    = C xi[k] + D u[k]

with inputs ``u`` and outputs ``y`` described by :class:`Port` lists. Input kinds:

``command``   commanded position x_r of an axis (mm); an FMU input.
``external``  a measured extra input (e.g. EMPS ``pulses_N``); an FMU input.
``friction``  normalised Coulomb friction d_nf = L * sat(v / v_tilde) (Eqn 4.12-4.13), closed
              around the model's own velocity v of the axis and solved exactly at each step.
``feature``   a nonlinear function of the previous step's velocity or of the position
              (``params["function"]``: ``sat``, ``abs_sat``, ``stribeck``, ``sin_position``,
              ``cos_position``, ``play``, ``play_stribeck``); used by effects that diagnosis
              adds and by the structure choice. ``play`` is the play (backlash) operator of the
              model's own position x with half-width b = ``width_mm``: h_k = min(max(h_k-1,
              x_k - b), x_k + b), value (x_k - h_k) / b in [-1, 1], a friction force that builds
              up over the travel 2b after each reversal (presliding) instead of over a velocity
              band. ``play_stribeck`` is that value times exp(-(v / v_s)^2): the breakaway
              excess of a play-law axis, which like the play holds at rest (``stribeck`` is
              the sat law's, s exp(-(v / v_s)^2) with s = sat(v / v_tilde)).

Output kinds: ``position`` (required per axis), ``error`` (x_r - x), ``velocity``,
``tool_position``, ``acceleration``, ``other``. The simulation semantics that use these
live in :mod:`fdid_fmi.simulate`; the FMU implements exactly the same.

Models are saved as versioned JSON (:meth:`DriveModel.save` / :func:`load_model`).
"""
from __future__ import annotations

import copy
import json
import re
import unicodedata
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError, finite_number

FORMAT = "fdid-fmi-model"
FORMAT_VERSION = 3          # 2: causal models (no same-sample response to commands);
                            # 3: ``limits``, the feed, acceleration and jerk per axis seen in the
                            #    identification traces (older files load with none)
LIMIT_KEYS = ("v_mm_s", "a_mm_s2", "j_mm_s3")
INPUT_KINDS = ("command", "external", "friction", "feature")
OUTPUT_KINDS = ("position", "error", "velocity", "tool_position", "acceleration", "other")
FEATURE_FUNCTIONS = ("sat", "abs_sat", "stribeck", "sin_position", "cos_position", "play", "play_stribeck")
PLAY_FUNCTIONS = ("play", "play_stribeck")      # features with a play operator's state
LIBM_FUNCTIONS = ("stribeck", "play_stribeck", "sin_position", "cos_position")   # exp / sin / cos
FEATURE_NUMBERS = {"v_tilde": "mm/s", "v_s": "mm/s", "period_mm": "mm", "width_mm": "mm"}
FEATURE_NEEDS = {"sat": ("v_tilde",), "abs_sat": ("v_tilde",), "stribeck": ("v_tilde", "v_s"),
                 "sin_position": ("period_mm",), "cos_position": ("period_mm",), "play": ("width_mm",),
                 "play_stribeck": ("width_mm", "v_s")}      # the numbers each function reads


def is_play(inp):
    """True for a play (presliding friction) feature input: a :class:`Port` of a model or an input
    of an identification structure (both carry ``kind`` and ``params``)."""
    return inp.kind == "feature" and inp.params.get("function") == "play"


def delayed_input(kind, params):
    """True for an input from outside the drive: a command, a measured external input, or a
    feature computed from the command. A sampled drive answers such an input one controller
    cycle later at the earliest (DESIGN.md, causality), so the physical outputs have no direct
    feed-through from it. Friction and velocity/position features are functions of the model's
    own state and act in the same sample."""
    if kind in ("command", "external"):
        return True
    return (kind == "feature" and params.get("function") in ("sin_position", "cos_position")
            and params.get("source", "command") == "command")


@dataclass
class Port:
    """An input or output of the LTI part.

    Attributes
    ----------
    name : str      e.g. ``x_cmd``, ``x_dnf``, ``x_pos``, ``x_err``, ``x_vel``
    unit : str      canonical unit (``mm``, ``mm_s``, ``1``, ...)
    kind : str      one of INPUT_KINDS / OUTPUT_KINDS
    axis : str or None
    params : dict   friction: ``v_tilde`` [mm/s], ``level`` [-];
                    feature: ``function``, ``v_tilde``, ``v_s`` [mm/s], ``period_mm``,
                    ``width_mm``, ``source`` (``command`` or ``position``; ``play`` and
                    ``play_stribeck``: ``position``)
    description : str
    """

    name: str
    unit: str
    kind: str
    axis: str | None = None
    params: dict = field(default_factory=dict)
    description: str = ""


@dataclass
class DriveModel:
    """Identified feed-drive model (see module docstring).

    Attributes
    ----------
    Ts : float, s
    A, B, C, D : ndarray, the unscaled discrete state space
    inputs, outputs : list[Port]
    method : str                 identification method (``pole-search``, ``mimo``, ``full-ls``...)
    poles : list[complex]        continuous poles, rad/s (of all blocks)
    identification : dict        method details: blocks, denominators, continuous numerators,
                                 tracking-TF zeros, search record
    metrics : dict               fit figures (training RMS etc.)
    effects : list[dict]         effects added by diagnosis (``kind`` + parameters)
    provenance : dict            data file hashes, ranges, software version
    limits : dict                axis -> {``v_mm_s``, ``a_mm_s2``, ``j_mm_s3``, ``method``}: the
                                 largest velocity, acceleration and jerk of the commanded positions
                                 in the identification traces (:func:`fdid_fmi.identify.limits.
                                 recorded_limits`); what ``fdid plan`` interpolates within by
                                 default. Empty for models saved before format version 3.
    """

    Ts: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: list
    outputs: list
    method: str = ""
    poles: list = field(default_factory=list)
    identification: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    effects: list = field(default_factory=list)
    provenance: dict = field(default_factory=dict)
    limits: dict = field(default_factory=dict)

    def __post_init__(self):
        self.A = np.atleast_2d(_numbers(self.A, "A", "square matrix"))
        if self.A.ndim != 2 or self.A.shape[0] != self.A.shape[1] or not self.A.shape[0]:
            raise InputError(f"A must be a square matrix with at least one state, got shape "
                             f"{self.A.shape}", column="A")
        n = self.A.shape[0]
        self.B = _matrix(self.B, n, -1, "B")
        self.C = _matrix(self.C, -1, n, "C")
        self.D = _matrix(self.D, self.C.shape[0], self.B.shape[1], "D")
        self.inputs = _ports(self.inputs, "inputs")
        self.outputs = _ports(self.outputs, "outputs")
        self.poles = _poles(self.poles)
        self.validate()

    # ----------------------------------------------------------- structure
    @property
    def n_states(self):
        return self.A.shape[0]

    @property
    def axes(self):
        """Axes in the order of their command inputs."""
        return [p.axis for p in self.inputs if p.kind == "command"]

    def input_index(self, kind, axis=None, name=None):
        return _find(self.inputs, kind, axis, name)

    def output_index(self, kind, axis=None, name=None):
        return _find(self.outputs, kind, axis, name)

    def friction_velocity_source(self, i):
        """``(output index, differenced)`` of the velocity friction input ``i`` sees: the axis's
        velocity output, else its position output differenced over one sample (the step's rule,
        fmu_templates/fdid_core.c; the FMU layout and the friction-resolution check read it here)."""
        axis = self.inputs[i].axis
        vo = self.output_index("velocity", axis)
        return (vo, False) if vo is not None else (self.output_index("position", axis), True)

    def position_side(self, axis):
        """``"motor"`` or ``"tool"``: which side the axis's position/error outputs describe (a
        model fitted on tool-side signals only predicts the tool side)."""
        i = self.output_index("position", axis)
        return self.outputs[i].params.get("side", "motor") if i is not None else "motor"

    def validate(self):
        """Check shapes, kinds and per-axis completeness; raise InputError if inconsistent."""
        check_ports_and_names(self)
        n, m, p = self.A.shape[0], self.B.shape[1], self.C.shape[0]
        if self.A.shape != (n, n):
            raise InputError(f"A must be square, got {self.A.shape}", column="A")
        if len(self.inputs) != m or len(self.outputs) != p:
            raise InputError(f"B/C/D have {m} inputs and {p} outputs but the model lists "
                             f"{len(self.inputs)} inputs and {len(self.outputs)} outputs", column="inputs")
        for arr, nm in ((self.A, "A"), (self.B, "B"), (self.C, "C"), (self.D, "D")):
            if not np.isfinite(arr).all():
                raise InputError("contains NaN or inf", column=nm)
            if arr.size and np.max(np.abs(arr)) > MAX_ABS:      # before eigvals: rho was 1e308
                raise InputError(f"has an entry of magnitude {float(np.max(np.abs(arr))):.3g} "
                                 f"(at most {MAX_ABS:g})", column=nm)
        finite_number(self.Ts, "Ts", positive=True)    # inf was "must be positive"
        axes = self.axes
        for prt in self.inputs:     # one command per axis: a second one would never be fed
            if prt.kind == "command" and (not isinstance(prt.axis, str) or axes.count(prt.axis) > 1):
                raise InputError(f"each axis needs exactly one command input; axis {prt.axis!r} "
                                 f"has {axes.count(prt.axis)}", column=prt.name)
        for prt in self.inputs:
            if prt.kind not in INPUT_KINDS:
                raise InputError(f"input kind '{prt.kind}' not in {INPUT_KINDS}", column=prt.name)
            if prt.kind == "friction":
                if prt.axis not in self.axes:
                    raise InputError("friction input has no command input for its axis", column=prt.name)
                _positive(prt, "v_tilde", "mm/s")      # a string or a dict was a TypeError
                prt.params.setdefault("level", 1.0)
            if prt.kind == "feature" and prt.params.get("function") not in FEATURE_FUNCTIONS:
                raise InputError(f"feature function must be one of {FEATURE_FUNCTIONS}", column=prt.name)
        for prt in self.outputs:
            if prt.kind not in OUTPUT_KINDS:
                raise InputError(f"output kind '{prt.kind}' not in {OUTPUT_KINDS}", column=prt.name)
        check_port_units(self)
        for ax in self.axes:
            if self.output_index("position", ax) is None:
                raise InputError(f"axis '{ax}' has no position output", column=ax)
        if len(set(p.name for p in self.inputs)) != m or len(set(p.name for p in self.outputs)) != p:
            raise InputError("input and output names must be unique", column="names")
        self._check_causal()
        check_limits(self.limits, self.axes)
        rho = max(abs(np.linalg.eigvals(self.A))) if n else 0.0
        if rho >= 1.0:
            shown = f"{rho:.6f}" if rho < 1e6 else f"{rho:.3g}"     # not 150 digits
            raise InputError(f"the model is not stable (spectral radius of A = {shown})", column="A")
        check_simulation_numbers(self)

    def _check_causal(self):
        """No same-sample response to an input from outside the drive (``delayed_input``),
        except e = x_r - x following its own command with gain 1 (DESIGN.md, causality)."""
        for j, out in enumerate(self.outputs):
            if out.kind == "other":
                continue
            for i, inp in enumerate(self.inputs):
                if not delayed_input(inp.kind, inp.params):
                    continue
                own = out.kind == "error" and inp.kind == "command" and inp.axis == out.axis
                if abs(self.D[j, i] - (1.0 if own else 0.0)) > 1e-12:
                    raise InputError(
                        f"output '{out.name}' responds to input '{inp.name}' in the same sample "
                        f"(D = {float(self.D[j, i]):.6g}, expected {1.0 if own else 0.0:g}); a sampled "
                        "drive answers one cycle later: identify the model again with this version",
                        column="D")

    # ------------------------------------------------ steady-state helpers
    def steady_state_maps(self):
        """Matrices for the ramp steady state and the d.c. gain.

        Returns
        -------
        S : (I - A)^-1 B          state per unit constant input
        S2 : (I - A)^-1 S         state correction per unit input increment per step
        G1 : C S + D              d.c. gain of every input/output pair
        """
        n = self.n_states
        if n == 0:
            return np.zeros((0, self.B.shape[1])), np.zeros((0, self.B.shape[1])), self.D.copy()
        IA = np.eye(n) - self.A
        S = np.linalg.solve(IA, self.B)
        S2 = np.linalg.solve(IA, S)
        return S, S2, self.C @ S + self.D

    def to_control(self):
        """The linear part as a discrete python-control state space.

        Returns
        -------
        control.StateSpace
            ``A, B, C, D`` with ``dt = Ts`` [s]; inputs and outputs named like the model's ports
            (commands in mm, friction/feature inputs dimensionless, outputs in their units).
            The friction nonlinearity is not included: it closes a loop around this system
            (see :mod:`fdid_fmi.simulate`). Frequency responses, poles and zeros of the linear
            part come from here (``control.frequency_response``, ``.poles()``, ``.zeros()``).
        """
        import control
        return control.ss(self.A, self.B, self.C, self.D, self.Ts,
                          inputs=[p.name for p in self.inputs],
                          outputs=[p.name for p in self.outputs],
                          states=[f"xi{k}" for k in range(self.n_states)])

    # --------------------------------------------------------------- JSON
    def to_dict(self):
        return {
            "format": FORMAT, "format_version": FORMAT_VERSION, "kind": "state_space",
            "Ts": self.Ts, "method": self.method,
            "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(), "D": self.D.tolist(),
            "inputs": [jsonable(asdict(p)) for p in self.inputs],        # numpy scalars in params
            "outputs": [jsonable(asdict(p)) for p in self.outputs],
            "poles": [[p.real, p.imag] for p in self.poles],
            "identification": jsonable(self.identification), "metrics": jsonable(self.metrics),
            "effects": jsonable(self.effects), "provenance": jsonable(self.provenance),
            "limits": jsonable(self.limits),
        }

    def save(self, path):
        """Write the model JSON atomically (complete or not at all; :mod:`fdid_fmi.outputs`)."""
        from .outputs import atomic_write
        return atomic_write(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path):
        """Read a state-space model JSON written by :meth:`save` (InputError naming the file when
        it holds no state-space model: a quasi-static one is read with :func:`load_model`)."""
        model = load_model(path)
        if not isinstance(model, cls):
            raise InputError("holds a quasi-static model, not a state-space one (read it with "
                             "fdid_fmi.load_model)", source=str(path))
        return model

    @property
    def records(self):
        """How the model was identified, typed: one
        :class:`~fdid_fmi.identify.record.PoleSearchRecord` per pole-search / MIMO block (one for
        the model of one axis, one per axis of a combined per-axis model); empty for a Full LS
        model, whose record is ``identification["pole_constraints"]``."""
        from .identify.record import PoleSearchRecord
        ident = self.identification or {}
        return [PoleSearchRecord.from_dict(b) for b in ident.get("blocks", [ident]) if b.get("structure")]

    def copy(self):
        return DriveModel.from_dict(json.loads(json.dumps(self.to_dict())))

    @classmethod
    def from_dict(cls, d, source="<dict>"):
        _check_header(d, source, "state_space")
        keys = ("Ts", "A", "B", "C", "D", "inputs", "outputs")
        missing = [k for k in keys if k not in d]
        if missing:
            raise InputError(f"model file lacks {missing}", source=source)
        for key, typ, what in (("identification", dict, "object"), ("metrics", dict, "object"),
                               ("provenance", dict, "object"), ("effects", list, "array"),
                               ("limits", dict, "object")):
            if key in d and not isinstance(d[key], typ):
                raise InputError(f"must be a JSON {what}, got {_short(d[key])}", source=source, column=key)
        if any(not isinstance(e, dict) for e in d.get("effects", [])):
            raise InputError("every effect must be a JSON object (kind, axis, parameters)",
                             source=source, column="effects")
        try:
            return cls(Ts=float(d["Ts"]), A=d["A"], B=d["B"], C=d["C"], D=d["D"],
                       inputs=d["inputs"], outputs=d["outputs"], method=d.get("method", ""),
                       poles=d.get("poles", []), identification=d.get("identification", {}),
                       metrics=d.get("metrics", {}), effects=d.get("effects", []),
                       provenance=d.get("provenance", {}), limits=d.get("limits", {}))
        except InputError as exc:
            raise InputError(str(exc), source=source) from None
        except (TypeError, ValueError, OverflowError, AttributeError, KeyError, IndexError) as exc:
            raise InputError(f"is not a valid model: {exc}", source=source) from None

    # -------------------------------------------------------- combination
    @classmethod
    def combine(cls, models, method=None):
        """Block-diagonal combination of decoupled per-axis models (same Ts)."""
        if not models:
            raise InputError("combine needs at least one model")
        Ts = models[0].Ts
        for m in models:
            if abs(m.Ts - Ts) > 1e-12 * Ts:
                raise InputError(f"models have different sample times ({Ts} s, {m.Ts} s)", column="Ts")
        from scipy.linalg import block_diag
        A = block_diag(*[m.A for m in models])
        B = block_diag(*[m.B for m in models])
        C = block_diag(*[m.C for m in models])
        D = block_diag(*[m.D for m in models])
        # copies: a port, record or effect shared with a block would change with it (validate()
        # itself fills in a friction level), and the blocks with a later change of the combination
        own = copy.deepcopy
        return cls(Ts=Ts, A=A, B=B, C=C, D=D,
                   inputs=own([p for m in models for p in m.inputs]),
                   outputs=own([p for m in models for p in m.outputs]),
                   method=method or "+".join(sorted(set(m.method for m in models))),
                   poles=[p for m in models for p in m.poles],
                   identification={"blocks": own([m.identification for m in models])},
                   metrics={"blocks": own([m.metrics for m in models])},
                   effects=own([e for m in models for e in m.effects]),
                   provenance={"blocks": own([m.provenance for m in models])},
                   limits=own({a: lim for m in models for a, lim in m.limits.items()}))


@dataclass
class QuasiStaticModel:
    """Quasi-static tracking-error model (thesis Eqn 3.3-3.4), one set of gains per axis.

    e(t) = K_vel x_r' + K_acc x_r'' + K_jerk x_r''' with the command derivatives taken
    through a zero-phase Butterworth filter of ``order`` and ``cutoff_hz``.
    """

    Ts: float
    gains: dict                     # axis -> {"K_vel": s, "K_acc": s^2, "K_jerk": s^3}
    cutoff_hz: float
    order: int = 2
    method: str = "quasi-static"
    metrics: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)

    @property
    def axes(self):
        return list(self.gains)

    def to_dict(self):
        return {"format": FORMAT, "format_version": FORMAT_VERSION, "kind": "quasi_static",
                "Ts": self.Ts, "gains": self.gains, "cutoff_hz": self.cutoff_hz, "order": self.order,
                "method": self.method, "metrics": jsonable(self.metrics),
                "provenance": jsonable(self.provenance)}

    def save(self, path):
        """Write the model JSON atomically (complete or not at all; :mod:`fdid_fmi.outputs`)."""
        from .outputs import atomic_write
        return atomic_write(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path):
        """Read a quasi-static model JSON written by :meth:`save`."""
        model = load_model(path)
        if not isinstance(model, cls):
            raise InputError("holds a state-space model, not a quasi-static one", source=str(path))
        return model

    @classmethod
    def from_dict(cls, d, source="<dict>"):
        _check_header(d, source, "quasi_static")
        cutoff, order = d.get("cutoff_hz", 1.0), d.get("order", 2)
        if isinstance(cutoff, bool) or not isinstance(cutoff, (int, float)):   # true read as 1 Hz
            raise InputError(f"cutoff_hz must be a number of Hz, got {_short(cutoff)}", source=source,
                             column="cutoff_hz")
        if isinstance(order, bool) or not isinstance(order, (int, float)) or not float(order).is_integer():
            raise InputError(f"order must be an integer 1 .. 8, got {_short(order)}", source=source,
                             column="order")                                # 2.7 was read as 2
        try:
            m = cls(Ts=float(d["Ts"]), gains=d["gains"], cutoff_hz=float(d["cutoff_hz"]),
                    order=int(d.get("order", 2)), method=d.get("method", "quasi-static"),
                    metrics=d.get("metrics", {}), provenance=d.get("provenance", {}))
        except KeyError as exc:
            raise InputError(f"model file lacks {exc}", source=source) from None
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(f"is not a valid model: {exc}", source=source) from None
        check_quasi_static(m, source)
        return m


def load_model(path):
    """Load a model JSON file written by ``save`` (state-space or quasi-static)."""
    from .io.common import check_file
    path = check_file(path, what="model file")      # a directory is not "not found"
    parse_int, pairs = _json_hooks()
    with open(path, "rb") as f:
        if f.read(4) == b"PK\x03\x04":     # a zip archive: an FMU (or another zip) where the JSON belongs
            raise InputError("is a zip archive (an FMU?), not a model file: give the model JSON that "
                             "fdid identify wrote (fdid export makes the FMU from it)", source=str(path))
    try:
        d = json.loads(path.read_text(), object_pairs_hook=pairs, parse_int=parse_int)
    except _DuplicateKey as exc:
        raise InputError(f"the key '{exc}' is given twice in one JSON object (which one is meant?)",
                         source=str(path), column=str(exc)) from None
    except _LongInteger as exc:
        key, digits = exc.args
        raise InputError(f"{key} holds an integer of {digits} digits: a number too long (expected a "
                         f"number below 1e308)", source=str(path), column=key) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"is not a JSON model file ({exc})", source=str(path)) from None
    except RecursionError:
        raise InputError("is not a model file (JSON nested too deeply)", source=str(path)) from None
    if not isinstance(d, dict):
        raise InputError("is not a model file (expected a JSON object)", source=str(path))
    if d.get("kind") == "quasi_static":
        return QuasiStaticModel.from_dict(d, source=str(path))
    return DriveModel.from_dict(d, source=str(path))


class _DuplicateKey(Exception):
    """A JSON object names a key twice (json keeps the last one without a word)."""


class _LongInteger(Exception):
    """A JSON integer too long for a float, with the key that holds it: (key, digits)."""


MAX_INT_DIGITS = 308    # a longer integer is >= 1e308: no float (and past Python's int-string limit)


class _TooLong:
    """Placeholder of an over-long JSON integer until the object holding it names its key."""

    def __init__(self, digits):
        self.digits = digits


def _holds(v, x):
    return v is x or (isinstance(v, list) and any(_holds(e, x) for e in v))


def _json_hooks():
    """``(parse_int, object_pairs_hook)`` for ``json.loads`` of a model file: a key given twice
    raises _DuplicateKey (json keeps the last one without a word); an integer of more than
    MAX_INT_DIGITS digits raises _LongInteger naming the key that holds it (json's int() raised
    a bare ValueError past 4300 digits, float() an OverflowError past 1e308)."""
    long_ints = []

    def parse_int(text):
        digits = len(text.lstrip("-"))
        if digits > MAX_INT_DIGITS:
            long_ints.append(_TooLong(digits))
            return long_ints[-1]
        return int(text)

    def pairs(items):
        d = {}
        for k, v in items:
            if k in d:
                raise _DuplicateKey(k)
            if long_ints and _holds(v, long_ints[0]):     # only after a long integer was read
                raise _LongInteger(k, long_ints[0].digits)
            d[k] = v
        return d
    return parse_int, pairs


def check_limits(limits, axes):
    """The ``limits`` of a model: axis (one of the model's) -> {v_mm_s, a_mm_s2, j_mm_s3: finite
    numbers > 0, method: text}; InputError (column ``limits``) otherwise."""
    if not isinstance(limits, dict):
        raise InputError(f"must be a JSON object (axis -> limits), got {_short(limits)}", column="limits")
    for ax, lim in limits.items():
        if ax not in axes:
            raise InputError(f"names axis {_short(ax)}, which the model does not have (axes {axes})",
                             column="limits")
        if not isinstance(lim, dict):
            raise InputError(f"axis {ax}: expected an object with {', '.join(LIMIT_KEYS)}, got {_short(lim)}",
                             column="limits")
        for key in LIMIT_KEYS:
            v = lim.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
                raise InputError(f"axis {ax}: {key} must be a number > 0, got {_short(v)}", column="limits")
        extra = [k for k in lim if k not in LIMIT_KEYS + ("method",)]
        if extra or not isinstance(lim.get("method", ""), str):
            raise InputError(f"axis {ax}: unknown entries {extra or ['method']}: expected "
                             f"{', '.join(LIMIT_KEYS)} and a method text", column="limits")


def _check_header(d, source, kind):
    if d.get("format") != FORMAT:
        raise InputError(f"is not an fdid-fmi model (format '{d.get('format')}')", source=source)
    v = d.get("format_version")
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise InputError(f"model format version {v!r} is not a format version (an integer 1 .. "
                         f"{FORMAT_VERSION})", source=source, column="format_version")
    if v > FORMAT_VERSION:
        raise InputError(f"model format version {v} is newer than this software reads "
                         f"({FORMAT_VERSION})", source=source, column="format_version")
    Ts = d.get("Ts", 0.0)
    if isinstance(Ts, bool) or not isinstance(Ts, (int, float)):    # JSON true would read as 1 s
        raise InputError(f"Ts must be a number of seconds, got {Ts!r}", source=source, column="Ts")
    if d.get("kind", "state_space") != kind:
        raise InputError(f"is a '{d.get('kind')}' model, expected '{kind}'", source=source)


def _matrix(x, rows, cols, name):
    """``x`` as a float matrix of ``rows`` x ``cols`` (-1: any). A vector or a number is reshaped
    (one input or output); a matrix must have the shape already: reshaping a transposed B
    would scramble the model without a word."""
    want = " x ".join("k" if w == -1 else str(w) for w in (rows, cols))
    a = _numbers(x, name, f"{want} matrix")
    if a.ndim == 2 and all(w in (-1, g) for w, g in zip((rows, cols), a.shape)):
        return a
    if a.ndim < 2:
        try:
            return a.reshape(rows, cols)
        except ValueError:
            pass
    raise InputError(f"must be a {want} matrix, got shape {a.shape}", column=name)


REAL_TYPES = (int, float, np.integer, np.floating)     # bool (an int) is refused apart


def _not_number(x, depth=0):
    """``(position, value)`` of the first entry of ``x`` (a number, a list of numbers or a list
    of such rows) that is not a real number (a string, a boolean, null, an object, a list nested
    deeper), or None."""
    if isinstance(x, np.ndarray) and x.dtype.kind in "fiu":
        return None
    if isinstance(x, (list, tuple, np.ndarray)) and depth < 2:
        for k, v in enumerate(x):
            if type(v) is not float:        # the common case, at no cost
                bad = _not_number(v, depth + 1)
                if bad is not None:
                    return f"[{k}]{bad[0]}", bad[1]
        return None
    if isinstance(x, REAL_TYPES) and not isinstance(x, bool):
        return None
    return "", x


def _numbers(x, name, want="matrix"):
    """``x`` as a float array (at most 2-D) when it holds real numbers only, in rows of one
    length; else InputError naming ``name``: numpy read the string '1.0' and true as numbers
    without a word, and rows of different lengths as an error about sequences."""
    bad = _not_number(x)
    if bad is not None:
        where, v = bad
        raise InputError(f"{name} must be a {want} of numbers, got {type(v).__name__} {_short(v)}"
                         f"{' at ' + name + where if where else ''}", column=name)
    try:
        return np.asarray(x, dtype=float)
    except OverflowError:   # a Python int past 1e308
        raise InputError(f"{name} holds a number too large (expected numbers below 1e308)",
                         column=name) from None
    except ValueError:      # rows of different lengths (the entries are numbers)
        lens = [len(r) if isinstance(r, (list, tuple, np.ndarray)) else None for r in x]
        k = next((k for k, n in enumerate(lens) if n != lens[0]), 0)
        what = lambda n: "a number" if n is None else f"{n} entries"       # noqa: E731
        raise InputError(f"{name} must be a {want} of numbers in rows of one length, but row 1 has "
                         f"{what(lens[0])} and row {k + 1} {what(lens[k])}", column=name) from None


def _ports(x, what):
    """``x`` (a model's ``inputs`` or ``outputs``) as a list of :class:`Port`: a JSON array of
    objects with the fields of Port (name, unit, kind required)."""
    if not isinstance(x, (list, tuple)):
        raise InputError(f"{what} must be a JSON array of port objects (name, unit, kind, axis, "
                         f"params), got {type(x).__name__} {_short(x)}", column=what)
    fields = list(Port.__dataclass_fields__)
    out = []
    for k, p in enumerate(x):
        if isinstance(p, Port):
            out.append(p)
            continue
        if not isinstance(p, dict):
            raise InputError(f"{what[:-1]} {k + 1} must be a JSON object ({', '.join(fields)}), got "
                             f"{type(p).__name__} {_short(p)}", column=what)
        unknown = [key for key in p if key not in fields]
        missing = [key for key in fields[:3] if key not in p]
        if unknown or missing:
            raise InputError(f"{what[:-1]} {k + 1} " + (f"has the unknown key {_short(unknown[0])}"
                             if unknown else f"lacks '{missing[0]}'") + f"; expected the keys "
                             f"{', '.join(fields)}", column=what)
        out.append(Port(**p))
    return out


def _poles(x):
    """``x`` as a list of complex poles [rad/s]: a JSON array of numbers or [real, imag] pairs."""
    if not isinstance(x, (list, tuple, np.ndarray)):
        raise InputError(f"poles must be a JSON array of [real, imag] pairs in rad/s, got "
                         f"{type(x).__name__} {_short(x)}", column="poles")
    out = []
    for k, p in enumerate(x):
        if isinstance(p, (complex, np.complexfloating)):
            out.append(complex(p))
            continue
        pair = p if isinstance(p, (list, tuple)) else [p, 0.0]
        if len(pair) != 2 or _not_number(pair) is not None:
            raise InputError(f"pole {k + 1} must be a number or a [real, imag] pair of numbers in "
                             f"rad/s, got {_short(p)}", column="poles")
        out.append(complex(float(pair[0]), float(pair[1])))
    return out


def _find(ports, kind, axis, name):
    for i, p in enumerate(ports):
        if p.kind == kind and (axis is None or p.axis == axis) and (name is None or p.name == name):
            return i
    return None


def jsonable(obj):
    """Recursively turn numpy / complex values into JSON-friendly ones (non-finite -> None)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (complex, np.complexfloating)):
        return [float(obj.real), float(obj.imag)]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if np.isfinite(x) else None
    return obj


# ------------------------------------------------------------------ checks of untrusted models
# Model files are exchanged between companies: names reach generated C and modelDescription.xml,
# numbers reach the simulator and the FMU. Both are checked here, when a model is built or loaded.
NAME_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
MAX_NAME = 128          # characters of a port or axis name
MAX_TEXT = 1000         # characters of a unit, description or method
MAX_STATES = 400        # model order
MAX_PORTS = 256         # inputs, outputs
TS_RANGE = (1e-6, 10.0)  # s
MAX_ABS = 1e150         # largest magnitude of a model number (products stay finite)


def port_name(text):
    """An identifier for a port named after a trace channel (``spindle-load`` -> ``spindle_load``,
    ``2nd`` -> ``c_2nd``); the channel itself stays in the port's ``params["channel"]``."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", str(text))[:120] or "channel"
    return name if NAME_RE.fullmatch(name) else "c_" + name


def check_name(name, what, source=None):
    """Raise InputError unless ``name`` is a C/FMI identifier ``[A-Za-z_][A-Za-z0-9_]*`` of at
    most MAX_NAME characters. ``what`` says what it names (``"axis"``, ``"input name"``)."""
    if not isinstance(name, str):
        raise InputError(f"{what} must be a string, got {type(name).__name__} {_short(name)}",
                         source=source, column=what)
    if not name:
        raise InputError(f"{what} is empty", source=source, column=what)
    if len(name) > MAX_NAME or not NAME_RE.fullmatch(name):
        raise InputError(f"{what} {_short(name)} is not a name: expected letters, digits and '_' "
                         f"(not starting with a digit), at most {MAX_NAME} characters",
                         source=source, column=what)
    return name


# bidirectional-text controls (embeddings, overrides, isolates, marks): printed in an XML file, a
# tool's variable list or a log they reorder what follows, so a name can read as another
BIDI_CONTROLS = frozenset([*range(0x202A, 0x202F), *range(0x2066, 0x206A), 0x200E, 0x200F, 0x061C])


def check_text(text, what, column=None, source=None, max_len=MAX_TEXT):
    """Raise InputError unless ``text`` is printable UTF-8 (no control characters, no lone
    surrogates, no line breaks, no bidirectional-text controls: ``BIDI_CONTROLS``) of at most
    ``max_len`` characters."""
    if not isinstance(text, str):
        raise InputError(f"{what} must be a string, got {type(text).__name__} {_short(text)}",
                         source=source, column=column)
    if len(text) > max_len:
        raise InputError(f"{what} is longer than {max_len} characters", source=source, column=column)
    for k, ch in enumerate(text):
        o = ord(ch)
        if (unicodedata.category(ch) in ("Cc", "Cs", "Zl", "Zp") or 0xFDD0 <= o <= 0xFDEF
                or (o & 0xFFFE) == 0xFFFE):
            raise InputError(f"{what} has the non-printable character U+{o:04X} at position {k + 1}; "
                             f"expected printable text", source=source, column=column)
        if o in BIDI_CONTROLS:
            raise InputError(f"{what} has the bidirectional-text control character U+{o:04X} at position "
                             f"{k + 1} (it reorders how the text is displayed); expected printable text "
                             f"without direction controls", source=source, column=column)
    return text


def _short(x, n=40):
    r = repr(x)
    return r if len(r) <= n else r[:n - 3] + "..."


def check_ports_and_names(model):
    """Types and names of the ports, axes and method of ``model`` (first step of validate).

    Port and axis names must be identifiers (:func:`check_name`), units, descriptions and
    the method printable text (:func:`check_text`), ``params`` a dict, and the model no
    larger than MAX_STATES states / MAX_PORTS inputs and outputs.
    """
    check_text(model.method, "method", column="method", max_len=200)
    if model.A.shape[0] > MAX_STATES:
        raise InputError(f"the model has {model.A.shape[0]} states; at most {MAX_STATES} are supported",
                         column="A")
    for ports, what in ((model.inputs, "input"), (model.outputs, "output")):
        if len(ports) > MAX_PORTS:
            raise InputError(f"the model has {len(ports)} {what}s; at most {MAX_PORTS} are supported",
                             column=f"{what}s")
        seen = set()
        for k, prt in enumerate(ports):
            check_name(prt.name, f"{what} {k + 1} name")
            if prt.name in seen:
                raise InputError(f"two {what}s are named '{prt.name}'; names must be unique",
                                 column=prt.name)
            seen.add(prt.name)
            if not isinstance(prt.kind, str):
                raise InputError(f"kind must be a string, got {_short(prt.kind)}", column=prt.name)
            if prt.axis is not None:
                check_name(prt.axis, f"axis of {what} '{prt.name}'")
            check_text(prt.unit, "unit", column=prt.name, max_len=64)
            check_text(prt.description, "description", column=prt.name)
            if not isinstance(prt.params, dict):
                raise InputError(f"params must be a JSON object, got {_short(prt.params)}",
                                 column=prt.name)
            for key, val in prt.params.items():
                if isinstance(val, str):
                    check_text(val, f"parameter '{key}'", column=prt.name, max_len=200)


# the CNC convention every simulation, every regressor and the FMU's unit definitions assume
# (fdid_fmi.units): a port in another unit ("m", "um", a typo) would be simulated and exported as
# if it were in these, 1000x off without a word
POSITION_UNITS = ("mm", "deg")             # deg: a rotary axis
PORT_UNITS = {"command": POSITION_UNITS, "position": POSITION_UNITS, "error": POSITION_UNITS,
              "tool_position": POSITION_UNITS, "velocity": ("mm_s", "deg_s"),
              "acceleration": ("mm_s2",), "friction": ("1",), "feature": ("1",)}


def check_port_units(model):
    """Every port's unit is the canonical one of its kind (PORT_UNITS; external inputs and
    ``other`` outputs: any canonical unit of :mod:`fdid_fmi.units`), and an axis's positions,
    command and errors share one unit."""
    from .units import CANONICAL
    canonical = sorted(set(CANONICAL.values()))
    for ports, what in ((model.inputs, "input"), (model.outputs, "output")):
        for prt in ports:
            allowed = PORT_UNITS.get(prt.kind, canonical)
            if prt.unit not in allowed:
                raise InputError(f"{prt.kind} {what} has unit '{prt.unit}'; expected "
                                 f"{' or '.join(allowed) if len(allowed) < 4 else f'one of {allowed}'} "
                                 f"(models are unscaled, in the CNC convention: mm, mm/s, mm/s^2)",
                                 column=prt.name)
    for ax in model.axes:
        units = {p.unit for p in list(model.inputs) + list(model.outputs)
                 if p.axis == ax and PORT_UNITS.get(p.kind) is POSITION_UNITS}
        if len(units) > 1:
            raise InputError(f"axis '{ax}' mixes position units {sorted(units)}; its command, "
                             f"positions and errors must share one", column=ax)


def _positive(prt, key, unit):
    v = prt.params.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise InputError(f"parameter {key} must be a number > 0 [{unit}], got {_short(v)}",
                         column=f"{prt.name}.{key}")
    v = float(v)
    if not (np.isfinite(v) and 0.0 < v <= MAX_ABS):
        raise InputError(f"parameter {key} must be a finite number > 0 [{unit}], got {v!r}",
                         column=f"{prt.name}.{key}")
    return v


def check_simulation_numbers(model):
    """Every number a simulation uses is finite and in range (last step of validate).

    Ts in TS_RANGE; friction ``v_tilde`` > 0 and ``level`` finite >= 0; feature parameters
    (``v_tilde`` for sat/abs_sat/stribeck, ``v_s`` for stribeck/play_stribeck, ``period_mm`` for
    sin/cos, ``source`` command/position, ``width_mm`` and source position for
    play/play_stribeck); friction ``v_tilde`` no smaller than the friction solve resolves
    (:func:`check_friction_resolution`); the steady-state maps finite and at most MAX_ABS in
    magnitude (the matrix entries are checked so by validate, before the stability check).
    Raises InputError naming the parameter.
    """
    lo, hi = TS_RANGE
    if not lo <= model.Ts <= hi:
        raise InputError(f"sample time {float(model.Ts)!r} s is outside the supported range {lo:g} .. {hi:g} s",
                         column="Ts")
    for prt in model.inputs:
        if prt.kind == "friction":
            _positive(prt, "v_tilde", "mm/s")
            lev = prt.params.get("level", 1.0)
            if isinstance(lev, bool) or not isinstance(lev, (int, float, np.integer, np.floating)) \
                    or not (np.isfinite(float(lev)) and 0.0 <= float(lev) <= MAX_ABS):
                raise InputError(f"friction level must be a finite number >= 0, got {_short(lev)}",
                                 column=f"{prt.name}.level")
        elif prt.kind == "feature":
            fn = prt.params.get("function")
            # the function's numbers, and any other given: every one reaches the C model data
            for key, unit in FEATURE_NUMBERS.items():
                if key in FEATURE_NEEDS.get(fn, ()) or key in prt.params:
                    _positive(prt, key, unit)
            if fn in ("sin_position", "cos_position"):
                if prt.params.get("source", "command") not in ("command", "position"):
                    raise InputError("feature source must be 'command' or 'position', got "
                                     f"{_short(prt.params.get('source'))}", column=f"{prt.name}.source")
            if fn in PLAY_FUNCTIONS:
                if prt.params.get("source") != "position":
                    raise InputError(f"the {fn} feature acts on the model's own position: source "
                                     f"must be 'position', got {_short(prt.params.get('source'))}",
                                     column=f"{prt.name}.source")
            if prt.axis is None:
                raise InputError("a feature input needs an axis", column=prt.name)
    check_friction_resolution(model)
    if model.A.shape[0]:
        with np.errstate(all="ignore"):
            maps = model.steady_state_maps()
        for arr, nm in zip(maps, ("S", "S2", "G1")):
            if not np.isfinite(arr).all() or (arr.size and np.max(np.abs(arr)) > MAX_ABS):
                raise InputError(f"the steady-state map {nm} of the model is not finite (A has an "
                                 f"eigenvalue too close to 1)", column="A")


# Smallest v_tilde the friction solve resolves. With several friction inputs, the step
# (fmu_templates/fdid_core.c, solve_friction) solves each branch by LU with the linear rows
# 1 - g beta, g = L / v_tilde (L the level, beta the velocity change per unit friction in one
# sample: D of the velocity source, over Ts for a differenced position), and accepts the
# linear branch when |v| = |alpha + beta d| <= v_tilde. v carries the rounding eps |alpha| of
# that cancellation, so the accepted |d| may exceed L by eps L |beta| / v_tilde relative (measured:
# 1e-5 at L |beta| / v_tilde = 2.4e11, 4e-3 at 2.4e13, 0.3 at 2.4e15 on the virtual two-axis
# drive); from L |beta| / v_tilde ~ 1 / eps = 4.5e15 on, 1 - g beta loses its 1, the force is
# unbounded and the outputs grow to 1e270 or to inf (the reviewer's 1e-20 .. 1e-310 mm/s; on
# that drive 1e-17 mm/s already). FRICTION_RATIO_MAX keeps that excess below eps * 1e12 =
# 2.2e-4 of L. g itself must stay a model number (<= MAX_ABS: with beta = 0, g = inf gave NaN
# outputs from 1e-308 mm/s). One friction input is solved in closed form, |d| <= L at any
# v_tilde > 0 (measured down to 1e-320 mm/s): no bound there.
FRICTION_RATIO_MAX = 1e12


def vtilde_floor_per_level(model):
    """``{friction input index: least v_tilde per unit friction level}`` (mm/s): the bound
    above, max(sum_c |beta_qc| / FRICTION_RATIO_MAX, 1 / MAX_ABS) for input q; ``{}`` with fewer
    than two friction inputs (solved in closed form). v_tilde must be at least ``level`` times
    this, in the model file and as a tunable FMU / simulation parameter."""
    fric = [i for i, p in enumerate(model.inputs) if p.kind == "friction"]
    if len(fric) < 2:
        return {}
    out = {}
    for i in fric:
        vo, differenced = model.friction_velocity_source(i)
        beta = float(np.sum(np.abs(model.D[vo, fric]))) / (model.Ts if differenced else 1.0)  # mm/s per unit
        out[i] = max(beta / FRICTION_RATIO_MAX, 1.0 / MAX_ABS)
    return out


def vtilde_floor_message(vt, level, floor, n_friction):
    """Why a v_tilde below ``level * floor`` is refused (one sentence, for every place that checks)."""
    return (f"v_tilde must be at least {level * floor:.3g} mm/s at friction level {level:g}, got {vt:.3g}: "
            f"the friction solve of {n_friction} friction inputs resolves no smaller one; below it the "
            f"friction exceeds its level and the outputs grow without bound or are NaN")


def check_friction_resolution(model):
    """Raise InputError naming ``<input>.v_tilde`` when a model with several friction inputs has
    a v_tilde below its level times :func:`vtilde_floor_per_level` (see above)."""
    floors = vtilde_floor_per_level(model)
    for i, floor in floors.items():
        prt = model.inputs[i]
        level, vt = float(prt.params.get("level", 1.0)), float(prt.params["v_tilde"])
        if vt < level * floor:
            raise InputError(vtilde_floor_message(vt, level, floor, len(floors)), column=f"{prt.name}.v_tilde")


def check_quasi_static(model, source=None):
    """Checks of a loaded quasi-static model: Ts in TS_RANGE, axis names, finite gains,
    a positive finite cutoff below Nyquist, filter order 1..8, printable method."""
    lo, hi = TS_RANGE
    if not lo <= model.Ts <= hi:
        raise InputError(f"sample time {float(model.Ts)!r} s is outside the supported range "
                         f"{lo:g} .. {hi:g} s", source=source, column="Ts")
    check_text(model.method, "method", column="method", source=source, max_len=200)
    if not isinstance(model.gains, dict) or not model.gains:
        raise InputError("gains must be a JSON object axis -> {K_vel, K_acc, K_jerk}", source=source,
                         column="gains")
    for ax, g in model.gains.items():
        check_name(ax, "axis", source=source)
        if not isinstance(g, dict):
            raise InputError(f"gains of axis '{ax}' must be a JSON object", source=source, column=ax)
        for k in ("K_vel", "K_acc", "K_jerk"):
            v = g.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) \
                    or abs(v) > MAX_ABS:
                raise InputError(f"{k} must be a finite number, got {_short(v)}", source=source,
                                 column=f"{ax}.{k}")
    if not (np.isfinite(model.cutoff_hz) and 0 < model.cutoff_hz < 0.5 / model.Ts):
        raise InputError(f"cutoff_hz must be in (0, {0.5 / model.Ts:g}) Hz, got {model.cutoff_hz!r}",
                         source=source, column="cutoff_hz")
    if not 1 <= model.order <= 8:
        raise InputError(f"filter order must be in 1 .. 8, got {model.order}", source=source,
                         column="order")
