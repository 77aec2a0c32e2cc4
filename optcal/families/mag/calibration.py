"""The magnetometer's calibration file (``cal_type`` ``"magnetometer"``) and the fit that makes it.

``m̄ = T (m − o)`` with ``‖m̄‖ = 1`` in the local field (T symmetric: the hard iron ``o`` in the
data's units, the soft iron and scale ``T`` per unit); the calibrated field in the data's
units is ``field_strength · m̄``.  The file carries the JSON contract the held-out checks read:
``sensor``, ``n_samples``, ``field_strength``, ``o``, ``T``, ``rms_norm_residual`` and, with an
accelerometer, ``dip_deg``, ``dip_std_deg`` (and the frames' rotation ``R_mag_to_acc``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.jsonio import check_version
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.mag.dip import DipResult, estimate_dip
from optcal.families.mag.fit import MagFit, MagSettings, choose_form
from optcal.families.mag.samples import MagSamples
from optcal.families.mag.units import MAG_UNITS


@dataclass(eq=False)
class MagCalibration(Calibration):
    """A magnetometer calibration ``m̄ = T (m − o)``, ``‖m̄‖ = 1`` (module docstring).

    Attributes
    ----------
    T : ndarray, shape (3, 3)
        Symmetric positive definite, per data unit.
    o : ndarray, shape (3,)
        Hard iron, data units.
    units : str
        The magnetometer's units (one of :data:`optcal.families.mag.units.MAG_UNITS`).
    field_strength : float
        The local field, data units (``det(T)^(−1/3)``).
    fitted_on : None
        (The samples are not stored; :attr:`info` keeps the fit's statistics.)
    R_mag_to_acc : ndarray, shape (3, 3), optional
        Rotation of the calibrated magnetometer's frame into the accelerometer's.
    info : dict
        The fit's statistics and decisions (the JSON contract's other keys).
    """

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str
    field_strength: float
    fitted_on: FitPoses | None = None
    R_mag_to_acc: NDArray[np.float64] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    cal_type: ClassVar[str] = "magnetometer"

    def __post_init__(self) -> None:
        self.T = np.asarray(self.T, dtype=float).reshape(3, 3)
        self.o = np.asarray(self.o, dtype=float).reshape(3)
        if not (np.all(np.isfinite(self.T)) and np.all(np.isfinite(self.o))):
            raise InputError("T and o of a magnetometer calibration must be finite")
        if self.units not in MAG_UNITS:
            raise InputError(f"magnetometer units {self.units!r} are not one of {', '.join(MAG_UNITS)}")

    def correct(self, acc: ArrayLike, temp: ArrayLike | None = None, t: ArrayLike | None = None) -> NDArray[np.float64]:
        """``T (m − o)``: the field direction with unit norm, for raw samples ``m`` (n, 3); ``temp``, ``t`` unused."""
        return (as_samples(acc, "m") - self.o) @ self.T.T

    def field(self, m: ArrayLike) -> NDArray[np.float64]:
        """The calibrated field in the data's units: ``field_strength · T (m − o)``."""
        return self.field_strength * self.correct(m)

    def parameters(self) -> dict[str, Any]:
        out: dict[str, Any] = {**self.info, "sensor": "magnetometer", "T": self.T, "o": self.o,
                               "field_strength": self.field_strength}
        if self.R_mag_to_acc is not None:
            out["R_mag_to_acc"] = self.R_mag_to_acc
        return out

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "MagCalibration":
        keep = ("n_samples", "rms_norm_residual", "form", "form_reason", "dip_deg", "dip_std_deg", "coverage_missing",
                "method", "stderr", "decisions", "notes", "dip_se_deg", "dip_std_unaligned_deg", "rotation_deg", "rotation_se_deg",
                "wmm", "form_heldout")
        R = read_matrix(d, "R_mag_to_acc", (3, 3)) if d.get("R_mag_to_acc") is not None else None
        return cls(read_matrix(d, "T", (3, 3)), read_matrix(d, "o", (3,)), units, float(d["field_strength"]), None, R,
                   {k: d[k] for k in keep if k in d})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "MagCalibration":
        """Rebuild from :meth:`to_dict` (the magnetometer's units, not the accelerometer's)."""
        if not isinstance(d, dict) or d.get("cal_type") != cls.cal_type:
            raise InputError(f"this is a {d.get('cal_type') if isinstance(d, dict) else d!r} calibration, not 'magnetometer'")
        check_version(d.get("format_version"))
        units = d.get("units")
        units = units.get("input") if isinstance(units, dict) else units
        try:
            return cls.from_parameters(d, str(units), None)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not a valid 'magnetometer' calibration ({exc.__class__.__name__}: {exc})") from exc

    def unit_fields(self) -> dict[str, str]:
        return {"T": f"field strengths per {self.units}", "o": self.units, "field_strength": self.units, "output": "field strengths"}

    def lumped(self) -> Any:
        """The same ``T`` (canonical) and ``o`` as a lumped calibration (what the accelerometer's tools read)."""
        from optcal.families.caltypes.lumped import LumpedCalibration

        return LumpedCalibration.from_any_T(self.T, self.o, "counts")

    def describe(self) -> str:
        return f"magnetometer calibration ({self.units} in, unit field out; field {self.field_strength:.4g} {self.units})"


@dataclass(frozen=True)
class MagCalibrationResult:
    """What :func:`calibrate_mag` found: the calibration, the fit's evidence and the dip.

    Attributes
    ----------
    calibration : MagCalibration
    fit : MagFit
    dip : DipResult or None
    samples : MagSamples
    """

    calibration: MagCalibration
    fit: MagFit
    dip: DipResult | None
    samples: MagSamples

    def summary(self) -> dict[str, Any]:
        """The JSON contract (module docstring) with the calibration file's entries."""
        return self.calibration.to_dict()

    def save(self, path: str | Path) -> None:
        """Write the calibration's JSON (the file ``optcal calibrate --sensor mag -o`` writes)."""
        self.calibration.save(path)

    def correct(self, m: ArrayLike) -> NDArray[np.float64]:
        """Calibrated samples ``T (m − o)``: the unit field (:meth:`MagCalibration.correct`)."""
        return self.calibration.correct(m)


def calibrate_mag(samples: MagSamples, settings: MagSettings | None = None) -> MagCalibrationResult:
    """Calibrate a magnetometer from its raw samples (:mod:`optcal.families.mag.fit`), with the dip where an accelerometer was recorded.

    Raises
    ------
    InputError
        Samples no fit can use, with the option that fixes or overrides it.
    """
    settings = settings or MagSettings()
    fit = choose_form(samples, settings)
    f = fit.fit
    calibrated = (samples.m - f.o) @ f.T.T
    dip = (estimate_dip(samples.acc, calibrated, gyro=samples.gyro, t=samples.t, gyro_units=settings.gyro_units)
           if samples.acc is not None else None)
    info: dict[str, Any] = {
        "n_samples": samples.n, "rms_norm_residual": f.rms, "form": f.form, "form_reason": fit.form_reason,
        "method": f.method, "solver": f.solver, "stderr": f.stderr, "coverage_missing": list(fit.coverage.missing),
        "decisions": samples.decision_lines(), "notes": fit.notes, "exclusions": samples.exclusions,
    }
    if fit.heldout is not None:
        info["form_heldout"] = fit.heldout.summary()
    R = None
    if dip is not None:
        info.update(dip_deg=dip.dip_deg, dip_se_deg=dip.dip_se_deg, dip_std_deg=dip.dip_std_deg,
                    dip_std_unaligned_deg=dip.dip_std_unaligned_deg, rotation_deg=dip.rotation_deg,
                    rotation_se_deg=dip.rotation_se_deg)
        R = dip.R
    cal = MagCalibration(f.T, f.o, samples.units.units, f.field_strength, None, R, info)
    return MagCalibrationResult(cal, fit, dip, samples)
