"""Units of gyro samples: raw counts, rad/s or °/s, decided once, printed, overridable.

The calibration ``T_g`` absorbs the units (rad/s per raw unit), so the units decide only
the *nominal* conversion: the "before calibration" baseline and the starting point of the
fit.  The decision follows the accelerometer's (:mod:`optcal.data.units`): the user's
``gyro_units`` wins, then a unit word in the file's column names or the file format (ROS
``sensor_msgs/Imu`` and PX4 ULog state rad/s), then the data: integer-valued samples are
counts; otherwise the fastest rates reached in the moves (99th percentile of ``|g − b|``)
tell rad/s (a hand-turned sensor peaks at 1-20 rad/s) from °/s (60-1200 °/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError

GYRO_UNITS: tuple[str, ...] = ("counts", "rad/s", "deg/s")
_ALIASES: dict[str, str] = {
    "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts",
    "rad/s": "rad/s", "rad_s": "rad/s", "rads": "rad/s", "rps": "rad/s",
    "deg/s": "deg/s", "deg_s": "deg/s", "dps": "deg/s", "°/s": "deg/s", "degs": "deg/s",
}
#: Peak rate (99th percentile of the bias-free rate norm) above which float data are °/s.
DEG_S_MIN_PEAK: float = 40.0
#: rad/s per unit for the units with a stated scale.
RAD_PER_UNIT: dict[str, float] = {"rad/s": 1.0, "deg/s": float(np.pi / 180.0)}


def normalise_gyro_units(units: str) -> str:
    """Map a spelling (``"dps"``, ``"rad_s"``, ``"LSB"``, ...) to one of :data:`GYRO_UNITS`."""
    key = str(units).strip().lower()
    if key not in _ALIASES:
        raise InputError(f"unknown gyro units {units!r}; use one of {', '.join(GYRO_UNITS)}")
    return _ALIASES[key]


@dataclass(frozen=True)
class GyroUnitsDecision:
    """The gyro units and how they were decided."""

    units: str
    reason: str

    @property
    def rad_per_unit(self) -> float | None:
        """rad/s per raw unit (``None`` for counts, whose scale is what calibration finds)."""
        return RAD_PER_UNIT.get(self.units)


def decide_gyro_units(
    gyro: NDArray, bias: NDArray, requested: str | None = None, hint: str | None = None
) -> GyroUnitsDecision:
    """Decide the units of raw gyro samples (module docstring).

    Parameters
    ----------
    gyro : ndarray, shape (n, 3)
        Raw samples, moves included.
    bias : ndarray, shape (3,)
        Rest reading (mean of the still intervals), raw units.
    requested : str, optional
        The caller's ``gyro_units``; always wins.
    hint : str, optional
        Units stated by the file (column names, file format).
    """
    if requested is not None:
        return GyroUnitsDecision(normalise_gyro_units(requested), "given with gyro_units")
    if hint is not None:
        return GyroUnitsDecision(normalise_gyro_units(hint), "stated by the file")
    g = np.asarray(gyro, float)
    g = g[np.all(np.isfinite(g), axis=1)]
    if g.size == 0:
        raise InputError("no finite gyro samples; cannot tell the gyro units")
    if np.all(g == np.round(g)):
        return GyroUnitsDecision("counts", "integer-valued samples (raw counts)")
    peak = float(np.percentile(np.linalg.norm(g - bias, axis=1), 99))
    if peak >= DEG_S_MIN_PEAK:
        return GyroUnitsDecision("deg/s", f"peak rate {peak:.3g} ≥ {DEG_S_MIN_PEAK:g} (°/s)")
    return GyroUnitsDecision("rad/s", f"peak rate {peak:.3g} < {DEG_S_MIN_PEAK:g} (rad/s)")
