"""PX4: ``CAL_ACC0_*``, ``CAL_GYRO0_*OFF``, the ids and the ``TC_A0_*`` thermal terms, as a QGroundControl parameter file.

Upstream conventions (PX4-Autopilot):

* ``src/lib/sensor_calibration/Accelerometer.hpp``, ``Accelerometer::Correct``:
  ``rotation · ((data − thermal_offset − offset) ∘ scale)`` with ``data`` in m/s² in the sensor
  frame, ``offset = CAL_ACC0_xOFF``, ``scale = CAL_ACC0_xSCALE``; ``Gyroscope.hpp``,
  ``Gyroscope::Correct``: ``rotation · (data − thermal_offset − CAL_GYRO0_xOFF)`` in rad/s.
* ``src/lib/sensor_calibration/Utilities.cpp``, ``FindCurrentCalibrationIndex``: a sensor uses the
  calibration slot ``n`` whose ``CAL_ACCn_ID`` (``CAL_GYROn_ID``) equals its device id, and none
  otherwise; the names are ``CAL_%s%u_%c%s`` (``GetCalibrationParamsVector3f``).
* ``src/modules/temperature_compensation/TemperatureCompensation.cpp``,
  ``calc_thermal_offsets_3D``: ``thermal_offset_i = X0_i + X1_i dT + X2_i dT² + X3_i dT³`` with
  ``dT = clamp(T, TC_A0_TMIN, TC_A0_TMAX) − TC_A0_TREF`` (parameters ``TC_A0_X{n}_{axis}``,
  ``TC_A0_ID``, ``temp_comp_params_accel_0.yaml``); enabled by ``TC_A_ENABLE`` (a boolean: int32).

optcal's thermal offset (:mod:`optcal.applications.export.firmware`) is exactly this polynomial with
``TC_A0_TREF = T_ref`` and ``X0 = 0``.  Mapped: the bias, per-axis scales, ``temperature_bias``
of orders 1-3, an ``imu`` calibration's gyro bias, the device ids when given.  Not mapped:
cross-axis terms, ``temperature_scale``, ``bias_drift``, ``scale_nonlinearity``, the gyro's scale,
misalignment and g-sensitivity (each with its loss).

Two files: ``px4`` is the parameter file QGroundControl loads (Parameters > Tools > Load from
file), whose reader, ``ParameterManager::readParametersFromStream``
(``src/FactSystem/ParameterManager.cc``), skips lines starting with ``#`` and takes a line with
exactly five tab-separated fields, vehicle id, component id, name, value and ``MAV_PARAM_TYPE``
(9 ``REAL32`` for floats, 6 ``INT32`` for integers, which must match the parameter's own type);
its writer, ``writeParametersToStream``, heads the file with ``#`` lines that this file repeats.
``px4-shell`` writes the same parameters as ``param set`` commands for the NSH or MAVLink console.
"""

from __future__ import annotations

from collections.abc import Callable

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import (THERMAL_ORDER, FirmwareFormat, FirmwareNames, Param, ThermalOffset,
                                                 render_lines, write_firmware)

#: MAVLink's MAV_PARAM_TYPE of a float32 and of an int32 parameter (QGroundControl checks it).
MAV_PARAM_TYPE_REAL32: int = 9
MAV_PARAM_TYPE_INT32: int = 6
#: MAV_COMP_ID_AUTOPILOT1: the component that holds PX4's parameters.
AUTOPILOT_COMPONENT_ID: int = 1
#: First comments of the file.
HEADER: tuple[str, ...] = (
    "PX4 IMU calibration (calibration slot {instance}) exported by optcal from {source}",
    "applied upstream as (data - thermal_offset - {acc_offset}) * {acc_scale} per axis, data in m/s^2",
    "(src/lib/sensor_calibration/Accelerometer.hpp, Accelerometer::Correct; sensor frame)",
)


def names(instance: int) -> FirmwareNames:
    """The names of calibration slot ``instance`` (0, 1, 2): ``CAL_ACC0_XOFF``, ``CAL_ACC1_XOFF``, ..."""
    return FirmwareNames(f"CAL_ACC{instance}_{{axis}}OFF", f"CAL_ACC{instance}_{{axis}}SCALE", f"CAL_ACC{instance}_ID",
                         f"CAL_GYRO{instance}_{{axis}}OFF", f"CAL_GYRO{instance}_ID", f"TC_A{instance}_")


def thermal_block(thermal: ThermalOffset, names: FirmwareNames, acc_id: Param | None) -> tuple[list[Param], list[str]]:
    """The ``TC_An_*`` parameters of the thermal offset polynomial (``X0 = 0``), with ``TC_An_ID`` when the id is given."""
    tc = names.thermal
    params = [Param("TC_A_ENABLE", 1, integer=True)]
    notes = ["TC_A_ENABLE needs a reboot to take effect (temp_comp_params_accel.yaml: reboot_required)"]
    if acc_id is not None:
        params.append(Param(f"{tc}ID", acc_id.value, integer=True))
    else:
        notes.append(f"{tc}ID is not written: PX4 applies the thermal terms only to the device whose id {tc}ID holds "
                     "(device_id=N writes it)")
    params += [Param(f"{tc}TREF", thermal.temp_ref), Param(f"{tc}TMIN", thermal.tmin), Param(f"{tc}TMAX", thermal.tmax)]
    for k in range(3):
        params.append(Param(f"{tc}X0_{k}", 0.0))
        params += [Param(f"{tc}X{n + 1}_{k}", thermal.coefficients[k, n]) for n in range(THERMAL_ORDER)]
    return params, notes


def render_qgc(comments: list[str], params: list[Param], options: ExportOptions) -> str:
    """QGroundControl's parameter file: its header comments, then ``vehicle component name value type`` lines.

    The header repeats ``ParameterManager::writeParametersToStream`` (``src/FactSystem/ParameterManager.cc``)
    with what optcal knows: no vehicle, firmware version or git revision, for it was not downloaded.
    """
    v, c = options.vehicle_id, AUTOPILOT_COMPONENT_ID
    lines = [f"# Onboard parameters for Vehicle {v}", "#", "# Stack: PX4 Pro",
             "# Vehicle, Version, Git Revision: none (written by optcal export, not downloaded from a vehicle)", "#"]
    lines += [f"# {comment}" for comment in comments]
    lines += ["#", "# Vehicle-Id Component-Id Name Value Type"]
    lines += [f"{v}\t{c}\t{p.name}\t{p.text()}\t{MAV_PARAM_TYPE_INT32 if p.integer else MAV_PARAM_TYPE_REAL32}"
              for p in params]
    return "\n".join(lines) + "\n"


def px4_format(name: str, render: Callable[[list[str], list[Param], ExportOptions], str], note: str) -> FirmwareFormat:
    """PX4's parameters written by ``render`` (the QGroundControl file or ``param set`` lines)."""
    return FirmwareFormat(
        name, HEADER, names, note,
        "PX4 applies a calibration only to the sensor whose device id is in {acc_id} (Utilities.cpp, "
        "FindCurrentCalibrationIndex): this file does not set it, so the firmware will not apply the calibration until "
        "{acc_id} holds the accelerometer's device id (device_id=N; read the vehicle's current {acc_id})",
        "{gyro_id} is not written: PX4 applies the gyro offsets only to the gyro whose device id is in {gyro_id} "
        "(gyro_device_id=N writes it; read the vehicle's current {gyro_id})",
        "PX4's estimator goes on learning the gyro bias in flight; these offsets are its starting point",
        "the file writes no thermal terms and leaves TC_A_ENABLE and {thermal}* as they are: if the vehicle applies a "
        "thermal calibration to this sensor, its offsets are subtracted as well as these, which were fitted without it",
        "gyro applied upstream as data - thermal_offset - {gyro_offset}, rad/s (Gyroscope.hpp, Gyroscope::Correct)",
        thermal_block,
        render,
    )


#: QGroundControl's parameter file (``--format px4``).
PX4 = px4_format("px4", render_qgc,
                 "load the file in QGroundControl (Parameters > Tools > Load from file); it refuses a file whose vehicle "
                 "id differs from the vehicle's MAV_SYS_ID (vehicle_id=N writes another) and skips parameters the "
                 "firmware does not have")
#: NSH/MAVLink-console ``param set`` commands (``--format px4-shell``).
PX4_SHELL = px4_format("px4-shell", render_lines("param set ", " "),
                       "run the lines in the NSH or MAVLink console (not a file for param load, which reads PX4's "
                       "binary format)")


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The PX4 parameters of ``cal`` (slot ``options.instance``) as a QGroundControl parameter file."""
    return write_firmware(cal, options, PX4)


def export_shell(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The PX4 parameters of ``cal`` (slot ``options.instance``) as ``param set`` console commands."""
    return write_firmware(cal, options, PX4_SHELL)
