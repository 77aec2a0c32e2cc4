"""The gyroscope of an ``imu`` calibration in ArduPilot's and PX4's parameters: bias offsets, and what they lose.

Both firmwares correct a gyro sample (rad/s, sensor frame) by an offset per axis and nothing else:

* PX4 ``calibration::Gyroscope::Correct`` (``src/lib/sensor_calibration/Gyroscope.hpp``):
  ``rotation · (data − thermal_offset − CAL_GYROn_{X,Y,Z}OFF)``;
* ArduPilot ``AP_InertialSensor_Backend::_rotate_and_correct_gyro``
  (``libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp``): the thermal correction, then
  ``gyro -= INS_GYROFFS`` (``INS_GYR2OFFS``, ``INS_GYR3OFFS``), then the board rotation.

optcal's gyro calibration is ``ω = T_g (g − b_g − G_g ā)`` (:mod:`optcal.core.gyro_model`, rad/s in
the accelerometer frame).  With ``k`` the factor from the raw gyro units to rad/s of the driver's
output (1 for rad/s, π/180 for °/s, (π/180)/counts_per_dps for counts) and ``z`` the raw reading the
driver subtracts (counts only), the firmware's output is ``k (g − z) − offset``; the offset that
removes the bias is ``offset = k (b_g − z)``, so the firmware gives ``ω_fw = k (g − b_g)``.
Since ``g − b_g = T_g⁻¹ ω + G_g ā``, its error is::

    ω_fw − ω = (k T_g⁻¹ − I) ω + k G_g ā

the first term from the scale and misalignment (no firmware parameter), the second from the
g-sensitivity (none either).  :class:`GyroLoss` states both: the error as a fraction of the rate,
in the worst direction (the largest singular value of ``E = k T_g⁻¹ − I``) and rms over all
directions (``‖E‖_F / √3``, the mean of ``|E u|²`` over unit vectors ``u`` being ``tr(EᵀE)/3``),
and at a stated rate; the g-sensitivity's in the worst direction of a 1 g specific force.  Given a
recording (``options.recording``), :func:`gravity_prediction_loss` also carries gravity across its
moves with the firmware's gyro and with the full model (Tedaldi 2014, eq. 13-14,
:mod:`optcal.families.gyro.propagation`), both from the full accelerometer's directions, so that
the difference is the gyroscope's alone.
No calibration type carries gyro temperature terms, so ``TC_G*`` and ``INS_TCALn_GYR*`` are not
written (and say so).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.export.base import ExportOptions
from optcal.core.units import RAD_PER_UNIT
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration
from optcal.families.gyro.moves import moves_from_segmentation
from optcal.families.gyro.propagation import GravityPredictor, angles_deg, unit_rows
from optcal.core.stats import rms


def rad_s_per_gyro_unit(units: str, counts_per_dps: float | None) -> float:
    """``k``: the factor from the calibration's raw gyro units to rad/s of the driver's output."""
    if units in RAD_PER_UNIT:
        return RAD_PER_UNIT[units]
    if counts_per_dps is None or not counts_per_dps > 0:
        raise InputError(
            "the gyroscope takes raw counts, but firmware gyro offsets are in rad/s of the driver's output: give "
            "counts_per_dps (the sensitivity the driver divides by, counts per deg/s, e.g. 16.4 for an MPU-6050 at "
            "±2000 deg/s; see the sensor's datasheet)"
        )
    return RAD_PER_UNIT["deg/s"] / float(counts_per_dps)


@dataclass(frozen=True)
class GyroLoss:
    """What the firmware's offset-only gyro model cannot correct (module docstring).

    Attributes
    ----------
    relative_worst, relative_rms : float
        Rate error as a fraction of the rate: worst direction, rms over directions.
    rate_deg_s : float
        The rate the error is stated at, °/s.
    scale_error : ndarray, shape (3,)
        ``k K_g,i − 1``: each axis's scale error left in the firmware's output.
    misalignment_deg : ndarray, shape (3,)
        Each gyro sensing axis's angle to the accelerometer frame's axis, degrees.
    g_sensitivity_deg_s_per_g : float or None
        Worst rate error from the g-sensitivity at 1 g, °/s (``None``: not modelled).
    """

    relative_worst: float
    relative_rms: float
    rate_deg_s: float
    scale_error: NDArray[np.float64]
    misalignment_deg: NDArray[np.float64]
    g_sensitivity_deg_s_per_g: float | None

    def describe_scale(self) -> str:
        scales = ", ".join(f"{100 * e:+.3f}%" for e in self.scale_error)
        angles = ", ".join(f"{a:.3f}" for a in self.misalignment_deg)
        return (f"gyro scale ({scales} on x, y, z) and misalignment ({angles} deg): the firmware gyro model is an "
                f"offset only; rate error {100 * self.relative_worst:.3f}% of the rate in the worst direction "
                f"({100 * self.relative_rms:.3f}% rms over directions), {self.relative_worst * self.rate_deg_s:.4g} "
                f"deg/s at {self.rate_deg_s:g} deg/s")

    def describe_g_sensitivity(self) -> str | None:
        if self.g_sensitivity_deg_s_per_g is None:
            return None
        return (f"gyro g-sensitivity G_g: the firmware has no such term; rate error up to "
                f"{self.g_sensitivity_deg_s_per_g:.4g} deg/s under a 1 g specific force (worst direction)")


@dataclass(frozen=True)
class GyroOffsets:
    """The firmware's gyro offsets of an ``imu`` calibration, and what they leave out.

    Attributes
    ----------
    offset_rad_s : ndarray, shape (3,)
        ``k (b_g − z)``, rad/s.
    rad_s_per_raw : float
        ``k``.
    raw_zero : float
        ``z``.
    loss : GyroLoss
    mapped, dropped : tuple of str
    """

    offset_rad_s: NDArray[np.float64]
    rad_s_per_raw: float
    raw_zero: float
    loss: GyroLoss
    mapped: tuple[str, ...]
    dropped: tuple[str, ...]
    moves_line: str | None = None

    def correct(self, raw: NDArray[np.float64]) -> NDArray[np.float64]:
        """The firmware's ``k (g − z) − offset``, rad/s, of raw gyro samples."""
        return (np.asarray(raw, float) - self.raw_zero) * self.rad_s_per_raw - self.offset_rad_s


def gyro_offsets(cal: Calibration, options: ExportOptions, raw_zero: float) -> GyroOffsets | None:
    """The gyro offsets of ``cal`` (``None`` unless it has a gyroscope: ``imu``, a peer's file with one).

    ``raw_zero`` is the reading the accelerometer's driver subtracts
    (:func:`optcal.applications.export.firmware.driver_zero`): a gyro in counts is taken to come
    from the same converter, with the same zero reading; a gyro in rad/s or °/s has none.
    """
    model = getattr(cal, "gyro", None)
    gyro_units = getattr(cal, "gyro_units", None)
    if model is None or gyro_units is None:  # a peer's file without a gyroscope too
        return None
    k = rad_s_per_gyro_unit(gyro_units, options.gyro_counts_per_dps())
    z = raw_zero if gyro_units == "counts" else 0.0
    E = k * np.linalg.inv(model.T) - np.eye(3)  # ω_fw − ω = E ω (module docstring)
    phys = model.physical()
    g_sens = None
    if model.g_sensitivity is not None:
        g_sens = float(np.degrees(np.linalg.norm(k * model.g_sensitivity, 2)))
    loss = GyroLoss(float(np.linalg.norm(E, 2)), float(np.linalg.norm(E) / np.sqrt(3.0)), float(options.gyro_rate_deg_s),
                    k * phys.scale - 1.0, phys.misalignment_deg, g_sens)
    mapped = [f"gyro bias b_g (offsets, rad/s{'; less the zero reading ' + format(z, 'g') if z else ''})"]
    dropped = [loss.describe_scale()]
    g_line = loss.describe_g_sensitivity()
    if g_line is not None:
        dropped.append(g_line)
    dropped.append("gyro temperature terms: the calibration has none, so the firmware's gyro thermal parameters are "
                   "not written")
    offsets = GyroOffsets(k * (model.bias - z), k, z, loss, tuple(mapped), tuple(dropped))
    if options.recording is None:
        return offsets
    n, full, firmware = gravity_prediction_loss(cal, offsets, options.recording)
    line = (f"gravity carried across the recording's {n} moves, rms angle to the next pose: full gyro model "
            f"{full:.3f} deg, the firmware's offsets only {firmware:.3f} deg (loss {firmware - full:.3f} deg)")
    return replace(offsets, moves_line=line)


def gravity_prediction_loss(cal: Any, offsets: GyroOffsets, recording: Any) -> tuple[int, float, float]:
    """Moves, and the rms gravity-prediction angle of the full gyro model and of the firmware's, degrees.

    ``recording`` is a :class:`optcal.data.static.Segmentation` of a raw recording in the
    calibration's units with gyro columns; the gravity directions are the full accelerometer's.
    """
    rec = recording.recording
    if rec.gyro is None:
        raise InputError("the recording has no gyro columns: the gravity prediction across its moves needs gx, gy, gz")
    gyro_units = rec.gyro_units or cal.gyro_units  # not stated by the file: the calibration's, as optcal check takes
    if rec.units != cal.units or gyro_units != cal.gyro_units:
        raise InputError(f"the recording is in {rec.units} and {gyro_units}, the calibration in {cal.units} and "
                         f"{cal.gyro_units}: give the recording it was fitted on")
    moves = moves_from_segmentation(recording)
    u = unit_rows(cal.correct(moves.acc_means))
    u0, u1 = u[moves.move_from], u[moves.move_to]
    predictor = GravityPredictor(moves.first_step, moves.last_step)  # Tedaldi 2014, eq. 13-14
    full = angles_deg(predictor(cal.correct_gyro(moves.gyro_mid(), moves.acc_mid), moves.dt, u0), u1)
    firmware = angles_deg(predictor(offsets.correct(moves.gyro_mid()), moves.dt, u0), u1)
    return int(moves.n_moves), rms(full), rms(firmware)
