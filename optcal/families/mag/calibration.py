"""The magnetometer's calibration file (``cal_type`` ``"magnetometer"``) and the fit that makes it.

``m̄ = T (m − o)`` with ``‖m̄‖ = 1`` in the local field (T symmetric: the hard iron ``o`` in the
data's units, the soft iron and scale ``T`` per unit); the calibrated field in the data's
units is ``field_strength · m̄``.  The file carries the JSON contract the held-out checks read:
``sensor``, ``n_samples``, ``field_strength``, ``o``, ``T``, ``rms_norm_residual`` and, with an
accelerometer, ``dip_deg``, ``dip_std_deg`` (and the frames' rotation ``R_mag_to_acc``).

A planar (heading) calibration (``form`` ``"planar"``, :mod:`optcal.families.mag.planar`) adds ``plane_normal``:
``T`` is ``Pᵀ T₂ P + (1/H) n nᵀ`` and ``field_strength`` the field's component in the plane ``H``, so the calibrated
field ``H T (m − o)`` holds the in-plane field calibrated and the raw normal component ``n·m`` unchanged (its hard
iron, ``normal_offset``, undetermined and taken as 0); its norm residual is the in-plane one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.jsonio import check_version
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration, FitPoses, as_samples, read_matrix
from optcal.families.mag.dip import DipResult, estimate_dip
from optcal.families.mag.fit import PLANAR_SPREAD, FormFit, MagFit, MagSettings, choose_form, coverage
from optcal.families.mag.planar import HEADING_SECTORS as HEADING_SECTORS_N
from optcal.families.mag.planar import (PlanarFit, fit_planar, planar_decision, planar_evidence,
                                        vertical_field_heading_error)
from optcal.families.mag.samples import MagSamples
from optcal.families.mag.units import MAG_UNITS, units_from_plane_field


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
    plane_normal : ndarray, shape (3,), optional
        A planar (heading) calibration's plane normal ``n`` (module docstring); None for a 3-D one.
    """

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str
    field_strength: float
    fitted_on: FitPoses | None = None
    R_mag_to_acc: NDArray[np.float64] | None = None
    info: dict[str, Any] = field(default_factory=dict)
    plane_normal: NDArray[np.float64] | None = None

    cal_type: ClassVar[str] = "magnetometer"

    def __post_init__(self) -> None:
        self.T = np.asarray(self.T, dtype=float).reshape(3, 3)
        self.o = np.asarray(self.o, dtype=float).reshape(3)
        if not (np.all(np.isfinite(self.T)) and np.all(np.isfinite(self.o))):
            raise InputError("T and o of a magnetometer calibration must be finite")
        if self.units not in MAG_UNITS:
            raise InputError(f"magnetometer units {self.units!r} are not one of {', '.join(MAG_UNITS)}")
        if self.plane_normal is not None:
            n = np.asarray(self.plane_normal, dtype=float).reshape(3)
            if not (np.all(np.isfinite(n)) and abs(np.linalg.norm(n) - 1.0) < 1e-6):
                raise InputError("plane_normal of a planar magnetometer calibration must be a finite unit vector")
            self.plane_normal = n

    def norm(self, m: ArrayLike) -> NDArray[np.float64]:
        """``|T(m − o)|``, 1 in the calibration's field; for a planar calibration the in-plane part's norm (the normal
        component is not calibrated)."""
        v = self.correct(m)
        if self.plane_normal is not None:
            v = v - np.outer(v @ self.plane_normal, self.plane_normal)
        return np.asarray(np.linalg.norm(v, axis=1))

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
        if self.plane_normal is not None:
            out["plane_normal"] = self.plane_normal
        return out

    @classmethod
    def from_parameters(cls, d: dict[str, Any], units: str, fitted_on: FitPoses | None) -> "MagCalibration":
        keep = ("n_samples", "rms_norm_residual", "form", "form_reason", "dip_deg", "dip_std_deg", "coverage_missing",
                "method", "stderr", "decisions", "notes", "dip_se_deg", "dip_std_unaligned_deg", "rotation_deg", "rotation_se_deg",
                "wmm", "form_heldout", "planar")
        R = read_matrix(d, "R_mag_to_acc", (3, 3)) if d.get("R_mag_to_acc") is not None else None
        n = read_matrix(d, "plane_normal", (3,)) if d.get("plane_normal") is not None else None
        if (n is None) != (d.get("form") != "planar"):
            raise InputError("a planar magnetometer calibration (form 'planar') needs its plane_normal, and only it has one")
        return cls(read_matrix(d, "T", (3, 3)), read_matrix(d, "o", (3,)), units, float(d["field_strength"]), None, R,
                   {k: d[k] for k in keep if k in d}, n)

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
        if self.plane_normal is not None:
            return (f"planar (heading) magnetometer calibration ({self.units} in; the plane's normal "
                    f"[{', '.join(f'{v:+.3f}' for v in self.plane_normal)}]; field in the plane {self.field_strength:.4g} "
                    f"{self.units}; the normal component passed through uncalibrated)")
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
    planar : PlanarFit, optional
        A planar (heading) calibration's fit (``fit`` then holds its 3-D embedding).
    """

    calibration: MagCalibration
    fit: MagFit
    dip: DipResult | None
    samples: MagSamples
    planar: PlanarFit | None = None

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
    if settings.form.startswith("planar"):
        return _calibrate_planar(samples, settings, None)
    if settings.form == "auto":
        tilt, normal = planar_evidence(samples.m)
        if tilt < PLANAR_SPREAD:
            return _calibrate_planar(samples, settings, planar_decision(tilt, normal))
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


#: ``--mag-form`` choices of the planar calibration: the form in the plane chosen held out, or forced.
PLANAR_CHOICES: dict[str, str] = {"planar": "auto", "planar-circle": "circle", "planar-ellipse": "ellipse"}


def _calibrate_planar(samples: MagSamples, settings: MagSettings, decision: str | None) -> MagCalibrationResult:
    """The planar (heading) calibration (:mod:`optcal.families.mag.planar`) as a :class:`MagCalibrationResult`:
    ``decision`` the line that chose it from the samples' tilt (None where ``--mag-form`` asked for it)."""
    if settings.form not in ("auto", *PLANAR_CHOICES):
        raise InputError(f"unknown --mag-form {settings.form!r}")
    pf = fit_planar(samples.m, PLANAR_CHOICES.get(settings.form, "auto"), dict(settings.estimator), settings.method,
                    settings.accept_fit, settings.allow_degenerate)
    why = decision or f"--mag-form {settings.form}: " + planar_decision(pf.tilt_share, pf.normal)
    reason = (f"{why}; {pf.form} in the plane: {pf.reason} (override with --mag-form planar-circle|planar-ellipse; "
              "--mag-form offsets|diagonal|full fits a 3-D form, refused on planar samples unless --allow-degenerate)")
    H = pf.horizontal_field
    # the unit from the fit's evidence: the field in the plane, its hard iron removed (not the median |m|)
    samples = replace(samples, units=units_from_plane_field(samples.units, H))
    undetermined = ("undetermined by a turn in one plane: the hard iron along the normal (taken as 0: the normal "
                    "component passes through uncalibrated), the field's normal component and so the dip")
    notes = [undetermined, pf.tilt_heading_error(), vertical_field_heading_error()] + ([pf.note] if pf.note else [])
    missing = HEADING_SECTORS_N - len(pf.sectors)
    if missing:
        notes.append(f"headings covered {len(pf.sectors)} of {HEADING_SECTORS_N} sectors of {360 // HEADING_SECTORS_N}°: "
                     "turn the sensor through a full circle in its plane")
    cov = coverage((samples.m - pf.o) @ pf.T.T)
    ff = FormFit("planar", pf.T, pf.o, pf.residuals, pf.stderr, pf.worst_share, pf.method, pf.solver, pf.note)
    fit = MagFit(ff, reason, {}, cov, notes, None)
    info: dict[str, Any] = {
        "n_samples": samples.n, "rms_norm_residual": pf.rms, "form": "planar", "form_reason": reason,
        "method": pf.method, "solver": pf.solver, "stderr": pf.stderr, "coverage_missing": [],
        "decisions": samples.decision_lines(), "notes": notes, "exclusions": samples.exclusions,
        "planar": {
            "form": pf.form, "horizontal_field": H, "T2": pf.T2.tolist(), "c": pf.c.tolist(),
            "plane_basis": pf.basis.tolist(),
            "normal_offset": {"value": 0.0, "determined": False, "note": undetermined},
            "normal_row": "T's row along the normal is n/H: H T (m - o) passes n.m through unchanged, in data units",
            "tilt_share": pf.tilt_share, "tilt_deg_rms": pf.tilt_deg,
            "tilt_heading_error": pf.tilt_heading_error(),
            "vertical_field_heading_error": vertical_field_heading_error(),
            "headings_covered": {"sectors": list(pf.sectors), "of": HEADING_SECTORS_N},
            "dip": "undetermined",
        },
    }
    if pf.heldout is not None:
        h = pf.heldout
        info["planar"]["heldout"] = {"sectors": h.cells.tolist(), "n_samples": h.n_samples,
                                     "rms": {f: h.rms(f) for f in h.mse},
                                     "gain_over_circle": dict(zip(("gain", "se"), h.gain("circle", "ellipse")))}
    cal = MagCalibration(pf.T, pf.o, samples.units.units, H, None, None, info, pf.normal)
    return MagCalibrationResult(cal, fit, None, samples, pf)


def state_vertical_field(result: MagCalibrationResult, dip_deg: float) -> None:
    """A planar calibration's vertical-field heading error stated at the place's dip (``--location``): its note and
    ``planar.vertical_field_heading_error`` in the JSON (:func:`optcal.families.mag.planar.vertical_field_heading_error`)."""
    info = result.calibration.info
    if "planar" not in info:
        return
    old, new = info["planar"]["vertical_field_heading_error"], vertical_field_heading_error(dip_deg)
    info["planar"]["vertical_field_heading_error"] = new
    for notes in (info["notes"], result.fit.notes):  # the JSON's and the report's (the same list where they are one)
        if old in notes:
            notes[notes.index(old)] = new
