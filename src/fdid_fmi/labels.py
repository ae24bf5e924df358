"""What the reports call the package's keys: one table, key -> label with its unit.

The machine-readable outputs (JSON, CSV, a model's ``metrics``) keep the keys; a table a person
reads shows the label: :meth:`fdid_fmi.report.Report.add_table` looks every column up here, so
the HTML reports of ``fdid plan``, ``fdid diagnose``, ``fdid demo`` and the fleet say
"contour error MAX [µm]" where the JSON says ``contour_max_um``. A column that is not a key of
this table (already words, e.g. "v [mm/s]") is shown as it is.

Words used throughout:

- *measured tracking error*: commanded minus measured position, what the drive did;
- *predicted tracking error*: commanded minus the twin's position, what the twin says it does;
- *discrepancy*: the difference between the twin's prediction and the measurement (of the
  position, or equally of the tracking error; RMS and MAX do not depend on its sign), how far
  the twin is off. Judge a discrepancy against the measured tracking error beside it.

A key written ``<axis>_...`` stands for every axis: ``x_max_err_um`` is labelled from
``<axis>_max_err_um`` with ``x`` for ``<axis>``; ``<output>`` in a label is the model output a
figure belongs to (:func:`metric_label`).
"""
from __future__ import annotations

from typing import NamedTuple


class Term(NamedTuple):
    """A key's label (unit in brackets) and the factor from the stored value to that unit."""

    label: str
    scale: float = 1.0


LABELS = {
    # --- plan: per NC block (plan.predict) and the feed table (plan.optimize)
    "N": Term("N (block number)"),
    "feed_mm_min": Term("programmed feed [mm/min]"),
    "length_mm": Term("length [mm]"),
    "duration_s": Term("time [s]"),
    "<axis>_max_err_um": Term("<axis> predicted tracking error MAX [µm]"),
    "contour_rms_um": Term("contour error RMS [µm]"),
    "contour_max_um": Term("contour error MAX [µm]"),
    "contour_signed_peak_um": Term("contour error signed peak [µm]"),
    "contour_max_with_dwell_um": Term("contour error MAX with the dwells after it [µm]"),
    "flag": Term("above the tolerance"),
    "first_pass_mm_min": Term("first-pass feed [mm/min]"),
    "new_feed_mm_min": Term("new feed [mm/min]"),
    "override_pct": Term("feed override [%]"),
    "contour_max_before_um": Term("contour error MAX before [µm]"),
    "contour_max_after_um": Term("contour error MAX after [µm]"),
    "time_before_s": Term("time before [s]"),
    "time_after_s": Term("time after [s]"),
    # --- the plan's whole-program table
    "predicted_rms_um": Term("predicted RMS [µm]"),
    "predicted_max_um": Term("predicted MAX [µm]"),
    # --- measured against predicted: diagnose, demo
    "measured_rms_um": Term("measured tracking error RMS [µm]"),
    "measured_max_um": Term("measured tracking error MAX [µm]"),
    "rms_before_um": Term("discrepancy RMS before [µm]"),
    "rms_after_um": Term("discrepancy RMS after [µm]"),
    "max_before_um": Term("discrepancy MAX before [µm]"),
    "max_after_um": Term("discrepancy MAX after [µm]"),
    "rms_change": Term("discrepancy RMS change"),
    "fmu_rms_before_um": Term("FMU discrepancy RMS before [µm]"),
    "fmu_rms_after_um": Term("FMU discrepancy RMS after [µm]"),
    "fmu_max_before_um": Term("FMU discrepancy MAX before [µm]"),
    "fmu_max_after_um": Term("FMU discrepancy MAX after [µm]"),
    "fmu_rms_um": Term("FMU discrepancy RMS [µm]"),
    "fmu_max_um": Term("FMU discrepancy MAX [µm]"),
    # the columns of ``fdid demo``'s table, as its summary.json names them
    "error RMS [µm]": Term("measured tracking error RMS [µm]"),
    "FMU RMS [µm]": Term("FMU discrepancy RMS [µm]"),
    "FMU MAX [µm]": Term("FMU discrepancy MAX [µm]"),
    "Full LS RMS [µm]": Term("full-LS model discrepancy RMS [µm]"),
    "quasi-static RMS [µm]": Term("quasi-static model discrepancy RMS [µm]"),
    # --- fleet: one row per axis (fleet.runner.table_rows)
    "error": Term("error message"),
    "fmu_vs_reference_mm": Term("largest |FMU − reference simulator| [mm]"),
    "model_rms_motor_um": Term("model discrepancy RMS, motor side [µm]"),
    "model_rms_tool_um": Term("model discrepancy RMS, tool side [µm]"),
    "friction_peak_um": Term("friction step-response peak [µm]"),
    "effects_added": Term("effects added by diagnosis"),
    "wall_s": Term("wall time [s]"),
    # --- a model's training record (DriveModel.metrics, written by the identification)
    "objective_scaled_rms": Term("search objective: RMS of the weighted fit residual [-]"),
    "fit_rms": Term("<output>: RMS of the fit residual [µm]", 1e3),
    "fit_rms_mm": Term("RMS of the fit residual [µm]", 1e3),
    "fit_rms_um": Term("RMS of the fit residual [µm]"),
    "samples": Term("training samples"),
    "wall_time_s": Term("identification time [s]"),
}


def term(key):
    """The :class:`Term` of ``key`` (exact, else as ``<axis>_rest``), or None."""
    key = str(key)
    if key in LABELS:
        return LABELS[key]
    axis, sep, rest = key.partition("_")
    t = LABELS.get(f"<axis>_{rest}") if sep and axis else None
    return Term(t.label.replace("<axis>", axis), t.scale) if t else None


def label(key):
    """What a reader sees for ``key``: its label, or the key itself when it has none."""
    t = term(key)
    return t.label if t else str(key)


def metric_label(key, output=None):
    """Label of a training-record key; ``output`` fills ``<output>`` (per-output figures)."""
    t = term(key)
    if t is None:
        return str(key) if output is None else f"{output}: {key}"
    return t.label.replace("<output>", str(output)) if output is not None else t.label
