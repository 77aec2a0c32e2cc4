"""The whole-IMU calibration: accelerometer and gyroscope from one recording (``cal_type`` ``imu``)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.gyro.model import G_NAMES, GyroModel
from optcal.gyro.propagation import rms
from optcal.result import CalibrationResult, SolverInfo, jsonable

CAL_TYPE: str = "imu"
FORMAT_VERSION: int = 1


@dataclass
class ImuCalibration:
    """Accelerometer and gyroscope calibrated together.

    Attributes
    ----------
    accelerometer : CalibrationResult
        ``ā = T (a − o)`` in g (fixed, or re-estimated jointly with the gyro).
    gyro : GyroModel
        ``ω = T_g (g − b_g − G_g f)`` in rad/s in the accelerometer frame.
    gyro_units : str
        Units of the raw gyro input (``counts``, ``rad/s``, ``deg/s``).
    gyro_units_reason : str
    param_names : list of str
        Names of :attr:`params` (θ_g of :mod:`optcal.gyro.model`, then ``G_g`` if modelled).
    params : ndarray
    covariance : ndarray
        Covariance of :attr:`params` (T_g from the Gauss–Newton matrix scaled by the residual
        variance; bias and ``G_g`` from the still intervals).
    angles_before_deg, angles_after_deg : ndarray, shape (m,)
        Angle between the gravity direction predicted across each move and the one measured
        at the next pose, before (bias removed, nominal scale) and after calibration.
    before : str
        What "before" means.
    accelerometer_mode : str
        ``fixed`` or ``joint``.
    solver : SolverInfo
    identifiability : dict
    exclusions : dict of str to int
    notes : list of str
    """

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
    cal_type: str = CAL_TYPE
    format_version: int = FORMAT_VERSION

    @property
    def stderr(self) -> dict[str, float]:
        """Standard error of each parameter."""
        return dict(zip(self.param_names, np.sqrt(np.clip(np.diag(self.covariance), 0.0, None)).tolist()))

    @property
    def rms_angle_before_deg(self) -> float:
        return rms(self.angles_before_deg)

    @property
    def rms_angle_after_deg(self) -> float:
        return rms(self.angles_after_deg)

    def correct(self, acc: ArrayLike, gyro: ArrayLike | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Calibrated specific force (g) and body rate (rad/s, accelerometer frame) for raw samples."""
        f = self.accelerometer.correct(acc)
        if gyro is None:
            return f, None
        return f, self.gyro.correct(gyro, f if self.gyro.g_sensitivity is not None else None)

    def summary(self) -> dict[str, Any]:
        """JSON-safe dictionary (``optcal calibrate --imu --json``)."""
        phys = self.gyro.physical()
        return jsonable({
            "cal_type": self.cal_type,
            "format_version": self.format_version,
            "accelerometer_mode": self.accelerometer_mode,
            "accelerometer": self.accelerometer.to_dict(),
            "gyro": {
                "units": {"input": self.gyro_units, "output": "rad/s", "T": f"rad/s per {self.gyro_units}",
                          "bias": self.gyro_units, "reason": self.gyro_units_reason},
                "T": self.gyro.T,
                "bias": self.gyro.bias,
                "g_sensitivity": self.gyro.g_sensitivity,
                "scale": phys.scale,
                "axes": phys.axes,
                "misalignment_deg": phys.misalignment_deg,
                "params": dict(zip(self.param_names, self.params)),
                "stderr": self.stderr,
                "covariance": self.covariance,
                "param_names": self.param_names,
                "params_vector": self.params,
            },
            "gravity_prediction": {
                "n_moves": int(self.angles_after_deg.size),
                "rms_deg_before": self.rms_angle_before_deg,
                "rms_deg_after": self.rms_angle_after_deg,
                "angles_deg_before": self.angles_before_deg,
                "angles_deg_after": self.angles_after_deg,
                "before": self.before,
            },
            "solver": self.solver.to_dict(),
            "identifiability": self.identifiability,
            "exclusions": self.exclusions,
            "notes": self.notes,
        })

    to_dict = summary

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "ImuCalibration":
        """Rebuild a calibration written by :meth:`to_dict`."""
        try:
            if d.get("cal_type") != CAL_TYPE:
                raise InputError(f"not an IMU calibration (cal_type {d.get('cal_type')!r}, expected {CAL_TYPE!r})")
            version = int(d["format_version"])
            if not 1 <= version <= FORMAT_VERSION:
                raise InputError(f"IMU calibration format version {version}; this optcal reads 1..{FORMAT_VERSION}")
            g = d["gyro"]
            gs = g.get("g_sensitivity")
            gp = d["gravity_prediction"]
            return cls(
                accelerometer=CalibrationResult.from_dict(d["accelerometer"]),
                gyro=GyroModel(np.asarray(g["T"], float), np.asarray(g["bias"], float),
                               None if gs is None else np.asarray(gs, float)),
                gyro_units=str(g["units"]["input"]),
                gyro_units_reason=str(g["units"].get("reason", "")),
                param_names=list(g["param_names"]),
                params=np.asarray(g["params_vector"], float),
                covariance=np.asarray(g["covariance"], float),
                angles_before_deg=np.asarray(gp["angles_deg_before"], float),
                angles_after_deg=np.asarray(gp["angles_deg_after"], float),
                before=str(gp["before"]),
                accelerometer_mode=str(d["accelerometer_mode"]),
                solver=SolverInfo(**d["solver"]),
                identifiability=dict(d.get("identifiability") or {}),
                exclusions=dict(d.get("exclusions") or {}),
                notes=list(d.get("notes") or []),
                format_version=version,
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not an optcal IMU calibration ({exc.__class__.__name__}: {exc})") from exc

    def save(self, path: str | Path) -> None:
        """Write the calibration as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> "ImuCalibration":
        """Read a calibration written by :meth:`save`."""
        p = Path(path)
        if not p.exists():
            raise InputError(f"{p}: no such calibration file")
        try:
            d = json.loads(p.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{p}: not a JSON calibration file ({exc})") from exc
        if not isinstance(d, dict):
            raise InputError(f"{p}: not an optcal calibration file")
        return cls.from_dict(d)

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


__all__ = ["CAL_TYPE", "G_NAMES", "ImuCalibration"]
