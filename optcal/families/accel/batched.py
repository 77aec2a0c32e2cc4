"""Many independent maximum-likelihood calibrations in one IPOPT problem (throughput).

IPOPT has a fixed cost per solve (≈ 0.4 ms on the reference machine: problem set-up, the
first factorisation, the bookkeeping of every iteration), which caps one-at-a-time ``mle``
fits at a few hundred per second however small the problem.  :class:`BatchedMaximumLikelihood`
solves K units of the same pose count as **one NLP with K separable 9-parameter blocks**:

* the cost is ``Σ_j c_j Σ_k w_jk r_jk(θ_j)²`` (Lu 2017, eq. 13-14, each unit with its own
  cost scale ``c_j`` of :func:`optcal.families.accel.mle.cost_scale` and mean-1 weights, as in
  ``mle``), evaluated for all K units at once on (K, n) numpy arrays, and handed to IPOPT
  with its gradient and its block-diagonal Gauss–Newton Hessian (upper triangles of K 9 × 9
  blocks) as CasADi callbacks (:func:`optcal.families.accel.mle.numpy_callback`);
* IPOPT's convergence test is the largest scaled gradient entry, so every block meets the
  tolerance it would meet alone: each unit lands on its own optimum (to the solver
  tolerance, ≪ 10⁻⁴ standard errors; tested against :class:`~optcal.families.accel.mle.MaximumLikelihood`);
* everything around the solve is vectorised too, with the same rules as ``mle``: the convex
  starting point (Lu 2017 eq. 18-30 with ``tr A = 3``; the KKT solution of the
  equality-constrained fit, checked against the semidefinite constraint, otherwise the
  unit's own ``mle`` start), the propagated weights re-computed until they settle
  (the units whose weights settled leave the next pass), the covariance from the Fisher
  information and the identifiability check of :mod:`optcal.core.identifiability` (rank of the
  correlation-form Fisher matrix, weak directions of the covariance).

The squared loss without bounds only (the default ``optcal calibrate``); use
:class:`~optcal.families.accel.mle.MaximumLikelihood` for robust losses and bounds.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.accel.mle import ML_IPOPT_DEFAULTS, MIN_RESIDUAL_RMS, MaximumLikelihood, numpy_callback
from optcal.core.identifiability import WEAK_STDERR, numerical_rank, parameter_full_scale, pseudo_inverse, scaled_information
from optcal.core.model import PARAM_NAMES
from optcal.core.norm_residual import TRIL_COLS, TRIL_ROWS
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, problem_cache

#: Units per IPOPT problem: large enough to amortise IPOPT's fixed cost, small enough that one
#: hard unit does not hold many others in extra iterations.
DEFAULT_BATCH: int = 512


class BatchedNormResidualCost:
    """``Σ_j c_j Σ_k w_jk r_jk²`` of K units with n poses each, its gradient and GN Hessian blocks.

    ``u`` is (K, n, 3) normalised data, ``w`` (K, n) weights, ``scale`` (K,) the cost scales;
    ``x`` is the 9K vector of the stacked θ_j.
    """

    def __init__(self, u: NDArray, w: NDArray, scale: NDArray) -> None:
        self.u = np.ascontiguousarray(np.swapaxes(np.asarray(u, dtype=float), 1, 2))  # (K, 3, n)
        self.w = np.asarray(w, dtype=float)
        self.scale = np.asarray(scale, dtype=float)
        self._x: NDArray | None = None

    @property
    def n_units(self) -> int:
        return int(self.w.shape[0])

    def _at(self, x: NDArray) -> None:
        """Residuals and calibrated directions at ``x`` (kept until ``x`` changes).

        The stacked form of :class:`optcal.core.norm_residual.NormResidualPoint`: the same formulas
        (Lu 2017, eq. 13) with a leading unit axis, the product with the lower-triangular T
        written out (three broadcasts instead of a 3 × 3 matrix product per pose).
        """
        x = np.asarray(x, dtype=float).ravel()
        if self._x is not None and np.array_equal(x, self._x):
            return
        th = x.reshape(-1, 9)[:, :, None]
        d = self.u - th[:, 6:9]  # a_k − o, (K, 3, n)
        v = np.empty_like(d)  # T (a_k − o), T lower-triangular (θ order of optcal.core.model.TRIL_INDEX)
        np.multiply(th[:, 0], d[:, 0], out=v[:, 0])
        v[:, 1] = th[:, 1] * d[:, 0] + th[:, 2] * d[:, 1]
        v[:, 2] = th[:, 3] * d[:, 0] + th[:, 4] * d[:, 1] + th[:, 5] * d[:, 2]
        nv = np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2 + v[:, 2] ** 2)
        v /= nv[:, None]  # ā_k
        self._x, self._r, self._J, self._gain = x.copy(), nv - 1.0, None, None  # eq. 13
        self._parts = (th, d, v)

    def residuals(self, x: NDArray) -> NDArray[np.float64]:
        """``r_jk = ‖T_j(u_jk − o_j)‖ − 1`` (K, n) (Lu 2017, eq. 13)."""
        self._at(x)
        return self._r

    def bias_jacobian(self, x: NDArray) -> NDArray[np.float64]:
        """``∂r/∂o = −Tᵀ ā`` (K, 3, n) (Lu 2017, eq. 16)."""
        self._at(x)
        th, _, a = self._parts
        g = np.empty_like(a)
        g[:, 0] = -(th[:, 0] * a[:, 0] + th[:, 1] * a[:, 1] + th[:, 3] * a[:, 2])
        g[:, 1] = -(th[:, 2] * a[:, 1] + th[:, 4] * a[:, 2])
        g[:, 2] = -th[:, 5] * a[:, 2]
        return g

    def jacobian(self, x: NDArray) -> NDArray[np.float64]:
        """``∂r/∂θ`` (K, 9, n): ``∂r/∂T_ij = ā_i u_j`` (Lu 2017, eq. 15), then ∂r/∂o (eq. 16)."""
        self._at(x)
        if self._J is None:
            _, d, a = self._parts
            J = np.empty((d.shape[0], 9, d.shape[2]))
            for k, (i, j) in enumerate(zip(TRIL_ROWS, TRIL_COLS)):
                np.multiply(a[:, i], d[:, j], out=J[:, k])
            J[:, 6:9] = self.bias_jacobian(x)
            self._J = J
        return self._J

    def evaluate(self, x: NDArray, jacobian: bool = True) -> tuple[NDArray, NDArray | None]:
        """Residuals ``r`` (K, n) and, if asked, their Jacobian (K, 9, n) at ``x`` (both cached)."""
        r = self.residuals(x)
        return r, (self.jacobian(x) if jacobian else None)

    def value(self, x: NDArray) -> float:
        r = self.residuals(x)
        return float(self.scale @ np.sum(self.w * r * r, axis=1))

    def gradient(self, x: NDArray) -> tuple[float, NDArray[np.float64]]:
        r, J = self.evaluate(x)
        wr = self.w * r
        g = (2.0 * self.scale)[:, None] * np.matmul(J, wr[:, :, None])[:, :, 0]
        return float(self.scale @ np.sum(wr * r, axis=1)), g.ravel()

    def hessian_blocks(self, x: NDArray) -> NDArray[np.float64]:
        """``2 c_j J_j W_j J_jᵀ`` per unit, (K, 9, 9)."""
        _, J = self.evaluate(x)
        Jw = J * np.sqrt((2.0 * self.scale)[:, None] * self.w)[:, None, :]
        return np.matmul(Jw, np.swapaxes(Jw, 1, 2))

    def normal_gain(self, x: NDArray) -> NDArray[np.float64]:
        """``‖Tᵀ ā_jk‖`` in normalised units (K, n) (= ‖∂r/∂o‖, as :meth:`NormResidualCost.normal_gain`)."""
        self._at(x)
        if self._gain is None:
            g = self.bias_jacobian(x) if self._J is None else self._J[:, 6:9]
            self._gain = np.sqrt(g[:, 0] ** 2 + g[:, 1] ** 2 + g[:, 2] ** 2)
        return self._gain


class BatchedMLProblem:
    """The NLP of K separable units, IPOPT through CasADi callbacks; built once per K, one solve at a time."""

    def __init__(self, n_units: int) -> None:
        import casadi as ca

        self.n_units = K = n_units
        self.cost: BatchedNormResidualCost | None = None
        problem = self

        def current() -> BatchedNormResidualCost:
            assert problem.cost is not None, "solve() sets the data"
            return problem.cost

        # upper triangle of each 9 × 9 block, in CasADi's column-major nonzero order
        blk, col, row = np.array([(k, c, r) for k in range(K) for c in range(9) for r in range(c + 1)]).T
        self._flat = blk * 81 + row * 9 + col
        hess_sp = ca.Sparsity.triplet(9 * K, 9 * K, (9 * blk + row).tolist(), (9 * blk + col).tolist())
        dense = ca.Sparsity.dense(9 * K, 1)
        scalar = ca.Sparsity.dense(1, 1)
        empty = ca.Sparsity(0, 1)

        self._gradient = numpy_callback(
            "batched_grad_f", [("x", dense), ("p", empty)], [("f", scalar), ("grad_f", dense)],
            lambda arg: list(current().gradient(arg[0])), nonzeros=True,
        )

        def cost_reverse(name: str, inames: list, onames: list, opts: dict) -> Any:
            x, out, adj = ca.MX.sym("x", 9 * K), ca.MX.sym("f", 1), ca.MX.sym("adj", 1)
            _, g = self._gradient(x, ca.MX(0, 1))
            return ca.Function(name, [x, out, adj], [adj * g], inames, onames, opts)

        self._cost = numpy_callback("batched_f", [("x", dense)], [("f", scalar)],
                                    lambda arg: [current().value(arg[0])], reverse=cost_reverse, nonzeros=True)
        self._hessian = numpy_callback(
            "batched_hess_lag", [("x", dense), ("p", empty), ("lam_f", scalar), ("lam_g", empty)],
            [("triu_hess_gamma_x_x", hess_sp)],
            lambda arg: [current().hessian_blocks(arg[0]).ravel()[self._flat] * float(arg[2][0])], nonzeros=True,
        )
        x = ca.MX.sym("theta", 9 * K)
        opts = {**ML_IPOPT_DEFAULTS, "grad_f": self._gradient, "hess_lag": self._hessian}
        self.solver = ca.nlpsol("ml_calibration_batched", "ipopt", {"x": x, "f": self._cost(x)}, opts)
        self._lock = threading.Lock()

    @staticmethod
    def get(n_units: int) -> "BatchedMLProblem":
        """The problem for ``n_units`` units, built on first use (:data:`BATCHED_PROBLEMS`)."""
        return BATCHED_PROBLEMS.get(n_units)

    def solve(self, theta0: NDArray, u: NDArray, w: NDArray) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve all K units from ``theta0`` (K, 9) for data ``u`` (K, n, 3) and mean-1 weights ``w`` (K, n)."""
        cost = BatchedNormResidualCost(u, w, np.ones(len(u)))
        r, _ = cost.evaluate(theta0.ravel(), jacobian=False)
        start_rms = np.sqrt(np.mean(w * r * r, axis=1))
        cost.scale = 1.0 / (u.shape[1] * np.maximum(start_rms, MIN_RESIDUAL_RMS))  # cost_scale() per unit
        with self._lock:  # the callbacks read the data of this solve; the solver keeps its statistics
            self.cost = cost
            try:
                sol = self.solver(x0=theta0.ravel())
                return np.asarray(sol["x"]).reshape(-1, 9), self.solver.stats()
            finally:
                self.cost = None


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
    reweight, reweight_rtol : int, float
        As :class:`~optcal.families.accel.mle.MaximumLikelihood` (the same defaults).
    """

    def __init__(self, batch: int = DEFAULT_BATCH, reweight: int = 2, reweight_rtol: float = 1e-3) -> None:
        if batch < 1:
            raise InputError(f"batch must be at least 1, got {batch}")
        self.batch = int(batch)
        defaults = MaximumLikelihood()
        self.reweight = int(reweight if reweight is not None else defaults.reweight)
        self.reweight_rtol = float(reweight_rtol)

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
        acc = np.stack([t.acc for t in tables])  # (K, n, 3)
        K, n, _ = acc.shape
        centre = acc.mean(axis=1)  # Normaliser.of, per unit
        scale = np.sqrt(np.mean(np.sum((acc - centre[:, None]) ** 2, axis=2), axis=1))
        u = (acc - centre[:, None]) / scale[:, None, None]
        theta = convex_start(u)
        for j in np.flatnonzero(~np.all(np.isfinite(theta), axis=1)):  # the PSD constraint is active: mle's own start
            from optcal.families.accel.base import Normaliser

            theta[j] = MaximumLikelihood().initial_normalised(tables[j], Normaliser(centre[j], float(scale[j])), u[j])[0]
        sigma = np.stack([t.sigma if t.sigma is not None else np.full(n, np.nan) for t in tables])
        known = np.all(np.isfinite(sigma), axis=1)
        sigma_or_1 = np.where(known[:, None], sigma, 1.0)

        def weights(th: NDArray) -> NDArray:
            """The propagated weights 1/(σ‖Tᵀā‖)² in raw units (MaximumLikelihood.weights), 1 without noise."""
            gain = BatchedNormResidualCost(u, np.ones((K, n)), np.ones(K)).normal_gain(th.ravel()) / scale[:, None]
            return np.where(known[:, None], 1.0 / (sigma_or_1 * gain) ** 2, 1.0)

        w_used = np.full((K, n), np.nan)
        active = np.ones(K, bool)
        passes = np.zeros(K, np.int64)
        iterations = np.zeros(K, np.int64)
        success = np.zeros(K, bool)
        for p in range(1 + max(self.reweight, 0)):
            w = weights(theta)
            if p > 0:
                active &= ~(np.max(np.abs(w / w_used - 1.0), axis=1) <= self.reweight_rtol)
            if not active.any():
                break
            a = np.flatnonzero(active)
            w_n = w[a] / np.mean(w[a], axis=1, keepdims=True)
            theta[a], stats = BatchedMLProblem.get(len(a)).solve(theta[a], u[a], w_n)
            success[a] = bool(stats.get("success", False))
            iterations[a] += int(stats.get("iter_count", 0))
            passes[a] += 1
            w_used[a] = w[a]
        return self._finish(theta, u, scale, centre, sigma_or_1, known, success, passes, iterations)

    @staticmethod
    def _finish(theta_n: NDArray, u: NDArray, scale: NDArray, centre: NDArray, sigma: NDArray, known: NDArray,
                success: NDArray, passes: NDArray, iterations: NDArray) -> BatchedFit:
        """Covariance and identifiability as :func:`optcal.families.accel.base.fisher_at_fit`, for every unit at once.

        One Jacobian per unit; the Fisher information with the noise propagated to the norm
        (:func:`optcal.core.identifiability.fisher_information`) serves the rank test and, for units
        with known noise, is also the information whose pseudo-inverse is the covariance; its
        eigenvalues give the weak-direction test (:func:`optcal.core.identifiability.add_weak_directions`).
        """
        K, n, _ = u.shape
        theta_n = theta_n.copy()
        flip = theta_n[:, [0, 2, 5]] < 0  # canonical form: positive diagonal of T (a row sign of T is free)
        for j in np.flatnonzero(flip.any(axis=1)):
            from optcal.core.model import canonicalise, theta_from, unpack_theta

            T, o = unpack_theta(theta_n[j])
            theta_n[j] = theta_from(canonicalise(T), o)
        cost = BatchedNormResidualCost(u, np.ones((K, n)), np.ones(K))
        r, J = cost.evaluate(theta_n.ravel())
        gain = cost.normal_gain(theta_n.ravel()) / scale[:, None]  # raw units
        w_fisher = 1.0 / (sigma * gain) ** 2  # fisher_information's weights (σ = 1 when not known)
        Jw = J * np.sqrt(w_fisher)[:, None, :]
        F_fisher = np.matmul(Jw, np.swapaxes(Jw, 1, 2))  # normalised θ
        w = np.where(known[:, None], w_fisher, 1.0)  # the fit's weights (pose_weights)
        F_n = F_fisher.copy()
        if not known.all():
            Ju = J[~known]
            F_n[~known] = np.matmul(Ju, np.swapaxes(Ju, 1, 2))
        cov_n, cov_eigenvalues, _ = pseudo_inverse(F_n)
        dof = n - 9
        chi2 = np.sum(w * r * r, axis=1)
        factor = np.where(known, 1.0, chi2 / dof if dof > 0 else np.nan)
        cov_n *= factor[:, None, None]
        # identifiability (optcal.core.identifiability.analyse): rank of the correlation-form Fisher matrix
        full_rank = numerical_rank(np.linalg.eigvalsh(scaled_information(F_fisher, parameter_full_scale(theta_n))[0])) == 9
        weak = np.max(cov_eigenvalues * factor[:, None], axis=1) > WEAK_STDERR**2
        D = np.concatenate([np.repeat(1.0 / scale[:, None], 6, axis=1), np.repeat(scale[:, None], 3, axis=1)], axis=1)
        theta = theta_n * D
        theta[:, 6:9] += centre  # Normaliser.theta_to_raw
        cov = cov_n * D[:, :, None] * D[:, None, :]
        return BatchedFit(theta, cov, np.sqrt(np.mean(r * r, axis=1)), full_rank & ~weak, success, passes,
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


def convex_start(u: NDArray) -> NDArray[np.float64]:
    """The convex algebraic fit of every unit (K, 9) in normalised coordinates; NaN where it does not apply.

    As :meth:`MaximumLikelihood.initial_normalised` with ``init="convex"``: the triangular factor
    R of the design matrix (Lu 2017, eq. 23), the solution of ``min ‖Rη‖²`` with ``tr A = 3``
    from its KKT system (:meth:`ConvexEllipsoidFit._kkt_polish`), accepted when its A clears the
    semidefinite constraint ``A ⪰ 2ε I`` and is a real ellipsoid (eq. 19-21, 27-30), the
    lower-triangular T from a Cholesky factor (:func:`optcal.core.model.canonical_T`).
    """
    from optcal.families.accel.ellipsoid import ConvexEllipsoidFit

    x, y, z = u[..., 0], u[..., 1], u[..., 2]
    Dm = np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, x, y, z, np.ones_like(x)], axis=-1)
    R = np.linalg.qr(Dm, mode="r")
    K = len(u)
    H = np.swapaxes(R, 1, 2) @ R
    g = np.zeros(10)
    g[:3] = 1.0
    kkt = np.zeros((K, 11, 11))
    kkt[:, :10, :10] = 2 * H
    kkt[:, :10, 10] = kkt[:, 10, :10] = g
    rhs = np.zeros((K, 11, 1))
    rhs[:, 10] = 3.0
    eta = np.linalg.solve(kkt, rhs)[:, :10, 0]
    a11, a22, a33, a12, a13, a23 = (eta[:, i] for i in range(6))
    A_s = np.stack([np.stack([a11, a12, a13], -1), np.stack([a12, a22, a23], -1), np.stack([a13, a23, a33], -1)], 1)
    b, c = eta[:, 6:9], eta[:, 9]
    ok = np.linalg.eigvalsh(A_s)[:, 0] >= 2 * ConvexEllipsoidFit(allow_degenerate=True).eps
    A_s[~ok] = np.eye(3)
    Ainv_b = np.linalg.solve(A_s, b[..., None])[..., 0]
    o = -0.5 * Ainv_b  # Lu 2017, eq. 20
    alpha = 1.0 / (0.25 * np.sum(b * Ainv_b, axis=1) - c)  # eq. 27
    ok &= alpha > 0
    A = A_s * np.where(ok, alpha, 1.0)[:, None, None]  # eq. 28
    P = np.eye(3)[::-1]
    L = np.linalg.cholesky(P @ A @ P)  # canonical_T: P A P = L Lᵀ, T = P Lᵀ P
    T = P @ np.swapaxes(L, 1, 2) @ P
    theta = np.concatenate([T[:, [0, 1, 1, 2, 2, 2], [0, 0, 1, 0, 1, 2]], o], axis=1)
    theta[~ok] = np.nan
    return theta
