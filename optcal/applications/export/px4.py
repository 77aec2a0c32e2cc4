"""PX4: ``CAL_ACC0_{X,Y,Z}OFF``, ``CAL_ACC0_{X,Y,Z}SCALE`` and the ``TC_A0_*`` thermal terms, as ``param set`` lines.

Upstream conventions (PX4-Autopilot):

* ``src/lib/sensor_calibration/Accelerometer.hpp``, ``Accelerometer::Correct``:
  ``rotation · ((data − thermal_offset − offset) ∘ scale)`` with ``data`` in m/s² in the sensor
  frame, ``offset = CAL_ACC0_xOFF``, ``scale = CAL_ACC0_xSCALE``.
* ``src/modules/temperature_compensation/TemperatureCompensation.cpp``,
  ``calc_thermal_offsets_3D``: ``thermal_offset_i = X0_i + X1_i dT + X2_i dT² + X3_i dT³`` with
  ``dT = clamp(T, TC_A0_TMIN, TC_A0_TMAX) − TC_A0_TREF`` (parameters ``TC_A0_X{n}_{axis}``,
  ``temp_comp_params_accel_0.yaml``); enabled by ``TC_A_ENABLE``.

optcal's thermal offset (:mod:`optcal.applications.export.firmware`) is exactly this polynomial with
``TC_A0_TREF = T_ref`` and ``X0 = 0``.  Mapped: the bias, per-axis scales, ``temperature_bias``
of orders 1-3.  Not mapped: cross-axis terms, ``temperature_scale``, ``bias_drift``,
``scale_nonlinearity``.
"""

from __future__ import annotations

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import THERMAL_ORDER, FirmwareFormat, ThermalOffset, write_firmware

#: First lines of the file.
HEADER: tuple[str, ...] = (
    "# PX4 accelerometer calibration (instance 0) exported by optcal from {source}",
    "# applied upstream as (data - thermal_offset - CAL_ACC0_xOFF) * CAL_ACC0_xSCALE per axis, data in m/s^2",
    "# (src/lib/sensor_calibration/Accelerometer.hpp, Accelerometer::Correct; sensor frame)",
    "# set CAL_ACC0_ID (and TC_A0_ID) to the device id of your sensor: PX4 ignores a calibration for another id",
)


def thermal_block(thermal: ThermalOffset) -> tuple[list[str], list[str]]:
    """The ``TC_A0_*`` lines of the thermal offset polynomial (``X0 = 0``); no note."""
    lines = [
        "# thermal offset polynomial (TemperatureCompensation.cpp, calc_thermal_offsets_3D)",
        "param set TC_A_ENABLE 1",
        f"param set TC_A0_TREF {thermal.temp_ref:.9g}",
        f"param set TC_A0_TMIN {thermal.tmin:.9g}",
        f"param set TC_A0_TMAX {thermal.tmax:.9g}",
    ]
    for k in range(3):
        lines.append(f"param set TC_A0_X0_{k} 0")
        for n in range(THERMAL_ORDER):
            lines.append(f"param set TC_A0_X{n + 1}_{k} {thermal.coefficients[k, n]:.9g}")
    return lines, []


#: PX4's parameters (instance 0) as NSH/MAVLink-console ``param set`` commands.
PX4 = FirmwareFormat(
    "px4", HEADER, "param set CAL_ACC0_{axis}OFF {value:.9g}", "param set CAL_ACC0_{axis}SCALE {value:.9g}",
    "CAL_ACC0_ID and TC_A0_ID must be set to the sensor's device id (optcal does not know it)",
    thermal_block,
)


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The PX4 parameters of ``cal`` (instance 0) as NSH/MAVLink-console ``param set`` commands."""
    return write_firmware(cal, options, PX4)
