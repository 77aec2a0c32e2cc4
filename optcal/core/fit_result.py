"""What every fit records: parameters with covariance, the solver's record and the fit statistics.

Modelled on lmfit's ``MinimizerResult`` and statsmodels' results classes: the estimate and its
uncertainty live apart from the algorithm that produced them, and the statistics that follow
from them (standard errors, degrees of freedom, reduced χ², AIC, BIC) are written once, here.

* :class:`FitRecord`: the parameters, their names and covariance, the solver record
  (:class:`SolverInfo`), the identifiability report
  (:class:`~optcal.core.identifiability.RankReport` or a richer subclass), what was excluded
  before the fit, notes; standard errors.
* :class:`FitResult`: a fit whose residuals are kept as well: residuals, weights, χ² and the
  number of scalar observations as typed fields; degrees of freedom, reduced χ², AIC and BIC.

The sensors' results derive from them: the accelerometer's
:class:`optcal.families.accel.result.CalibrationResult` from :class:`FitResult`, the gyroscope
part of :class:`optcal.families.gyro.result.ImuCalibration` from :class:`FitRecord` (its file
keeps no residuals).  The text reports are in :mod:`optcal.report`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.identifiability import RankReport

__all__ = ["FitRecord", "FitResult", "SolverInfo", "chi_square", "standard_errors"]


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
        """JSON-ready record."""
        return {
            "name": self.name,
            "status": self.status,
            "success": bool(self.success),
            "iterations": int(self.iterations),
            "solve_time_s": float(self.solve_time_s),
            "message": self.message,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SolverInfo":
        """Rebuild from :meth:`to_dict`."""
        return cls(**d)


def chi_square(residuals: ArrayLike, weights: ArrayLike) -> float:
    """Weighted sum of squared residuals ``χ² = Σ_k w_k r_k²``.

    Parameters
    ----------
    residuals, weights : array_like, shape (n,)
        Residuals and their weights (``1/σ_k²``, or ones).

    Returns
    -------
    float
    """
    r = np.asarray(residuals, dtype=float)
    return float(np.sum(np.asarray(weights, dtype=float) * r**2))


def standard_errors(covariance: NDArray[np.float64] | None, names: list[str]) -> dict[str, float]:
    """Standard error of each named parameter, ``sqrt(diag Σ)`` (NaN everywhere without a covariance).

    Parameters
    ----------
    covariance : ndarray, shape (p, p), or None
    names : list of str
        The parameters' names, in the covariance's order.

    Returns
    -------
    dict
        Name → standard error (a negative diagonal entry, from rounding, counts as 0).
    """
    if covariance is None:
        return {k: float("nan") for k in names}
    d = np.sqrt(np.clip(np.diag(covariance), 0, None))
    return dict(zip(names, map(float, d)))


@dataclass(kw_only=True, eq=False)
class FitRecord:
    """Estimated parameters with their covariance, the solver's record and the identifiability.

    Attributes
    ----------
    params : ndarray, shape (p,)
        The estimate.
    param_names : list of str
        Names of :attr:`params`.
    covariance : ndarray, shape (p, p), or None
        Covariance of :attr:`params` (``None`` when not available).
    solver : SolverInfo
    identifiability : RankReport or None
        Rank and conditioning of the information behind the fit (a subclass adds what it does
        not determine: :class:`~optcal.core.identifiability.IdentifiabilityReport`, the gyro's
        :class:`~optcal.families.gyro.identifiability.GyroIdentifiability`).
    exclusions : dict
        Everything excluded before the fit, counted.
    notes : list of str
        Warnings and remarks for the report.
    """

    params: NDArray[np.float64]
    param_names: list[str]
    covariance: NDArray[np.float64] | None
    solver: SolverInfo
    identifiability: RankReport | None = None
    exclusions: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def n_params(self) -> int:
        """Number of estimated parameters ``p``."""
        return int(len(self.params))

    @property
    def stderr(self) -> dict[str, float]:
        """Standard error of each parameter (:func:`standard_errors`)."""
        return standard_errors(self.covariance, self.param_names)


@dataclass(kw_only=True, eq=False)
class FitResult(FitRecord):
    """A fit with its residuals: χ², degrees of freedom, reduced χ², AIC and BIC.

    Attributes
    ----------
    residuals : ndarray, shape (n,)
        The residuals kept with the fit (one per pose for the accelerometer).
    weights : ndarray, shape (n,)
        Their weights in the cost (``1/σ_k²``, ones when no noise was given).
    chisqr : float
        χ² of the fitted cost: ``Σ w r²`` of :attr:`residuals` (:func:`chi_square`) unless the
        method's own cost is another (the six-position fit's vector residuals).
    n_observations : int
        Scalar observations behind the fit ``n``: one per residual, or more for a method that
        fits vector residuals (the six-position fit: three per pose).
    """

    residuals: NDArray[np.float64]
    weights: NDArray[np.float64]
    chisqr: float
    n_observations: int

    @property
    def dof(self) -> int:
        """Degrees of freedom ``n − p``."""
        return self.n_observations - self.n_params

    @property
    def redchi(self) -> float:
        """Reduced chi-square ``χ²/(n − p)`` (NaN without degrees of freedom)."""
        return self.chisqr / self.dof if self.dof > 0 else float("nan")

    def _neg2_log_likelihood(self) -> float:
        """``n ln(χ²/n)``: −2 ln L of Gaussian residuals up to a constant (χ² floored at 1e-300)."""
        n = self.n_observations
        return float(n * np.log(max(self.chisqr, 1e-300) / n))

    @property
    def aic(self) -> float:
        """Akaike information criterion, ``n ln(χ²/n) + 2p`` (lmfit's convention)."""
        return float(self._neg2_log_likelihood() + 2 * self.n_params)

    @property
    def bic(self) -> float:
        """Bayesian information criterion, ``n ln(χ²/n) + p ln n`` (lmfit's convention)."""
        return float(self._neg2_log_likelihood() + np.log(self.n_observations) * self.n_params)
