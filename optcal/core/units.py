"""Units of the sensors' samples: every unit name and accepted spelling, for both sensors, once.

The accelerometer's samples are in ``g``, ``m/s^2`` or raw ``counts``; the gyro's in
``counts``, ``rad/s`` or ``deg/s``.  :data:`UNIT_ALIASES` maps every accepted spelling (for
``--units``, ``--gyro-units`` and unit words in column names) to its unit, per sensor, and
:func:`normalise_units` reads a spelling.  The fixed factors of the units with a stated
scale are :data:`G_PER_UNIT` and :data:`RAD_PER_UNIT`; counts have none (their scale is what
calibration finds).  Which units a data set is in is a decision about the data, made in
:mod:`optcal.data.units`.
"""

from __future__ import annotations

import numpy as np

from optcal.core.model import STANDARD_GRAVITY
from optcal.errors import InputError

#: Accepted spellings of each sensor's units, mapped to the unit (the first spelling of each unit is its name).
UNIT_ALIASES: dict[str, dict[str, str]] = {
    "accelerometer": {
        "g": "g",
        "m/s^2": "m/s^2",
        "m/s2": "m/s^2",
        "m/s²": "m/s^2",
        "mps2": "m/s^2",
        "ms2": "m/s^2",
        "m_s2": "m/s^2",
        "m_s_2": "m/s^2",
        "ms_2": "m/s^2",
        "counts": "counts",
        "count": "counts",
        "lsb": "counts",
        "raw": "counts",
        "adc": "counts",
    },
    "gyro": {
        "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts",
        "rad/s": "rad/s", "rad_s": "rad/s", "rads": "rad/s", "rps": "rad/s",
        "deg/s": "deg/s", "deg_s": "deg/s", "dps": "deg/s", "°/s": "deg/s", "degs": "deg/s",
    },
}
#: The units of each sensor, in the order messages list them.
SENSOR_UNITS: dict[str, tuple[str, ...]] = {
    sensor: tuple(dict.fromkeys(aliases.values())) for sensor, aliases in UNIT_ALIASES.items()
}
#: Units of accelerometer samples (and of an accelerometer calibration's input).
ACCEL_UNITS: tuple[str, ...] = SENSOR_UNITS["accelerometer"]
#: Units of gyro samples.
GYRO_UNITS: tuple[str, ...] = SENSOR_UNITS["gyro"]
#: g per unit for the accelerometer units with a stated scale.
G_PER_UNIT: dict[str, float] = {"g": 1.0, "m/s^2": 1.0 / STANDARD_GRAVITY}
#: Seconds per unit of the time units a time column or ``--time-unit`` may state.
SECONDS_PER_TIME_UNIT: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: rad/s per unit for the gyro units with a stated scale.
RAD_PER_UNIT: dict[str, float] = {"rad/s": 1.0, "deg/s": float(np.pi / 180.0)}


def normalise_units(units: str, sensor: str = "accelerometer") -> str:
    """Map a spelling of one of ``sensor``'s units (``"m/s2"``, ``"LSB"``, ``"dps"``, ...) to the unit.

    Parameters
    ----------
    units : str
        Any accepted spelling (:data:`UNIT_ALIASES`), in any case, with surrounding spaces.
    sensor : {"accelerometer", "gyro"}

    Raises
    ------
    InputError
        For a spelling of none of the sensor's units.
    """
    aliases = UNIT_ALIASES[sensor]
    key = str(units).strip().lower()
    if key not in aliases:
        what = "units" if sensor == "accelerometer" else f"{sensor} units"
        raise InputError(f"unknown {what} {units!r}; use one of {', '.join(SENSOR_UNITS[sensor])}")
    return aliases[key]


def to_g_factor(units: str) -> float | None:
    """Factor converting accelerometer ``units`` to g (``None`` for counts, whose scale is what calibration finds)."""
    return G_PER_UNIT.get(normalise_units(units))
