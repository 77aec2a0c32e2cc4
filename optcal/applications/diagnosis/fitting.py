"""Fits of the extended model to one pose table: weights, likelihood-ratio tests, BIC, k-fold, covariance.

A :class:`Fitter` holds the data of one diagnosis in normalised units and fits any set of
terms (``{(effect, axis): order}``) with any poses given zero weight (outliers as mean-shift
terms), warm-started, in the one :class:`~optcal.applications.diagnosis.problem.ExtendedProblem` built for
the data's size.  The selection, the outlier test, the simulation check and the findings all
fit through it, so the work is shared and every number comes from the same formulas.

Weights are ``1/(σ_k ‖Tᵀ ā_k‖)²`` (Lu 2017, eq. 14: the norm residual's variance to first
order, :func:`optcal.core.norm_residual.normal_gain`), relative to their mean; the noise scale of
a fit is estimated from its residuals, so a wrong σ claim cannot manufacture findings.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.correlation import CorrelationOperator
from optcal.applications.diagnosis.effects import FITTED, describe_term, plain_term
from optcal.applications.diagnosis.problem import (BETA_INDEX, N_X, ExtendedProblem, PoseData, ProblemData, active_mask,
                                      session_shift, step_shift, to_model)
from optcal.applications.diagnosis.progress import Loop, plain_loop
from optcal.applications.diagnosis.regressors import Regressors
from optcal.families.accel.base import Normaliser
from optcal.core.extended_model import ExtendedModel
from optcal.core.model import theta_from
from optcal.core.poses import PoseTable

#: The paper's model, as the reports name it.
BASELINE_MODEL = "T, o, white noise (Lu 2017, eq. 5)"
#: Relative partial Fisher information below which a candidate is not identifiable from the poses.
IDENTIFIABLE_TOL: float = 1e-6
#: Residual degrees of freedom every test of the diagnosis keeps (a selection candidate on top of the current
#: model, the outlier test with its suspects set aside, the correlation's estimate after its trend terms) when the
#: noise scale is estimated from the residuals alone: below 10, the scale's own uncertainty (χ² with 10 degrees of
#: freedom: ±45 % in variance) takes most of a test's power.
MIN_DOF: int = 10
#: Residual degrees of freedom a test keeps when the noise of every pose mean was measured from its samples (a
#: small session): the F test's scale is then never let below that noise (:meth:`Fitter.noise_scale2`), so a scale
#: known from one degree of freedom cannot make a test more confident than the rests' own samples allow.
MIN_DOF_MEASURED: int = 1
#: Sorted ``((effect, axis), order)`` pairs: a hashable set of terms.
Terms = tuple[tuple[tuple[str, int], int], ...]


def terms_key(terms: dict[tuple[str, int], int]) -> Terms:
    """The terms in report order (effect in :data:`~optcal.applications.diagnosis.effects.FITTED` order, then axis)."""
    return tuple(sorted(terms.items(), key=lambda kv: (FITTED.index(kv[0][0]), kv[0][1])))


@dataclass
class Fit:
    """One fitted model: terms ``{(effect, axis): order}``, outlier poses, solution and residuals.

    Attributes
    ----------
    terms : dict
        ``{(effect, axis number): polynomial order}``.
    outliers : frozenset of int
        Pose indices given zero weight.
    x : ndarray, shape (N_X,)
        Solution in normalised units (θ, then every coefficient; inactive ones zero).
    residuals : ndarray, shape (n,)
        Norm residuals of every pose (g), outliers included.
    rss : float
        Weighted residual sum of squares over the kept poses.
    n_params : int
        Free parameters (9 + coefficients + one mean shift per outlier).
    success : bool
        Whether IPOPT reported success.
    """

    terms: dict[tuple[str, int], int]
    outliers: frozenset[int]
    x: NDArray[np.float64]
    residuals: NDArray[np.float64]
    rss: float
    n_params: int
    success: bool

    def kept(self, n: int) -> NDArray[np.bool_]:
        """Mask of the poses that are not outliers."""
        mask = np.ones(n, dtype=bool)
        mask[list(self.outliers)] = False
        return mask

    def describe(self) -> str:
        """E.g. ``T, o, white noise + temperature_bias(z) + outliers(2 poses zero-weighted)``."""
        parts = [BASELINE_MODEL.split(" (")[0]]
        parts += [describe_term(e, a, o) for (e, a), o in terms_key(self.terms)]
        if self.outliers:
            parts.append(f"outliers({len(self.outliers)} poses zero-weighted)")
        return " + ".join(parts)

    def describe_plain(self) -> str:
        """The model in plain words (figures), e.g. ``the paper's model + bias changing with temperature on z``."""
        parts = ["the paper's model"] + [plain_term(e, a, o) for (e, a), o in terms_key(self.terms)]
        if self.outliers:
            parts.append(f"{len(self.outliers)} outlier poses left out")
        return " + ".join(parts)


def orthogonal_part(g: NDArray[np.float64], G: NDArray[np.float64]) -> NDArray[np.float64]:
    """The part of ``g`` (or of each column of ``g``) orthogonal to the columns of ``G``.

    Through the small Gram matrix ``GᵀG`` (its eigen-decomposition, directions ``G`` lacks
    dropped), not a QR of the tall ``G``: LAPACK's threaded QR of an n×10 matrix is two orders
    of magnitude slower on a loaded machine, and the columns here are well scaled.
    """
    values, vectors = np.linalg.eigh(G.T @ G)
    keep = values > 1e-12 * max(float(values.max()), 1e-300)
    inverse = (vectors[:, keep] / values[keep]) @ vectors[:, keep].T
    return g - G @ (inverse @ (G.T @ g))


def measured_scale2(poses: PoseTable, w_mean: float, measured_sigma: NDArray | None = None) -> float | None:
    """The variance of a residual of unit relative weight that the measured noise of the pose means implies.

    The weights are ``1/(σ_k g_k)²`` relative to their mean ``w_mean`` (Lu 2017, eq. 14), so a pose mean whose
    noise is its σ gives a weighted residual of variance ``1/w_mean``.  ``poses.sigma`` is the noise of each
    pose mean measured from its samples, their colour included (batch means within the rest,
    :func:`optcal.data.static_poses.sigma_of_mean`); ``measured_sigma`` (optional) is the same noise measured on
    the recording's still parts at each pose's dwell (:mod:`optcal.applications.diagnosis.still_noise`), which
    also sees noise slower than a rest.  The larger of the two is taken pose by pose (noise one of them missed
    is still noise), as the mean of the squared ratios to σ.  ``None`` when the poses carry no σ.
    """
    if poses.sigma is None:
        return None
    sigma = np.asarray(poses.sigma, float)
    ratio2 = np.ones_like(sigma)
    if measured_sigma is not None:
        ratio2 = np.maximum(np.asarray(measured_sigma, float) / sigma, 1.0) ** 2
    return float(np.mean(ratio2)) / w_mean


def mean_shift_columns(n: int, outliers: frozenset[int]) -> NDArray[np.float64]:
    """One indicator column per outlier pose: its free mean shift in a generalised least-squares fit."""
    columns = np.zeros((n, len(outliers)))
    columns[sorted(outliers), np.arange(len(outliers))] = 1.0
    return columns


class Fitter:
    """Fits of the extended model to ``poses`` (module docstring).

    Parameters
    ----------
    poses : PoseTable
    regressors : Regressors
    T, o : ndarray
        The baseline calibration (the start of every fit and the source of the weights).
    folds : int
        k of the k-fold held-out error (folds interleaved along time, so each spans the recording).
    loop : callable, optional
        Wraps the loop over the folds (a progress bar, :mod:`optcal.applications.diagnosis.progress`).
    correlation : CorrelationOperator, optional
        The correlation of the pose noise in time (:mod:`optcal.applications.diagnosis.correlation`): every fit
        is then refined to generalised least squares and its ``rss`` is the generalised sum.
    measured_scale2 : float, optional
        The variance of a residual of unit relative weight that the noise of the pose means measured from their
        samples implies (:func:`measured_scale2`, the still parts' noise included); ``None`` when the poses carry
        no measured σ.  With it a small session is tested from :data:`MIN_DOF_MEASURED` residual degrees of
        freedom (:attr:`min_dof`); the tests' scale floor is the rests' own (:attr:`rest_scale2`).
    """

    #: Gauss–Newton steps from the weighted least-squares solution to the generalised one.
    GLS_STEPS: int = 2

    def __init__(self, poses: PoseTable, regressors: Regressors, T: NDArray, o: NDArray, folds: int,
                 loop: Loop = plain_loop, correlation: CorrelationOperator | None = None,
                 measured_scale2: float | None = None) -> None:
        from optcal.core.norm_residual import normal_gain

        self.poses = poses
        self.n = poses.n
        self.reg = regressors
        self.norm = Normaliser.of(poses.acc)
        self.data = PoseData.of(self.norm.forward(poses.acc), regressors)
        self.problem = ExtendedProblem.get(self.n, "squared")
        sigma = np.ones(self.n) if poses.sigma is None else poses.sigma
        w_abs = 1.0 / (sigma * normal_gain(T, o, poses.acc)) ** 2  # Lu 2017, eq. 14
        self.w_mean = float(np.mean(w_abs))
        self.w = w_abs / self.w_mean
        x0 = np.zeros(N_X)
        x0[:9] = self.norm.theta_to_normalised(theta_from(T, o))
        self.x_start = x0
        p0 = self.params(self.w, scale=1.0)
        r0 = self.problem.residual_values(x0, p0)
        self.s0 = max(float(np.sqrt(np.sum(self.w * r0**2) / max(self.n - 9, 1))), 1e-12)
        self.folds = min(int(folds), self.n)
        # has_time: the regressors of these poses found a usable time column
        order = np.argsort(poses.t, kind="stable") if regressors.has_time and poses.t is not None else np.arange(self.n)
        self.fold = np.empty(self.n, dtype=int)
        self.fold[order] = np.arange(self.n) % self.folds
        self.time_order = order
        self.loop = loop
        self.correlation = correlation
        self.measured_scale2 = measured_scale2
        #: The variance of a residual of unit relative weight that each pose mean's σ (measured from its own
        #: samples, :func:`measured_scale2` without the still parts) implies: the floor of a small session's test
        #: scale (:meth:`test_scale2`); ``None`` when the poses carry no σ.
        self.rest_scale2: float | None = None if poses.sigma is None else 1.0 / self.w_mean
        #: Poses before each bias step in time order, in the order the steps were placed (empty: no step in the
        #: model; :meth:`set_steps`).
        self.steps_at: tuple[int, ...] = ()
        self._heldout_cache: dict[tuple[Terms, frozenset[int], tuple[int, ...]], NDArray[np.float64]] = {}

    # ------------------------------------------------------------------ bias step
    def step_indicator(self, k: int) -> NDArray[np.float64]:
        """1 for the poses after the first ``k`` in time order (:attr:`time_order`), 0 for those ``k``."""
        step = np.zeros(self.n)
        step[self.time_order[k:]] = 1.0
        return step

    def steps_column(self, splits: tuple[int, ...]) -> NDArray[np.float64] | None:
        """The steps' indicators, one column per step after the first ``k`` poses of ``splits`` (``None``: none)."""
        return np.column_stack([self.step_indicator(k) for k in splits]) if splits else None

    def step_data(self, k: int) -> PoseData:
        """The fit's data with a bias step after the first ``k`` poses in time order, after the steps placed."""
        return replace(self.data, step=self.steps_column((*self.steps_at, k)))

    def set_steps(self, splits: tuple[int, ...]) -> None:
        """Fit every later model with bias steps after the first ``k`` poses in time order of each of ``splits``."""
        self.steps_at = tuple(int(k) for k in splits)
        self.data = replace(self.data, step=self.steps_column(self.steps_at))

    # ------------------------------------------------------------------ fitting
    def params(self, w: NDArray, data: PoseData | None = None, scale: float | None = None,
               delta: float = 1.0) -> ProblemData:
        """Problem parameters for relative weights ``w`` (divided by the noise scale²)."""
        s = self.s0 if scale is None else scale
        return (data or self.data).parameters(w / s**2, delta)

    def weights(self, fit: Fit) -> NDArray[np.float64]:
        """Relative weights with ``fit``'s outliers at zero."""
        return np.where(fit.kept(self.n), self.w, 0.0)

    def fit(
        self,
        terms: dict[tuple[str, int], int],
        outliers: frozenset[int] = frozenset(),
        x0: NDArray | None = None,
        data: PoseData | None = None,
    ) -> Fit:
        """Least-squares fit of the model with ``terms``, the ``outliers`` given zero weight."""
        kept = np.ones(self.n, dtype=bool)
        kept[list(outliers)] = False
        w = np.where(kept, self.w, 0.0)
        p = self.params(w, data)
        x, stats = self.problem.solve(self.x_start if x0 is None else x0, p, active_mask(terms))
        r = self.problem.residual_values(x, p)
        rss = float(np.sum(self.w[kept] * r[kept] ** 2))
        if self.correlation is not None:
            x, r, rss = self.generalised(x, r, terms, outliers, p)
        n_params = 9 + sum(terms.values()) + len(outliers)
        return Fit(dict(terms), frozenset(outliers), x, r, rss, n_params, bool(stats.get("success", False)))

    def generalised(self, x: NDArray, r: NDArray, terms: dict[tuple[str, int], int], outliers: frozenset[int],
                    p: ProblemData) -> tuple[NDArray, NDArray, float]:
        """Gauss–Newton steps from ``x`` to the generalised least-squares fit under :attr:`correlation`.

        Minimises ``(e + Gδ)ᵀ R⁻¹ (e + Gδ)`` over the free parameters and one mean shift per outlier pose
        (``e = √w r``); returns the solution, its residuals and the generalised sum.
        """
        assert self.correlation is not None
        free = np.flatnonzero(np.concatenate([np.ones(9, dtype=bool), active_mask(terms)]))
        sqrt_w = np.sqrt(self.w)
        shifts = mean_shift_columns(self.n, outliers)
        total = float("nan")
        for step_number in range(self.GLS_STEPS + 1):
            G = np.column_stack([sqrt_w[:, None] * self.problem.jacobian_values(x, p)[:, free], shifts])
            e = sqrt_w * r
            Z = self.correlation.solve(np.column_stack([e, G]))
            info, b = G.T @ Z[:, 1:], G.T @ Z[:, 0]
            step = -np.linalg.lstsq(info, b, rcond=None)[0]
            total = float(e @ Z[:, 0] + b @ step)  # the minimum of the linearised generalised sum
            if step_number == self.GLS_STEPS:
                break  # the last linearisation's step is negligible: its minimum is the sum at x
            x = x.copy()
            x[free] += step[: free.size]
            r = self.problem.residual_values(x, p)
        return x, r, total

    def evaluate(self, x: NDArray) -> Fit:
        """The baseline model at a given solution, not refitted (a calibration given as it is)."""
        r = self.problem.residual_values(x, self.params(self.w))
        return Fit({}, frozenset(), x, r, float(np.sum(self.w * r**2)), 9, True)

    def bic(self, fit: Fit) -> float:
        """``n log(RSS/n) + p log n`` (outliers as mean-shift parameters, so n is every pose)."""
        return float(self.n * np.log(max(fit.rss, 1e-300) / self.n) + fit.n_params * np.log(self.n))

    @property
    def min_dof(self) -> int:
        """Residual degrees of freedom a test keeps: :data:`MIN_DOF`, or :data:`MIN_DOF_MEASURED` with the
        noise of the pose means measured (:attr:`measured_scale2`)."""
        return MIN_DOF if self.measured_scale2 is None else MIN_DOF_MEASURED

    def noise_scale2(self, fit: Fit) -> tuple[float, float]:
        """The noise scale of a unit relative weight under ``fit`` and the degrees of freedom it is known with: the
        residuals' ``rss / (n − p)``, in a small session (fewer than :data:`MIN_DOF` residual degrees of freedom)
        never below :attr:`rest_scale2` (:meth:`test_scale2`'s reasons).  The scale of the tests
        (:meth:`test_scale2`), of the standard errors (:meth:`covariance`) and of the detection limits, so a
        finding's standard error is the one its test used."""
        dof = self.n - fit.n_params
        scale2 = fit.rss / max(dof, 1)
        if dof < MIN_DOF and self.rest_scale2 is not None:
            scale2 = max(scale2, self.rest_scale2)
        return scale2, float(dof)

    def test_scale2(self, small: Fit, big: Fit) -> tuple[float, float]:
        """The noise scale of the likelihood-ratio test of ``small`` inside ``big``, and its degrees of freedom.

        ``big``'s residual scale ``rss / (n − p)`` with its degrees of freedom (an F test); in a small session
        (fewer than :data:`MIN_DOF` residual degrees of freedom) never below :attr:`rest_scale2`, the noise of the
        pose means measured from their own samples (batch means within each rest, their colour included).

        The F test is exact under white pose noise of any scale, so it keeps its level whatever the pose means'
        scatter against the noise measured in the rests (IMU-TK's Xsens log: 18.7 times the rests' batch means on
        a 14-rest cut, 8.4 times what its still parts' Allan variance gives; mikoff's hand-held MPU-9150: 0.38 and
        0.04 times).  The floor only enlarges the denominator (the p value against F(q, n − p) can only rise, so
        the level holds): 4-5 residual degrees of freedom leave the scale uncertain by a factor of 2-6 (χ²(4)'s 1-99 %
        range), and a sum that falls below what the rests' own samples say by chance would otherwise name effects
        smaller than the pose means' noise (mikoff imu1, 14 rests, no effect: a z drift at p 0.00035, the full
        log's p 0.05).  A χ² test against the measured noise (the route before) is only valid where that noise
        explains the scatter, which 4-5 residual degrees of freedom cannot check (a χ² route chosen on each
        candidate's fit named a false effect in 8-20 % of null sessions at a 2 % family-wise level,
        docs/diagnosis.md); chosen on the null model ``small`` (only where its residual sum ``S`` is within the
        measured noise ``s²``), its statistic is at most ``S / s² ≤ n − p₀``, whose χ²(1) tail is above the step's
        level up to 19 poses (0.025 at 14 poses against about 0.002): it could name nothing, and it took the F
        test's place where the still parts overstate the noise (mikoff imu0, 14 rests, an x drift at 7 standard
        errors: p 0.081 on that route, 0.0021 now, against a level of 0.0020).  ``small`` is kept for the callers.
        """
        return self.noise_scale2(big)

    def f_test(self, small: Fit, big: Fit) -> float:
        """p value of the F form of the likelihood-ratio test of ``small`` inside ``big``.

        The noise scale is :meth:`test_scale2`'s: estimated from ``big``'s residuals (an F test).
        """
        q = big.n_params - small.n_params
        scale2, dof = self.test_scale2(small, big)
        if q <= 0 or dof <= 0:
            return 1.0
        F = max(small.rss - big.rss, 0.0) / q / scale2
        return float(sps.f.sf(F, q, dof))

    def heldout(self, fit: Fit) -> NDArray[np.float64]:
        """Held-out residual of every pose (k-fold; the model fitted without the pose's fold)."""
        key = (terms_key(fit.terms), fit.outliers, self.steps_at)
        if key in self._heldout_cache:
            return self._heldout_cache[key]
        out = np.empty(self.n)
        mask = active_mask(fit.terms)
        base_w = self.weights(fit)
        for f in self.loop(range(self.folds), f"{self.folds}-fold held-out error", self.folds):
            held = self.fold == f
            p = self.params(np.where(held, 0.0, base_w))
            x, _ = self.problem.solve(fit.x, p, mask)
            out[held] = self.problem.residual_values(x, p)[held]
        self._heldout_cache[key] = out
        return out

    # ------------------------------------------------------------------ information
    def jacobians(self, fit: Fit, w: NDArray, data: PoseData | None = None) -> tuple[NDArray, NDArray]:
        """Weighted Jacobian of the free parameters and the full weighted Jacobian at ``fit.x``."""
        J = self.problem.jacobian_values(fit.x, self.params(w, data))
        free = np.concatenate([np.ones(9, dtype=bool), active_mask(fit.terms)])
        sw = np.sqrt(w)[:, None]
        return sw * J[:, free], sw * J

    def correlated_solve(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """``R⁻¹ X`` under :attr:`correlation` (a copy of ``X`` for independent poses)."""
        return np.array(X, dtype=float, copy=True) if self.correlation is None else self.correlation.solve(X)

    def generalised_system(self, fit: Fit) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``H`` and ``(Hᵀ R⁻¹ H)⁻¹`` at ``fit`` (``R = I`` for independent poses).

        ``H``: the free parameters' weighted Jacobian (θ, then active β), then one mean-shift column per
        outlier pose of ``fit`` (in pose order).
        """
        G, _ = self.jacobians(fit, self.w)
        H = np.column_stack([G, mean_shift_columns(self.n, fit.outliers)])
        return H, np.linalg.pinv(H.T @ self.correlated_solve(H), rcond=1e-13, hermitian=True)  # type: ignore[return-value]  # numpy stubs type pinv of float64 as floating[Any]

    def generalised_solution(self, fit: Fit) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(Hᵀ R⁻¹ H)⁻¹`` (:meth:`generalised_system`) and the linearised generalised least-squares step at
        ``fit`` under :attr:`correlation`; the step's shift entries are the outlier poses' departures."""
        assert self.correlation is not None
        H, full = self.generalised_system(fit)
        return full, -full @ (H.T @ self.correlation.solve(np.sqrt(self.w) * fit.residuals))

    def covariance(self, fit: Fit) -> NDArray[np.float64]:
        """Covariance of the free normalised parameters (θ, then active β in layout order)."""
        s2 = self.noise_scale2(fit)[0]
        if self.correlation is not None:  # (Gᵀ R⁻¹ G)⁻¹ with a mean shift per outlier pose, kept to θ and β
            _, full = self.generalised_system(fit)
            p = full.shape[0] - len(fit.outliers)
            return s2 * full[:p, :p]
        G, _ = self.jacobians(fit, self.weights(fit))
        return s2 * np.linalg.pinv(G.T @ G, rcond=1e-13, hermitian=True)

    def identifiable(self, fit: Fit, effect: str, axis: int, order: int) -> bool:
        """Whether the term's regressor has information left after the model of ``fit``."""
        G, J = self.jacobians(fit, self.weights(fit))
        g = J[:, 9 + BETA_INDEX[(effect, axis, order)]]
        if not np.any(g):
            return False
        g_perp = orthogonal_part(g, G)
        return float(g_perp @ g_perp) > IDENTIFIABLE_TOL * float(g @ g)

    def pose_normals(self, fit: Fit) -> NDArray[np.float64]:
        """Unit gradient of each pose's residual with respect to its measurement (minus the bias columns)."""
        J = self.problem.jacobian_values(fit.x, self.params(self.w))
        d = -J[:, 6:9]
        return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)

    def model(self, fit: Fit) -> ExtendedModel:
        """The physical extended model of ``fit``."""
        scale = self.norm.scale
        if not isinstance(scale, float):  # impossible: the normaliser of one pose set (n, 3) has a float scale
            raise AssertionError("the normaliser of one pose set has an array scale")
        return to_model(fit.x, self.norm.centre, scale, self.reg)

    def session_shift(self, fit: Fit) -> NDArray[np.float64]:
        """Raw bias of each pose's session relative to the first session's under ``fit`` (zeros for one session),
        and of the poses after a bias step relative to those before it."""
        C = self.model(fit).base.C
        shift = session_shift(fit.x, C, self.reg.session, self.reg.n_sessions)
        return shift + step_shift(fit.x, C, self.data.step) if self.data.step is not None else shift

    def fitted_directions(self, fit: Fit) -> NDArray[np.float64]:
        """Unit specific-force directions of the poses under ``fit``'s model (its inversion at each pose)."""
        d = self.model(fit).correct(self.poses.acc - self.session_shift(fit), *self.columns())
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def noise_free(self, fit: Fit) -> NDArray[np.float64]:
        """What ``fit``'s model measures, without noise, at the poses' fitted directions, temperatures, times and sessions."""
        return self.model(fit).measure(self.fitted_directions(fit), *self.columns()) + self.session_shift(fit)

    def columns(self) -> tuple[NDArray | None, NDArray | None]:
        """Temperature and time of the poses where usable (``None`` otherwise)."""
        return (self.poses.temp if self.reg.has_temp else None, self.poses.t if self.reg.has_time else None)
