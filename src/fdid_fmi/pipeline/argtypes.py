"""argparse types of the command line: a bad number stops with one error line naming the option."""
from __future__ import annotations

import argparse
import math


def int_in(lo, hi, what):
    """An integer in [lo, hi]."""
    def conv(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be in {lo} .. {hi}, got {v}")
        return v
    return conv


def finite_float(what, positive=False):
    """A finite float (> 0 when ``positive``)."""
    def conv(text):
        v = _float(text)
        if not math.isfinite(v) or (positive and not v > 0):
            raise argparse.ArgumentTypeError(f"{what} must be a finite number{' > 0' if positive else ''}, "
                                             f"got {text}")
        return v
    return conv


def fraction(what):
    """A fraction in [0, 1)."""
    def conv(text):
        v = _float(text)
        if not 0.0 <= v < 1.0:          # NaN fails too
            raise argparse.ArgumentTypeError(f"{what} must be a fraction in [0, 1), got {text}")
        return v
    return conv


def _float(text):
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
