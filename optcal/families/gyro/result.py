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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.errors import InputError
from optcal.core.gyro_model import GyroModel
from optcal.core.stats import rms
from optcal.core.fit_result import CalibrationResult, SolverInfo

CAL_TYPE: str = "imu"


@dataclass(eq=False)
class ImuCalibration(Calibration):
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
    identifiability, exclusions, notes
    units : str
        Accelerometer input units.
    fitted_on : FitPoses, optional
    """

    cal_type: ClassVar[str] = CAL_TYPE

    accelerometer: CalibrationResult
    gyro: GyroModel
    gyro_units: str
    gyro_units_reason: str
    param_names: list[str]
    params: NDArray[np.float64]
    covariance: NDArray[np.float64]
    angles_before_deg: NDArray[np.float64]
    angles_after_deg: NDArray[np.float64]
    before: str
    accelerometer_mode: str
    solver: SolverInfo
    identifiability: dict[str, Any] = field(default_factory=dict)
    exclusions: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    units: str = "g"
    fitted_on: FitPoses | None = None

    @property
    def stderr(self) -> dict[str, float]:
        """Standard error of each gyro parameter."""
        return dict(zip(self.param_names, np.sqrt(np.clip(np.diag(self.covariance), 0.0, None)).tolist()))

    @property
    def rms_angle_before_deg(self) -> float:
        return rms(self.angles_before_deg)

    @property
    def rms_angle_after_deg(self) -> float:
        return rms(self.angles_after_deg)

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
                "identifiability": self.identifiability,
                "exclusions": self.exclusions,
                "notes": self.notes,
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
            solver=SolverInfo(**fit["solver"]),
            identifiability=dict(fit.get("identifiability") or {}),
            exclusions=dict(fit.get("exclusions") or {}),
            notes=list(fit.get("notes") or []),
            units=units,
            fitted_on=fitted_on,
        )

    def unit_fields(self) -> dict[str, str]:
        return {"T": f"g per {self.units}", "o": self.units, "Tg": f"rad/s per {self.gyro_units}",
                "bg": self.gyro_units, "Gg": f"{self.gyro_units} per g"}

    def lumped(self) -> LumpedCalibration:
        return LumpedCalibration.from_any_T(self.accelerometer.T, self.accelerometer.o, self.units, self.fitted_on)

    @classmethod
    def load(cls, path: str) -> "ImuCalibration":
        """Read a file written by :meth:`save` (``optcal.families.caltypes.load`` reads it too)."""
        from optcal.families.caltypes import load

        cal = load(path)
        if not isinstance(cal, cls):
            raise InputError(f"{path}: a {cal.cal_type!r} calibration, not an IMU calibration (cal_type 'imu')")
        return cal

    def report(self) -> str:
        """Readable report: the accelerometer's, then the gyro's parameters and the gravity-prediction residual."""
        se = self.stderr
        phys = self.gyro.physical()
        lines = [self.accelerometer.report(), f"[[Gyroscope: Tedaldi 2014, accelerometer {self.accelerometer_mode}]]",
                 f"    units              = {self.gyro_units} in ({self.gyro_units_reason}), rad/s out",
                 f"    moves              = {self.angles_after_deg.size}",
                 f"    gravity prediction = {self.rms_angle_before_deg:.3f}° rms before ({self.before}), "
                 f"{self.rms_angle_after_deg:.3f}° after",
                 f"    scale K_g          = {', '.join(f'{s:.6g}' for s in phys.scale)} {self.gyro_units} per rad/s",
                 f"    axis misalignment  = {', '.join(f'{m:.3f}' for m in phys.misalignment_deg)}° (x, y, z)",
                 f"    solver             = {self.solver.name}: {self.solver.status}, {self.solver.iterations} iterations, "
                 f"{self.solver.solve_time_s * 1e3:.1f} ms",
                 "[[Gyro parameters]]"]
        for name, value in zip(self.param_names, self.params):
            lines.append(f"    {name:<8s} = {value: .8g} +/- {se.get(name, float('nan')):.3g}")
        if self.identifiability:
            lines.append(f"    identifiability: {self.identifiability.get('description', '')}")
        if self.exclusions:
            lines.append("[[Excluded (gyro)]]")
            lines.extend(f"    {k}: {v}" for k, v in self.exclusions.items())
        if self.notes:
            lines.append("[[Notes (gyro)]]")
            lines.extend(f"    - {n}" for n in self.notes)
        return "\n".join(lines)


__all__ = ["CAL_TYPE", "ImuCalibration"]
