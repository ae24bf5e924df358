"""Closing the loop: from a model's residual on measured data to the effects it lacks.

``diagnose(model, train, val)`` computes free-run residuals (:mod:`.residuals`), runs the
detectors (:mod:`.friction`, :mod:`.mode`, :mod:`.delay`, :mod:`.periodic`, :mod:`.coupling`,
:mod:`.whiteness`), adds each detected effect to the model and refits it (:mod:`.augment`), and
keeps it only if the held-out error falls meaningfully (:mod:`.loop`); the independent refits
run side by side in worker processes (:mod:`.refits`).
"""
from .loop import DETECTORS, Diagnosis, diagnose
from .residuals import error_table, residuals

__all__ = ["diagnose", "Diagnosis", "DETECTORS", "residuals", "error_table"]
