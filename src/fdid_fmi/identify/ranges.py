"""The data ranges an identification is given, checked once at its entry."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..trace import Trace

ROLES_READ = ("cmd", "act", "tool", "vel", "acc")   # what the identifiers read of an axis


def training_ranges(traces, axes=(), channels=(), roles=ROLES_READ):
    """``traces`` (a Trace or a list of them) as a list, checked: at least one, all Traces, one
    sample time, and every channel the identification reads (``roles`` of ``axes``, extra
    ``channels``) finite. A Trace checks its channels when it is built; one replaced in
    ``trace.channels`` afterwards is not, and a NaN in it would give a NaN model or a numpy
    error instead of one line naming the column and row.

    Returns
    -------
    list[Trace]
    """
    traces = [traces] if not isinstance(traces, (list, tuple)) else list(traces)
    if not traces:
        raise InputError("no data range given: pass a Trace or a non-empty list of Traces", column="traces")
    for tr in traces:
        if not isinstance(tr, Trace):
            raise InputError(f"a data range must be a Trace, got {type(tr).__name__}", column="traces")
    Ts = traces[0].Ts
    for tr in traces[1:]:
        if abs(tr.Ts - Ts) > 1e-6 * Ts:
            raise InputError(f"data ranges have different sample times ({Ts:g} s, {tr.Ts:g} s); "
                             f"resample them to one", source=tr.source, column="time")
    for tr in traces:
        names = [tr.roles[ax][r] for ax in axes for r in roles if tr.has(ax, r)] + list(channels)
        for name in dict.fromkeys(names):
            if name not in tr.channels:
                continue          # the identifier names a missing channel itself
            data = np.asarray(tr.channels[name].data, float)
            if data.shape != tr.t.shape:
                raise InputError(f"has {data.size} samples but time has {tr.n}", source=tr.source, column=name)
            bad = ~np.isfinite(data)
            if bad.any():
                raise InputError("contains NaN or inf", source=tr.source, column=name,
                                 row=int(np.argmax(bad)) + 1)
    return traces


def check_externals(trace, axes, externals, what="external input"):
    """Refuse an external-input channel that is a role of an identified axis (``what`` names
    the input in the message: the CLI's ``--external``).

    An external input is a measured signal from outside the drive (``pulses_N``, another
    axis's command). The identified axes' own channels -- command, measured or tool-side
    position, velocity, acceleration, current (``trace.roles``) and tracking error
    (``meta["error_channels"]``) -- are the model's command or what it predicts: as an input,
    the model would predict the measured position from the measured position (a free run of
    0.05 um RMS on a 370 um error) and could not run without the measurement it replaces.
    """
    used = {}
    for ax in axes:
        for role, ch in trace.roles.get(ax, {}).items():
            used.setdefault(ch, f"{ax}.{role}")
        ch = (trace.meta.get("error_channels") or {}).get(ax)
        if ch is not None:
            used.setdefault(ch, f"{ax}.err (tracking error)")
    for ch in externals:
        if ch in used:
            raise InputError(f"{what} {ch}: this channel is {used[ch]} of the identified axes "
                             f"{list(axes)} (their command, or a measurement of what the model "
                             f"predicts), not an input from outside them; give a channel such as "
                             f"pulses_N or a command of an axis not identified (to model axes "
                             f"together: --coupled)", source=trace.source, column=ch)
