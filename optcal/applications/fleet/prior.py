"""The population prior: empirical Bayes for units that their own data do not determine.

1. :func:`estimate_prior` — the mean ``μ`` and covariance ``P`` of θ over the well-determined
   units (calibrated by their own data, not flagged).  The spread of the estimates is the
   population's spread *plus* each unit's estimation noise, so the method-of-moments
   population covariance is ``P = S − C̄`` (``S`` the sample covariance of the estimates,
   ``C̄`` the mean of their covariances), kept between ``PRIOR_FLOOR · S`` and ``S`` in the
   Loewner order (whitened by ``S``, the eigenvalues are clipped to ``[PRIOR_FLOOR, 1]``).
2. :class:`PriorMLProblem` — the maximum-likelihood problem of Lu 2017 (eq. 13-14, the norm
   residual of :func:`optcal.core.norm_residual.casadi_norm_residual`) with the Gaussian prior as a
   penalty: ``min_θ Σ_k w_k r_k(θ)² + (θ − μ)ᵀ P⁻¹ (θ − μ)``, i.e. −2 log posterior, in CasADi
   and solved by IPOPT; the squared loss only.
3. :func:`fit_with_prior` — one unit refitted: start at its own fit (or at μ), absolute
   weights ``1/σ_r,k²`` (the noise of the pose table propagated as in ``mle``, or the
   population's typical residual when the table has no noise column), one reweighting pass.
   Its covariance is the posterior ``(F + P⁻¹)⁻¹`` (F the Fisher information of the data), and
   ``prior_weight_i = (Σ_post P⁻¹)_ii`` says how much of parameter i comes from the prior:
   the linearised posterior mean is ``Σ_post (F θ̂ + P⁻¹ μ)``, a weighted average of the data's
   estimate and the prior mean with weight matrix ``Σ_post P⁻¹`` on the prior (the
   multivariate form of the shrinkage factor ``σ²/(σ² + τ²)`` of Efron and Morris).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.applications.fleet.unit import UnitOutcome
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, problem_cache
from optcal.solvers.convergence import plugin_iterations, solver_record
from optcal.solvers.registry import SolverChoice, choose_nlp_solver
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, cost_scale, nlp_solver

#: Fewest well-determined units for a prior (a 9 × 9 covariance needs well over 9).
MIN_PRIOR_UNITS: int = 20
#: Lower bound of the population covariance as a fraction of the estimates' covariance.
PRIOR_FLOOR: float = 0.05
#: Reweighting passes of the prior fit (weights re-propagated at the new estimate).
PRIOR_PASSES: int = 2


@dataclass(frozen=True)
class PopulationPrior:
    """A Gaussian prior ``θ ~ N(mean, covariance)`` estimated from a population.

    Attributes
    ----------
    mean : ndarray, shape (9,)
    covariance : ndarray, shape (9, 9)
    n_units : int
        Well-determined units it was estimated from.
    units : str
        Units of the raw data (θ is in these units).
    noise_g : float
        Median rms norm residual of those units (g): the noise assumed for a unit without a
        per-pose noise column.
    """

    mean: NDArray[np.float64]
    covariance: NDArray[np.float64]
    n_units: int
    units: str
    noise_g: float

    @property
    def precision(self) -> NDArray[np.float64]:
        """``P⁻¹``."""
        return np.linalg.inv(self.covariance)  # type: ignore[return-value]  # numpy stubs type inv of float64 as floating[Any]


def estimate_prior(outcomes: list[UnitOutcome], units: str | None = None) -> PopulationPrior | None:
    """The population prior from the well-determined units (``None`` when fewer than :data:`MIN_PRIOR_UNITS`)."""
    good = [o for o in outcomes if o.status == "calibrated" and not o.flag and o.theta is not None
            and o.covariance is not None and np.all(np.isfinite(o.covariance))]
    if units is None and good:
        units = max({o.units for o in good}, key=lambda u: sum(o.units == u for o in good))
    good = [o for o in good if o.units == units]
    if len(good) < MIN_PRIOR_UNITS:
        return None
    X = np.array([o.theta for o in good])
    S = np.cov(X, rowvar=False)
    C_mean = np.mean([o.covariance for o in good if o.covariance is not None], axis=0)  # every good unit has one
    lam, V = np.linalg.eigh(S)
    S_half = V @ np.diag(np.sqrt(np.clip(lam, 1e-300, None))) @ V.T
    S_half_inv = V @ np.diag(1.0 / np.sqrt(np.clip(lam, 1e-300, None))) @ V.T
    W = S_half_inv @ (S - C_mean) @ S_half_inv  # population share of the spread, whitened
    mu, U = np.linalg.eigh(0.5 * (W + W.T))
    W = U @ np.diag(np.clip(mu, PRIOR_FLOOR, 1.0)) @ U.T
    P = S_half @ W @ S_half
    return PopulationPrior(X.mean(axis=0), 0.5 * (P + P.T), len(good), str(units),
                           float(np.median([o.rms_g for o in good])))


def padded_size(n: int) -> int:
    """Poses of the problem that serves n poses: the next power of two, at least 16.

    The padding poses get weight zero, so one problem per size class serves every n.
    """
    return max(16, 1 << (int(n) - 1).bit_length())


class PriorMLProblem:
    """``min_θ c [Σ_k w_k r_k(θ)² + ‖L(θ − μ)‖²]`` in normalised coordinates, built once per size.

    ``L`` is a factor of the prior precision in normalised coordinates (``LᵀL = D P⁻¹ D``, D the
    Jacobian of :meth:`optcal.families.accel.base.Normaliser.jacobian`); data, weights, μ, L and
    the cost scale ``c`` are parameters of the NLP.
    """

    def __init__(self, n: int, ipopt_options: dict[str, Any] | None = None, solver: SolverChoice | None = None) -> None:
        import casadi as ca

        from optcal.core.norm_residual import casadi_norm_residual

        self.n = n
        x = ca.SX.sym("theta", 9)
        data = ca.SX.sym("a", 3, n)
        w = ca.SX.sym("w", 1, n)
        mu = ca.SX.sym("mu", 9)
        L = ca.SX.sym("L", 9, 9)
        scale = ca.SX.sym("scale")
        r = casadi_norm_residual().map(n)(x, data)  # Lu 2017, eq. 13
        penalty = ca.sumsqr(ca.mtimes(L, x - mu))
        cost = scale * (ca.sum2(w * r**2) + penalty)  # eq. 14 plus −2 log prior
        p = ca.vertcat(ca.vec(data), ca.vec(w), mu, ca.vec(L), scale)
        self.nlp: dict[str, Any] = {"x": x, "p": p, "f": cost}
        self.solver = nlp_solver("ml_with_prior", self.nlp, SCALED_COST_IPOPT_OPTIONS,
                                 solver=solver or "ipopt", solver_options=None if solver else ipopt_options)
        self._lock = threading.Lock()  # the solver keeps the statistics of its last call

    @staticmethod
    def get(n: int, ipopt_options: dict[str, Any] | None = None, solver: SolverChoice | None = None) -> "PriorMLProblem":
        """The problem serving n poses (size :func:`padded_size`), built on first use (:data:`PRIOR_PROBLEMS`)."""
        return PRIOR_PROBLEMS.get(padded_size(n), solver or choose_nlp_solver(None, ipopt_options))

    def solve(self, theta0: NDArray, u: NDArray, w: NDArray, mu: NDArray, L: NDArray) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``theta0`` for normalised data ``u`` (n, 3) with absolute weights ``w``."""
        from optcal.families.accel.mle import NormResidualCost

        n = len(u)
        pad = self.n - n
        # weights scaled to mean 1 and the prior with them (same optimum): the conditioning of mle
        w_mean = float(np.mean(w))
        w, L = w / w_mean, L / np.sqrt(w_mean)
        u_p = np.vstack([u, np.repeat(u[:1], pad, axis=0)])
        w_p = np.concatenate([w, np.zeros(pad)])
        start = NormResidualCost(u, w).value(theta0) + float(np.sum((L @ (theta0 - mu)) ** 2))
        scale = cost_scale(n, np.sqrt(start / n))
        p = np.concatenate([u_p.ravel(), w_p, mu, L.ravel(order="F"), [scale]])
        with self._lock:
            return self.solver.solve(x0=theta0, p=p)


#: Built :class:`PriorMLProblem` s by padded size and frozen IPOPT options (:func:`optcal.solvers.cache.problem_cache`).
PRIOR_PROBLEMS: ProblemCache[PriorMLProblem] = problem_cache(lambda n, choice: PriorMLProblem(n, solver=choice),
                                                             maxsize=8)


@dataclass
class PriorFit:
    """A unit refitted with the population prior.

    Attributes
    ----------
    result : CalibrationResult
        The fit, with the posterior covariance (``method`` = ``mle+prior``).
    prior_weight : ndarray, shape (9,)
        Share of each parameter that comes from the prior (see the module docstring).
    """

    result: Any
    prior_weight: NDArray[np.float64]


def fit_with_prior(poses: PoseTable, prior: PopulationPrior, start: NDArray | None = None,
                   ipopt_options: dict[str, Any] | None = None, solver: str | None = None) -> PriorFit:
    """Refit one unit's poses with the population prior (see the module docstring).

    Parameters
    ----------
    poses : PoseTable
        The unit's poses, in the prior's units.
    prior : PopulationPrior
    start : ndarray, shape (9,), optional
        Starting θ (the unit's own fit); the prior mean when omitted.
    ipopt_options : dict, optional
        Extra CasADi/IPOPT options (the options of ``solver`` when another is named); options
        it refuses are an :class:`InputError`.
    solver : str, optional
        The NLP solver by name (:data:`optcal.solvers.registry.NLP_SOLVERS`; IPOPT by default).
    """
    from optcal.families.accel.base import Normaliser, Stopwatch, finish
    from optcal.families.accel.mle import MaximumLikelihood
    from optcal.core.norm_residual import norm_residual_jacobian
    from optcal.core.model import unpack_theta

    if poses.units != prior.units:
        raise InputError(f"the unit's data are in {poses.units} but the population prior in {prior.units}")
    poses.validate(min_poses=3)
    norm = Normaliser.of(poses.acc)
    u = norm.forward(poses.acc)
    D = norm.jacobian()
    offset = norm.theta_to_raw(np.zeros(9))  # θ_raw = D θ_n + offset
    mu_n = np.linalg.solve(D, prior.mean - offset)
    L = np.linalg.cholesky(D @ prior.precision @ D).T  # LᵀL = D P⁻¹ D
    theta_n = norm.theta_to_normalised(prior.mean if start is None else np.asarray(start, float))
    choice = choose_nlp_solver(solver, ipopt_options)
    problem = PriorMLProblem.get(poses.n, solver=choice)
    ml = MaximumLikelihood()
    iterations, seconds = 0, 0.0
    stats: dict[str, Any] = {}
    for _ in range(PRIOR_PASSES):
        w = ml.weights(poses, norm, u, theta_n) if poses.sigma is not None else np.full(poses.n, prior.noise_g**-2)
        with Stopwatch() as sw:
            theta_n, stats = problem.solve(theta_n, u, w, mu_n, L)
        iterations += plugin_iterations(stats)
        seconds += sw.seconds
    record = solver_record(stats, seconds, choice.label,
                           f"CasADi nlpsol {choice.plugin} (SX, exact Hessian), norm residual + population prior, "
                           f"{PRIOR_PASSES} pass(es)", iterations=iterations)
    result = finish(method="mle+prior", poses=poses, theta=norm.theta_to_raw(theta_n), solver=record,
                    allow_degenerate=True, extra={"prior_units": prior.n_units})
    # posterior covariance (F + P⁻¹)⁻¹, inverted in normalised coordinates
    T, o = unpack_theta(result.params)
    J = norm_residual_jacobian(T, o, poses.acc)
    if poses.sigma is None:
        w = np.full(poses.n, prior.noise_g**-2)
    F_n = D @ (J.T @ (J * w[:, None])) @ D
    cov_n = np.linalg.inv(F_n + D @ prior.precision @ D)
    cov = D @ cov_n @ D
    result.covariance = 0.5 * (cov + cov.T)
    result.sigma_known = True
    result.notes = [n for n in result.notes if not n.startswith("DEGENERATE")] + [
        f"calibrated with the population prior of {prior.n_units} units: what the poses do not determine comes from the fleet"
    ]
    weight = np.diag(result.covariance @ prior.precision).copy()
    return PriorFit(result, weight)
