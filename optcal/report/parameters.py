"""The calibration in the units engineers use, with confidence intervals.

The nine identifiable numbers ``θ = (T, o)`` map one-to-one onto the physical parameters of
Lu 2017, eq. 1 and 5 (:meth:`optcal.core.model.LumpedModel.physical`): the scale factors ``S_M``
(raw units per g), the three non-orthogonality angles ρ, φ, λ of ``C_NO`` and the bias ``o``.
Their standard errors follow from the covariance of θ by the delta method (the Jacobian of
``θ → physical`` by central differences).  The mounting misalignment ``V_L`` is not
identifiable from static data (``‖Q T u‖ = ‖T u‖`` for every rotation ``Q``): the canonical
form absorbs it, which the report says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import AXES, PARAM_NAMES, STANDARD_GRAVITY, LumpedModel, theta_from
from optcal.families.accel.result import CalibrationResult

#: Two-sided 95 % normal quantile: the half-width of a 95 % confidence interval in standard errors.
Z95: float = 1.959963984540054


@dataclass(frozen=True)
class Quantity:
    """One reported number with its standard error and unit.

    Attributes
    ----------
    name : str
        What it is, in words (``"scale factor x"``).
    symbol : str
        Short symbol (``"S_x"``).
    value : float
    stderr : float
        Standard error (NaN when the fit gives no covariance).
    unit : str
    """

    name: str
    symbol: str
    value: float
    stderr: float
    unit: str

    @property
    def ci95(self) -> tuple[float, float]:
        """95 % confidence interval (normal approximation)."""
        return (self.value - Z95 * self.stderr, self.value + Z95 * self.stderr)


@dataclass(frozen=True)
class EngineeringParameters:
    """Scale factors, non-orthogonality angles and biases of a calibration.

    Attributes
    ----------
    units : str
        Raw units of the data (``counts``, ``g`` or ``m/s^2``).
    scale : list of Quantity
        Scale factor of each axis, raw units per g.
    scale_error : list of Quantity
        Deviation of each scale factor from the nominal one (1 g per g, 9.80665 m/s² per g), %;
        empty for counts (no nominal sensitivity is known).
    angles : list of Quantity
        Non-orthogonality angles ρ, φ, λ (Lu 2017, eq. 1), degrees.
    bias_raw : list of Quantity
        Bias ``o`` of each axis, raw units.
    bias_mg : list of Quantity
        Bias referred to the calibrated output, ``T (o − zero)`` in mg.
    zero : ndarray, shape (3,)
        The raw reading the bias in mg is measured from.
    """

    units: str
    scale: list[Quantity]
    scale_error: list[Quantity]
    angles: list[Quantity]
    bias_raw: list[Quantity]
    bias_mg: list[Quantity]
    zero: NDArray[np.float64]

    @property
    def rows(self) -> list[Quantity]:
        """Every quantity, in reading order."""
        return [*self.scale, *self.scale_error, *self.angles, *self.bias_raw, *self.bias_mg]

    @property
    def physical(self) -> list[Quantity]:
        """Scale factors, angles and biases in mg: the order of :func:`physical_vector`."""
        return [*self.scale, *self.angles, *self.bias_mg]


def physical_vector(theta: NDArray[np.float64], zero: NDArray[np.float64]) -> NDArray[np.float64]:
    """θ → (S_x, S_y, S_z, ρ, φ, λ in degrees, bias in mg (``T (o − zero)``))."""
    model = LumpedModel.from_theta(theta)
    phys = model.physical()
    bias_g = model.T_canonical @ (model.o - zero)
    return np.concatenate([phys.scale, np.rad2deg([phys.rho, phys.phi, phys.lam]), 1e3 * bias_g])


#: Relative step of the central differences that carry a full ``(W, V)`` covariance over to θ.
_WV_STEP: float = 1e-7


def theta_covariance(result: CalibrationResult) -> NDArray[np.float64] | None:
    """Covariance of the nine lumped-model parameters θ: the result's own when it is in θ order;
    for a fit of the full ``ā = W a + V`` (six positions, Ferraris, known orientations) that of
    ``θ(W, −W⁻¹V)`` by the delta method (the Jacobian by central differences)."""
    if result.covariance is None:
        return None
    cov = np.asarray(result.covariance, dtype=float)
    if tuple(result.param_names[:9]) == PARAM_NAMES:
        return cov[:9, :9]
    if result.W is None or result.V is None or cov.shape[0] < 12:
        return None
    wv = np.concatenate([result.W.ravel(), result.V])

    def theta(x: NDArray[np.float64]) -> NDArray[np.float64]:
        W = x[:9].reshape(3, 3)
        return theta_from(W, -np.linalg.solve(W, x[9:]))

    steps = _WV_STEP * np.maximum(np.abs(wv), np.max(np.abs(wv[:9])))
    J = np.empty((9, 12))
    for k, h in enumerate(steps):
        e = np.zeros(12)
        e[k] = h
        J[:, k] = (theta(wv + e) - theta(wv - e)) / (2 * h)
    return J @ cov[:12, :12] @ J.T


def result_parameters(result: CalibrationResult, zero: ArrayLike | None = None) -> EngineeringParameters:
    """:func:`engineering_parameters` of a fit, with the standard errors of its covariance."""
    return engineering_parameters(result.model, result.units, theta_covariance(result), zero)


def engineering_parameters(model: LumpedModel, units: str, covariance: ArrayLike | None = None,
                           zero: ArrayLike | None = None) -> EngineeringParameters:
    """A lumped calibration as scale factors, angles and biases with standard errors.

    Parameters
    ----------
    model : LumpedModel
        The calibration (``CalibrationResult.model``, ``LumpedCalibration.model``).
    units : str
        Raw units of the data.
    covariance : array_like, shape (9, 9), optional
        Covariance of θ (:data:`optcal.core.model.PARAM_NAMES` order); without it the standard errors are NaN.
    zero : array_like, shape (3,), optional
        The raw reading that nominally means zero force (e.g. mid-scale 32768 of unsigned
        16-bit counts, :func:`optcal.data.units.nominal_conversion`); the bias in mg is
        measured from it.  Default 0.

    Returns
    -------
    EngineeringParameters
    """
    zero_raw = np.zeros(3) if zero is None else np.asarray(zero, dtype=float).reshape(3)
    theta = model.theta
    values = physical_vector(theta, zero_raw)
    cov = None if covariance is None else np.asarray(covariance, dtype=float)
    if cov is None:
        stderr = np.full(values.size, np.nan)
    else:
        steps = 1e-6 * np.maximum(np.abs(theta), np.max(np.abs(theta[:6])))
        J = np.empty((values.size, theta.size))
        for k, h in enumerate(steps):
            e = np.zeros(theta.size)
            e[k] = h
            J[:, k] = (physical_vector(theta + e, zero_raw) - physical_vector(theta - e, zero_raw)) / (2 * h)
        stderr = np.sqrt(np.clip(np.diag(J @ cov @ J.T), 0.0, None))
    scale = [Quantity(f"scale factor {a}", f"S_{a}", values[i], stderr[i], f"{units}/g") for i, a in enumerate(AXES)]
    nominal = {"g": 1.0, "m/s^2": STANDARD_GRAVITY}.get(units)
    scale_error = (
        [Quantity(f"scale-factor error {q.symbol[-1]}", f"δS_{q.symbol[-1]}", 100 * (q.value / nominal - 1),
                  100 * q.stderr / nominal, "%") for q in scale]
        if nominal is not None else []
    )
    angle_words = (
        ("ρ", "non-orthogonality ρ (y axis towards x)"),
        ("φ", "non-orthogonality φ (z axis towards x)"),
        ("λ", "non-orthogonality λ (z axis towards y)"),
    )
    angles = [Quantity(words, sym, values[3 + k], stderr[3 + k], "°") for k, (sym, words) in enumerate(angle_words)]
    se_o = np.sqrt(np.clip(np.diag(cov)[6:9], 0.0, None)) if cov is not None else np.full(3, np.nan)
    bias_raw = [Quantity(f"bias {a}", f"o_{a}", float(model.o[i]), float(se_o[i]), units) for i, a in enumerate(AXES)]
    bias_mg = [Quantity(f"bias {a} in g", f"b_{a}", values[6 + i], stderr[6 + i], "mg") for i, a in enumerate(AXES)]
    return EngineeringParameters(units, scale, scale_error, angles, bias_raw, bias_mg, zero_raw)


__all__ = ["EngineeringParameters", "Quantity", "Z95", "engineering_parameters", "physical_vector", "result_parameters",
           "theta_covariance"]
