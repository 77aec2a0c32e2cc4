"""The information a pose adds, and the design criteria computed from it.

A pose whose gravity direction in the sensor frame is ``d`` adds the rank-one Fisher
information ``h hᵀ / σ²`` of the lumped model with the direction eliminated as a nuisance
parameter (:func:`optcal.core.identifiability.fisher_information`)::

    h = g / ‖Tᵀ ā‖,     g = ∂r/∂θ,     r = ‖T(a − o)‖ − 1      (Lu 2017, eq. 13-14)

evaluated at the prior ``(T, o)`` and the noise-free measurement ``a = C d + o``.  The planner
works in the normalised coordinates of :class:`optcal.families.accel.base.Normaliser` (``T``
relative to the sensor's scale, ``o`` in units of the 1 g radius) and at a pose noise of one raw
unit, so that the A and E criteria do not depend on the raw units and the D criterion differs from
its raw-unit value by a constant only.  ``M = Σ_k h_k h_kᵀ`` is the information matrix of a
design; the covariance of the normalised parameters at pose noise σ (raw units) is ``σ² M⁻¹``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.errors import InputError
from optcal.core.model import N_PARAMS, PARAM_NAMES, LumpedModel
from optcal.core.norm_residual import NormResidualKernel
from optcal.families.simulate.poses import user_directions

if TYPE_CHECKING:
    from optcal.core.poses import PoseTable


class Criterion(str, Enum):
    """Optimal-design criteria (of the information matrix ``M``)."""

    D = "D"  #: maximise log det M (the volume of the confidence ellipsoid)
    A = "A"  #: minimise tr M⁻¹ (the sum of the parameter variances)
    E = "E"  #: maximise λ_min(M) (the worst-determined combination)

    @classmethod
    def parse(cls, name: str | "Criterion") -> "Criterion":
        """The criterion named ``name`` (case-insensitive)."""
        try:
            return cls(str(getattr(name, "value", name)).upper())
        except ValueError:
            raise InputError(f"criterion must be one of D, A, E, not {name!r}") from None


@dataclass(frozen=True)
class Prior:
    """The sensor the poses are planned for.

    Attributes
    ----------
    model : LumpedModel
        Nominal (``T = I``, ``o = 0``) or an existing calibration.
    units : str
        Raw units of the model (``"g"``, ``"m/s^2"``, ``"counts"``).
    source : str
        Where the prior came from, for the report.
    """

    model: LumpedModel
    units: str = "g"
    source: str = "nominal (T = I, o = 0)"

    @classmethod
    def nominal(cls, units: str = "g") -> "Prior":
        """``T = I``, ``o = 0`` in g, or the exact unit factor for m/s²."""
        if units == "g":
            return cls(LumpedModel(np.eye(3), np.zeros(3)))
        if units == "m/s^2":
            from optcal.core.model import STANDARD_GRAVITY

            return cls(LumpedModel(np.eye(3) * STANDARD_GRAVITY, np.zeros(3)), "m/s^2",
                       "nominal (T = I/9.80665, o = 0)")
        raise InputError(f"there is no nominal calibration for data in {units}; pass a saved calibration as prior")

    @classmethod
    def load(cls, path: str) -> "Prior":
        """A saved lumped calibration (``optcal calibrate -o``; read by :func:`optcal.families.calibration_files.load`).

        Another tool's calibration (imucal's JSON, imu_tk's ``.calib``) is planned for through
        its lumped part (the same norms, :meth:`PeerCalibration.lumped
        <optcal.families.caltypes.peer.PeerCalibration.lumped>`): it holds no other terms.
        """
        from optcal.families.calibration_files import load
        from optcal.families.caltypes import LumpedCalibration

        cal = load(path)
        if cal.cal_type == "peer":
            return cls(cal.lumped().model, cal.units, f"{path}: {cal.describe()}; planned for through its lumped part")
        if not isinstance(cal, LumpedCalibration):
            raise InputError(
                f"{path}: a {cal.cal_type} calibration; poses are planned for the lumped model, so give a lumped "
                "calibration (optcal calibrate -o cal.json) or none for the nominal sensor"
            )
        return cls(cal.model, cal.units, f"{path}: {cal.describe()}")

    @classmethod
    def of_poses(cls, poses: "PoseTable", label: str = "the poses") -> "Prior":
        """The prior for planning after ``poses``: their convex ellipsoid fit when they determine
        it, even weakly (9 poses or more, full Fisher rank), else the nominal calibration in their units.

        Raises
        ------
        InputError
            Poses in counts that do not determine a fit (no nominal calibration exists).
        """
        from optcal.families.accel.calibration import calibrate
        from optcal.errors import IdentifiabilityError

        reason = f"{poses.n} poses, fewer than {N_PARAMS}"
        if poses.n >= N_PARAMS:
            try:
                cal = calibrate(poses, method="convex")
                return cls(cal.model, poses.units, f"convex ellipsoid fit of {label} ({poses.n} poses)")
            except IdentifiabilityError as exc:
                reason = str(exc)
                report = exc.report
                if report is not None and report.rank == report.n_params:
                    # weakly determined, not undetermined: the fit is still a point to plan about, and
                    # such a session is the one whose next poses matter most
                    try:
                        cal = calibrate(poses, method="convex", allow_degenerate=True)
                        return cls(cal.model, poses.units,
                                   f"convex ellipsoid fit of {label} ({poses.n} poses, weakly determined)")
                    except InputError as refit_exc:
                        reason = str(refit_exc)
            except InputError as exc:
                reason = str(exc)
        try:
            nominal = cls.nominal(poses.units)
        except InputError:
            raise InputError(
                f"{label} are in counts and do not determine a calibration ({reason}); pass a saved calibration as prior"
            ) from None
        return cls(nominal.model, nominal.units, f"{nominal.source}; {label} do not determine a fit: {reason}")

    @property
    def scale(self) -> float:
        """Raw units per g (the geometric mean of the scale factors)."""
        return float(abs(np.linalg.det(self.model.C)) ** (1.0 / 3.0))

    @property
    def to_raw(self) -> NDArray[np.float64]:
        """``dθ_raw/dθ_normalised`` (diagonal; as :meth:`Normaliser.jacobian`)."""
        s = self.scale
        return np.diag([1.0 / s] * 6 + [s] * 3)

    def information_vectors(self, directions: ArrayLike) -> NDArray[np.float64]:
        """``h`` of each direction (rows), normalised coordinates, unit noise; shape (n, 9)."""
        return self.measurement_vectors(self.model.measure(user_directions(np.asarray(directions, float).reshape(-1, 3))))

    def measurement_vectors(self, acc: ArrayLike) -> NDArray[np.float64]:
        """``h`` of measured poses (raw units, shape (n, 3)) at the prior; shape (n, 9)."""
        a = np.asarray(acc, float).reshape(-1, 3)
        point = NormResidualKernel(a).at(self.model.T_canonical, self.model.o)
        return (point.jacobian() / point.normal_gain()).T @ self.to_raw

    def stderr_raw(self, M: NDArray, sigma: float) -> NDArray[np.float64]:
        """Standard error of θ in raw units at pose noise ``sigma`` (raw units); inf where undetermined."""
        return np.sqrt(np.diag(covariance(M, sigma))) * np.diag(self.to_raw)


def information(H: NDArray, weights: ArrayLike | None = None, base: NDArray | None = None) -> NDArray[np.float64]:
    """``M = base + Σ_k w_k h_k h_kᵀ`` (weights 1 when omitted)."""
    w = np.ones(len(H)) if weights is None else np.asarray(weights, float)
    M = H.T @ (H * w[:, None])
    return M if base is None else M + base


def criterion_values(M: NDArray, criterion: Criterion) -> NDArray[np.float64]:
    """log det M (D), −tr M⁻¹ (A), λ_min(M) (E) of a stack of matrices (..., p, p).

    Larger is better; −inf (D, A) where ``M`` is singular.
    """
    evals = np.linalg.eigvalsh(0.5 * (M + np.swapaxes(M, -1, -2)))
    low, top = evals[..., 0], np.maximum(evals[..., -1], 1e-300)
    singular = low <= top * 1e-13
    if criterion is Criterion.E:
        return np.maximum(low, 0.0)
    safe = np.where(singular[..., None], 1.0, evals)
    value = np.sum(np.log(safe), axis=-1) if criterion is Criterion.D else -np.sum(1.0 / safe, axis=-1)
    return np.where(singular, -np.inf, value)


def criterion_value(M: NDArray, criterion: Criterion) -> float:
    """:func:`criterion_values` of one matrix."""
    return float(criterion_values(M, criterion))


def criterion_gradient(M: NDArray, criterion: Criterion) -> NDArray[np.float64]:
    """``∂f/∂M`` of the criterion (D: M⁻¹, A: M⁻², E: v vᵀ with v the weakest direction)."""
    evals, evecs = np.linalg.eigh(0.5 * (M + M.T))
    if criterion is Criterion.D:
        return (evecs / evals) @ evecs.T
    if criterion is Criterion.A:
        return (evecs / evals**2) @ evecs.T
    return np.outer(evecs[:, 0], evecs[:, 0])


def efficiency(value: float, best: float, criterion: Criterion, n_params: int = N_PARAMS) -> float:
    """Efficiency of a design of value ``value`` relative to ``best`` (1 = as good).

    D: ``exp((log det M − log det M*)/p)``; A: ``tr M*⁻¹ / tr M⁻¹``; E: ``λ_min / λ_min*``.
    """
    if not np.isfinite(value):
        return 0.0
    if criterion is Criterion.D:
        return float(np.exp((value - best) / n_params))
    if criterion is Criterion.A:
        return float(best / value)
    return float(value / best) if best > 0 else 0.0


def covariance(M: NDArray, sigma: float) -> NDArray[np.float64]:
    """``σ² M⁻¹``; infinite variance along directions ``M`` does not determine."""
    evals, evecs = np.linalg.eigh(0.5 * (M + M.T))
    if evals[0] <= max(evals[-1], 1e-300) * 1e-13:
        return np.full(M.shape, np.inf)
    return sigma**2 * (evecs / evals) @ evecs.T


def named(values: ArrayLike) -> dict[str, float]:
    """Parameter name → value (θ order of :mod:`optcal.core.model`)."""
    return dict(zip(PARAM_NAMES, (float(v) for v in np.asarray(values, float))))


__all__ = [
    "Criterion",
    "Prior",
    "covariance",
    "criterion_gradient",
    "criterion_value",
    "criterion_values",
    "efficiency",
    "information",
    "named",
]
