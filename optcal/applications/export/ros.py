"""ROS: the ``linear_acceleration_covariance`` of ``sensor_msgs/Imu``.

Upstream definition (``sensor_msgs/msg/Imu.msg``): ``float64[9] linear_acceleration_covariance``,
row-major about x, y, z, in (m/s²)²; all zeros means "unknown".  optcal writes a diagonal
covariance.  With an ``optcal allan --json`` result it is the sensor's noise per sample on each
axis, ``N_i² · rate`` (``N_i`` the velocity random walk; the density-to-sample conversion Kalibr
uses).  Without one, the only figure optcal has is the calibration's residual error ``σ_cal``
(rms ``|ā| − 1`` of the full model on its own poses, in m/s²), squared on every axis: a
systematic error of pose means, not the noise of a sample, and the notes say so.
"""

from __future__ import annotations

import numpy as np

from optcal.families.caltypes.base import Calibration
from optcal.errors import InputError
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import loss_poses
from optcal.applications.export.kalibr import AXIS_NAMES, axis_values, update_rate
from optcal.core.model import STANDARD_GRAVITY
from optcal.core.stats import rms


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """A YAML line with the 9 covariance numbers, and how they were made."""
    poses = loss_poses(cal, options)
    rms_g = rms(cal.norm_errors(poses.acc, poses.temp, poses.t))
    variance = np.full(3, (rms_g * STANDARD_GRAVITY) ** 2)
    lines = [
        f"# sensor_msgs/Imu linear_acceleration_covariance exported by optcal from {options.source}",
        "# row-major 3x3 about x, y, z in (m/s^2)^2 (sensor_msgs/msg/Imu.msg)",
    ]
    residual = f"rms |a|-1 = {rms_g * 1e3:.4f} mg on its {poses.n} poses"
    notes: list[str] = []
    if options.allan is not None:
        # an `optcal allan --sensor both` result holds the accelerometer's beside the gyroscope's
        allan = options.allan["accelerometer"] if options.allan.get("sensor") == "both" else options.allan
        density = axis_values(allan, "velocity_random_walk")
        if len(density) < 3:
            raise InputError("the Allan result lacks the velocity random walk of an axis; it is needed for every axis")
        rate = update_rate(allan, options)
        variance = np.array([density[a] ** 2 * rate for a in AXIS_NAMES])
        lines.append(f"# sensor noise per sample from the Allan result: N^2 * {rate:g} Hz on each axis")
        lines.append(f"# (the calibration residual, {residual}, is a systematic error and is not included)")
        mapped = ["Allan velocity random walk (white noise per sample)"]
    else:
        variance = np.full(3, (rms_g * STANDARD_GRAVITY) ** 2)
        lines.append(f"# calibration residual: {residual}, squared on each axis (NOT the sensor's sample noise)")
        mapped = ["rms |a|-1 of the calibration on its poses (residual error)"]
        notes.append(
            f"no Allan result given: the covariance is the calibration's residual error ({residual}), not the "
            "noise of one sample; pass allan= (an optcal allan --json result of a static log) for the sensor noise"
        )
    covariance = np.diag(variance).ravel()
    lines.append("linear_acceleration_covariance: [" + ", ".join(f"{v:.9g}" for v in covariance) + "]")
    return ExportResult("ros", "\n".join(lines) + "\n", None, mapped, [], notes)
