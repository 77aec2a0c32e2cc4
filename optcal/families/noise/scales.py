"""Raw-count scales of the Allan analysis taken from a calibration (``optcal allan --calibration CAL``).

The Allan deviation of a log in raw counts is converted to SI with one factor per sensor
(:meth:`optcal.families.noise.sensors.NoiseSensor.si_per_unit`): counts per g for the
accelerometer, counts per rad/s for the gyroscope.  A calibration knows both.  Raw axis ``i``'s
sensitivity is its reading per unit of the quantity along its own sensing direction: with the
calibration ``ā = T (a − o)`` (g out, Lu 2017, eq. 6) the raw reading of a force ``f`` is
``T⁻¹ f``, so axis ``i`` reads ``‖row i of T⁻¹‖`` counts per g; the gyroscope's
``ω = T_g (g − b_g − …)`` (Tedaldi 2014, eq. 9) gives ``‖row i of T_g⁻¹‖`` counts per rad/s.
The analysis takes one factor per sensor, the mean of the three axes'; their spread is reported
(a few tenths of a percent on a typical MEMS part) because each axis's noise is converted with
the mean.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError

if TYPE_CHECKING:  # an annotation only: the calibration types' import (18 ms) is not the allan command's to pay
    from optcal.families.caltypes.base import Calibration


@dataclass(frozen=True)
class CountScale:
    """One sensor's counts per physical unit, read from a calibration.

    Attributes
    ----------
    sensor : str
        ``"acc"`` or ``"gyro"``.
    per_axis : tuple of float
        Counts per g (accelerometer) or per rad/s (gyroscope) of raw axes x, y, z.
    unit : str
        ``"g"`` or ``"rad/s"``.
    """

    sensor: str
    per_axis: tuple[float, float, float]
    unit: str

    @property
    def value(self) -> float:
        """The mean of the axes' scales: the one factor the analysis converts every axis with."""
        return float(np.mean(self.per_axis))

    @property
    def spread(self) -> float:
        """Largest relative difference of an axis's scale from :attr:`value`."""
        return float(np.max(np.abs(np.asarray(self.per_axis) / self.value - 1.0)))

    def describe(self, source: str) -> str:
        axes = ", ".join(f"{v:.6g}" for v in self.per_axis)
        return (f"{self.sensor} scale {self.value:.6g} counts per {self.unit} from {source} (mean of the raw axes' "
                f"{axes}; each axis converted with the mean, at most {100 * self.spread:.2g} % off its own)")


def _per_axis(scale: NDArray[np.float64]) -> tuple[float, float, float]:
    """A model's physical scale (``‖row i of T⁻¹‖``: each raw axis's reading per unit along its sensing direction)."""
    x, y, z = (float(v) for v in scale)
    return x, y, z


def calibration_scales(cal: Calibration) -> dict[str, CountScale]:
    """Counts per g and (a ``cal_type`` ``imu`` calibration in gyro counts) counts per rad/s of ``cal``.

    Only sensors whose raw input is counts have a scale: a calibration in g or m/s² (or a gyro in
    rad/s or °/s) needs none, and none is returned for it.
    """
    out: dict[str, CountScale] = {}
    if cal.units == "counts":
        out["acc"] = CountScale("acc", _per_axis(cal.lumped().model.physical().scale), "g")
    gyro = getattr(cal, "gyro", None)
    if gyro is not None and getattr(cal, "gyro_units", None) == "counts":
        out["gyro"] = CountScale("gyro", _per_axis(gyro.physical().scale), "rad/s")
    return out


def scale_for(scales: dict[str, CountScale], sensor: str, units: str, source: str) -> float | None:
    """The counts scale of ``sensor`` for a log in ``units``: from ``scales`` when the log is in counts.

    Raises
    ------
    InputError
        The log is in counts but the calibration's input for that sensor is not.
    """
    if units != "counts":
        return None
    if sensor not in scales:
        what = "accelerometer" if sensor == "acc" else "gyroscope"
        raise InputError(f"the log's {what} is in counts, but {source} does not take counts for the {what} "
                         "(it holds no counts scale for it): give the scale by hand, or a calibration of the same sensor in counts")
    return scales[sensor].value
