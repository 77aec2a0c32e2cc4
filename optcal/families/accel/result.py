"""The accelerometer's calibration result: ``ā = T (a − o)`` with its uncertainty, solver record and file.

:class:`CalibrationResult` is a :class:`optcal.core.fit_result.FitResult` (parameters, covariance,
residuals, weights, χ², degrees of freedom, AIC/BIC, solver record, identifiability) with what
the accelerometer adds: ``T``, ``o``, the input units, the poses of the fit and the fitted
calibration as a typed :mod:`optcal.families.caltypes` object (:attr:`CalibrationResult.calibration`):
``lumped`` for the self-calibrating methods, ``sixpos_full`` for the six-position fit, which
carries its ``W`` and ``V`` (Yin 2014, eq. 3) as fields.  ``params`` keep each method's own
parameter layout; the calibration says what it means.

The saved file is that calibration (``cal_type``, ``format_version`` "2.0") with the fit's
statistics attached, so :func:`optcal.families.calibration_files.load` reads it; format-1 files
still load.  The text report is :func:`optcal.report.calibration_text.calibration_report`.
Modelled on imucal (result kept apart from the algorithm, JSON with a format version and
units in fields) and lmfit (parameters with standard errors and covariance, AIC/BIC).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.fit_result import FitResult, SolverInfo, chi_square
from optcal.core.identifiability import A_INDEX, IdentifiabilityReport, RankReport, dA_dT_entry
from optcal.core.jsonio import check_version, jsonable, read_json, write_json
from optcal.core.model import TRIL_INDEX, LumpedModel
from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration, FitPoses
from optcal.families.caltypes.lumped import LumpedCalibration
from optcal.families.caltypes.sixpos import SixPositionCalibration
from optcal.core.stats import rms

__all__ = ["CalibrationResult"]

#: Entries of a six-position fit's file that format 2.0 writes under ``extra`` as well (W and V
#: also as the calibration's own entries, n_observations and chisqr as the fit statistics);
#: kept there so that the file stays what it was, and set aside on reading.
SIX_POSITION_EXTRA_KEYS: tuple[str, ...] = ("W", "V", "n_observations", "chisqr")


@dataclass(kw_only=True, eq=False)
class CalibrationResult(FitResult):
    """A fitted calibration ``ā = T (a − o)`` with its uncertainty and solver record.

    Attributes
    ----------
    method : str
        Estimator that produced it (``svd``, ``convex``, ``mle``, ``exact``, ``gd``, ``sixpos``, ...).
    T : ndarray, shape (3, 3)
        Canonical lower-triangular calibration matrix, g per raw unit (see
        :mod:`optcal.core.model`); the full ``W`` for the six-position fit.
    o : ndarray, shape (3,)
        Bias, raw units.
    units : str
        Units of the raw input (``g``, ``m/s^2`` or ``counts``); output is always g.
    params, param_names, covariance, solver, identifiability, exclusions, notes
        See :class:`~optcal.core.fit_result.FitRecord`: θ = (6 entries of T, 3 of o) followed by
        the parameters of any model extension (W row-major and V for the six-position fit);
        the covariance from the Fisher information.
    residuals : ndarray, shape (n,)
        Norm residuals ``‖T(a_k − o)‖ − 1`` in g, one per pose.
    weights : ndarray, shape (n,)
        The weights ``1/σ_r,k²`` used in the cost (ones when no noise was given).
    chisqr, n_observations
        See :class:`~optcal.core.fit_result.FitResult` (``Σ w r²`` and one observation per pose,
        except for the six-position fit: its vector residuals, three per pose).
    sigma_known : bool
        Whether the covariance is absolute (per-pose noise given) or scaled by the
        reduced chi-square (noise estimated from the residuals).
    rows : list of int
        File rows (or interval numbers) of the poses, in order.
    extra : dict
        Method-specific additions (e.g. the start, the passes, the gradient-descent step).
    fitted_on : FitPoses, optional
        The poses of the fit (set by :func:`optcal.families.accel.calibration.calibrate`), saved with the
        calibration so that exporters can evaluate simpler models on them.
    W, V : ndarray, shape (3, 3) and (3,), optional
        The full calibration ``ā = W a + V`` of a fit with known orientations (Yin 2014, eq. 3);
        ``None`` for the self-calibrating methods.  Given, they make the calibration a
        :class:`~optcal.families.caltypes.SixPositionCalibration`.
    """

    method: str
    T: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str
    sigma_known: bool
    rows: list[int] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)
    fitted_on: FitPoses | None = None
    W: NDArray[np.float64] | None = None
    V: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if (self.W is None) != (self.V is None):
            raise ValueError("a six-position result needs both W and V (or neither)")

    # ------------------------------------------------------------------ derived
    @property
    def is_six_position(self) -> bool:
        """Whether the fit is the full six-position calibration (``W`` and ``V`` given)."""
        return self.W is not None and self.V is not None

    @property
    def calibration(self) -> Calibration:
        """The fitted calibration: :class:`~optcal.families.caltypes.SixPositionCalibration` (``W``, ``V``)
        for a six-position fit, else :class:`~optcal.families.caltypes.LumpedCalibration` (canonical ``T``, ``o``)."""
        if self.W is not None and self.V is not None:
            return SixPositionCalibration(self.W, self.V, self.units, self.fitted_on)
        return LumpedCalibration.from_any_T(self.T, self.o, self.units, self.fitted_on)

    @property
    def A(self) -> NDArray[np.float64]:
        """``A = Tᵀ T`` (Lu 2017, eq. 19)."""
        return self.T.T @ self.T

    @property
    def C(self) -> NDArray[np.float64]:
        """``C = T⁻¹`` (raw units per g)."""
        return np.linalg.inv(self.T)  # type: ignore[return-value]  # numpy stubs type inv of float64 as floating[Any]

    @property
    def model(self) -> LumpedModel:
        """The fitted lumped model."""
        return LumpedModel.from_T(self.T, self.o)

    @property
    def n_poses(self) -> int:
        """Number of poses (norm residuals)."""
        return int(self.residuals.size)

    @property
    def rms_norm_residual_g(self) -> float:
        """rms of ``‖ā_k‖ − 1`` over the poses, g."""
        return rms(self.residuals)

    def _T_entries(self) -> list[tuple[int, int, int]]:
        """``(position in params, row, column)`` of each estimated entry of ``T``: the full ``W``
        (row-major) of a six-position fit, else the lower triangle of θ (:data:`~optcal.core.model.TRIL_INDEX`)."""
        if self.is_six_position:
            return [(3 * i + j, i, j) for i in range(3) for j in range(3)]
        return [(k, i, j) for k, (i, j) in enumerate(TRIL_INDEX)]

    @property
    def A_stderr(self) -> NDArray[np.float64]:
        """Standard errors of the entries of ``A`` (delta method), shape (3, 3)."""
        out = np.full((3, 3), np.nan)
        if self.covariance is None:
            return out
        entries = self._T_entries()
        idx = [k for k, _, _ in entries]
        J = np.column_stack([dA_dT_entry(self.T, i, j) for _, i, j in entries])
        cov_A = J @ self.covariance[np.ix_(idx, idx)] @ J.T
        se = np.sqrt(np.clip(np.diag(cov_A), 0, None))
        for k, (i, j) in enumerate(A_INDEX):
            out[i, j] = out[j, i] = se[k]
        return out

    # -------------------------------------------------------------- application
    def correct(self, raw: ArrayLike) -> NDArray[np.float64]:
        """Calibrated specific force in g for raw samples of shape (..., 3) (:attr:`calibration` applied)."""
        a = np.asarray(raw, dtype=float)
        if a.ndim == 0 or a.shape[-1] != 3:
            raise InputError(f"raw samples must have 3 columns, got shape {a.shape}")
        return self.calibration.correct(a.reshape(-1, 3)).reshape(a.shape)

    # ------------------------------------------------------------------ output
    def summary(self) -> dict[str, Any]:
        """JSON-safe dictionary of the result (what ``optcal calibrate --json`` prints)."""
        se = self.stderr
        calibration = self.calibration.to_dict()
        calibration.pop("fitted_on", None)
        out = jsonable(
            {
                "method": self.method,
                "units": {"input": self.units, "output": "g", "T": f"g per {self.units}", "o": self.units},
                "T": self.T,
                "o": self.o,
                "A": self.A,
                "params": dict(zip(self.param_names, self.params)),
                "stderr": se,
                "A_stderr": self.A_stderr,
                "covariance": self.covariance,
                "sigma_known": self.sigma_known,
                "rms_norm_residual_g": self.rms_norm_residual_g,
                "max_abs_norm_residual_g": float(np.max(np.abs(self.residuals))) if self.n_poses else None,
                "n_poses": self.n_poses,
                "n_params": self.n_params,
                "n_observations": self.n_observations,
                "chisqr": self.chisqr,
                "aic": self.aic,
                "bic": self.bic,
                "solver": self.solver.to_dict(),
                "constraints": self.extra.get("constraints"),
                "identifiability": {} if self.identifiability is None else self.identifiability.to_dict(),
                "exclusions": self.exclusions,
                "notes": self.notes,
            }
        )
        if "physical_set" in self.extra:  # the maximum likelihood left the physical set: the start is kept
            out["physical_set"] = jsonable(self.extra["physical_set"])
        out["units"].update(calibration["units"])
        merged = {**calibration, **out}  # cal_type and format_version first
        merged.update({k: v for k, v in calibration.items() if k != "units"})
        return merged

    @property
    def constraints(self) -> Any:
        """The user's fixed and bounded parameters (:class:`optcal.core.constraints.ParameterConstraints`, empty when none)."""
        from optcal.core.constraints import ParameterConstraints

        return ParameterConstraints.from_dict(self.extra.get("constraints"))

    def _saved_extra(self) -> dict[str, Any]:
        """:attr:`extra` as the file holds it (a six-position fit's also holds :data:`SIX_POSITION_EXTRA_KEYS`)."""
        if not self.is_six_position:
            return self.extra
        return {"W": self.W, "V": self.V, **self.extra, "n_observations": self.n_observations, "chisqr": self.chisqr}

    def to_dict(self) -> dict[str, Any]:
        """Everything needed to rebuild the result (summary plus residuals, weights, rows, fit poses)."""
        d = self.summary()
        if self.fitted_on is not None:
            d["fitted_on"] = self.fitted_on.to_dict()
        d.update(
            jsonable(
                {
                    "params_vector": self.params,
                    "param_names": list(self.param_names),
                    "residuals": self.residuals,
                    "weights": self.weights,
                    "rows": [int(r) for r in self.rows],
                    "extra": self._saved_extra(),
                }
            )
        )
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "CalibrationResult":
        """Rebuild a result written by :meth:`to_dict` (or by optcal 0.1, format 1)."""
        try:
            major, _ = check_version(d.get("format_version", 0))
            cov = d.get("covariance")
            fitted = d.get("fitted_on")
            extra = dict(d.get("extra") or {})
            residuals = np.asarray(d["residuals"], dtype=float)
            weights = np.asarray(d["weights"], dtype=float)
            if "cal_type" in d:
                six_position = d["cal_type"] == SixPositionCalibration.cal_type
                W, V = (d["W"], d["V"]) if six_position else (None, None)
            else:  # format 1: the six-position W and V were written under extra only
                six_position = major == 1 and d.get("method") == "sixpos" and "W" in extra and "V" in extra
                W, V = (extra["W"], extra["V"]) if six_position else (None, None)
            chisqr = d.get("chisqr", extra.get("chisqr"))  # format 1 may have neither: Σ w r² of the residuals
            n_observations = d.get("n_observations", extra.get("n_observations"))
            if six_position:
                extra = {k: v for k, v in extra.items() if k not in SIX_POSITION_EXTRA_KEYS}
            idf = d.get("identifiability") or None
            report_type = RankReport if six_position else IdentifiabilityReport
            return cls(
                method=str(d["method"]),
                T=np.asarray(d["T"], dtype=float).reshape(3, 3),
                o=np.asarray(d["o"], dtype=float).reshape(3),
                units=str(d["units"]["input"]),
                params=np.asarray(d["params_vector"], dtype=float),
                param_names=list(d["param_names"]),
                covariance=None if cov is None else np.asarray(cov, dtype=float),
                residuals=residuals,
                weights=weights,
                chisqr=chi_square(residuals, weights) if chisqr is None else float(chisqr),
                n_observations=residuals.size if n_observations is None else int(n_observations),
                sigma_known=bool(d["sigma_known"]),
                solver=SolverInfo.from_dict(d["solver"]),
                rows=list(d.get("rows", [])),
                exclusions=dict(d.get("exclusions", {})),
                identifiability=None if idf is None else report_type.from_dict(idf),
                notes=list(d.get("notes", [])),
                extra=extra,
                fitted_on=None if fitted is None else FitPoses.from_dict(fitted),
                W=None if W is None else np.asarray(W, dtype=float).reshape(3, 3),
                V=None if V is None else np.asarray(V, dtype=float).reshape(3),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not an optcal calibration file ({exc.__class__.__name__}: {exc})") from exc

    def save(self, path: str | Path) -> None:
        """Write the result as JSON (:func:`optcal.core.jsonio.write_json`)."""
        write_json(path, self.to_dict())

    @classmethod
    def load(cls, path: str | Path) -> "CalibrationResult":
        """Read a result written by :meth:`save`."""
        return cls.from_dict(read_json(path))

    def __eq__(self, other: object) -> bool:
        """Value equality: the same numbers, solver record and notes (what the saved file holds)."""
        return isinstance(other, CalibrationResult) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]
