"""The calibration result: parameters with uncertainty, residuals, solver record, JSON I/O.

:attr:`CalibrationResult.calibration` is the fitted calibration as a typed
:mod:`optcal.families.caltypes` object (``lumped`` for the self-calibrating methods, ``sixpos_full`` for
``sixpos``): ``params`` keep each method's own parameter layout, the calibration says what it
means.  The saved file is that calibration (``cal_type``, ``format_version`` "2.0") with the fit's
statistics attached, so :func:`optcal.families.caltypes.load` reads it; format-1 files still load.

Modelled on imucal (result kept apart from the algorithm, JSON with a format version and
units in fields) and lmfit (parameters with standard errors and covariance, AIC/BIC, a
text :meth:`CalibrationResult.report` and a JSON-safe :meth:`CalibrationResult.summary`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.families.caltypes import Calibration, FitPoses, LumpedCalibration, SixPositionCalibration, check_version, read_json
from optcal.families.caltypes.base import FORMAT_VERSION, jsonable
from optcal.errors import InputError
from optcal.core.model import TRIL_INDEX, LumpedModel

__all__ = ["FORMAT_VERSION", "CalibrationResult", "SolverInfo", "jsonable"]


@dataclass
class SolverInfo:
    """What the solver did.

    Attributes
    ----------
    name : str
        Solver (``"IPOPT"``, ``"CLARABEL"``, ``"numpy.linalg.svd"``, ``"gradient descent"``).
    status : str
        The solver's own status word.
    success : bool
        Whether the solver reports convergence to an optimum.
    iterations : int
        Iterations used (0 for direct methods).
    solve_time_s : float
        Wall time of the solve, seconds.
    message : str
        Anything else worth saying.
    """

    name: str
    status: str
    success: bool
    iterations: int
    solve_time_s: float
    message: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "status": self.status,
            "success": bool(self.success),
            "iterations": int(self.iterations),
            "solve_time_s": float(self.solve_time_s),
            "message": self.message,
        }


def dA_dtheta(T: NDArray[np.float64]) -> NDArray[np.float64]:
    """Jacobian of the 6 unique entries of ``A = TᵀT`` w.r.t. the 6 entries of lower-triangular T.

    Rows follow :data:`A_INDEX` (upper triangle of A, row-major); columns follow
    :data:`optcal.core.model.TRIL_INDEX`.
    """
    J = np.zeros((6, 6))
    for c, (i, j) in enumerate(TRIL_INDEX):
        E = np.zeros((3, 3))
        E[i, j] = 1.0
        dA = E.T @ T + T.T @ E
        J[:, c] = [dA[a, b] for a, b in A_INDEX]
    return J


A_INDEX: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
AXES_STR = "xyz"


@dataclass
class CalibrationResult:
    """A fitted calibration ``ā = T (a − o)`` with its uncertainty and solver record.

    Attributes
    ----------
    method : str
        Estimator that produced it (``svd``, ``convex``, ``mle``, ``exact``, ``gd``, ...).
    T : ndarray, shape (3, 3)
        Canonical lower-triangular calibration matrix, g per raw unit (see
        :mod:`optcal.core.model`).
    o : ndarray, shape (3,)
        Bias, raw units.
    units : str
        Units of the raw input (``g``, ``m/s^2`` or ``counts``); output is always g.
    params, param_names : ndarray, list of str
        Estimated parameters: θ = (6 entries of T, 3 of o) followed by the parameters
        of any model extension.
    covariance : ndarray or None
        Covariance of ``params`` from the Fisher information (``None`` when not available).
    residuals : ndarray, shape (n,)
        Norm residuals ``‖T(a_k − o)‖ − 1`` in g, one per pose.
    weights : ndarray, shape (n,)
        The weights ``1/σ_r,k²`` used in the cost (ones when no noise was given).
    sigma_known : bool
        Whether the covariance is absolute (per-pose noise given) or scaled by the
        reduced chi-square (noise estimated from the residuals).
    solver : SolverInfo
    rows : list of int
        File rows (or interval numbers) of the poses, in order.
    exclusions : dict
        Everything excluded before the fit, counted.
    identifiability : dict
        Rank and conditioning of the Fisher information (see :mod:`optcal.core.identifiability`).
    notes : list of str
        Warnings and remarks for the report.
    extra : dict
        Method-specific additions (e.g. model-extension terms, gradient-descent step).
    fitted_on : FitPoses, optional
        The poses of the fit (set by :func:`optcal.families.accel.calibration.calibrate`), saved with the
        calibration so that exporters can evaluate simpler models on them.
    """

    method: str
    T: NDArray[np.float64]
    o: NDArray[np.float64]
    units: str
    params: NDArray[np.float64]
    param_names: list[str]
    covariance: NDArray[np.float64] | None
    residuals: NDArray[np.float64]
    weights: NDArray[np.float64]
    sigma_known: bool
    solver: SolverInfo
    rows: list[int] = field(default_factory=list)
    exclusions: dict[str, int] = field(default_factory=dict)
    identifiability: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)
    fitted_on: FitPoses | None = None

    # ------------------------------------------------------------------ derived
    @property
    def calibration(self) -> Calibration:
        """The fitted calibration: :class:`~optcal.families.caltypes.SixPositionCalibration` (``W``, ``V``)
        for ``sixpos``, else :class:`~optcal.families.caltypes.LumpedCalibration` (canonical ``T``, ``o``)."""
        if self.param_names[:1] == ["W_xx"] and "W" in self.extra and "V" in self.extra:
            return SixPositionCalibration(np.asarray(self.extra["W"]), np.asarray(self.extra["V"]), self.units, self.fitted_on)
        return LumpedCalibration.from_any_T(self.T, self.o, self.units, self.fitted_on)

    @property
    def A(self) -> NDArray[np.float64]:
        """``A = Tᵀ T`` (Lu 2017, eq. 19)."""
        return self.T.T @ self.T

    @property
    def C(self) -> NDArray[np.float64]:
        """``C = T⁻¹`` (raw units per g)."""
        return np.linalg.inv(self.T)

    @property
    def model(self) -> LumpedModel:
        """The fitted lumped model."""
        return LumpedModel.from_T(self.T, self.o)

    @property
    def n_poses(self) -> int:
        return int(self.residuals.size)

    @property
    def n_params(self) -> int:
        return int(len(self.params))

    @property
    def n_observations(self) -> int:
        """Scalar observations behind the fit: one norm per pose, or ``extra["n_observations"]``
        for methods that fit vector residuals (``sixpos``: three per pose)."""
        return int(self.extra.get("n_observations", self.n_poses))

    @property
    def dof(self) -> int:
        """Degrees of freedom ``n_observations − p``."""
        return self.n_observations - self.n_params

    @property
    def chisqr(self) -> float:
        """Weighted sum of squared residuals of the fitted cost (norm residuals unless the method
        records its own in ``extra["chisqr"]``)."""
        if "chisqr" in self.extra:
            return float(self.extra["chisqr"])
        return float(np.sum(self.weights * self.residuals**2))

    @property
    def redchi(self) -> float:
        return self.chisqr / self.dof if self.dof > 0 else float("nan")

    @property
    def rms_norm_residual_g(self) -> float:
        """rms of ``‖ā_k‖ − 1`` over the poses, g."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def aic(self) -> float:
        """Akaike information criterion, ``n ln(χ²/n) + 2p`` (lmfit's convention)."""
        n = self.n_observations
        return float(n * np.log(max(self.chisqr, 1e-300) / n) + 2 * self.n_params)

    @property
    def bic(self) -> float:
        """Bayesian information criterion, ``n ln(χ²/n) + p ln n``."""
        n = self.n_observations
        return float(n * np.log(max(self.chisqr, 1e-300) / n) + np.log(n) * self.n_params)

    @property
    def stderr(self) -> dict[str, float]:
        """Standard error of each parameter (NaN where no covariance is available)."""
        if self.covariance is None:
            return {k: float("nan") for k in self.param_names}
        d = np.sqrt(np.clip(np.diag(self.covariance), 0, None))
        return dict(zip(self.param_names, map(float, d)))

    @property
    def A_stderr(self) -> NDArray[np.float64]:
        """Standard errors of the entries of ``A`` (delta method), shape (3, 3)."""
        out = np.full((3, 3), np.nan)
        if self.covariance is None:
            return out
        # the entries of T among the parameters: canonical "T_ij" (lower triangle) or full "W_ij"
        idx, J_cols = [], []
        for k, name in enumerate(self.param_names):
            if len(name) == 4 and name[0] in "TW" and name[1] == "_" and name[2] in AXES_STR and name[3] in AXES_STR:
                E = np.zeros((3, 3))
                E[AXES_STR.index(name[2]), AXES_STR.index(name[3])] = 1.0
                dA = E.T @ self.T + self.T.T @ E
                idx.append(k)
                J_cols.append([dA[a, b] for a, b in A_INDEX])
        if not idx:
            return out
        J = np.array(J_cols).T
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
                "identifiability": self.identifiability,
                "exclusions": self.exclusions,
                "notes": self.notes,
            }
        )
        out["units"].update(calibration["units"])
        merged = {**calibration, **out}  # cal_type and format_version first
        merged.update({k: v for k, v in calibration.items() if k != "units"})
        return merged

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
                    "extra": self.extra,
                }
            )
        )
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "CalibrationResult":
        """Rebuild a result written by :meth:`to_dict`."""
        try:
            check_version(d.get("format_version", 0))
            cov = d.get("covariance")
            fitted = d.get("fitted_on")
            return cls(
                method=str(d["method"]),
                T=np.asarray(d["T"], dtype=float).reshape(3, 3),
                o=np.asarray(d["o"], dtype=float).reshape(3),
                units=str(d["units"]["input"]),
                params=np.asarray(d["params_vector"], dtype=float),
                param_names=list(d["param_names"]),
                covariance=None if cov is None else np.asarray(cov, dtype=float),
                residuals=np.asarray(d["residuals"], dtype=float),
                weights=np.asarray(d["weights"], dtype=float),
                sigma_known=bool(d["sigma_known"]),
                solver=SolverInfo(**d["solver"]),
                rows=list(d.get("rows", [])),
                exclusions=dict(d.get("exclusions", {})),
                identifiability=dict(d.get("identifiability") or {}),
                notes=list(d.get("notes", [])),
                extra=dict(d.get("extra", {})),
                fitted_on=None if fitted is None else FitPoses.from_dict(fitted),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not an optcal calibration file ({exc.__class__.__name__}: {exc})") from exc

    def save(self, path: str | Path) -> None:
        """Write the result as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> "CalibrationResult":
        """Read a result written by :meth:`save`."""
        return cls.from_dict(read_json(path))

    def __eq__(self, other: object) -> bool:
        """Value equality: the same numbers, solver record and notes (what the saved file holds)."""
        return isinstance(other, CalibrationResult) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def _engineering_text(self) -> str:
        """The block of scale factors, non-orthogonality angles and biases (:mod:`optcal.report.parameters`)."""
        from optcal.data.units import nominal_conversion
        from optcal.report.parameters import result_parameters

        zero = nominal_conversion(self.units, self.fitted_on.acc).offset if self.fitted_on is not None else None
        params = result_parameters(self, zero)
        lines = ["[[Scale factors, non-orthogonality, bias]]"]
        for q in params.rows:
            lines.append(f"    {q.symbol:<5s} = {q.value:>13.7g} +/- {q.stderr:<8.2g} {q.unit:<9s} {q.name}")
        if np.any(params.zero):
            lines.append(f"    (bias in mg measured from the nominal zero reading {', '.join(f'{z:g}' for z in params.zero)} {self.units})")
        lines.append("    (mounting misalignment: not determined by static poses; the frame is the sensor's x axis and xy plane)")
        return "\n".join(lines)

    def report(self) -> str:
        """Readable text report (parameters ± standard error, scale factors and angles, fit statistics, solver)."""
        se = self.stderr
        lines = [
            f"[[Calibration: method {self.method}]]",
            f"    poses              = {self.n_poses}",
            f"    parameters         = {self.n_params}",
            f"    units              = {self.units} in, g out",
            f"    rms |a|-1          = {self.rms_norm_residual_g * 1e3:.4f} mg",
            f"    max ||a|-1|        = {np.max(np.abs(self.residuals)) * 1e3:.4f} mg" if self.n_poses else "",
            f"    chi-square         = {self.chisqr:.6g}",
            f"    reduced chi-square = {self.redchi:.6g}" if self.dof > 0 else "    reduced chi-square = n/a (no degrees of freedom)",
            f"    Akaike info crit   = {self.aic:.4f}",
            f"    Bayesian info crit = {self.bic:.4f}",
            f"    covariance         = {'absolute (noise given)' if self.sigma_known else 'scaled by reduced chi-square'}",
            "[[Solver]]",
            f"    {self.solver.name}: {self.solver.status}, {self.solver.iterations} iterations, "
            f"{self.solver.solve_time_s * 1e3:.2f} ms" + (f" ({self.solver.message})" if self.solver.message else ""),
            "[[Parameters]]",
        ]
        for name, value in zip(self.param_names, self.params):
            e = se.get(name, float("nan"))
            rel = f"({abs(e / value) * 100:.2g} %)" if value != 0 and np.isfinite(e) else ""
            lines.append(f"    {name:<12s} = {value: .8g} +/- {e:.3g} {rel}")
        lines.append(self._engineering_text())
        lines.append(f"[[A = T'T, g² per {self.units}²]]")
        A_se = self.A_stderr
        for i in range(3):
            lines.append("    " + "  ".join(
                f"{self.A[i, j]: .6e}" + (f" +/- {A_se[i, j]:.2g}" if np.isfinite(A_se[i, j]) else "") for j in range(3)))
        if self.identifiability:
            idf = self.identifiability
            lines.append("[[Identifiability]]")
            lines.append(
                f"    Fisher rank {idf.get('rank')}/{idf.get('n_params')}, condition number {idf.get('condition_number', float('nan')):.3g}"
            )
            for item in idf.get("unidentified", []):
                lines.append(f"    not determined: {item['text']}")
            for item in idf.get("weak", []):
                lines.append(f"    weakly determined: {item['text']} (standard error {item['stderr'] * 100:.2g} % of full scale)")
        if self.exclusions:
            lines.append("[[Excluded before the fit]]")
            lines.extend(f"    {k}: {v}" for k, v in self.exclusions.items())
        if self.notes:
            lines.append("[[Notes]]")
            lines.extend(f"    - {n}" for n in self.notes)
        return "\n".join(line for line in lines if line != "")

