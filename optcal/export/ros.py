"""ROS: the ``linear_acceleration_covariance`` of ``sensor_msgs/Imu`` from the calibration's residual noise.

Upstream definition (``sensor_msgs/msg/Imu.msg``): ``float64[9] linear_acceleration_covariance``,
row-major about x, y, z, in (m/s²)²; all zeros means "unknown".  optcal writes a diagonal
covariance: the calibration's residual error ``σ_cal`` (rms ``|ā| − 1`` of the full model on its
own poses, in m/s²) squared on every axis, plus, when an ``optcal allan --json`` result is given,
the white noise of one sample on each axis, ``N_i² · rate`` (``N_i`` the velocity random walk,
the same density-to-sample conversion Kalibr uses).
"""

from __future__ import annotations

import numpy as np

from optcal.caltypes.base import Calibration
from optcal.errors import InputError
from optcal.export import ExportOptions, ExportResult
from optcal.export.firmware import loss_poses
from optcal.export.kalibr import AXIS_NAMES, axis_values, update_rate
from optcal.model import STANDARD_GRAVITY


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """A YAML line with the 9 covariance numbers, and how they were made."""
    poses = loss_poses(cal, options)
    rms_g = float(np.sqrt(np.mean(cal.norm_errors(poses.acc, poses.temp, poses.t) ** 2)))
    variance = np.full(3, (rms_g * STANDARD_GRAVITY) ** 2)
    lines = [
        f"# sensor_msgs/Imu linear_acceleration_covariance exported by optcal from {options.source}",
        "# row-major 3x3 about x, y, z in (m/s^2)^2 (sensor_msgs/msg/Imu.msg)",
        f"# calibration residual: rms |a|-1 = {rms_g * 1e3:.4f} mg on its {poses.n} poses, squared on each axis",
    ]
    mapped = ["rms |a|-1 of the calibration on its poses (residual error)"]
    if options.allan is not None:
        density = axis_values(options.allan, "velocity_random_walk")
        if len(density) < 3:
            raise InputError("the Allan result lacks the velocity random walk of an axis; it is needed for every axis")
        rate = update_rate(options.allan, options)
        white = np.array([density[a] ** 2 * rate for a in AXIS_NAMES])
        variance = variance + white
        lines.append(f"# + white noise per sample: N^2 * {rate:g} Hz = {', '.join(f'{v:.4g}' for v in white)} (m/s^2)^2")
        mapped.append("Allan velocity random walk (white noise per sample)")
    covariance = np.diag(variance).ravel()
    lines.append("linear_acceleration_covariance: [" + ", ".join(f"{v:.9g}" for v in covariance) + "]")
    return ExportResult("ros", "\n".join(lines) + "\n", None, mapped, [], [])
