"""IMU intrinsics for camera–IMU and VIO tools: optcal's calibration in the SI units of the IMU topic.

The VIO tools (Kalibr, OpenVINS, Basalt) correct the readings of the IMU *topic* (ROS
``sensor_msgs/Imu``: m/s² and rad/s as the driver converts them), not raw counts.  With ``k`` the
driver's m/s² per raw accelerometer unit, ``z`` the raw reading it subtracts (counts only), ``s``
and ``z_g`` the same for the gyroscope and ``g`` the gravity the calibration normalised to, the
topic carries ``α = k (a − z)`` and ``ω_m = s (r − z_g)``.  optcal's model
(:mod:`optcal.families.gyro.result`)::

    ā = T (a − o)                      Lu 2017, eq. 6 (g; T as apply applies it: base.linear_part)
    ω = T_g (r − b_g − G_g ā)          Tedaldi 2014, eq. 9 (rad/s, accelerometer frame)

becomes, in the topic's units (``f = g ā`` the specific force, m/s²)::

    f = A (α − α₀),      A = (g/k) T,     α₀ = k (o − z)
    ω = W (ω_m − ω₀ − S f),   W = T_g / s,   ω₀ = s (b_g − z_g),   S = s G_g / g    ((rad/s)/(m/s²))

:class:`SIModel` holds ``A, α₀, W, ω₀, S``; each format module writes it in its tool's own
convention and says what the convention cannot hold.  Where the tool's matrices are triangular,
:func:`lq` factors a matrix into a triangular one and a rotation.  :func:`accel_loss` measures,
on the calibration's own poses, ``|a| − 1`` of the full calibration against the exported model
applied as the tool applies it; :func:`gyro_loss` the rate the exported gyroscope model misses
(the g-sensitivity, where the tool has no place for it) for 1 g along each pose's direction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import STANDARD_GRAVITY
from optcal.core.rotations import rotation_angle_deg
from optcal.core.stats import rms
from optcal.core.units import RAD_PER_UNIT
from optcal.data.units import UNSIGNED_16_MIDSCALE, around_midscale
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, LossReport, linear_part
from optcal.applications.export.firmware import driver_zero, loss_poses, ms2_per_raw_unit

@dataclass(frozen=True)
class SIModel:
    """The calibration in the IMU topic's SI units (module docstring).

    Attributes
    ----------
    A : ndarray, shape (3, 3)
        ``f = A (α − α₀)``: specific force (m/s², optcal's frame) from the topic's accelerometer.
    acc_offset : ndarray, shape (3,)
        ``α₀``, m/s² of the topic.
    W : ndarray, shape (3, 3) or None
        ``ω = W (ω_m − ω₀ − S f)``: body rate (rad/s, optcal's frame) from the topic's gyroscope;
        None for an accelerometer-only calibration.
    gyro_offset : ndarray, shape (3,) or None
        ``ω₀``, rad/s of the topic.
    S : ndarray, shape (3, 3) or None
        g-sensitivity, (rad/s)/(m/s²) of the topic's gyroscope per specific force; None when not modelled.
    M, o : ndarray, shape (3, 3) and (3,)
        The accelerometer's ``ā = M (a − o)`` the matrices come from, as ``optcal apply`` applies it
        (:func:`~optcal.applications.export.base.linear_part`: in the calibration's own frame, the
        gyroscope's).
    gravity : float
        m/s² per g of the calibration.
    driver : list of str
        How the topic's units were taken (the driver conversion, zero readings).
    acc_per_raw, acc_zero : float
        ``k`` and ``z``: the topic's accelerometer reading is ``k (a − z)``.
    """

    A: NDArray[np.float64]
    acc_offset: NDArray[np.float64]
    W: NDArray[np.float64] | None
    gyro_offset: NDArray[np.float64] | None
    S: NDArray[np.float64] | None
    M: NDArray[np.float64]
    o: NDArray[np.float64]
    gravity: float
    driver: list[str]
    acc_per_raw: float = 1.0
    acc_zero: float = 0.0

    def topic_acc(self, raw: NDArray[np.float64]) -> NDArray[np.float64]:
        """The topic's accelerometer reading ``k (a − z)`` of raw samples, m/s²."""
        return self.acc_per_raw * (np.asarray(raw, float) - self.acc_zero)


def gyro_driver(cal: Calibration, options: ExportOptions) -> tuple[float, float, str | None]:
    """``s`` (rad/s of the topic per raw gyro unit), ``z_g`` (the raw reading the driver subtracts) and why.

    rad/s and °/s have their unit factor; counts need the driver's sensitivity
    (:meth:`~optcal.applications.export.base.ExportOptions.gyro_counts_per_rad`) and the zero reading ``options.gyro_counts_zero``, by default the
    unsigned 16-bit mid-scale 32768 when the bias lies around it (as the accelerometer's,
    :func:`optcal.applications.export.firmware.driver_zero`), else 0.
    """
    units = str(getattr(cal, "gyro_units", ""))
    if units in RAD_PER_UNIT:
        if options.gyro_counts_zero:
            raise InputError(f"gyro_counts_zero applies to a gyroscope in counts; this one is in {units}")
        return RAD_PER_UNIT[units], 0.0, None
    counts_per_rad_s = options.gyro_counts_per_rad()
    if counts_per_rad_s is None:
        raise InputError(
            "the gyroscope's calibration takes raw counts, but the VIO tools read the IMU topic in rad/s: give "
            "gyro_counts_per_rad_s (the sensitivity the driver divides by, from the datasheet, e.g. 131 per deg/s "
            "= 7505.7 per rad/s for an MPU-6050 at ±250 deg/s)"
        )
    s = 1.0 / float(counts_per_rad_s)
    if options.gyro_counts_zero is not None:
        z = float(options.gyro_counts_zero)
        return s, z, (f"gyro counts zero {z:g} (given)" if z else None)
    bias = np.asarray(getattr(cal, "gyro").bias, float)
    if around_midscale(bias):
        return s, UNSIGNED_16_MIDSCALE, (f"the gyro bias lies around the unsigned 16-bit mid-scale "
                                         f"{UNSIGNED_16_MIDSCALE:g}: a driver that outputs rad/s has removed it, "
                                         "so it is subtracted from the bias (gyro_counts_zero=VALUE sets another)")
    return s, 0.0, None


def si_model(cal: Calibration, options: ExportOptions, needs_topic_units: bool = True) -> SIModel:
    """:class:`SIModel` of ``cal`` (the gyroscope's part when ``cal`` has one).

    ``needs_topic_units=False`` keeps the raw units (``k = 1``, ``s = 1``, no zero readings): for a
    tool that reads the raw samples itself (imu_tk).
    """
    g = float(options.gravity_m_s2)
    M, o, _ = linear_part(cal)  # its own frame, in which T_g is stated (not the canonical T's)
    driver: list[str] = []
    if needs_topic_units:
        k = ms2_per_raw_unit(cal.units, options.counts_per_g)
        z, zero_reason = driver_zero(cal, options)
        driver.append(f"accelerometer topic = {k:.9g} m/s^2 per {cal.units}" + (f" after subtracting {z:g}" if z else ""))
        if zero_reason:
            driver.append(zero_reason)
    else:
        k, z = 1.0, 0.0
    A = (g / k) * M
    offset = k * (o - z)
    gyro = getattr(cal, "gyro", None)
    if gyro is None:
        return SIModel(A, offset, None, None, None, M, o, g, driver, k, z)
    if needs_topic_units:
        s, zg, zg_reason = gyro_driver(cal, options)
        driver.append(f"gyroscope topic = {s:.9g} rad/s per {getattr(cal, 'gyro_units')}" + (f" after subtracting {zg:g}" if zg else ""))
        if zg_reason:
            driver.append(zg_reason)
    else:
        s, zg = 1.0, 0.0
    S = None if gyro.g_sensitivity is None else s * gyro.g_sensitivity / g
    return SIModel(A, offset, gyro.T / s, s * (gyro.bias - zg), S, M, o, g, driver, k, z)


def proper_rotation(Q: NDArray[np.float64]) -> bool:
    return bool(np.linalg.det(Q) > 0)


def lq(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``M = L Q``: ``L`` lower-triangular with a positive diagonal where ``det M > 0``, ``Q`` a proper rotation.

    From the QR factorisation of ``Mᵀ`` (``Mᵀ = Q' R``: ``M = Rᵀ Q'ᵀ``).  A reflection (``det M < 0``, a
    left-handed set of axes) keeps ``Q`` proper and gives ``L`` a negative last diagonal element.
    """
    Q, U = qr_upper(np.asarray(M, float).T)
    return U.T, Q.T


def qr_upper(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``M = Q U``: ``Q`` a proper rotation, ``U`` upper-triangular with a positive diagonal where ``det M > 0``."""
    q, r = np.linalg.qr(np.asarray(M, float))
    signs = np.sign(np.diag(r))
    signs[signs == 0] = 1.0
    q, r = q * signs, r * signs[:, None]
    if not proper_rotation(q):
        flip = np.diag([1.0, 1.0, -1.0])
        q, r = q @ flip, flip @ r
    r = np.where(np.tril(np.ones((3, 3)), -1) > 0, 0.0, r)
    return q, r


def ql(A: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``R``, ``L`` with ``R A = L``: ``R`` a proper rotation, ``L`` lower-triangular (``R = I``, ``L = A`` when ``A``
    already is).  From :func:`qr_upper` of ``A`` with its rows and columns reversed (``P A P = Q U``:
    ``A = (P Q P)(P U P)``, ``P U P`` lower-triangular, ``P Q P`` proper as ``Q``).
    """
    A = np.asarray(A, dtype=float)
    if not np.any(np.triu(A, 1) != 0):
        return np.eye(3), A
    Q, U = qr_upper(A[::-1, ::-1])
    return Q[::-1, ::-1].T, U[::-1, ::-1]


def accel_loss(cal: Calibration, options: ExportOptions, exported_g: Callable[[NDArray[np.float64]], NDArray[np.float64]],
               what: str) -> LossReport:
    """rms ``|a| − 1`` of the full calibration and of the exported model on the calibration's poses.

    ``exported_g`` maps the poses' raw samples to the specific force the tool computes, in g of the
    calibration; refused above ``options.max_loss_g`` (as the firmware formats).
    """
    poses = loss_poses(cal, options)
    full = cal.norm_errors(poses.acc, poses.temp, poses.t)
    exported = np.linalg.norm(exported_g(poses.acc), axis=1) - 1.0
    report = LossReport(poses.n, rms(full), rms(exported))
    if report.loss_g > options.max_loss_g:
        raise InputError(f"the {what} model would lose too much: {report.describe()}, more than max_loss_g = "
                         f"{options.max_loss_g * 1e3:g} mg. Raise max_loss_g to export anyway, or use the c exporter, "
                         "which keeps the whole model")
    return report


def gyro_loss(cal: Calibration, options: ExportOptions, model: SIModel) -> tuple[float, float]:
    """The rate the dropped g-sensitivity adds, rms and largest over the calibration's poses, rad/s.

    ``|W S f|`` with ``f`` the specific force of each pose (1 g in its direction): what a tool without
    a g-sensitivity term leaves in the corrected rate at rest in that pose.
    """
    if model.S is None or model.W is None:
        return 0.0, 0.0
    poses = loss_poses(cal, options)
    f = model.gravity * (poses.acc - model.o) @ model.M.T
    f = model.gravity * f / np.linalg.norm(f, axis=1, keepdims=True)
    missed = np.linalg.norm(f @ (model.W @ model.S).T, axis=1)
    return rms(missed), float(missed.max())


def describe_gyro_loss(rms_rad_s: float, max_rad_s: float, n: int) -> str:
    return (f"gyro g-sensitivity G_g: the tool has no place for it; the rate it adds at 1 g is "
            f"{np.degrees(rms_rad_s):.4g} deg/s rms ({np.degrees(max_rad_s):.4g} deg/s largest) over the "
            f"calibration's {n} poses, left in the corrected rate")


def matrix_yaml(M: NDArray[np.float64], indent: str) -> list[str]:
    """A 3×3 (or 4×4) matrix as YAML rows ``- [a, b, c]`` (Kalibr's and OpenVINS's layout)."""
    return [f"{indent}- [{', '.join(f'{v:.12g}' for v in row)}]" for row in np.asarray(M, float)]


__all__ = ["SIModel", "accel_loss", "describe_gyro_loss", "gyro_driver", "gyro_loss", "lq",
           "matrix_yaml", "ql", "qr_upper", "rotation_angle_deg", "si_model", "STANDARD_GRAVITY"]
