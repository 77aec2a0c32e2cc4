"""Many independent maximum-likelihood calibrations in one IPOPT problem (throughput).

IPOPT has a fixed cost per solve (≈ 0.4 ms on the reference machine: problem set-up, the
first factorisation, the bookkeeping of every iteration), which caps one-at-a-time ``mle``
fits at a few hundred per second however small the problem.  :class:`BatchedMaximumLikelihood`
solves K units of the same pose count as **one NLP with K separable 9-parameter blocks**, the
batched form of :class:`~optcal.families.accel.mle.MaximumLikelihood` on its own kernels, each
taking a leading axis of units:

* the cost ``Σ_j c_j Σ_k w_jk r_jk(θ_j)²`` (Lu 2017, eq. 13-14) is
  :class:`~optcal.families.accel.mle.NormResidualCost` of the stacked units, each with its own
  cost scale ``c_j`` and mean-1 weights (:func:`~optcal.families.accel.mle.scaled_cost`), handed
  to IPOPT with its gradient and its block-diagonal Gauss–Newton Hessian (K 9 × 9 blocks) as
  callbacks (:class:`optcal.solvers.nlp.CallbackNLP`);
* IPOPT's convergence test is the largest scaled gradient entry, so every block meets the
  tolerance it would meet alone: each unit lands on its own optimum (to the solver
  tolerance, ≪ 10⁻⁴ standard errors; tested against ``mle``);
* around the solve, the same rules as ``mle``, applied to all units at once: the normalisation
  (:class:`~optcal.families.accel.base.Normaliser`), the convex starting point
  (:func:`~optcal.families.accel.mle.convex_start`, Lu 2017 eq. 18-30; where the semidefinite
  constraint is active, the unit's own ``mle`` start), the propagated weights
  (:func:`~optcal.families.accel.base.propagated_weights`) re-computed until they settle
  (:func:`~optcal.families.accel.mle.weights_settled`; the units whose weights settled leave the
  next pass), the canonical form of T, the covariance
  (:func:`~optcal.families.accel.base.weighted_covariance`) and the identifiability test of
  :mod:`optcal.core.identifiability` (rank of the correlation-form Fisher matrix, weak directions
  of the covariance).

The squared loss without bounds only (the default ``optcal calibrate``); use
:class:`~optcal.families.accel.mle.MaximumLikelihood` for robust losses and bounds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.accel.base import Normaliser, is_collapsed, propagated_weights, weighted_covariance
from optcal.families.accel.mle import MaximumLikelihood, NormResidualCost, convex_start, scaled_cost, weights_settled
from optcal.core.identifiability import WEAK_STDERR, numerical_rank, parameter_full_scale, scaled_information
from optcal.core.model import PARAM_NAMES, canonicalise, theta_from, unpack_theta
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, problem_cache
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP

#: Units per IPOPT problem: large enough to amortise IPOPT's fixed cost, small enough that one
#: hard unit does not hold many others in extra iterations.
DEFAULT_BATCH: int = 512


class BatchedMLProblem:
    """The NLP of K separable units (:class:`~optcal.families.accel.mle.NormResidualCost` with a unit axis),
    IPOPT through CasADi callbacks; built once per K, one solve at a time."""

    def __init__(self, n_units: int) -> None:
        self.n_units = n_units
        self.nlp = CallbackNLP("ml_calibration_batched", 9 * n_units, hessian_block_size=9,
                               tuning=SCALED_COST_IPOPT_OPTIONS)

    @staticmethod
    def get(n_units: int) -> "BatchedMLProblem":
        """The problem for ``n_units`` units, built on first use (:data:`BATCHED_PROBLEMS`)."""
        return BATCHED_PROBLEMS.get(n_units)

    def solve(self, theta0: NDArray, u: NDArray, w: NDArray) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve all K units from ``theta0`` (K, 9) for data ``u`` (K, n, 3) and mean-1 weights ``w`` (K, n)."""
        cost = scaled_cost(u, w, theta0)
        x, stats = self.nlp.solve(cost.objective(), x0=theta0.ravel())
        return x.reshape(-1, 9), stats


#: Built :class:`BatchedMLProblem` s by number of units (:func:`optcal.solvers.cache.problem_cache`).
BATCHED_PROBLEMS: ProblemCache[BatchedMLProblem] = problem_cache(BatchedMLProblem, maxsize=16)


@dataclass
class BatchedFit:
    """K calibrations from :meth:`BatchedMaximumLikelihood.fit_many` (raw units, order of the input).

    Attributes
    ----------
    theta : ndarray, shape (K, 9)
        θ of :data:`optcal.core.model.PARAM_NAMES`.
    covariance : ndarray, shape (K, 9, 9)
    rms_g : ndarray, shape (K,)
        Rms norm residual, g.
    identifiable : ndarray of bool, shape (K,)
        Whether the unit's poses identify every parameter (``mle`` refuses the others).
    success : ndarray of bool, shape (K,)
        Whether IPOPT reported success for the unit's last solve.
    passes : ndarray of int, shape (K,)
        Solves until the weights settled.
    iterations : ndarray of int, shape (K,)
        IPOPT iterations of the problems the unit was solved in, summed over its passes.
    residuals, weights : list of ndarray, shape (n_j,) each
        Each unit's norm residuals and their weights at the fit (as ``CalibrationResult``).
    """

    theta: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rms_g: NDArray[np.float64]
    identifiable: NDArray[np.bool_]
    success: NDArray[np.bool_]
    passes: NDArray[np.int64]
    iterations: NDArray[np.int64]
    residuals: list[NDArray[np.float64]]
    weights: list[NDArray[np.float64]]

    @classmethod
    def empty(cls, n_units: int) -> "BatchedFit":
        """A fit of ``n_units`` units to be filled in."""
        K = n_units
        return cls(np.zeros((K, 9)), np.zeros((K, 9, 9)), np.zeros(K), np.zeros(K, bool), np.zeros(K, bool),
                   np.zeros(K, np.int64), np.zeros(K, np.int64), [np.empty(0)] * K, [np.empty(0)] * K)

    def put(self, index: list[int], part: "BatchedFit") -> None:
        """Store ``part`` (a fit of ``len(index)`` units) at positions ``index``."""
        for name in ("theta", "covariance", "rms_g", "identifiable", "success", "passes", "iterations"):
            getattr(self, name)[index] = getattr(part, name)
        for j, k in enumerate(index):
            self.residuals[k], self.weights[k] = part.residuals[j], part.weights[j]

    @property
    def stderr(self) -> NDArray[np.float64]:
        """Standard errors (K, 9)."""
        return np.sqrt(np.clip(np.diagonal(self.covariance, axis1=1, axis2=2), 0.0, None))

    def summary(self, k: int) -> dict[str, float]:
        """Unit k's parameters by name."""
        return dict(zip(PARAM_NAMES, self.theta[k].tolist()))


class BatchedMaximumLikelihood:
    """The default ``mle`` calibration of many pose tables, K units per IPOPT problem.

    Parameters
    ----------
    batch : int
        Units per IPOPT problem (:data:`DEFAULT_BATCH`).
    reweight, reweight_rtol : int, float, optional
        As :class:`~optcal.families.accel.mle.MaximumLikelihood`; by default its own.
    """

    def __init__(self, batch: int = DEFAULT_BATCH, reweight: int | None = None, reweight_rtol: float | None = None) -> None:
        if batch < 1:
            raise InputError(f"batch must be at least 1, got {batch}")
        self.batch = int(batch)
        defaults = MaximumLikelihood()
        self.reweight = int(defaults.reweight if reweight is None else reweight)
        self.reweight_rtol = float(defaults.reweight_rtol if reweight_rtol is None else reweight_rtol)

    def fit_many(self, tables: list[PoseTable], validate: bool = True) -> BatchedFit:
        """Calibrate every table (grouped by pose count, ``batch`` units per problem).

        ``validate=False`` skips :func:`validate_many` for tables the caller has validated
        (:func:`invalid_tables`).
        """
        out = BatchedFit.empty(len(tables))
        by_n: dict[int, list[int]] = {}
        for j, t in enumerate(tables):
            by_n.setdefault(t.n, []).append(j)
        for idx in by_n.values():
            if validate:
                validate_many([tables[j] for j in idx], idx)
            for s in range(0, len(idx), self.batch):
                part = idx[s:s + self.batch]
                out.put(part, self._fit_group([tables[j] for j in part]))
        return out

    def _fit_group(self, tables: list[PoseTable]) -> BatchedFit:
        from optcal.families.accel.ellipsoid import ConvexEllipsoidFit

        acc = np.stack([t.acc for t in tables])  # (K, n, 3)
        K, n, _ = acc.shape
        norm = Normaliser.of(acc)
        scale = np.asarray(norm.scale)  # (K,)
        u = norm.forward(acc)
        ml = MaximumLikelihood()
        theta = convex_start(u, ConvexEllipsoidFit(allow_degenerate=True).eps)
        for j in np.flatnonzero(~np.all(np.isfinite(theta), axis=1)):  # the PSD constraint is active: mle's own start
            theta[j] = ml.initial_normalised(tables[j], Normaliser(norm.centre[j], float(scale[j])), u[j])[0]
        sigma = np.stack([t.sigma if t.sigma is not None else np.full(n, np.nan) for t in tables])
        known = np.all(np.isfinite(sigma), axis=1)
        sigma_or_1 = np.where(known[:, None], sigma, 1.0)

        def weights(th: NDArray) -> NDArray:
            """The propagated weights in raw units (MaximumLikelihood.weights), 1 without noise."""
            gain = NormResidualCost(u, np.ones((K, n))).normal_gain(th) / scale[:, None]
            return np.where(known[:, None], propagated_weights(sigma_or_1, gain), 1.0)

        w_used: NDArray | None = None
        active = np.ones(K, bool)
        passes = np.zeros(K, np.int64)
        iterations = np.zeros(K, np.int64)
        success = np.zeros(K, bool)
        for _ in range(1 + max(self.reweight, 0)):
            w = weights(theta)
            active &= ~weights_settled(w, w_used, self.reweight_rtol)
            if not active.any():
                break
            a = np.flatnonzero(active)
            w_n = w[a] / np.mean(w[a], axis=-1, keepdims=True)  # scale-free weights, as mle
            theta[a], stats = BatchedMLProblem.get(len(a)).solve(theta[a], u[a], w_n)
            success[a] = bool(stats.get("success", False))
            iterations[a] += int(stats.get("iter_count", 0))
            passes[a] += 1
            w_used = w
        return self._finish(norm.theta_to_raw(theta), acc, norm, sigma_or_1, known, success, passes, iterations)

    @staticmethod
    def _finish(theta: NDArray, acc: NDArray, norm: Normaliser, sigma: NDArray, known: NDArray,
                success: NDArray, passes: NDArray, iterations: NDArray) -> BatchedFit:
        """Canonical form, covariance and identifiability as :func:`optcal.families.accel.base.finish`, for every unit at once.

        θ (raw units) is put in the canonical form (lower-triangular T with positive diagonal;
        a collapsed T is left as it is).  One Jacobian per unit at θ; the Fisher information
        with the noise propagated to the norm (:func:`optcal.core.identifiability.fisher_information`)
        serves the rank test and, for units with known noise, is also the information whose
        pseudo-inverse is the covariance (:func:`optcal.families.accel.base.weighted_covariance`);
        its eigenvalues give the weak-direction test (:func:`optcal.core.identifiability.add_weak_directions`).
        """
        K, n, _ = acc.shape
        T, o = unpack_theta(theta)
        regular = np.array([not is_collapsed(t) for t in T])
        if regular.any():
            T[regular] = canonicalise(T[regular])
        theta = theta_from(T, o)
        cost = NormResidualCost(acc, np.ones((K, n)))  # raw data, raw θ: the quantities of fisher_at_fit
        r = cost.residuals(theta)
        J = np.swapaxes(cost.jacobian(theta), 1, 2)  # (K, n, 9)
        w_fisher = propagated_weights(sigma, cost.normal_gain(theta))  # fisher_information's weights (σ = 1 when not known)
        w = np.where(known[:, None], w_fisher, 1.0)  # the fit's weights (pose_weights)
        D = norm.jacobian()
        F, cov_n, cov_eigenvalues, _ = weighted_covariance(J, r, w, known, D)
        information = F.copy()
        if not known.all():
            Ju = J[~known]
            information[~known] = np.swapaxes(Ju, 1, 2) @ (Ju * w_fisher[~known][:, :, None])
        # identifiability (optcal.core.identifiability.analyse): rank of the correlation-form Fisher matrix
        full_rank = numerical_rank(np.linalg.eigvalsh(scaled_information(information, parameter_full_scale(theta))[0])) == 9
        weak = np.max(cov_eigenvalues, axis=1) > WEAK_STDERR**2
        return BatchedFit(theta, D @ cov_n @ D, np.sqrt(np.mean(r * r, axis=1)), full_rank & ~weak, success, passes,
                          iterations, list(r), list(w))


def invalid_tables(tables: list[PoseTable]) -> dict[int, InputError]:
    """The tables (of one pose count) that :meth:`PoseTable.validate` refuses, with its error.

    The checks (finite values, positive noise, enough poses, enough distinct poses, not
    coplanar) are screened on the stacked (K, n, 3) array; a table the screen cannot pass
    is validated on its own, so that the verdict and the error are exactly
    :meth:`PoseTable.validate`'s.  (Distinct poses are screened by the distinct quantised x
    values, a lower bound of the distinct rows.)
    """
    from optcal.core.poses import MIN_POSES

    if not tables:
        return {}
    acc = np.stack([t.acc for t in tables])
    n = acc.shape[1]
    suspect = ~np.all(np.isfinite(acc), axis=(1, 2)) | (n < MIN_POSES)
    for name in ("sigma", "t", "temp"):
        have = [j for j, t in enumerate(tables) if getattr(t, name) is not None]
        if have:
            v = np.stack([getattr(tables[j], name) for j in have])
            bad = ~np.all(np.isfinite(v), axis=1) | (np.any(v <= 0, axis=1) if name == "sigma" else False)
            suspect[np.asarray(have)[bad]] = True
    ok = np.flatnonzero(~suspect)
    if n >= MIN_POSES and ok.size:
        a = acc[ok]
        full = np.max(np.abs(a), axis=(1, 2))
        qx = np.sort(np.round(a[..., 0] / (np.where(full > 0, full, 1.0) * 1e-9)[:, None]), axis=1)
        distinct_x = 1 + np.sum(np.diff(qx, axis=1) != 0, axis=1)
        sv = np.linalg.svd(a - a.mean(axis=1, keepdims=True), compute_uv=False)
        flat = (sv[:, 0] == 0) | (sv[:, -1] < 1e-6 * sv[:, 0])
        suspect[ok[(distinct_x < MIN_POSES) | flat]] = True
    errors = {}
    for j in np.flatnonzero(suspect):
        try:
            tables[j].validate()
        except InputError as exc:
            errors[int(j)] = exc
    return errors


def validate_many(tables: list[PoseTable], index: list[int] | None = None) -> None:
    """:meth:`PoseTable.validate` for tables of one pose count, vectorised (:func:`invalid_tables`).

    The first failure is raised, prefixed with its position in ``tables`` (or ``index``).
    """
    index = list(range(len(tables))) if index is None else index
    for j, exc in sorted(invalid_tables(tables).items()):
        raise InputError(f"tables[{index[j]}]: {exc}") from exc
