"""What every static estimator shares: data normalisation, noise weights, result assembly.

All estimators work on normalised data ``u' = (a − m)/s`` (``m`` the mean pose, ``s`` the rms
distance to it), so that raw counts, m/s² and g give equally well-scaled problems.  A fit
``(T', o')`` in normalised coordinates maps back exactly by ``T = T'/s``, ``o = m + s o'``;
being linear in θ, the map carries the covariance exactly too.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, IdentifiabilityError, InputError
from optcal.core.constraints import ConstraintReport, ParameterConstraints, constrained_covariance, constraint_report, parameter_gradient
from optcal.core.identifiability import IdentifiabilityReport, add_weak_directions, analyse, pseudo_inverse
from optcal.core.model import PARAM_NAMES, canonicalise, theta_from, unpack_theta
from optcal.core.norm_residual import NormResidualKernel, normal_gain
from optcal.core.poses import PoseTable
from optcal.core.fit_result import SolverInfo, chi_square
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import SOLVER_FAILURES, Remedy, check_solver

WEIGHTINGS = ("propagated", "paper")


@dataclass(frozen=True)
class Normaliser:
    """Affine normalisation of the measurements, ``u' = (a − centre)/scale``.

    Of one pose set (``acc`` (n, 3): ``centre`` (3,), ``scale`` a float) or of a stack of K pose
    sets of n poses each (``acc`` (K, n, 3): ``centre`` (K, 3), ``scale`` (K,)); the maps then
    apply set by set, to θ of shape (K, 9).
    """

    centre: NDArray[np.float64]
    scale: float | NDArray[np.float64]

    @classmethod
    def of(cls, acc: NDArray) -> "Normaliser":
        centre = acc.mean(axis=-2)
        scale = np.sqrt(np.mean(np.sum((acc - centre[..., None, :]) ** 2, axis=-1), axis=-1))
        if not np.all(np.isfinite(scale)) or np.any(scale <= 0):
            raise InputError("all poses are identical; rotate the sensor between poses")
        return cls(centre, float(scale) if np.ndim(scale) == 0 else scale)

    def _scale(self, axes: int) -> NDArray[np.float64]:
        """The scale with ``axes`` trailing axes added, for broadcasting against a set's arrays."""
        return np.asarray(self.scale).reshape(np.shape(self.scale) + (1,) * axes)

    def forward(self, acc: NDArray) -> NDArray[np.float64]:
        return (acc - self.centre[..., None, :]) / self._scale(2)

    def theta_to_raw(self, theta_n: NDArray) -> NDArray[np.float64]:
        """θ in normalised coordinates → θ in raw units (``T = T'/s``, ``o = m + s o'``)."""
        theta_n = np.asarray(theta_n, dtype=float)
        s = self._scale(1)
        return np.concatenate([theta_n[..., :6] / s, self.centre + s * theta_n[..., 6:9]], axis=-1)

    def theta_to_normalised(self, theta: NDArray) -> NDArray[np.float64]:
        """θ in raw units → θ in normalised coordinates (``T' = T s``, ``o' = (o − m)/s``)."""
        theta = np.asarray(theta, dtype=float)
        s = self._scale(1)
        return np.concatenate([theta[..., :6] * s, (theta[..., 6:9] - self.centre) / s], axis=-1)

    def jacobian(self) -> NDArray[np.float64]:
        """d θ_raw / d θ_normalised (diagonal; (9, 9), or (K, 9, 9) for a stack)."""
        s = self._scale(1)
        diagonal = np.concatenate([np.repeat(1 / s, 6, axis=-1), np.repeat(s, 3, axis=-1)], axis=-1)
        return diagonal[..., :, None] * np.eye(9)


def propagated_weights(sigma: NDArray, gain: NDArray) -> NDArray[np.float64]:
    """``1/(σ_k ‖Tᵀā_k‖)²``: the inverse first-order variance of the norm residual (any leading axes).

    ``gain`` is :func:`optcal.core.norm_residual.normal_gain`, in the units of ``sigma``.
    """
    return 1.0 / (sigma * gain) ** 2


def pose_weights(poses: PoseTable, T: NDArray, o: NDArray, weighting: str = "propagated",
                 gain: NDArray | None = None) -> tuple[NDArray, bool]:
    """Weights of the norm residuals and whether they are absolute (noise known).

    ``paper``: ``1/σ_k²`` (Lu 2017, eq. 14).  ``propagated`` (default): ``1/(σ_k ‖Tᵀā_k‖)²``,
    the first-order variance of the norm residual, which makes the cost the maximum-likelihood
    cost of the norm residuals whatever the units (it equals ``paper`` when T ≈ I in g).
    Without per-pose noise all weights are 1 and the covariance is scaled by the fit.
    ``gain`` is :func:`optcal.core.norm_residual.normal_gain` at (T, o) when the caller has it.
    """
    if weighting not in WEIGHTINGS:
        raise InputError(f"unknown weighting {weighting!r}; use one of {', '.join(WEIGHTINGS)}")
    if poses.sigma is None:
        return np.ones(poses.n), False
    if weighting == "paper":
        return 1.0 / poses.sigma**2, True
    return propagated_weights(poses.sigma, normal_gain(T, o, poses.acc) if gain is None else gain), True


@dataclass(frozen=True)
class FisherAtFit:
    """The Fisher information of a pose set at a fit, as :func:`finish` needs it.

    Attributes
    ----------
    identifiability : IdentifiabilityReport
        Rank, conditioning, and the combinations not determined or only weakly determined.
    covariance : ndarray, shape (9, 9)
        Covariance of θ in raw units (scaled by the reduced chi-square when the noise is not known).
    residuals, weights : ndarray, shape (n,)
        Norm residuals and their weights at the fit.
    sigma_known : bool
        Whether the weights are absolute (per-pose noise given).
    """

    identifiability: IdentifiabilityReport
    covariance: NDArray[np.float64]
    residuals: NDArray[np.float64]
    weights: NDArray[np.float64]
    sigma_known: bool


def fisher_at_fit(poses: PoseTable, T: NDArray, o: NDArray, weighting: str = "propagated",
                  covariance_scale: str = "auto") -> FisherAtFit:
    """Covariance and identifiability of θ at ``(T, o)`` (see :mod:`optcal.core.identifiability`).

    The weak-direction test needs the covariance, so both come from one Fisher matrix:
    inverted in normalised coordinates (in raw counts the T and o blocks differ by ~1e16).
    The norm residuals are evaluated once; with the propagated weights of known noise the
    weighted information *is* the Fisher information of :func:`optcal.core.identifiability.fisher_information`,
    computed once for the verdict and the covariance.
    """
    point = NormResidualKernel(poses.acc).at(T, o)
    r = point.residuals
    J = point.jacobian().T
    gain = point.normal_gain()
    w, known = pose_weights(poses, T, o, weighting, gain=gain)
    norm = Normaliser.of(poses.acc)
    D = norm.jacobian()  # dθ_raw/dθ_normalised
    F, cov_n, cov_eigenvalues, eigenvectors = weighted_covariance(J, r, w, known, D, covariance_scale)
    if known and weighting == "propagated":
        information = F  # w = 1/(σ‖Tᵀā‖)², the weights of fisher_information
    else:
        s = np.ones(poses.n) if poses.sigma is None else poses.sigma
        information = J.T @ (J * propagated_weights(s, gain)[:, None])
    ident = analyse(T, o, poses.acc, poses.sigma, information=information)
    if ident.rank == ident.n_params and np.all(np.isfinite(cov_n)):
        add_weak_directions(ident, cov_n, T * norm.scale, eigen=(cov_eigenvalues, eigenvectors))
    return FisherAtFit(ident, D @ cov_n @ D, r, w, known)


def weighted_covariance(
    J: NDArray, r: NDArray, w: NDArray, sigma_known: bool | NDArray, D: NDArray, covariance_scale: str = "auto"
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The information ``JᵀWJ`` of θ and its pseudo-inverse in normalised coordinates, of one fit or a stack.

    Parameters
    ----------
    J : ndarray, shape (..., n, 9)
        ``∂r_k/∂θ`` in raw units.
    r, w : ndarray, shape (..., n)
        Norm residuals and their weights.
    sigma_known : bool or ndarray of bool, shape (...)
        Whether the weights are absolute; where not (and ``covariance_scale`` is ``"auto"``) the
        covariance is scaled by the reduced chi-square ``Σ w r² / (n − 9)``.
    D : ndarray, shape (..., 9, 9)
        ``dθ_raw/dθ_normalised`` (:meth:`Normaliser.jacobian`): the information is inverted in
        normalised coordinates (in raw counts the T and o blocks differ by ~1e16).

    Returns
    -------
    information : ndarray, shape (..., 9, 9)
        ``JᵀWJ`` in raw units.
    covariance : ndarray, shape (..., 9, 9)
        Of θ in normalised coordinates (``D covariance D`` in raw units).
    eigenvalues, eigenvectors : ndarray
        Of the covariance (:func:`optcal.core.identifiability.pseudo_inverse`).
    """
    F = np.swapaxes(J, -1, -2) @ (J * w[..., :, None])
    cov_n, cov_eigenvalues, eigenvectors = pseudo_inverse(D @ F @ D)
    if covariance_scale == "auto" and not np.all(sigma_known):
        dof = J.shape[-2] - len(PARAM_NAMES)
        chi2 = np.sum(w * r**2, axis=-1)
        factor = np.where(sigma_known, 1.0, chi2 / dof if dof > 0 else np.nan)
        cov_n, cov_eigenvalues = cov_n * factor[..., None, None], cov_eigenvalues * factor[..., None]
    return F, cov_n, cov_eigenvalues, eigenvectors


def degenerate_note(ident: IdentifiabilityReport, allow_degenerate: bool) -> str | None:
    """The note for a pose set that does not identify θ, or :class:`IdentifiabilityError` without ``allow_degenerate``."""
    if ident.identifiable:
        return None
    msg = ident.describe()
    if not allow_degenerate:
        consequence = ("the undetermined combinations are then arbitrary" if ident.rank < ident.n_params
                       else "the weakly determined combinations then carry these large standard errors")
        raise IdentifiabilityError(
            msg + ". Add poses that tilt the sensor about other axes (or pass allow_degenerate=True "
            f"to proceed anyway: {consequence})",
            ident,
        )
    return ("DEGENERATE POSE SET: " if ident.rank < ident.n_params else "WEAKLY DETERMINED POSE SET: ") + msg


def is_collapsed(T: NDArray) -> bool:
    """Whether the lower-triangular ``T`` is singular to working precision (a diagonal entry ≈ 0)."""
    diag = np.abs(np.diag(T))
    return bool(diag.min() <= 1e-6 * max(diag.max(), 1e-300))


def check_pose_set(poses: PoseTable, theta: NDArray, weighting: str = "propagated", allow_degenerate: bool = False) -> None:
    """Refuse, before an iterative fit, a pose set that does not identify θ at the start ``theta`` (raw units).

    The same test as :func:`finish` applies after the fit; run first, it spares the user an
    iterative solve (and its convergence warnings) that would end in that refusal.
    """
    if allow_degenerate or not np.all(np.isfinite(theta)):
        return
    T, o = unpack_theta(theta)
    if is_collapsed(T):
        return  # a collapsed start: the fit may still recover; finish() judges its answer
    degenerate_note(fisher_at_fit(poses, canonicalise(T), o, weighting).identifiability, allow_degenerate)


def finish(
    *,
    method: str,
    poses: PoseTable,
    theta: NDArray,
    solver: SolverInfo,
    weighting: str = "propagated",
    allow_degenerate: bool = False,
    notes: list[str] | None = None,
    extra: dict[str, Any] | None = None,
    covariance_scale: str = "auto",
    remedy: Remedy | None = None,
    constraints: ParameterConstraints | None = None,
) -> CalibrationResult:
    """Assemble a :class:`CalibrationResult` from θ in raw units.

    Checks that the solver returned an answer (:func:`check_solver`; ``remedy`` says which
    argument to change), then computes the norm residuals, the Fisher information at θ (with
    directions eliminated, see :mod:`optcal.core.identifiability`), its inverse as covariance
    (scaled by the reduced chi-square when the noise is not known) and the identifiability
    report; refuses a pose set that does not identify θ unless ``allow_degenerate``.  An early
    stop of the solver is warned about only for a pose set that is not refused.  With user
    ``constraints`` the covariance and the identifiability are those of the free subspace
    (:func:`constrained_fisher`), and the result's ``extra["constraints"]`` says which bound is active.
    """
    finite = bool(np.all(np.isfinite(theta)))
    if solver.status in SOLVER_FAILURES or not finite:
        check_solver(method, solver, theta, remedy)  # raises SolverError
    T, o = unpack_theta(theta)
    if is_collapsed(T):
        diag = np.abs(np.diag(T))
        raise FitError(
            f"the {method} fit collapsed to a singular T (|diagonal| = {', '.join(f'{d:.3g}' for d in diag)}): "
            "the poses do not pin the ellipsoid down, so the cost has a degenerate minimum; "
            "record more orientations spread over the sphere, or bound the scale (mle: scale_range=(low, high))"
        )
    T = canonicalise(T)  # no-op for lower-triangular T with positive diagonal
    theta = theta_from(T, o)
    notes = list(notes or [])
    fisher = fisher_at_fit(poses, T, o, weighting, covariance_scale)
    extra = dict(extra or {})
    if constraints:
        fisher, held = constrained_fisher(poses, theta, fisher, constraints, covariance_scale)
        extra["constraints"] = held.to_dict()
        notes += ["constraints: " + line for line in held.lines()]
    ident = fisher.identifiability
    note = degenerate_note(ident, allow_degenerate)
    if note:
        notes.append(note)
    check_solver(method, solver, theta, remedy)  # warns of an early stop
    if poses.n <= len(theta):
        notes.append(f"no degrees of freedom left ({poses.n} poses, {len(theta)} parameters)")
    return CalibrationResult(
        method=method,
        T=T,
        o=o,
        units=poses.units,
        params=theta,
        param_names=list(PARAM_NAMES),
        covariance=fisher.covariance,
        residuals=fisher.residuals,
        weights=fisher.weights,
        chisqr=chi_square(fisher.residuals, fisher.weights),
        n_observations=poses.n,
        sigma_known=fisher.sigma_known,
        solver=solver,
        rows=[int(x) for x in poses.rows],
        exclusions=dict(poses.exclusions),
        identifiability=ident,
        notes=notes,
        extra=extra,
    )


#: Weight of a held constraint in the identifiability test, relative to the largest diagonal
#: entry of the Fisher information in correlation form: a held parameter counts as measured far
#: better than any combination the poses determine (its standard error is zero).
HELD_INFORMATION: float = 1e6


def constrained_fisher(poses: PoseTable, theta: NDArray, fisher: FisherAtFit, constraints: ParameterConstraints,
                       covariance_scale: str = "auto") -> tuple[FisherAtFit, ConstraintReport]:
    """The covariance and identifiability at θ with the fixed parameters and active bounds held.

    The bound test uses the unconstrained standard errors (:func:`optcal.core.constraints.constraint_report`);
    the covariance is :func:`optcal.core.constraints.constrained_covariance` in normalised
    coordinates (scaled by ``χ²/(n − 9 + m)`` when the noise is not known, m the held
    constraints); the identifiability test counts each held constraint as an exactly measured
    combination, so a pose set that leaves only a fixed parameter undetermined identifies the rest.
    """
    unconstrained = fisher.covariance

    def stderr(name: str) -> float:
        g = parameter_gradient(theta, name)
        return float(np.sqrt(max(float(g @ unconstrained @ g), 0.0)))

    report = constraint_report(constraints, theta, stderr)
    if not report.held:
        return fisher, report
    T, o = unpack_theta(theta)
    point = NormResidualKernel(poses.acc).at(T, o)
    J = point.jacobian().T
    F = J.T @ (J * fisher.weights[:, None])
    D = Normaliser.of(poses.acc).jacobian()
    G_n = np.array([parameter_gradient(theta, name) for name in report.held]) @ D
    cov_n = constrained_covariance(D @ F @ D, G_n)
    if covariance_scale == "auto" and not fisher.sigma_known:
        dof = poses.n - len(PARAM_NAMES) + len(report.held)
        cov_n = cov_n * (float(np.sum(fisher.weights * fisher.residuals**2)) / dof if dof > 0 else np.nan)
    # each held constraint as an exactly measured combination: w g gᵀ with w large against the
    # largest diagonal entry of the information in normalised coordinates (D F D)
    G = np.array([parameter_gradient(theta, name) for name in report.held])
    weights = HELD_INFORMATION * float(np.max(np.diag(D @ F @ D))) / np.maximum(np.sum(G_n**2, axis=1), 1e-300)
    held_information = (G.T * weights) @ G  # = D⁻¹ (Σ w g_n g_nᵀ) D⁻¹, g_n = g D
    ident = analyse(T, o, poses.acc, poses.sigma, information=F + held_information)
    ident.constrained = list(report.held)
    if ident.rank == ident.n_params and np.all(np.isfinite(cov_n)):
        add_weak_directions(ident, cov_n, T * Normaliser.of(poses.acc).scale)
    return FisherAtFit(ident, D @ cov_n @ D, fisher.residuals, fisher.weights, fisher.sigma_known), report


class Stopwatch:
    """``with Stopwatch() as sw: ...; sw.seconds``."""

    def __enter__(self) -> "Stopwatch":
        self._t0 = time.perf_counter()
        self.seconds = 0.0
        return self

    def __exit__(self, *exc: object) -> None:
        self.seconds = time.perf_counter() - self._t0
