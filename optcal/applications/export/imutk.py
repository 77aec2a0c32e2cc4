"""imu_tk: the ``T``, ``K``, ``B`` ``.calib`` pair its ``CalibratedTriad_`` writes and reads.

Upstream definition (imu_tk, ``include/imu_tk/calibration.h``, Kyle-ak/imu_tk @7780270): a triad
corrects a raw reading ``X`` as ``X' = T K (X − B)`` (``unbiasNormalize``), ``T`` the misalignment
matrix with a unit diagonal (upper-triangular for the accelerometer, the "body frame special case";
general for the gyroscope), ``K`` the diagonal scale, ``B`` the bias in raw units.  ``save`` writes
``T``, ``K`` and ``B`` as Eigen prints them (rows of space-separated numbers, a blank line between
them); ``load`` reads 9 numbers row-major into ``T``, 9 into ``K`` and 3 into ``B``.  imu_tk reads
the raw samples itself, so the matrices act on raw units; its output is m/s² (its ``g_mag``) and
rad/s.

From optcal's ``ā = T_o (a − o)`` (``T_o`` the matrix apply applies, :func:`~.base.linear_part`:
lower-triangular for a lumped fit, full for the Ferraris method) and ``ω = T_g (r − b_g − G_g ā)``:
imu_tk's body frame is the one in which the accelerometer's matrix is upper-triangular, optcal's
turned by ``R`` with ``T_o = Rᵀ U`` (:func:`~optcal.applications.export.intrinsics.qr_upper`).  Then
``T K = g U`` (``K`` its diagonal, ``T`` unit upper-triangular), ``B = o``; the gyroscope in that
frame ``T K = R T_g`` (``K`` its diagonal), ``B = b_g``.  Both are exact; what imu_tk cannot hold
is the g-sensitivity (its rate error reported) and an extended calibration's extra terms (the loss
measured on the poses).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.firmware import loss_poses
from optcal.applications.export.intrinsics import (
    accel_loss,
    describe_gyro_loss,
    gyro_loss,
    qr_upper,
    rotation_angle_deg,
    si_model,
)
from optcal.applications.export.kalibr_imu import extra_terms

#: The suffix of the gyroscope's file (imu_tk's test app saves ``test_imu_acc.calib`` and ``test_imu_gyro.calib``).
GYRO_FILE_SUFFIX: str = "_gyro"


def triad_text(T: NDArray[np.float64], K: NDArray[np.float64], B: NDArray[np.float64]) -> str:
    """``CalibratedTriad_::save``'s layout: T, K (3 rows each) and B (3 rows), blank lines between."""
    def rows(M: NDArray[np.float64]) -> str:
        return "\n".join(" ".join(f"{v:.15g}" for v in np.atleast_1d(row)) for row in M)

    return f"{rows(T)}\n\n{rows(K)}\n\n{rows(B.reshape(3, 1))}\n\n"


def split_scale(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``M = T K``: ``K`` the diagonal of ``M``, ``T = M K⁻¹`` (unit diagonal; columns scaled)."""
    K = np.diag(np.diag(M))
    return M @ np.linalg.inv(K), K


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """imu_tk's accelerometer ``.calib`` (the text) and gyroscope ``.calib`` (``files``) of ``cal``."""
    model = si_model(cal, options, needs_topic_units=False)
    Q, U = qr_upper(model.M)  # T_o = Q U: imu_tk's body frame is optcal's turned by R = Qᵀ
    R = Q.T
    T_a, K_a = split_scale(model.gravity * U)
    B_a = model.o
    loss = accel_loss(cal, options, lambda raw: (raw - B_a) @ (T_a @ K_a).T / model.gravity, "imutk")
    angle = rotation_angle_deg(R)
    mapped = ["accelerometer scale, misalignment and bias (T, K, B in raw units, m/s^2 out)"]
    dropped = extra_terms(cal)
    ours = ("lower-triangular, the sensor's x axis" if not np.any(np.triu(model.M, 1) != 0)
            else "its full matrix's, in which the gyroscope is stated")
    notes = [f"imu_tk's body frame (accelerometer misalignment upper-triangular, the sensor's z axis) is optcal's "
             f"({ours}) turned by {angle:.4g} deg; 1 g = {model.gravity:.9g} m/s^2 (imu_tk's g_mag)"]
    files: dict[str, str] = {}
    gyro = getattr(cal, "gyro", None)
    if gyro is not None:
        T_g, K_g = split_scale(R @ gyro.T)
        files[GYRO_FILE_SUFFIX] = triad_text(T_g, K_g, gyro.bias)
        mapped.append("gyroscope scale, misalignment and bias (T, K, B in raw units, rad/s out, imu_tk's body frame)")
        if gyro.g_sensitivity is not None:
            rms_missed, max_missed = gyro_loss(cal, options, model)
            dropped.append(describe_gyro_loss(rms_missed, max_missed, loss_poses(cal, options).n))
        notes.append(f"two files: the accelerometer's is the output, the gyroscope's is written beside it with "
                     f"{GYRO_FILE_SUFFIX} before the extension (CalibratedTriad_::load reads each)")
    else:
        dropped.append("gyroscope: the calibration has none (no gyroscope file)")
    return ExportResult("imutk", triad_text(T_a, K_a, B_a), loss, mapped, dropped, notes, files)
