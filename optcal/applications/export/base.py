"""What every exporter shares: the options, the result, and the loss of a simplified model.

The format modules (:mod:`optcal.applications.export.ardupilot` and the others) import these;
the registry in :mod:`optcal.applications.export` imports the format modules on first use.
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import STANDARD_GRAVITY
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration, FitPoses

#: Default largest acceptable loss of a diagonal firmware model, g (5 mg).
DEFAULT_MAX_LOSS_G: float = 5e-3
#: Default rate at which a firmware's uncorrected gyroscope error is stated, °/s: a brisk turn of a
#: hand-held or flying vehicle (the error grows in proportion; ``gyro_rate_deg_s`` states another).
DEFAULT_GYRO_RATE_DEG_S: float = 100.0


@dataclass(frozen=True)
class ExportOptions:
    """Settings shared by the exporters.

    Attributes
    ----------
    counts_per_g : float, optional
        The driver's sensitivity (counts per g) for a calibration in counts: firmware
        parameters are in m/s² of the driver's output.
    counts_zero : float, optional
        The raw reading the driver subtracts before scaling (e.g. 32768, the mid-scale of an
        unsigned 16-bit converter; 0 for signed counts).  Default: 32768 when the poses are
        unsigned 16-bit counts around mid-scale (the test of ``optcal check``), else 0.
    max_loss_g : float
        Refuse a diagonal firmware model whose rms ``|a|`` error exceeds the full model's by more.
    poses : FitPoses, optional
        Poses to measure the loss on, when the calibration file has none (``fitted_on``).
    allan : dict, optional
        An ``optcal allan --json`` result (``kalibr``, ``ros``).
    random_walk_bound : bool
        ``kalibr``: write the Allan result's upper bound of the rate random walk on axes where
        the log shows none (labelled as a bound), instead of refusing.
    gyro_allan : dict, optional
        An ``optcal allan --sensor gyro --json`` result (``kalibr``: the gyroscope keys).
    rate_hz : float, optional
        Sample rate of the IMU topic (``kalibr``; default: the Allan log's rate).
    rostopic : str
        Topic of the IMU messages (``kalibr``).
    source : str
        Where the calibration came from (named in the file's comments).
    device_id : int, optional
        ``ardupilot``/``px4``: the accelerometer's device id (``INS_ACC_ID``, ``CAL_ACC0_ID``,
        ``TC_A0_ID``); the firmware applies a calibration only to the device whose id it names.
    gyro_device_id : int, optional
        ``ardupilot``/``px4``, ``imu`` calibrations: the gyroscope's device id (``INS_GYR_ID``,
        ``CAL_GYRO0_ID``); a different number from the accelerometer's, also on one chip.
    instance : int
        ``ardupilot``/``px4``: which IMU (0, 1 or 2) the parameters are for (``CAL_ACC1_*``,
        ``INS_ACC2OFFS_*``, ...).
    counts_per_dps : float, optional
        ``ardupilot``/``px4``, a gyroscope in counts: the driver's sensitivity, counts per °/s.
    gyro_rate_deg_s : float
        ``ardupilot``/``px4``: the rate at which the gyroscope error the firmware cannot correct
        is stated, °/s.
    vehicle_id : int
        ``px4``: the vehicle's MAVLink system id written in each line (QGroundControl refuses a
        file saved from another system id).
    recording : Segmentation, optional
        ``ardupilot``/``px4``, ``imu`` calibrations: a segmented raw recording with gyro columns
        (:class:`optcal.data.static.Segmentation`), across whose moves the gravity prediction of
        the firmware's gyro model is compared with the full model's.
    gyro_counts_per_rad_s : float, optional
        The driver's gyro sensitivity (counts per rad/s) for a gyroscope calibrated in counts:
        the VIO intrinsics (``kalibr-imu``, ``openvins``, ``basalt``) are in rad/s of the IMU topic.
    gyro_counts_zero : float, optional
        The raw gyro reading the driver subtracts (default: 32768 when the bias lies around the
        unsigned 16-bit mid-scale, else 0).
    gravity_m_s2 : float
        m/s² per g of the calibration (its |ā| = 1 is the local gravity where it was recorded):
        the VIO intrinsics and ``imutk`` are in m/s²; set the estimator's gravity to the same.
    inflate : tuple of (float, float)
        Factors applied to the noise densities (white) and the random walks (walk) of the noise
        keys (``vins``, ``orbslam3``, ``okvis``, ``kalibr-imu``, ``openvins``, ``basalt``), written
        into the file's comments.
    accept_planar : bool
        ``ardupilot``/``px4``/``px4-shell``: write a planar (heading) magnetometer calibration, whose hard iron along
        the plane's normal is undetermined (taken as 0), instead of refusing it (``--accept-planar``).
    """

    counts_per_g: float | None = None
    counts_zero: float | None = None
    max_loss_g: float = DEFAULT_MAX_LOSS_G
    poses: FitPoses | None = None
    allan: dict[str, Any] | None = None
    random_walk_bound: bool = False
    gyro_allan: dict[str, Any] | None = None
    rate_hz: float | None = None
    rostopic: str = "/imu0"
    source: str = "a calibration"
    device_id: int | None = None
    gyro_device_id: int | None = None
    instance: int = 0
    counts_per_dps: float | None = None
    gyro_rate_deg_s: float = DEFAULT_GYRO_RATE_DEG_S
    vehicle_id: int = 1
    recording: Any = None
    gyro_counts_per_rad_s: float | None = None
    gyro_counts_zero: float | None = None
    gravity_m_s2: float = STANDARD_GRAVITY
    inflate: tuple[float, float] = (1.0, 1.0)
    accept_planar: bool = False

    def __post_init__(self) -> None:
        # every number written into a firmware or estimator file finite and in its range (an inf scale would be
        # written as "inf" into a PX4 parameter file, which the firmware reads as a broken calibration)
        positive = {"counts_per_g": "--counts-per-g", "counts_per_dps": "--counts-per-dps",
                    "gyro_counts_per_rad_s": "--counts-per-rad-s", "rate_hz": "--rate",
                    "gravity_m_s2": "--gravity", "gyro_rate_deg_s": "--gyro-rate"}
        for name, flag in positive.items():
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a finite positive number, got {value} ({flag})")
        for name, flag in {"counts_zero": "--counts-zero", "gyro_counts_zero": "--gyro-counts-zero"}.items():
            value = getattr(self, name)
            if value is not None and not math.isfinite(value):
                raise InputError(f"{name} must be finite, got {value} ({flag})")
        if not (math.isfinite(self.max_loss_g) and self.max_loss_g >= 0):
            raise InputError(f"max_loss_g must be a finite number >= 0, got {self.max_loss_g} (--max-loss)")
        if not all(math.isfinite(f) and f > 0 for f in self.inflate):
            raise InputError(f"inflate factors must be finite and positive, got {self.inflate} (--inflate)")

    def gyro_counts_per_dps(self) -> float | None:
        """The driver's gyro sensitivity in counts per °/s, given as either :attr:`counts_per_dps` or
        :attr:`gyro_counts_per_rad_s` (the firmware formats state it per °/s, the VIO ones per rad/s)."""
        if self.counts_per_dps is not None:
            return self.counts_per_dps
        return None if self.gyro_counts_per_rad_s is None else self.gyro_counts_per_rad_s * math.pi / 180.0

    def gyro_counts_per_rad(self) -> float | None:
        """The same sensitivity in counts per rad/s (:meth:`gyro_counts_per_dps`)."""
        if self.gyro_counts_per_rad_s is not None:
            return self.gyro_counts_per_rad_s
        return None if self.counts_per_dps is None else self.counts_per_dps * 180.0 / math.pi


def linear_part(cal: Calibration) -> tuple[NDArray[np.float64], NDArray[np.float64], str]:
    """``M``, ``o`` and their name: the accelerometer map ``ā = M (a − o)`` that ``cal.correct`` applies.

    ``M`` is the calibration's own matrix in its own frame (the full ``W`` of ``sixpos_full`` and of a
    peer's file, the accelerometer ``T`` of an ``imu`` calibration, which the Ferraris method fits as
    the full ``W``), not the canonical lower-triangular ``T`` of :meth:`Calibration.lumped`, which
    is the same calibration turned into another frame (Lu 2017, eq. 6 against Yin 2014, eq. 3): a
    format written from it would move the accelerometer's axes against the gyroscope's and against
    ``optcal apply``.  ``extended``: the lumped part at its reference temperature and time.
    """
    W = getattr(cal, "W", None)
    if W is not None:  # sixpos_full, a peer's: W, o
        return np.asarray(W, float), np.asarray(getattr(cal, "o"), float), "W (full)"
    acc = getattr(cal, "accelerometer", None)
    if acc is not None:  # imu: the accelerometer's fit as correct() applies it
        T = np.asarray(acc.T, float)
        lower = not np.any(np.triu(T, 1) != 0)
        return T, np.asarray(acc.o, float), "T (canonical lower-triangular)" if lower else "T (full)"
    lumped = cal.lumped()
    return lumped.T, lumped.o, "T (canonical lower-triangular)"


@dataclass(frozen=True)
class LossReport:
    """rms ``|a| − 1`` of the full calibration and of the exported model on the same poses, g."""

    n_poses: int
    rms_full_g: float
    rms_exported_g: float

    @property
    def loss_g(self) -> float:
        return self.rms_exported_g - self.rms_full_g

    def describe(self) -> str:
        loss_mg = self.loss_g * 1e3
        if abs(loss_mg) < 0.5e-4:  # below the printed digits: no loss, not a "-0.0000" gain
            loss_mg = 0.0
        return (
            f"rms |a|-1 on the calibration's {self.n_poses} poses: full model {self.rms_full_g * 1e3:.4f} mg, "
            f"exported {self.rms_exported_g * 1e3:.4f} mg (loss {loss_mg:.4f} mg)"
        )


@dataclass
class ExportResult:
    """An exported calibration.

    Attributes
    ----------
    format : str
    text : str
        The file's content.
    loss : LossReport, optional
        For formats that simplify the model.
    mapped : list of str
        optcal terms written into the format.
    dropped : list of str
        optcal terms the format cannot hold (with the reason).
    notes : list of str
        What the user must know (units, frames, parameters optcal cannot fill in).
    files : dict of str to str
        Further files of the format (``imutk``: the gyroscope's ``.calib``), by the suffix added to
        the output file's stem.
    """

    format: str
    text: str
    loss: LossReport | None = None
    mapped: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    files: dict[str, str] = field(default_factory=dict)
