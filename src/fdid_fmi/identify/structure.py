"""Model structure of the scaled MIMO LTI pole search (thesis ch. 5, Figures 5-3 and 5-12).

A structure says which signals enter (inputs w), which measured signals are fitted (outputs z),
the order of the shared characteristic polynomial (n_r real + n_c complex poles, Eqn 5.2), which
numerator terms are known to be zero (mask), the d.c.-gain constraints (Eqn 5.13-5.17) and the
integrators appended to an output (Eqn 5.26-5.29). The SISO rigid-body model of chapter 4 is the
special case ``siso_structure``.

Numerator convention: ``b[l]`` multiplies s^(n-l) / A(s), l = 0..n (thesis Eqn 5.3).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..model import delayed_input, is_play, port_name
from .regressors import SAME_SAMPLE

INPUT_SOURCES = ("command", "friction", "external", "feature")
# output kind -> trace role it is measured from (integrators: how many appended to predict it)
OUTPUT_SOURCES = {
    "error": "cmd-act", "position": "act", "velocity": "vel", "tool_position": "tool",
    "tool_error": "cmd-tool", "acceleration": "acc",
}
PAIR_SEP = "|"     # JSON key of an (output name, input name) pair: "x_error|x_cmd"


def pair_key(pair):
    """JSON key of an (output name, input name) pair."""
    return f"{pair[0]}{PAIR_SEP}{pair[1]}"


def split_pair_key(key):
    """(output name, input name) of a JSON pair key (port names contain no ``|``)."""
    o, i = key.split(PAIR_SEP, 1)
    return o, i


@dataclass
class InputSpec:
    """An input of the structure.

    kind : ``command`` (x_r of ``axis``), ``friction`` (sat(v/v_tilde) of ``axis``, v from the
           measured velocity), ``external`` (trace channel ``channel``), ``feature`` (a
           nonlinear function, see DriveModel; ``params``)
    """

    kind: str
    axis: str | None = None
    channel: str | None = None
    params: dict = field(default_factory=dict)
    name: str | None = None

    @property
    def late(self):
        """True for inputs from outside the drive (``model.delayed_input``): their same-sample
        term uses the extrapolation of earlier samples (regressors.py); False for functions of
        the model's own state."""
        return delayed_input(self.kind, self.params)

    def __post_init__(self):
        if self.kind not in INPUT_SOURCES:
            raise InputError(f"input kind '{self.kind}' not in {INPUT_SOURCES}", column="inputs")
        if self.name is None:
            suffix = {"command": "cmd", "friction": "dnf", "external": self.channel or "ext",
                      "feature": self.params.get("function", "feat")}[self.kind]
            self.name = f"{self.axis}_{suffix}" if self.axis else str(suffix)


@dataclass
class OutputSpec:
    """A fitted output.

    kind : key of OUTPUT_SOURCES (what is measured)
    integrators : number of integrators appended after the fit (Eqn 5.26-5.29), e.g. 2 to
                  predict tool position from a fitted tool acceleration
    predicts : model output kind after the integrators (default: same as ``kind``)
    """

    kind: str
    axis: str
    integrators: int = 0
    predicts: str | None = None
    name: str | None = None

    def __post_init__(self):
        if self.kind not in OUTPUT_SOURCES:
            raise InputError(f"output kind '{self.kind}' not in {sorted(OUTPUT_SOURCES)}", column="outputs")
        if self.predicts is None:
            self.predicts = self.kind
        if self.name is None:
            self.name = f"{self.axis}_{self.kind}"

    @property
    def is_error(self):
        """A tracking error x_r - x: it follows its own axis's command in the same sample
        (e_k = x_r,k - x_k), the only same-sample response a causal model has."""
        return self.kind in ("error", "tool_error")


@dataclass
class Bounds:
    """Search space of the poles (Hz, zeta) and of v_tilde (mm/s); all searched on log scale
    except zeta. Each list has one (min, max) per real pole / complex pair."""

    real_hz: list
    omega_hz: list
    zeta: list
    v_tilde: tuple | None = None

    def check(self, Ts):
        nyq = 0.5 / Ts
        for name, lst in (("real pole", self.real_hz), ("natural frequency", self.omega_hz)):
            for lo, hi in lst:
                if not (0 < lo < hi <= nyq * (1 + 1e-9)):
                    raise InputError(f"{name} bounds [{lo}, {hi}] Hz must satisfy 0 < min < max <= "
                                     f"Nyquist = {nyq:g} Hz", column="bounds")
        for lo, hi in self.zeta:
            if not (0 < lo < hi):
                raise InputError(f"damping bounds [{lo}, {hi}] must satisfy 0 < min < max", column="bounds")
        if self.v_tilde is not None:
            lo, hi = self.v_tilde
            if not (0 < lo < hi):
                raise InputError(f"v_tilde bounds [{lo}, {hi}] mm/s must satisfy 0 < min < max",
                                 column="bounds")


@dataclass
class Structure:
    """Structure of a pole-search model.

    Attributes
    ----------
    inputs, outputs : lists of InputSpec / OutputSpec
    n_real, n_complex : number of real poles and complex pairs searched (Eqn 5.2)
    locked_real_hz, locked_complex : known poles kept out of the search
    mask : dict (output name, input name) -> tuple of allowed l (b[l] multiplies s^(n-l));
           missing pairs allow all l; an empty tuple removes the pair
    dc_gain : dict (output name, input name) -> (q, value): d.c. gain of order q (Eqn 5.15)
              of the UNSCALED transfer function; b[n-q] is fixed, b[n-q+1..n] are zero
    friction_sign : dict (output name, input name) -> +1/-1: sign the friction path's
              low-frequency coefficient must have (section 4.4.1: d0 < 0 rejected)
    velocity : how the measured velocity that drives friction is estimated from the encoder:
               ``backward`` (default) the backward difference (x[k] - x[k-1]) / Ts, the same
               definition the simulator closes the friction loop with; ``central`` the thesis's
               central difference (section 4.3); either followed by a centred moving average of
               ``ma_order`` samples (1 = none)
    ma_order : moving-average order for the measured velocity
    same_sample : how the same-sample term of commands and external inputs is predicted from
               earlier samples (``regressors.SAME_SAMPLE``: ``hold``, ``cubic`` or ``quadratic``);
               None: identify with each and keep the lower free-run error on the training data
    """

    inputs: list
    outputs: list
    n_real: int = 1
    n_complex: int = 1
    locked_real_hz: list = field(default_factory=list)
    locked_complex: list = field(default_factory=list)
    mask: dict = field(default_factory=dict)
    dc_gain: dict = field(default_factory=dict)
    friction_sign: dict = field(default_factory=dict)
    velocity: str = "backward"
    ma_order: int = 1
    same_sample: str | None = None

    @property
    def order(self):
        return (self.n_real + len(self.locked_real_hz)) + 2 * (self.n_complex + len(self.locked_complex))

    def to_dict(self):
        """The JSON form (``identification["structure"]``; locked poles are stored beside it)."""
        return {"inputs": [vars(i) for i in self.inputs], "outputs": [vars(o) for o in self.outputs],
                "n_real": self.n_real, "n_complex": self.n_complex,
                "mask": {pair_key(k): list(v) for k, v in self.mask.items()},
                "dc_gain": {pair_key(k): list(v) for k, v in self.dc_gain.items()},
                "friction_sign": {pair_key(k): v for k, v in self.friction_sign.items()},
                "velocity": self.velocity, "ma_order": self.ma_order, "same_sample": self.same_sample}

    @classmethod
    def from_dict(cls, d, locked_real_hz=(), locked_complex=()):
        """Inverse of :meth:`to_dict`."""
        ins = [InputSpec(**{k: v for k, v in x.items() if k in ("kind", "axis", "channel", "params", "name")})
               for x in d["inputs"]]
        outs = [OutputSpec(**{k: v for k, v in x.items() if k in ("kind", "axis", "integrators", "predicts",
                                                                  "name")}) for x in d["outputs"]]
        return cls(inputs=ins, outputs=outs, n_real=int(d.get("n_real", 1)), n_complex=int(d.get("n_complex", 1)),
                   locked_real_hz=list(locked_real_hz), locked_complex=[tuple(c) for c in locked_complex],
                   mask={split_pair_key(k): tuple(int(l) for l in v) for k, v in d.get("mask", {}).items()},
                   dc_gain={split_pair_key(k): tuple(v) for k, v in d.get("dc_gain", {}).items()},
                   friction_sign={split_pair_key(k): v for k, v in d.get("friction_sign", {}).items()},
                   velocity=d.get("velocity", "backward"), ma_order=int(d.get("ma_order", 1)),
                   same_sample=d.get("same_sample"))

    @property
    def axes(self):
        out = []
        for s in self.inputs:
            if s.kind == "command" and s.axis not in out:
                out.append(s.axis)
        return out

    def allowed(self, out_name, in_name):
        """Boolean vector (n+1,) of the numerator terms estimated or fixed for this pair."""
        n = self.order
        allow = np.ones(n + 1, bool)
        if (out_name, in_name) in self.mask:
            allow[:] = False
            for l in self.mask[(out_name, in_name)]:
                if not 0 <= l <= n:
                    raise InputError(f"mask term {l} is outside 0..{n} for ({out_name}, {in_name})",
                                     column="mask")
                allow[l] = True
        return allow

    def check(self):
        if self.n_real < 0 or self.n_complex < 0 or self.order < 1:
            raise InputError("the model needs at least one pole", column="order")
        names = [s.name for s in self.inputs]
        if len(set(names)) != len(names):
            raise InputError(f"input names must be unique: {names}", column="inputs")
        onames = [s.name for s in self.outputs]
        if len(set(onames)) != len(onames):
            raise InputError(f"output names must be unique: {onames}", column="outputs")
        for s in self.inputs:
            if s.kind in ("friction", "feature") and s.axis not in self.axes:
                raise InputError(f"input {s.name} needs the command input of axis {s.axis}", column=s.name)
        if self.same_sample is not None and self.same_sample not in SAME_SAMPLE:
            raise InputError(f"same-sample prediction must be one of {sorted(SAME_SAMPLE)}, got "
                             f"{self.same_sample!r}", column="same_sample")
        if self.velocity not in ("backward", "central"):
            raise InputError(f"velocity estimate must be 'backward' or 'central', got '{self.velocity}'",
                             column="velocity")
        for key in list(self.mask) + list(self.dc_gain):
            if key[0] not in onames or key[1] not in names:
                raise InputError(f"({key[0]}, {key[1]}) names an unknown output or input", column="mask")
        for ax in self.axes:    # the model's position and error are derived from one of these
            kinds = [o.predicts for o in self.outputs if o.axis == ax]
            if not set(kinds) & {"error", "position", "tool_position", "tool_error"}:
                raise InputError(f"the outputs of axis '{ax}' ({', '.join(kinds) or 'none'}) predict no "
                                 f"position; add error, position, tool_position or tool_error (or "
                                 f"acceleration with 2 integrators)", column="outputs")


def default_bounds(Ts, n_real, n_complex, zeta=(0.05, 2.0), lowest_hz=0.1):
    """Default search space derived from Ts (thesis Tables 4-1, 5-1, 7-2: up to Nyquist)."""
    nyq = 0.5 / Ts
    hi = 0.95 * nyq
    return Bounds(real_hz=[(lowest_hz, hi)] * n_real, omega_hz=[(max(lowest_hz, 0.5), hi)] * n_complex,
                  zeta=[tuple(zeta)] * n_complex)


def siso_structure(axis="x", integral_action=True, outputs=("error",), ma_order=1, friction=True,
                   velocity="backward", same_sample=None):
    """The rigid-body SISO model of thesis Eqn 4.10-4.15 as a structure.

    e = (c0 s^3 + c1 s^2 + c2 s)/P(s) x_r + d0 s/P(s) sat(v/v_tilde)     (integral action)

    Without integral action in the controller (P/PD loop, e.g. EMPS) the friction path also gets
    the 1/P(s) term (d.c. gain): e_d = (d0 s + d1)/P(s) d_nf.
    """
    ins = [InputSpec("command", axis)]
    if friction:
        ins.append(InputSpec("friction", axis))
    outs = [OutputSpec(k, axis) for k in outputs]
    mask, sign = {}, {}
    for o in outs:
        if o.kind == "error":
            mask[(o.name, ins[0].name)] = (0, 1, 2)          # (c0 s^3 + c1 s^2 + c2 s)
            if friction:
                mask[(o.name, ins[1].name)] = (2,) if integral_action else (2, 3)
                sign[(o.name, ins[1].name)] = +1
        elif o.kind == "velocity":
            mask[(o.name, ins[0].name)] = (0, 1, 2)          # velocity: zero d.c. gain to x_r
            if friction:
                mask[(o.name, ins[1].name)] = (0, 1, 2) if integral_action else (0, 1, 2, 3)
    return Structure(inputs=ins, outputs=outs, n_real=1, n_complex=1, mask=mask,
                     friction_sign=sign, ma_order=ma_order, velocity=velocity, same_sample=same_sample)


def default_mask(out_kind, in_kind, n, integral_action=True):
    """Numerator terms (l: b[l] multiplies s^(n-l)) a pair may have, from the physics.

    - tracking error / velocity from the command: zero d.c. gain (no s^0 term);
    - positions from the command: all terms (d.c. gain 1 is fitted, or constrained);
    - friction to error / positions: strictly proper; no d.c. gain with integral action in the
      controller (the thesis's s/P(s)), a d.c. gain without it (P/PD loops such as EMPS);
    - friction to the tool side: a d.c. gain either way -- the integral action holds the motor
      position, not the tool body, and the friction acting on the tool body deflects the drive
      train by F/k while the axis moves (plant2's flexible Y: 9 N / 1140 N/mm = 7.9 um);
    - accelerations: the terms that survive the appended integrators (handled in LSProblem).
    """
    if in_kind == "command":
        if out_kind in ("error", "velocity", "tool_error"):
            return tuple(range(0, n))
        return tuple(range(0, n + 1))
    if in_kind in ("friction", "feature", "external"):
        tool_side = in_kind == "friction" and out_kind in ("tool_position", "tool_error")
        top = n + 1 if not integral_action or tool_side else n
        if out_kind == "velocity":
            return tuple(range(0, top))
        return tuple(range(1, top))
    return tuple(range(0, n + 1))


def mimo_structure(axes=("x",), outputs=("error",), n_real=1, n_complex=1, coupled=False,
                   friction=True, integral_action=True, integrators=None, dc_gain=None,
                   locked_complex=(), locked_real=(), velocity="backward", ma_order=1, externals=(),
                   same_sample=None, play_mm=None):
    """Build a MIMO structure (thesis Figure 5-3 / 5-12 / 7-8).

    Parameters
    ----------
    axes : axis names; ``coupled=True`` shares one denominator and lets every output depend on
        every input (the 6th-order two-axis model); otherwise pass one axis at a time
    outputs : output kinds per axis (``error``, ``velocity``, ``position``, ``tool_position``,
        ``tool_error``, ``acceleration``)
    integrators : dict output kind -> number of integrators appended (``{"acceleration": 2}``
        predicts the tool-side position from a fitted tool acceleration)
    dc_gain : dict output kind -> (q, value) for the own-axis command input (Eqn 5.15)
    externals : extra trace channels used as inputs (each with its own numerator)
    play_mm : half-width b (mm) of a play feature per axis (presliding friction: the play
        operator of the model's own position, ``model.FEATURE_FUNCTIONS``), with the friction's
        numerator terms and sign; None: none. With ``friction=False`` it is the friction law: a
        force that builds up over the travel 2b after a reversal, where sat(v / v_tilde) builds
        it up over a velocity band
    same_sample : ``hold``, ``cubic``, ``quadratic`` or None (chosen from the data), see :class:`Structure`
    """
    integrators = integrators or {}
    dc_gain = dc_gain or {}
    for k, q in integrators.items():
        # any other count gave an integrated signal labelled as the fitted one (error=1: the
        # "error" output was the integral of the error, 90 % off, reported as a model)
        if q and (k, q) != ("acceleration", 2):
            raise InputError(f"{k}={q}: integrators are appended to a fitted tool-side acceleration "
                             f"(acceleration=2 predicts the tool position); no other output has a "
                             f"meaning with {q} integrator(s)", column="integrators")
    if not coupled and len(axes) > 1:
        raise InputError("a decoupled structure has one axis; identify the axes one by one",
                         column="axes")
    ins = []
    for ax in axes:
        ins.append(InputSpec("command", ax))
        if friction:
            ins.append(InputSpec("friction", ax))
        if play_mm is not None:
            ins.append(InputSpec("feature", ax, params={"function": "play", "width_mm": float(play_mm),
                                                        "source": "position"}))
    for ch in externals:
        ins.append(InputSpec("external", axes[0], channel=ch, name=port_name(ch)))
    outs = []
    for ax in axes:
        for k in outputs:
            q = integrators.get(k, 0)
            predicts = {"acceleration": "tool_position"}.get(k, k) if q == 2 else k
            outs.append(OutputSpec(k, ax, integrators=q, predicts=predicts))
    n = (n_real + len(locked_real)) + 2 * (n_complex + len(locked_complex))
    mask, sign, dcg = {}, {}, {}
    for o in outs:
        for s in ins:
            if not coupled and s.axis != o.axis and s.kind != "external":
                continue
            # the play feature is a friction force (presliding): the friction's terms and sign
            kind = "friction" if is_play(s) else s.kind
            mask[(o.name, s.name)] = default_mask(o.kind, kind, n, integral_action)
            if kind == "friction" and s.axis == o.axis and o.kind == "error":
                sign[(o.name, s.name)] = +1
            if s.kind == "command" and s.axis == o.axis and o.kind in dc_gain:
                dcg[(o.name, s.name)] = tuple(dc_gain[o.kind])
    return Structure(inputs=ins, outputs=outs, n_real=n_real, n_complex=n_complex,
                     locked_real_hz=list(locked_real), locked_complex=list(locked_complex), mask=mask,
                     dc_gain=dcg, friction_sign=sign, velocity=velocity, ma_order=ma_order,
                     same_sample=same_sample)
