"""The record of how a pole-search model was identified: one typed view of
``DriveModel.identification``.

The pole search writes it (:func:`~.pole_search.identify_mimo`), the structure choice and the
diagnosis add to it, and the CLI summary, the report and the diagnosis read it back through
:meth:`PoleSearchRecord.from_dict`: the JSON encoding of structures and of (output, input) pairs
(``"x_error|x_cmd"``) lives here and in :meth:`~.structure.Structure.to_dict`, nowhere else.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import InputError
from .structure import Structure, pair_key, split_pair_key


@dataclass
class PoleSearchRecord:
    """How a pole-search / MIMO model was identified (``DriveModel.identification``).

    Attributes
    ----------
    structure : the Structure fitted (same-sample form included)
    real_hz, complex_hz_zeta : searched poles, Hz and [Hz, zeta] (locked ones apart)
    locked_real_hz, locked_complex : known poles kept out of the search
    v_tilde_mm_s : friction transition velocity of each axis in the model, mm/s
    numerators : (output name, input name) -> b (b[l] multiplies s^(n-l), unscaled, Eqn 5.3)
    denominator : A(s) coefficients, highest power first
    same_sample_choice, structure_choice, diagnose : what chose the form / the structure, and
        the diagnosis's command delays (dicts; see ``pole_search._choose_same_sample``,
        :class:`~.choose_structure.StructureChoice`)
    extra : every other entry (search settings, minima, candidates, refinement, ...), as stored
    """

    structure: Structure
    real_hz: list = field(default_factory=list)
    complex_hz_zeta: list = field(default_factory=list)
    locked_real_hz: list = field(default_factory=list)
    locked_complex: list = field(default_factory=list)
    v_tilde_mm_s: dict = field(default_factory=dict)
    numerators: dict = field(default_factory=dict)
    denominator: list = field(default_factory=list)
    same_sample_choice: dict | None = None
    structure_choice: dict | None = None
    diagnose: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    _TYPED = ("structure", "real_hz", "complex_hz_zeta", "locked_real_hz", "locked_complex", "v_tilde_mm_s",
              "numerators", "denominator", "same_sample_choice", "structure_choice", "diagnose")

    @property
    def all_real_hz(self):
        """Searched and locked real poles, Hz."""
        return list(self.real_hz) + list(self.locked_real_hz)

    @property
    def all_complex(self):
        """Searched and locked complex pairs, [(Hz, zeta)]."""
        return [tuple(c) for c in self.complex_hz_zeta] + [tuple(c) for c in self.locked_complex]

    def to_dict(self):
        d = dict(self.extra)
        d.update({"structure": self.structure.to_dict(), "real_hz": list(self.real_hz),
                  "complex_hz_zeta": [list(c) for c in self.complex_hz_zeta],
                  "locked_real_hz": list(self.locked_real_hz),
                  "locked_complex": [list(c) for c in self.locked_complex],
                  "v_tilde_mm_s": dict(self.v_tilde_mm_s),
                  "numerators": {pair_key(k): list(v) for k, v in self.numerators.items()},
                  "denominator": list(self.denominator)})
        for k in ("same_sample_choice", "structure_choice"):
            if getattr(self, k) is not None:
                d[k] = getattr(self, k)
        if self.diagnose:
            d["diagnose"] = self.diagnose
        return d

    @classmethod
    def from_dict(cls, d, source=None):
        """The record of a model's ``identification``; InputError when it is not a pole-search
        record (quasi-static, Full LS, a combined per-axis model: see ``blocks``)."""
        d = d or {}
        if not d.get("structure"):
            what = ("a combined per-axis model (its blocks are records)" if d.get("blocks")
                    else "no 'structure'")
            raise InputError(f"not a pole-search / MIMO identification record ({what})",
                             source=source, column="identification")
        locked_r, locked_c = d.get("locked_real_hz", []), d.get("locked_complex", [])
        return cls(structure=Structure.from_dict(d["structure"], locked_r, locked_c),
                   real_hz=[float(f) for f in d.get("real_hz", [])],
                   complex_hz_zeta=[[float(w), float(z)] for w, z in d.get("complex_hz_zeta", [])],
                   locked_real_hz=[float(f) for f in locked_r],
                   locked_complex=[[float(w), float(z)] for w, z in locked_c],
                   v_tilde_mm_s={a: float(v) for a, v in (d.get("v_tilde_mm_s") or {}).items()},
                   numerators={split_pair_key(k): list(v) for k, v in d.get("numerators", {}).items()},
                   denominator=list(d.get("denominator", [])),
                   same_sample_choice=d.get("same_sample_choice"), structure_choice=d.get("structure_choice"),
                   diagnose=dict(d.get("diagnose") or {}),
                   extra={k: v for k, v in d.items() if k not in cls._TYPED})
