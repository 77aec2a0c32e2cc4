"""ArduPilot: ``INS_ACCOFFS_*``, ``INS_ACCSCAL_*`` and the ``INS_TCAL1_*`` thermal terms, as a param file.

Upstream conventions (ArduPilot ``libraries/AP_InertialSensor``):

* ``AP_InertialSensor_Backend.cpp``, ``_rotate_and_correct_accel``: the sample (m/s², rotated to
  the IMU's orientation) is temperature-corrected, then ``accel -= INS_ACCOFFS``, then multiplied
  per axis by ``INS_ACCSCAL``, then rotated to the board frame.
* ``AP_InertialSensor_tempcal.cpp``, ``TCal::correct_sensor``: with ``T`` and the calibration
  temperature ``INS_ACC1_CALTEMP`` both clamped to ``[INS_TCAL1_TMIN, INS_TCAL1_TMAX]``,
  ``accel -= p(T − 35) − p(CALTEMP − 35)`` where ``p(x) = (c1 x + c2 x² + c3 x³)·1e-6`` and
  ``c_n = INS_TCAL1_ACCn_{X,Y,Z}`` (a fixed reference of 35 °C, ``TEMP_REFERENCE``; coefficients
  stored ×1e6, ``SCALE_FACTOR``).

optcal's thermal offset ``q(T) = Σ_p c_p (T − T_ref)^p`` (:mod:`optcal.applications.export.firmware`) is
re-expanded about 35 °C and ``INS_ACC1_CALTEMP = T_ref``, so ``p(T − 35) − p(T_ref − 35) = q(T)``
exactly.  Mapped: the bias, per-axis scales, ``temperature_bias`` of orders 1-3.  Not mapped:
cross-axis terms, ``temperature_scale``, ``bias_drift``, ``scale_nonlinearity``.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Polynomial

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import THERMAL_ORDER, FirmwareFormat, ThermalOffset, per_axis, write_firmware

#: ArduPilot's fixed reference temperature and coefficient scale (AP_InertialSensor_tempcal.cpp).
TEMP_REFERENCE_C: float = 35.0
COEFFICIENT_SCALE: float = 1e6
#: First lines of the file.
HEADER: tuple[str, ...] = (
    "# ArduPilot accelerometer calibration (first IMU) exported by optcal from {source}",
    "# applied upstream as accel = (raw - INS_ACCOFFS) * INS_ACCSCAL per axis, raw in m/s^2",
    "# (AP_InertialSensor_Backend.cpp, _rotate_and_correct_accel; after the IMU orientation rotation)",
)


def tcal_coefficients(coefficients: np.ndarray, temp_ref: float) -> np.ndarray:
    """``INS_TCAL1_ACC1..3`` per axis (rows) from the offset polynomial about ``temp_ref``, ×1e6."""
    shift = Polynomial([TEMP_REFERENCE_C - temp_ref, 1.0])  # T − T_ref = x + (35 − T_ref), x = T − 35
    out = np.zeros((3, THERMAL_ORDER))
    for i in range(3):
        about_35 = Polynomial(np.concatenate([[0.0], coefficients[i]]))(shift).coef
        padded = np.zeros(THERMAL_ORDER + 1)
        padded[: about_35.size] = about_35
        out[i] = padded[1:] * COEFFICIENT_SCALE  # the constant term cancels against the CALTEMP term
    return out


def thermal_block(thermal: ThermalOffset) -> tuple[list[str], list[str]]:
    """The ``INS_TCAL1_*`` lines of the thermal offset polynomial (re-expanded about 35 °C, ×1e6) and their note."""
    c = tcal_coefficients(thermal.coefficients, thermal.temp_ref)
    lines = [
        "# thermal offset polynomial about 35 C, x1e6 (AP_InertialSensor_tempcal.cpp, correct_sensor)",
        "INS_TCAL1_ENABLE,1",
        f"INS_TCAL1_TMIN,{thermal.tmin:.9g}",
        f"INS_TCAL1_TMAX,{thermal.tmax:.9g}",
        f"INS_ACC1_CALTEMP,{thermal.temp_ref:.9g}",
    ]
    for n in range(THERMAL_ORDER):
        lines += per_axis(f"INS_TCAL1_ACC{n + 1}_{{axis}},{{value:.9g}}", c[:, n])
    return lines, ["INS_TCAL1_ENABLE=1 also enables the gyro thermal terms INS_TCAL1_GYR*, which this file leaves as they are"]


#: ArduPilot's parameter file (first IMU), in Mission Planner's ``NAME,VALUE`` format.
ARDUPILOT = FirmwareFormat(
    "ardupilot", HEADER, "INS_ACCOFFS_{axis},{value:.9g}", "INS_ACCSCAL_{axis},{value:.9g}",
    "the offsets and scales apply to the axes of the calibration data; log them in the IMU's own orientation",
    thermal_block,
)


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The ArduPilot parameters of ``cal`` (first IMU) in Mission Planner's ``NAME,VALUE`` format."""
    return write_firmware(cal, options, ARDUPILOT)
