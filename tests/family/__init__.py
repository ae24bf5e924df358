"""A seeded family of CNC feed-drive plants for calibrating and testing the diagnosis.

``case(seed)`` draws a plant (one or two axes, masses 20-500 kg, P-PI or PID cascades tuned
from the current loop, Coulomb/viscous or LuGre friction, Stribeck breakaway optional, encoder
quantisation and noise), zero to two undeclared effects with their magnitudes in physical units,
and simulates training and validation traces; nothing is stored. The simulator
(:mod:`family.plant`) is written apart from ``fdid_fmi.virtual`` and ``tests/plant2``.

See :mod:`family.cases` (drawing and effects), :mod:`family.params` (parameters and tuning),
:mod:`family.plant` (integration) and :mod:`family.paths` (commanded paths).
"""
from .cases import KINDS, SPLITS, Case, case, seeds, split_of, visibility
from .params import AxisPlant, Effect, Machine

__all__ = ["AxisPlant", "Case", "Effect", "KINDS", "Machine", "SPLITS", "case", "seeds", "split_of", "visibility"]
