"""The whole-IMU calibration: accelerometer and gyroscope from one recording (``cal_type`` ``imu``).

Parameters, units and equation
------------------------------
=========  =====================  ===========================================================
``T``, o   g per raw unit, raw    the accelerometer's lumped calibration (:mod:`optcal.core.model`)
``Tg``     rad/s per gyro unit    3×3 full: scale and misalignment relative to the
                                  accelerometer frame (:mod:`optcal.core.gyro_model`)
``bg``     gyro units             bias
``Gg``     gyro units per g       g-sensitivity (optional)
=========  =====================  ===========================================================

::

    ā = T (a − o)                          Lu 2017, eq. 6
    ω = T_g (g − b_g − G_g ā)              Tedaldi 2014, eq. 9 (rad/s, accelerometer frame)

:class:`ImuCalibration` is a calibration type (:class:`~optcal.families.caltypes.base.Calibration`)
and, for its gyroscope part, a fit record (:class:`~optcal.core.fit_result.FitRecord`: parameters,
covariance, solver, identifiability, exclusions, notes); the accelerometer part is the
accelerometer's own :class:`~optcal.families.accel.result.CalibrationResult`.  The text report is
:func:`optcal.report.imu_text.imu_report`.

The class lives with the gyroscope, not in :mod:`optcal.families.caltypes`: it holds the
accelerometer's result, whose module imports the calibration types, so in ``caltypes`` it would
close a cycle ``caltypes → accel → caltypes``.  The registry that reads any file by its
``cal_type`` (:mod:`optcal.families.calibration_files`) sits above both for the same reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.accel.result import CalibrationResult
from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.families.gyro.identifiability import GyroIdentifiability
from optcal.errors import InputError
from optcal.core.fit_result import FitRecord, SolverInfo
from optcal.core.gyro_model import GyroModel
from optcal.core.jsonio import read_json
from optcal.core.stats import rms

CAL_TYPE: str = "imu"


@dataclass(kw_only=True, eq=False)
class ImuCalibration(Calibration, FitRecord):
    """Accelerometer and gyroscope calibrated together (module docstring).

    Attributes
    ----------
    accelerometer : CalibrationResult
        The accelerometer fit (fixed, or re-estimated jointly with the gyro).
    gyro : GyroModel
    gyro_units : str
        Units of the raw gyro input (``counts``, ``rad/s``, ``deg/s``); output rad/s.
    gyro_units_reason : str
    param_names : list of str
        Names of :attr:`params` (θ_g of :mod:`optcal.core.gyro_model`, then ``G_g`` if modelled).
    params : ndarray
    covariance : ndarray
        Covariance of :attr:`params` (``T_g`` from the Gauss–Newton matrix scaled by the
        residual variance; bias and ``G_g`` from the still intervals).
    angles_before_deg, angles_after_deg : ndarray, shape (m,)
        Angle between the gravity direction predicted across each move and the one measured
        at the next pose, before (bias removed, nominal scale) and after calibration.
    before : str
        What "before" means.
    accelerometer_mode : str
        ``fixed`` or ``joint``.
    solver : SolverInfo
    identifiability : GyroIdentifiability, optional
    exclusions, notes
        Of the gyro fit (:class:`~optcal.core.fit_result.FitRecord`).
    units : str
        Accelerometer input units.
    fitted_on : FitPoses, optional
    fit_check : dict, optional
        The tests of the fit against the moves (:meth:`optcal.families.gyro.consistency.GyroFitCheck.to_dict`).
    """

    cal_type: ClassVar[str] = CAL_TYPE

    accelerometer: CalibrationResult
    gyro: GyroModel
    gyro_units: str
    gyro_units_reason: str
    angles_before_deg: NDArray[np.float64]
    angles_after_deg: NDArray[np.float64]
    before: str
    accelerometer_mode: str
    identifiability: GyroIdentifiability | None = None
    units: str = "g"
    fitted_on: FitPoses | None = None
    fit_check: dict[str, Any] | None = None

    @property
    def rms_angle_before_deg(self) -> float:
        return rms(self.angles_before_deg)

    @property
    def rms_angle_after_deg(self) -> float:
        return rms(self.angles_after_deg)

    @property
    def fit_warning(self) -> str | None:
        """The warning of the fit's tests (kept despite findings, or a flagged residual), if any."""
        return None if self.fit_check is None else self.fit_check.get("warning")

    # ------------------------------------------------------------ Calibration
    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """Calibrated specific force ``T (a − o)`` in g (Lu 2017, eq. 6)."""
        return (as_samples(acc) - self.accelerometer.o) @ self.accelerometer.T.T

    def correct_gyro(self, gyro: ArrayLike, acc: ArrayLike | None = None) -> NDArray[np.float64]:
        """Body rate in rad/s in the accelerometer frame for raw gyro samples (and raw ``acc`` for ``G_g``)."""
        f = None
        if self.gyro.g_sensitivity is not None:
            if acc is None:
                raise InputError("this gyro calibration has a g-sensitivity: pass the raw accelerometer samples (acc=)")
            f = self.correct(acc)
        return self.gyro.correct(as_samples(gyro, "gyro"), f)

    def parameters(self) -> dict[str, Any]:
        acc = self.accelerometer.to_dict()
        acc.pop("fitted_on", None)
        phys = self.gyro.physical()
        return {
            "T": self.accelerometer.T,
            "o": self.accelerometer.o,
            "Tg": self.gyro.T,
            "bg": self.gyro.bias,
            "Gg": self.gyro.g_sensitivity,
            "gyro_units": {"input": self.gyro_units, "output": "rad/s", "reason": self.gyro_units_reason},
            "gyro_physical": {"scale": phys.scale, "axes": phys.axes, "misalignment_deg": phys.misalignment_deg},
            "gyro_fit": {
                "param_names": self.param_names,
                "params": self.params,
                "stderr": self.stderr,
                "covariance": self.covariance,
                "accelerometer_mode": self.accelerometer_mode,
                "solver": self.solver.to_dict(),
                "identifiability": {} if self.identifiability is None else self.identifiability.to_dict(),
                "exclusions": self.exclusions,
                "notes": self.notes,
                **({"fit_check": self.fit_check} if self.fit_check is not None else {}),
            },
            "gravity_prediction": {
                "n_moves": int(self.angles_after_deg.size),
                "rms_deg_before": self.rms_angle_before_deg,
                "rms_deg_after": self.rms_angle_after_deg,
                "angles_deg_before": self.angles_before_deg,
                "angles_deg_after": self.angles_after_deg,
                "before": self.before,
            },
            "accelerometer_fit": acc,
        }

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "ImuCalibration":
        fit, gp = d["gyro_fit"], d["gravity_prediction"]
        gs = d.get("Gg")
        return cls(
            accelerometer=CalibrationResult.from_dict(d["accelerometer_fit"]),
            gyro=GyroModel(read_matrix(d, "Tg", (3, 3)), read_matrix(d, "bg", (3,)),
                           None if gs is None else np.asarray(gs, float).reshape(3, 3)),
            gyro_units=str(d["gyro_units"]["input"]),
            gyro_units_reason=str(d["gyro_units"].get("reason", "")),
            param_names=list(fit["param_names"]),
            params=np.asarray(fit["params"], float),
            covariance=np.asarray(fit["covariance"], float),
            angles_before_deg=np.asarray(gp["angles_deg_before"], float),
            angles_after_deg=np.asarray(gp["angles_deg_after"], float),
            before=str(gp["before"]),
            accelerometer_mode=str(fit["accelerometer_mode"]),
            solver=SolverInfo.from_dict(fit["solver"]),
            identifiability=GyroIdentifiability.from_dict(fit["identifiability"]) if fit.get("identifiability") else None,
            exclusions=dict(fit.get("exclusions") or {}),
            notes=list(fit.get("notes") or []),
            units=units,
            fitted_on=fitted_on,
            fit_check=dict(fit["fit_check"]) if fit.get("fit_check") else None,
        )

    def unit_fields(self) -> dict[str, str]:
        return {"T": f"g per {self.units}", "o": self.units, "Tg": f"rad/s per {self.gyro_units}",
                "bg": self.gyro_units, "Gg": f"{self.gyro_units} per g"}

    def lumped(self) -> LumpedCalibration:
        return LumpedCalibration.from_any_T(self.accelerometer.T, self.accelerometer.o, self.units, self.fitted_on)

    @classmethod
    def load(cls, path: str | Path) -> "ImuCalibration":
        """Read a file written by :meth:`save` (:func:`optcal.families.calibration_files.load` reads it too)."""
        d = read_json(path)
        found = d.get("cal_type")
        if found != cls.cal_type:
            raise InputError(f"{path}: a {found!r} calibration, not an IMU calibration (cal_type 'imu')")
        try:
            return cls.from_dict(d)
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from exc


__all__ = ["CAL_TYPE", "ImuCalibration"]
