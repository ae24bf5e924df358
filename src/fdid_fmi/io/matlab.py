"""MATLAB .mat trace reader (``scipy.io.loadmat``), with the EMPS benchmark layout.

EMPS (Janot, Gautier, Brunot 2019; ``DATA_EMPS.mat``, ``DATA_EMPS_PULSES.mat``) is
recognised by its variables ``t``, ``qg``, ``qm``:

==========  =====================================  =============================
variable    meaning                                in the Trace
==========  =====================================  =============================
``t``       time [s]                               ``trace.t``
``qg``      commanded position [m]                 axis ``x`` cmd, channel ``qg`` [mm]
``qm``      measured motor position [m]            axis ``x`` act, channel ``qm`` [mm]
``vir``     controller output [V] (force = gtau*vir)  extra channel ``vir`` [V]
``pulses_N`` injected force pulses [N] (PULSES)     extra channel ``pulses_N`` [N]
``kp kv gtau``  controller gains (1/s, V/(m/s), N/V)  ``trace.meta`` (SI, as in the file)
==========  =====================================  =============================

Any other .mat file: every numeric vector of the same length becomes a column, and roles
and units come from the names or a mapping exactly as for CSV files (see
``fdid_fmi.io.columns``); numeric scalars go to ``trace.meta["scalars"]``. Row numbers in
errors are 1-based sample indices (MATLAB indexing). v7.3 (HDF5) files are not read.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..trace import Trace
from .columns import assemble
from .common import check_file, file_sha256

EMPS_VARS = {"t", "qg", "qm"}
EMPS_UNITS = {"t": "s", "qg": "m", "qm": "m", "vir": "V", "pulses_N": "N"}
EMPS_SCALAR_UNITS = {"kp": "1/s", "kv": "V/(m/s)", "gtau": "N/V"}


def load_mat_variables(path):
    """Numeric vectors and scalars of a .mat file.

    Returns
    -------
    vectors : dict[str, ndarray]  (1-D float copies, file order)
    scalars : dict[str, float]
    skipped : list[str]           (matrices, structs, cells, strings)
    """
    from scipy.io import loadmat

    p = check_file(path)
    try:
        raw = loadmat(str(p), squeeze_me=False, mat_dtype=False)
    except NotImplementedError:
        raise InputError("is a MATLAB v7.3 (HDF5) file, which is not supported; save it with "
                         "save(..., '-v7')", source=str(p)) from None
    except Exception as exc:  # scipy raises ValueError/TypeError/... on non-.mat bytes
        raise InputError(f"is not a readable MATLAB .mat file ({type(exc).__name__}: {exc})",
                         source=str(p)) from None
    vectors, scalars, skipped = {}, {}, []
    for name, val in raw.items():
        if name.startswith("__"):
            continue
        arr = np.asarray(val)
        if arr.dtype.kind not in "biuf" or arr.size == 0:
            skipped.append(name)
        elif arr.size == 1:
            scalars[name] = float(arr.ravel()[0])
        elif arr.ndim <= 2 and max(arr.shape) == arr.size:
            vectors[name] = arr.ravel().astype(float)
        else:
            skipped.append(name)
    return vectors, scalars, skipped


def read_mat(path, mapping=None, units=None, *, axis="x", jitter_tol=0.05) -> Trace:
    """Read a MATLAB .mat trace (EMPS layout recognised).

    Parameters
    ----------
    path : str or Path
    mapping : dict, optional
        ``{"t": var, "<axis>.<role>": var}``; overrides the EMPS layout and name rules.
    units : dict, optional
        ``{var: unit}``; overrides the EMPS units and name suffixes.
    axis : str
        Axis name for the EMPS layout (default ``"x"``).

    Returns
    -------
    Trace
        Positions in mm. ``meta``: ``sha256``, ``layout`` (``"emps"`` or ``"mat"``),
        ``scalars`` (all numeric scalars) and, for EMPS, ``kp``, ``kv``, ``gtau`` and
        ``scalar_units``.
    """
    src = str(path)
    vectors, scalars, skipped = load_mat_variables(path)
    if not vectors:
        raise InputError(f"holds no numeric vectors (variables: {sorted(scalars) + skipped})", source=src)
    meta = {"file": src, "sha256": file_sha256(path), "scalars": dict(scalars)}
    if skipped:
        meta["skipped_variables"] = skipped
    file_units = {}
    if EMPS_VARS <= set(vectors):
        # the EMPS file's units (qg, qm in metres, ...) hold whether or not the roles are mapped
        file_units = {k: u for k, u in EMPS_UNITS.items() if k in vectors}
    if mapping is None and EMPS_VARS <= set(vectors):
        mapping = {"t": "t", f"{axis}.cmd": "qg", f"{axis}.act": "qm"}
        meta["layout"] = "emps"
        for k in EMPS_SCALAR_UNITS:
            if k in scalars:
                meta[k] = scalars[k]
        meta["scalar_units"] = {k: u for k, u in EMPS_SCALAR_UNITS.items() if k in scalars}
    else:
        meta["layout"] = "mat"
    return assemble(vectors, source=src, mapping=mapping, units=units, file_units=file_units,
                    meta=meta, jitter_tol=jitter_tol)
