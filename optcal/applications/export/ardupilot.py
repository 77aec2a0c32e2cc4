"""ArduPilot: ``INS_ACCOFFS_*``, ``INS_ACCSCAL_*``, ``INS_GYROFFS_*``, ``INS_ACC_ID``, ``INS_TCAL1_*``: a param file.

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
exactly.  Mapped: the bias, per-axis scales, ``temperature_bias`` of orders 1-3, an ``imu``
calibration's gyro bias (``INS_GYROFFS``, :mod:`optcal.applications.export.firmware_gyro`) and the
device ids when given.  Not mapped: cross-axis terms, ``temperature_scale``, ``bias_drift``,
``scale_nonlinearity``, the gyro's scale, misalignment and g-sensitivity (each with its loss).

Names (``libraries/AP_InertialSensor/AP_InertialSensor.cpp``, ``var_info``): the first three IMUs
keep the classic names, ``INS_ACCOFFS``/``INS_ACC2OFFS``/``INS_ACC3OFFS``, ``INS_ACCSCAL``...,
``INS_GYROFFS``/``INS_GYR2OFFS``/``INS_GYR3OFFS``, ``INS_ACC_ID``/``INS_ACC2_ID``/``INS_ACC3_ID``,
``INS_GYR_ID``..., ``INS_TCAL1_``/``INS_TCAL2_``/``INS_TCAL3_`` and ``INS_ACCn_CALTEMP``.
``AP_InertialSensor::register_accel`` marks an accelerometer whose saved ``INS_ACC_ID`` is missing
or differs from the detected device uncalibrated; ``register_gyro`` marks a gyro whose saved id
differs as needing calibration.  The file is Mission Planner's ``NAME,VALUE`` lines, which
pymavlink's ``MAVParmDict.load`` reads (``#`` comments stripped).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Polynomial

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import (THERMAL_ORDER, FirmwareFormat, FirmwareNames, Param, ThermalOffset,
                                                 per_axis, render_lines, write_firmware)

#: ArduPilot's fixed reference temperature and coefficient scale (AP_InertialSensor_tempcal.cpp).
TEMP_REFERENCE_C: float = 35.0
COEFFICIENT_SCALE: float = 1e6
#: First lines of the file.
HEADER: tuple[str, ...] = (
    "ArduPilot IMU calibration (IMU {imu}) exported by optcal from {source}",
    "applied upstream as accel = (raw - {acc_offset}) * {acc_scale} per axis, raw in m/s^2",
    "(AP_InertialSensor_Backend.cpp, _rotate_and_correct_accel; after the IMU orientation rotation)",
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


def names(instance: int) -> FirmwareNames:
    """The classic names of IMU ``instance`` (0, 1, 2): ``INS_ACCOFFS``, ``INS_ACC2OFFS``, ``INS_ACC3OFFS``, ..."""
    n = "" if instance == 0 else str(instance + 1)  # INS_ACCOFFS, INS_ACC2OFFS; INS_GYROFFS, INS_GYR2OFFS
    return FirmwareNames(f"INS_ACC{n}OFFS_{{axis}}", f"INS_ACC{n}SCAL_{{axis}}", f"INS_ACC{n}_ID",
                         f"INS_GYR{n}OFFS_{{axis}}" if n else "INS_GYROFFS_{axis}", f"INS_GYR{n}_ID",
                         f"INS_TCAL{instance + 1}_")


def thermal_block(thermal: ThermalOffset, names: FirmwareNames, acc_id: Param | None) -> tuple[list[Param], list[str]]:
    """The ``INS_TCALn_*`` parameters of the thermal offset polynomial (re-expanded about 35 °C, ×1e6) and their note."""
    c = tcal_coefficients(thermal.coefficients, thermal.temp_ref)
    imu = names.thermal[len("INS_TCAL"):-1]
    params = [
        Param(f"{names.thermal}ENABLE", 1, integer=True),
        Param(f"{names.thermal}TMIN", thermal.tmin),
        Param(f"{names.thermal}TMAX", thermal.tmax),
        Param(f"INS_ACC{imu}_CALTEMP", thermal.temp_ref),
    ]
    for n in range(THERMAL_ORDER):
        params += per_axis(f"{names.thermal}ACC{n + 1}_{{axis}}", c[:, n])
    return params, [f"{names.thermal}ENABLE=1 also enables the gyro thermal terms {names.thermal}GYR*, which this file "
                    "leaves as they are"]


#: ArduPilot's parameter file, in Mission Planner's ``NAME,VALUE`` format.
ARDUPILOT = FirmwareFormat(
    "ardupilot", HEADER, names,
    "the offsets and scales apply to the axes of the calibration data; log them in the IMU's own orientation",
    "ArduPilot treats an accelerometer whose saved {acc_id} is missing or differs from the detected device as "
    "uncalibrated (AP_InertialSensor::register_accel): this file does not set {acc_id}, so the firmware will not apply "
    "the calibration until {acc_id} holds the accelerometer's device id (device_id=N; the vehicle shows it as {acc_id})",
    "{gyro_id} is not written: ArduPilot marks a gyro whose saved {gyro_id} differs from the detected device as needing "
    "calibration (register_gyro); give gyro_device_id=N (the vehicle's {gyro_id}) to write it",
    "ArduPilot re-measures the gyro offsets at every boot while INS_GYR_CAL = 1 (its default, start-up only), replacing "
    "{gyro_offset}: set INS_GYR_CAL to 0 to keep these",
    "the file writes no thermal terms and leaves {thermal}ENABLE as it is: if the vehicle applies a thermal calibration "
    "to this IMU, its offsets are subtracted as well as these, which were fitted without it",
    "gyro applied upstream as gyro = raw - {gyro_offset}, rad/s (AP_InertialSensor_Backend.cpp, _rotate_and_correct_gyro)",
    thermal_block,
    render_lines("", ","),
)


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The ArduPilot parameters of ``cal`` (IMU ``options.instance + 1``) in Mission Planner's ``NAME,VALUE`` format."""
    return write_firmware(cal, options, ARDUPILOT)
