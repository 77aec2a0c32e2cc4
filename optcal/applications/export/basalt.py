"""Basalt: the ``calib_accel_bias`` and ``calib_gyro_bias`` vectors (and the IMU noise) of its ``calibration.json``.

Upstream definition (VladyslavUsenko/basalt-headers, ``include/basalt/calibration/calib_bias.hpp``):
``CalibAccelBias`` holds 9 numbers ``[b_x, b_y, b_z, s_1 … s_6]`` and corrects a topic reading ``a_r``
(m/s²) as ``a_c = (I + S_a) a_r − b`` with ``S_a`` lower-triangular, filled column by column
(``getBiasAndScale``: column 0 = ``s_1, s_2, s_3``, ``S(1,1) = s_4``, ``S(2,1) = s_5``, ``S(2,2) =
s_6``); ``CalibGyroBias`` 12 numbers ``[b_x, b_y, b_z, s_1 … s_9]``, ``ω_c = (I + S_g) ω_r − b``,
``S_g`` full, column-major.  The file is cereal's JSON of ``basalt::Calibration``
(``include/basalt/serialization/headers_serialization.h``: ``value0`` with ``T_imu_cam``,
``intrinsics``, ``resolution``, ``calib_accel_bias``, ``calib_gyro_bias``, ``imu_update_rate``,
``accel_noise_std``, ``gyro_noise_std``, ``accel_bias_std``, ``gyro_bias_std``,
``cam_time_offset_ns``, ``vignette``); the noise figures are continuous-time per axis
(``calibration.hpp``: ``dicrete_time_accel_noise_std() = accel_noise_std · √imu_update_rate``).

From :class:`~optcal.applications.export.intrinsics.SIModel` (``f = A (α − α₀)``): ``R A = L``
(:func:`~.intrinsics.ql`: ``R`` a rotation, ``L`` lower-triangular; ``R = I`` for optcal's lower-triangular T, a
turn of Basalt's frame against optcal's for a full matrix, stated in the notes), ``I + S_a = L``,
``b = L α₀``; ``I + S_g = R W``, ``b = R W ω₀``: both sensors exact in Basalt's frame.
Basalt has no g-sensitivity: its rate error is reported.  optcal writes the IMU part of ``value0``
only; the camera keys come from the camera calibration the user merges it into.
"""

from __future__ import annotations

import json

import numpy as np

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.intrinsics import (
    accel_loss,
    describe_gyro_loss,
    gyro_loss,
    ql,
    rotation_angle_deg,
    si_model,
)
from optcal.applications.export.kalibr_imu import extra_terms
from optcal.applications.export.noise import Figure, noise_model
from optcal.applications.export.firmware import loss_poses

#: The keys of ``basalt::Calibration`` that optcal does not write (the cameras'), in cereal's order.
CAMERA_KEYS: tuple[str, ...] = ("T_imu_cam", "intrinsics", "resolution", "cam_time_offset_ns", "vignette")


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The IMU part of Basalt's ``calibration.json`` for ``cal`` (module docstring)."""
    model = si_model(cal, options)
    R, L = ql(model.A)  # CalibAccelBias: I + S_a lower-triangular, in Basalt's frame R (optcal's turned)
    b_a = L @ model.acc_offset
    accel = [*b_a, L[0, 0] - 1.0, L[1, 0], L[2, 0], L[1, 1] - 1.0, L[2, 1], L[2, 2] - 1.0]
    loss = accel_loss(cal, options, lambda raw: (model.topic_acc(raw) @ L.T - b_a) / model.gravity, "basalt")
    mapped = ["accelerometer bias, scale and misalignment (calib_accel_bias: T, o)"]
    dropped = extra_terms(cal)
    notes = list(model.driver)
    angle = rotation_angle_deg(R)
    if angle > 0:
        notes.append(f"optcal's accelerometer matrix is not lower-triangular: Basalt's IMU frame is optcal's turned by "
                     f"{angle:.4g} deg (the accelerometer's and the gyroscope's alike)")
    imu: dict[str, object] = {"calib_accel_bias": [float(v) for v in accel]}
    if model.W is not None and model.gyro_offset is not None:
        W = R @ model.W  # the rate in Basalt's frame
        gyro = [*(W @ model.gyro_offset), *(W - np.eye(3)).T.ravel()]  # column-major S_g after the bias
        imu["calib_gyro_bias"] = [float(v) for v in gyro]
        mapped.append("gyroscope bias, scale, misalignment and axes (calib_gyro_bias: Tg, bg)")
        if model.S is not None:
            rms_missed, max_missed = gyro_loss(cal, options, model)
            dropped.append(describe_gyro_loss(rms_missed, max_missed, loss_poses(cal, options).n))
    else:
        imu["calib_gyro_bias"] = [0.0] * 12
        dropped.append("gyroscope: the calibration has none (calib_gyro_bias left at zero, Basalt's identity)")
    noise = noise_model(options, "the basalt format")
    if noise is not None:
        def axes(figure: Figure) -> list[float]:
            return [figure.per_axis[a] * figure.factor for a in "xyz"]

        imu.update({"imu_update_rate": noise.rate_hz, "accel_noise_std": axes(noise.acc_white),
                    "gyro_noise_std": axes(noise.gyro_white), "accel_bias_std": axes(noise.acc_walk),
                    "gyro_bias_std": axes(noise.gyro_walk)})
        mapped += list(noise.mapped)
        notes += list(noise.notes)
    else:
        dropped.append("imu_update_rate and the noise (no Allan result given: optcal allan LOG --sensor both --json)")
    notes.append(f"the IMU keys of basalt::Calibration only: merge them into the camera calibration's value0, which "
                 f"holds {', '.join(CAMERA_KEYS)}; 1 g = {model.gravity:.9g} m/s^2")
    about = {"source": options.source, "calibration": cal.describe(), "exported": mapped, "not_exported": dropped,
             "loss": loss.describe(), "units": "m/s^2 and rad/s of the IMU topic; noise continuous-time per axis",
             "inflation": {"white": options.inflate[0], "walk": options.inflate[1]}, "driver": model.driver}
    text = json.dumps({"value0": imu, "optcal_export": about}, indent=4)
    return ExportResult("basalt", text + "\n", loss, mapped, dropped, notes)
