"""Units of trace channels and their conversion to the CNC convention.

Positions are held in mm, velocities in mm/s, accelerations in mm/s^2, jerk in
mm/s^3, rotary angles in deg, time in s. Other physical channels (current,
voltage, force) keep their own unit.
"""
from .errors import InputError

# unit name -> (quantity, factor to the canonical unit of that quantity)
UNITS = {
    "s": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6),
    "m": ("position", 1e3), "mm": ("position", 1.0), "um": ("position", 1e-3),
    "nm": ("position", 1e-6), "deg": ("angle", 1.0), "rad": ("angle", 57.29577951308232),
    "m_s": ("velocity", 1e3), "mm_s": ("velocity", 1.0), "mm_min": ("velocity", 1 / 60.0),
    "um_s": ("velocity", 1e-3), "m_min": ("velocity", 1e3 / 60.0),
    "deg_s": ("angular_velocity", 1.0), "rad_s": ("angular_velocity", 57.29577951308232),
    "rpm": ("angular_velocity", 6.0),
    "m_s2": ("acceleration", 1e3), "mm_s2": ("acceleration", 1.0), "g": ("acceleration", 9806.65),
    "m_s3": ("jerk", 1e3), "mm_s3": ("jerk", 1.0),
    "A": ("current", 1.0), "mA": ("current", 1e-3),
    "V": ("voltage", 1.0), "N": ("force", 1.0), "Nm": ("torque", 1.0),
    "1": ("dimensionless", 1.0), "pct": ("dimensionless", 0.01),
}
CANONICAL = {
    "time": "s", "position": "mm", "angle": "deg", "velocity": "mm_s",
    "angular_velocity": "deg_s", "acceleration": "mm_s2", "jerk": "mm_s3",
    "current": "A", "voltage": "V", "force": "N", "torque": "Nm", "dimensionless": "1",
}
_ALIASES = {"µm": "um", "sec": "s", "mm/s": "mm_s", "m/s": "m_s", "mm/s^2": "mm_s2",
            "mm/s2": "mm_s2", "m/s^2": "m_s2", "m/s2": "m_s2", "mm/min": "mm_min", "-": "1", "": "1"}


def normalise_unit(unit, source=None, column=None):
    """Return the canonical spelling of ``unit`` or raise a clear InputError."""
    u = _ALIASES.get(unit, unit)
    if u not in UNITS:
        raise InputError(f"unknown unit '{unit}'; expected one of {sorted(UNITS)}",
                         source=source, column=column)
    return u


def to_canonical(values, unit, source=None, column=None, in_place=False):
    """Convert ``values`` (array) given in ``unit`` to the canonical unit of its quantity.

    ``in_place``: convert the caller's own float64 array itself (a reader's column of a long
    trace), with the same doubles.

    Returns
    -------
    values : ndarray (a new array, the input unchanged; with ``in_place`` the input itself)
    unit : str, the canonical unit
    """
    u = normalise_unit(unit, source, column)
    quantity, factor = UNITS[u]
    if in_place:
        values *= factor
        return values, CANONICAL[quantity]
    return values * factor, CANONICAL[quantity]


def unit_from_suffix(name):
    """Guess a unit from a column-name suffix such as ``x_cmd_mm`` or ``x_v_mm_s``.

    The longest matching suffix wins (``_mm_s`` before ``_s``). Returns None
    when no known suffix is present.
    """
    best = None
    for u in UNITS:
        if u in ("1",):
            continue
        if name.endswith("_" + u) and (best is None or len(u) > len(best)):
            best = u
    return best
