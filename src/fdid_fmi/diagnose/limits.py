"""Notes the diagnosis reports without adding an effect: what the data cannot show, or only
suggest, and whether the model's structure is adequate for them.

An effect is added only when a refit with it predicts held-out data better (:mod:`.loop`). Some
effects cannot get there from the data given, and some residuals are the structure's, not an
effect's; the user should hear so instead of silence:

``not_observable``  lost motion (backlash) between motor and table when the trace has no
                    tool-side channel for the axis: a motor encoder measures the motor, and the
                    table's lost motion need not reach it (on the virtual drive it does not: the
                    motor-side concentration statistic below is 1.3-1.6 with 20 µm backlash,
                    inside its clean range). Record a tool-side position (grid encoder) or
                    acceleration to check it (``fdid align``).
``suspected``       the final model's motor-side residual is concentrated after motion starts /
                    stops far beyond any clean run of either plant (:func:`.friction.concentration`
                    with the larger of its moving and resting residual as the reference, not the
                    Stribeck detector's pooled one) and neither a Stribeck term nor a backlash
                    was kept: lost motion (or another reversal effect the friction model lacks) is
                    suspected, and without a tool-side channel it cannot be identified.

``carried``         the final model carries a lost motion between motor and tool side itself:
                    its friction input (level sat(v/v_tilde) = +-level while moving) reaches the
                    tool-side output with a d.c. gain G_t (``identify.structure.default_mask``)
                    and the motor-side position with G_m (zero with integral action), a lost
                    motion of 2 level |G_t - G_m| (:func:`lost_motion_carried`). Backlash and the
                    elastic deflection of a drive train with friction on the tool side (2 F/k)
                    give it alike; the note says how large it is and that position data cannot
                    tell the two apart. On an axis without a tool-side channel whose model has
                    the play friction law (``identify.choose_structure``), the note gives the
                    travel 2b over which its friction builds up after a reversal when it is at
                    least the same 5 µm: presliding, or a lost motion the motor crosses before
                    it drives the load, which motor-side data cannot tell apart either (plant2's
                    15 µm backlash with the motor encoder only: r2c1-play16um, 32 µm; its clean
                    feed-forward axis: r1c2-play2um, 4 µm, no note).

``not_checked``     a detector could not test for its effect on these data (too few moves, no
                    command energy in its band, too little constant-velocity motion, no
                    feasible refit): the effect was not looked for, which is not "nothing found".

``held_out_unlike`` the given model predicts the held-out trace ``HELD_OUT_UNLIKE`` times worse
                    (RMS) than its training trace, more than any missing effect did on either
                    plant: the traces may not come from the same machine and axis, or not in the
                    same units or column mapping, and effects judged on them may be wrong.

``order_too_low``   the model as given, refitted with one more real pole (:mod:`.order`),
                    predicts the held-out data better by the keep criterion and the training
                    data no worse: the structure is not adequate, and a residual it leaves is
                    not an effect. Identify with the default structure choice or a higher
                    order.

Threshold of ``suspected`` (``REVERSAL_SUSPECT``), calibrated on the second plant and measured on
the virtual drive. The statistic's reference outside the windows is the larger of the residual
while moving and at rest (:func:`.friction.concentration`): pooled, as the Stribeck detector
has it, it fell with the share of the trace the axis rests, and on the bundled clean example
(``virtual_xy_moves.csv``, Y at rest 83 % of the trace with 0.066 µm of residual there) the
default path's r2c2-noI model gave 42.8 and a false note (21.2 was the gate then, set on the
thesis path's pooled 6.55-17.7). Calibration: plant2's 9 clean training traces (clean_rigid,
clean_rigid_2ms, clean_ff, seeds 0-2), each with fdid identify's default model
(``identify_auto``) and the thesis path's (``identify_siso``): 4.72-15.80 and 5.42-15.95, so
1.2 x 15.95 = 19.1. There, its 15 µm backlash with the motor encoder only gives 28.3 (default
path) and 47.1 (thesis path): the note. Measured on the virtual drive (not used to set it): the
bundled example's default model 10.5 (X) and 14.8 (Y; 2.1 with ``--structure rigid``), five
clean scenarios (``diagnose.scenarios``: clean seeds 1 and 3, clean_fast, clean_soft, clean_xy)
1.04-1.41 (default) and 1.22-1.81 (thesis): no note; its backlash does not reach the motor side,
which the ``not_observable`` note covers. The structure still matters on the example (14.8
against 2.1: r2c2-noI fits the moving residual to 0.138 µm, the rigid model to 0.371 µm, and
both leave 0.53 µm in the windows); on plant2 the two paths differ by less than 30 %.

Threshold of ``held_out_unlike`` (``HELD_OUT_UNLIKE``), calibrated on the second plant and measured
on the virtual drive (each scenario's base model, the thesis path's, its held-out / training free-run RMS per channel and validation trace). On
plant2 an unmodelled effect raises it up to 20.2 (the 3-sample dead time on the diamond: 5.79
against 0.287 µm; 22.8 with the default path's r1c2 hold model), the rest 0.59-4.3: 1.2 x 22.8 =
27.4. Measured on the virtual drive: its 12 diagnosis scenarios 0.92-1.29, no note. Another
machine: the virtual clean model on plant2's clean_rigid circle /
diamond / reversals 1069 / 1166 / 441, plant2's model on the virtual clean held-out trace 1184;
positions in µm under a mm header about 1000x (tests/test_diagnose_inputs.py): notes.

Threshold of ``carried`` (``LOST_MOTION_NOTE_MM``), calibrated on the virtual drive (MIMO r1c1 of
error and tool position): its flexible Y axis, without lost motion, reads 2.7 µm
(the tool side's velocity-proportional lag projected on sat(v/v_tilde)), its 20 µm backlash 21.4
µm: hence 5 µm. Measured on the second plant: its backlash axis reads 16.4 µm against 16.0 µm
(15 µm of backlash, 1.0 µm of elastic deflection), its flexible Y axis 15.6 µm (the 9 N of
friction on its tool body over a 1140 N/mm drive train: 15.8 µm).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import Enum

from ..model import is_play
from .augment import TOOL_KINDS, friction_path

REVERSAL_SUSPECT = 19.1
HELD_OUT_UNLIKE = 27.4
LOST_MOTION_NOTE_MM = 0.005


class NoteKind(str, Enum):
    NOT_OBSERVABLE = "not_observable"
    SUSPECTED = "suspected"
    ORDER_TOO_LOW = "order_too_low"
    NOT_CHECKED = "not_checked"
    HELD_OUT_UNLIKE = "held_out_unlike"
    CARRIED = "carried"


@dataclass
class Note:
    """A finding reported without adding an effect.

    kind : :class:`NoteKind`; axis : the axis it concerns; effect : the effect kind it is about
    (as in ``effects_added``); text : one sentence for the user; statistic, threshold : the
    evidence, when a statistic decided it.
    """

    kind: NoteKind
    axis: str
    effect: str
    text: str
    statistic: float | None = None
    threshold: float | None = None

    def to_dict(self):
        d = asdict(self)
        d["kind"] = self.kind.value
        return d


def play_input(model, axis):
    """Index of the axis's play friction input (``model.FEATURE_FUNCTIONS``), or None."""
    return next((i for i, p in enumerate(model.inputs) if p.axis == axis and is_play(p)), None)


def lost_motion_carried(model, axis):
    """Lost motion (mm) the model carries between the motor and the tool side of ``axis``.

    The friction input is ``level`` sat(v/v_tilde), +-``level`` while the axis moves (the play
    friction law: +-1 once the axis has moved 2b); with d.c. gains G_t to the tool-side output
    and G_m to the motor-side position (zero with integral action; without it the motor lags
    too), the tool moves against the motor by 2 level |G_t - G_m| between the two directions.
    None when the model has no friction input, no tool-side output or no motor-side position for
    the axis.
    """
    i = friction_path(model.inputs, axis)     # sat(v/v_tilde), else the play (level 1)
    o = next((k for k in (model.output_index(kind, axis) for kind in TOOL_KINDS) if k is not None), None)
    p = model.output_index("position", axis)
    if i is None or o is None or p is None or model.position_side(axis) != "motor":
        return None
    G = model.steady_state_maps()[2]
    level = float(model.inputs[i].params.get("level", 1.0))
    return 2.0 * level * abs(float(G[o, i] - G[p, i]))


def data_limits(axes, tool_axes, concentration, kept, lost_motion=None, play_mm=None):
    """Notes on what the data of a diagnosis cannot show or only suggest.

    Parameters
    ----------
    axes : axes diagnosed
    tool_axes : axes whose training trace has a tool-side channel
    concentration : dict axis -> the final model's reversal-concentration statistic on the
        training trace (:func:`.friction.concentration`, its default ``rest="larger"``); an
        effect that was kept may explain it
    kept : effect dicts that were kept (``Diagnosis.effects_added``) or that the model had already
    lost_motion : dict axis -> :func:`lost_motion_carried` of the final model (mm or None)
    play_mm : dict axis -> the half-width b (mm) of the final model's play friction law, if any

    Returns
    -------
    list of :class:`Note`
    """
    notes = []
    for a in axes:
        kept_here = {e.get("kind") for e in kept if e.get("axis") == a}
        b = (play_mm or {}).get(a)
        if b is not None and a not in tool_axes and 2 * b >= LOST_MOTION_NOTE_MM:
            notes.append(Note(NoteKind.CARRIED, a, "backlash",
                              f"axis {a}: the model's friction builds up over {2e3 * b:.3g} µm of travel "
                              f"after each reversal (the play friction law, half-width {1e3 * b:.3g} µm): "
                              "presliding friction, or lost motion (backlash) the motor crosses before "
                              "it drives the load; motor-side data cannot tell the two apart: record a "
                              "tool-side position or acceleration", 2 * b))
            continue      # it says what the not_observable / suspected notes would
        if a in tool_axes:
            lm = (lost_motion or {}).get(a)
            if lm is not None and lm >= LOST_MOTION_NOTE_MM and "backlash" not in kept_here:
                notes.append(Note(NoteKind.CARRIED, a, "backlash",
                                  f"axis {a}: the model carries a lost motion of {lm * 1e3:.1f} µm between "
                                  "motor and tool side (its friction's d.c. gain to the tool side): "
                                  "backlash, or the elastic deflection of the drive train by friction on "
                                  "the tool side; position data cannot tell the two apart",
                                  lm, LOST_MOTION_NOTE_MM))
            continue
        conc = concentration.get(a)
        if conc is not None and conc >= REVERSAL_SUSPECT and not kept_here & {"stribeck", "backlash"}:
            notes.append(Note(NoteKind.SUSPECTED, a, "backlash",
                              f"axis {a}: residual after motion starts/stops {conc:.3g}x the rest "
                              f"(clean runs of both plants stay below {REVERSAL_SUSPECT:g}) and no "
                              "Stribeck term explains it: lost motion (backlash) is suspected; it is "
                              "not identifiable from motor-side data: record a tool-side position "
                              "or acceleration", conc, REVERSAL_SUSPECT))
        else:
            notes.append(Note(NoteKind.NOT_OBSERVABLE, a, "backlash",
                              f"axis {a}: lost motion (backlash) between motor and table was not "
                              "checked: the trace has no tool-side channel for this axis"))
    return notes


def order_too_low(axis, gain, min_gain, chosen=False):
    """The note for a first-round order check that met the keep criterion (:mod:`.loop`).

    gain : the largest relative held-out RMS reduction of the refit with one more real pole
    (against the better of the model and its refit with the same order); min_gain : the keep
    criterion's; chosen : the model's structure was chosen from its training data (``fdid
    identify``'s default), so the advice is not to choose it again.
    """
    advice = ("its structure was chosen on the training data, where no larger one won by the "
              "parsimony margin: record training moves that excite what the held-out data show, "
              "or pin a higher order (fdid identify --method mimo --n-real/--n-complex)" if chosen else
              "identify with the default structure choice (fdid identify without structure flags) "
              "or a higher order")
    return Note(NoteKind.ORDER_TOO_LOW, axis, "order",
                f"axis {axis}: one more real pole lowers the held-out RMS by {100 * gain:.1f} % "
                f"(criterion {100 * min_gain:g} %): the model's order is too low for these data; "
                f"{advice}", gain, min_gain)


def held_out_unlike(before, split=False, unseen=()):
    """Notes for the axes whose held-out free-run RMS is at least ``HELD_OUT_UNLIKE`` times the
    training one (``before``: ``Diagnosis.before``, tables of the given model per trace and
    channel), the channel with the largest ratio named; ``split``: the held-out data are the
    second part of the training record (no held-out trace was given); ``unseen``: channels only
    the held-out data have (an input the model does not know may be what moves them: EMPS's
    pulses_N, 35 x)."""
    worst = {}
    for ch, row in before.get("val", {}).items():
        t = before.get("train", {}).get(ch, {}).get("rms_um")
        if t and t > 0 and row["rms_um"] >= HELD_OUT_UNLIKE * t:
            a = ch.split(".")[0]
            if row["rms_um"] / t > worst.get(a, (0.0,))[0]:
                worst[a] = (row["rms_um"] / t, ch, row["rms_um"], t)
    held, train, check = (("the second part of the record (held out)", "its first part",
                           "the record does not change machine, axis, units or mapping between its parts")
                          if split else
                          ("the held-out trace", "the training trace",
                           "both traces come from this machine and axis, in the same units and column mapping"))
    return [Note(NoteKind.HELD_OUT_UNLIKE, a, "diagnosis",
                 f"axis {a}: the given model predicts {held} {r:.0f} x worse than {train} ({ch}: {v:.4g} "
                 f"against {t:.4g} µm RMS), more than a missing effect gave on either test plant "
                 f"({HELD_OUT_UNLIKE:g} x): "
                 + (f"its channels {list(unseen)}, which the training data lack, may carry an input the model "
                    f"does not know (the coupling detector looks for it), else check that {check}" if unseen
                    else f"check that {check}; the effects judged on it may be wrong"),
                 statistic=r, threshold=HELD_OUT_UNLIKE)
            for a, (r, ch, v, t) in worst.items()]


def not_checked(candidates):
    """Notes for the candidates (:class:`.base.Candidate`) whose detector could not run on the
    data (``Candidate.not_checked``), one per effect kind and axis; none where another
    statistic of the kind checked it (the dead time's free run on a trace too short for its
    early answer)."""
    candidates = list(candidates)
    checked = {(c.kind, c.axis) for c in candidates if not c.not_checked}
    notes, seen = [], set(checked)
    for c in candidates:
        if c.not_checked and (c.kind, c.axis) not in seen:
            seen.add((c.kind, c.axis))
            notes.append(Note(NoteKind.NOT_CHECKED, c.axis, c.kind,
                              f"axis {c.axis}: {c.kind.replace('_', ' ')} was not checked: {c.not_checked}"))
    return notes
