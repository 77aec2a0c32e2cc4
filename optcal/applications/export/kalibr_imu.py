"""Kalibr's ``scale-misalignment`` IMU intrinsics, and OpenVINS's ``kalibr_imu_chain.yaml`` built from them.

Kalibr (ethz-asl/kalibr, ``aslam_offline_calibration/kalibr/python/kalibr_imu_camera_calibration/
IccSensors.py``, ``IccScaledMisalignedImu``) predicts the IMU topic's readings from the true
specific force ``a_i`` and body rate ``ω_i`` in the IMU frame ``i`` (``addAccelerometerErrorTerms``
and ``addGyroscopeErrorTerms``)::

    α   = M_a a_i + b_a                          M_a lower-triangular (MatrixBasicDv pattern [[1,0,0],[1,1,0],[1,1,1]])
    ω_m = M_g C_gyro_i ω_i + A C_gyro_i a_i + b_g   M_g lower-triangular, A full ((rad/s)/(m/s²)), C_gyro_i a rotation

and writes them, with ``model: scale-misalignment``, into the ``imu0`` entry of its IMU result
(``setIntrisicsMatrices``: ``accelerometers: {M}``, ``gyroscopes: {M, A, C_gyro_i}``; the
entry's other keys are ``ConfigReader.ImuParameters``' with ``T_i_b`` and ``time_offset``).  The
biases are not in the file: Kalibr estimates them as splines.

From :class:`~optcal.applications.export.intrinsics.SIModel` (``f = A (α − α₀)``, ``ω = W (ω_m −
ω₀ − S f)``, optcal's frame): ``α = A⁻¹ f + α₀``, so with ``A⁻¹ = L Q`` (:func:`~.intrinsics.lq`)
the IMU frame is ``a_i = Q f`` (``Q = I`` for optcal's lower-triangular T) and ``M_a = L``;
``ω_m = W⁻¹ Qᵀ ω_i + S Qᵀ a_i + ω₀``, so with ``W⁻¹ Qᵀ = L_g Q_g``: ``M_g = L_g``, ``C_gyro_i =
Q_g``, ``A = S Qᵀ Q_gᵀ``.  Both factorisations are exact: nothing of optcal's lumped model is lost.

OpenVINS (rpng/open_vins, ``ov_msckf/src/core/VioManagerOptions.h`` reads ``Tw``, ``Ta``,
``R_IMUtoACC``, ``R_IMUtoGYRO``, ``Tg`` from ``imu0`` and ``model`` in
``ov_msckf/src/state/StateOptions.h``; ``ov_msckf/src/state/Propagator.cpp`` applies them)::

    a_I = R_ACCtoIMU D_a (a_m − b_a),   ω_I = R_GYROtoIMU D_w (ω_m − b_g − T_g a_I),   D = T⁻¹

its ``kalibr`` model keeping the lower triangles of ``D_a`` and ``D_w``.  Against Kalibr's:
``Ta = M_a``, ``R_IMUtoACC = I``, ``Tw = M_g``, ``R_IMUtoGYRO = C_gyro_i`` and ``Tg = A C_gyro_i``
(the example ``config/euroc_mav/kalibr_imu_chain.yaml`` says "Tg is imu0:gyroscopes:A", exact
only when ``C_gyro_i = I``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.intrinsics import (
    SIModel,
    accel_loss,
    lq,
    matrix_yaml,
    rotation_angle_deg,
    si_model,
)
from optcal.applications.export.noise import NoiseModel, noise_model


class KalibrIntrinsics:
    """Kalibr's matrices of an :class:`SIModel` (module docstring).

    Attributes
    ----------
    M_a, M_g, A, C_gyro_i : ndarray, shape (3, 3)
        Kalibr's matrices (``M_g``, ``A`` identity and zero without a gyroscope).
    Q : ndarray, shape (3, 3)
        optcal's frame → Kalibr's IMU frame ``i``.
    b_a, b_g : ndarray, shape (3,)
        The biases in Kalibr's model (m/s², rad/s of the topic): not in Kalibr's file.
    """

    def __init__(self, model: SIModel) -> None:
        self.M_a, self.Q = lq(np.asarray(np.linalg.inv(model.A), dtype=np.float64))
        self.b_a = model.acc_offset
        if model.W is None or model.gyro_offset is None:
            self.M_g, self.C_gyro_i, self.A = np.eye(3), np.eye(3), np.zeros((3, 3))
            self.b_g = np.zeros(3)
            return
        self.M_g, self.C_gyro_i = lq(np.asarray(np.linalg.inv(model.W) @ self.Q.T, dtype=np.float64))
        S = np.zeros((3, 3)) if model.S is None else model.S
        self.A = S @ self.Q.T @ self.C_gyro_i.T
        self.b_g = model.gyro_offset

    def specific_force(self, alpha: NDArray[np.float64]) -> NDArray[np.float64]:
        """``a_i = M_a⁻¹ (α − b_a)``: Kalibr's accelerometer model solved for the force, m/s²."""
        return np.asarray(np.linalg.solve(self.M_a, (np.asarray(alpha, float) - self.b_a).T).T, dtype=np.float64)


def noise_lines(noise: NoiseModel | None, indent: str) -> tuple[list[str], list[str]]:
    """Kalibr's four noise keys (``ConfigReader.ImuParameters``), or comments and a note without a result."""
    if noise is None:
        keys = ["accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk"]
        return ([f"{indent}# {k}: FILL IN (no Allan result given: optcal allan LOG --sensor both --json)" for k in keys],
                ["no Allan result given: the four noise keys are left as comments, and the consumer's reader refuses the "
                 "file until they are filled in (pass allan=, an optcal allan LOG --sensor both --json result)"])
    lines = [f"{indent}{c}" for c in noise.comments()] + [
        f"{indent}accelerometer_noise_density: {noise.acc_white.value:.9g}  # [ m/s^2/sqrt(Hz) ]",
        f"{indent}accelerometer_random_walk: {noise.acc_walk.value:.9g}  # [ m/s^3/sqrt(Hz) ]"
        + (" UPPER BOUND" if noise.acc_walk.bounded else ""),
        f"{indent}gyroscope_noise_density: {noise.gyro_white.value:.9g}  # [ rad/s/sqrt(Hz) ]",
        f"{indent}gyroscope_random_walk: {noise.gyro_walk.value:.9g}  # [ rad/s^2/sqrt(Hz) ]"
        + (" UPPER BOUND" if noise.gyro_walk.bounded else ""),
    ]
    return lines, list(noise.notes)


def prepare(cal: Calibration, options: ExportOptions, fmt: str) -> tuple[SIModel, KalibrIntrinsics, list[str], ExportResult]:
    """What both formats share: the model, Kalibr's matrices, the header lines, and the result (loss, mapped,
    dropped, notes) without its text."""
    model = si_model(cal, options)
    kalibr = KalibrIntrinsics(model)
    loss = accel_loss(cal, options, lambda raw: kalibr.specific_force(model.topic_acc(raw)) / model.gravity, fmt)
    header = [f"# {line}" for line in model.driver]
    header.append(f"# 1 g = {model.gravity:.9g} m/s^2 (the calibration's |a| = 1; set the estimator's gravity to it)")
    mapped = ["accelerometer scale and misalignment (T)"]
    dropped = ["accelerometer bias o (the estimator estimates it; written as a comment for its initial value)"]
    notes = list(model.driver)
    angle = rotation_angle_deg(kalibr.Q)
    if angle > 0:
        notes.append(f"optcal's T is not lower-triangular: Kalibr's IMU frame is optcal's turned by {angle:.4g} deg")
    if model.W is None:
        dropped.append("gyroscope: the calibration has none (identity M, zero A, identity C_gyro_i written)")
    else:
        mapped += ["gyroscope scale, misalignment and axes (Tg)"]
        dropped.append("gyroscope bias bg (the estimator estimates it; written as a comment)")
        mapped.append("gyroscope g-sensitivity (Gg)" if model.S is not None else "gyroscope g-sensitivity: not modelled, A = 0")
    dropped += extra_terms(cal)
    result = ExportResult(fmt, "", loss, mapped, dropped, notes)
    return model, kalibr, header, result


def extra_terms(cal: Calibration) -> list[str]:
    """The terms of an extended calibration the lumped model (and so every VIO tool) cannot hold."""
    terms = getattr(cal, "terms", None) or []
    return [f"{t.effect} on {t.axis} (order {t.order}): the tool's model is a constant linear one" for t in terms]


def bias_comments(kalibr: KalibrIntrinsics, indent: str, has_gyro: bool) -> list[str]:
    out = [f"{indent}# accelerometer bias b_a (m/s^2 of the topic, Kalibr's a = M a_i + b): "
           + ", ".join(f"{v:.9g}" for v in kalibr.b_a)]
    if has_gyro:
        out.append(f"{indent}# gyroscope bias b_g (rad/s of the topic): " + ", ".join(f"{v:.9g}" for v in kalibr.b_g))
    return out


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """Kalibr's IMU result (``imu0``, ``model: scale-misalignment``) of ``cal`` (module docstring)."""
    model, kalibr, header, result = prepare(cal, options, "kalibr-imu")
    notes = result.notes
    noise = noise_model(options, "the kalibr-imu format")
    keys, noise_notes = noise_lines(noise, "  ")
    lines = [f"# Kalibr IMU intrinsics exported by optcal from {options.source} ({cal.describe()})",
             "# model scale-misalignment (kalibr_imu_camera_calibration/IccSensors.py, IccScaledMisalignedImu):",
             "#   alpha = M_a a_i + b_a;  omega_m = M_g C_gyro_i w_i + A C_gyro_i a_i + b_g  (topic units: m/s^2, rad/s)",
             f"# loss: {result.loss.describe() if result.loss else ''}", *header,
             "imu0:",
             "  T_i_b:", *matrix_yaml(np.eye(4), "    "),
             *keys,
             "  model: scale-misalignment",
             f"  rostopic: {options.rostopic}",
             "  time_offset: 0.0",
             f"  update_rate: {noise.rate_hz if noise else (options.rate_hz or 0.0):.9g}",
             *bias_comments(kalibr, "  ", model.W is not None),
             "  accelerometers:",
             "    M:", *matrix_yaml(kalibr.M_a, "    "),
             "  gyroscopes:",
             "    A:", *matrix_yaml(kalibr.A, "    "),
             "    C_gyro_i:", *matrix_yaml(kalibr.C_gyro_i, "    "),
             "    M:", *matrix_yaml(kalibr.M_g, "    ")]
    if noise is None and options.rate_hz is None:
        notes.append("update_rate is 0: give rate= (the IMU topic's rate, Hz) or an Allan result")
    result.text = "\n".join(lines) + "\n"
    result.mapped += list(noise.mapped) if noise else []
    result.notes = notes + noise_notes
    return result


def export_openvins(cal: Calibration, options: ExportOptions) -> ExportResult:
    """OpenVINS's ``kalibr_imu_chain.yaml`` (``model: kalibr``) of ``cal`` (module docstring)."""
    model, kalibr, header, result = prepare(cal, options, "openvins")
    notes = result.notes
    noise = noise_model(options, "the openvins format")
    keys, noise_notes = noise_lines(noise, "  ")
    lines = ["%YAML:1.0",
             f"# OpenVINS IMU intrinsics exported by optcal from {options.source} ({cal.describe()})",
             "# ov_msckf/src/state/Propagator.cpp: a_I = R_ACCtoIMU Da (a_m - b_a); "
             "w_I = R_GYROtoIMU Dw (w_m - b_g - Tg a_I); D = T^-1 (model kalibr: lower triangles)",
             f"# loss: {result.loss.describe() if result.loss else ''}", *header,
             "imu0:",
             "  T_i_b:", *matrix_yaml(np.eye(4), "    "),
             *keys,
             f"  rostopic: {options.rostopic}",
             "  time_offset: 0.0",
             f"  update_rate: {noise.rate_hz if noise else (options.rate_hz or 0.0):.9g}",
             "  model: kalibr",
             *bias_comments(kalibr, "  ", model.W is not None),
             "  Tw:", *matrix_yaml(kalibr.M_g, "    "),
             "  R_IMUtoGYRO:", *matrix_yaml(kalibr.C_gyro_i, "    "),
             "  Ta:", *matrix_yaml(kalibr.M_a, "    "),
             "  R_IMUtoACC:", *matrix_yaml(np.eye(3), "    "),
             "  Tg:", *matrix_yaml(kalibr.A @ kalibr.C_gyro_i, "    ")]
    result.text = "\n".join(lines) + "\n"
    result.mapped += list(noise.mapped) if noise else []
    notes.append("Tg is Kalibr's A times C_gyro_i (the rate per specific force in the IMU frame), not A alone")
    result.notes = notes + noise_notes
    return result
