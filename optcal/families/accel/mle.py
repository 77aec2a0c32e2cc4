"""Maximum-likelihood calibration as IPOPT nonlinear least squares in CasADi (Lu 2017, eq. 13-14).

Model, problem and solver are built in separate steps (as in CasADi's ``sysid.py`` example):

1. :func:`optcal.core.norm_residual.casadi_norm_residual` — the per-pose norm residual
   ``r_k = ‖T(a_k − o)‖ − 1`` (eq. 13) as a CasADi ``Function`` of θ and one measurement.
2. The NLP ``min_θ c Σ_k ρ(√w_k r_k)`` (eq. 14 for the squared loss ρ(z) = z²) over the nine
   identifiable parameters (T lower-triangular, o), with the measurements, weights, loss
   scale and cost scale ``c`` (:func:`optcal.solvers.nlp.cost_scale`) as data, in one of two
   forms, both built by :mod:`optcal.solvers.nlp` and solved by IPOPT:

   * :class:`MLProblem` (up to :attr:`MLProblem.SX_LIMIT` poses): the cost mapped over n poses
     and expanded into one SX graph with the exact Hessian; built once per (n, loss, options)
     and kept in :data:`ML_PROBLEMS` (:func:`optcal.solvers.cache.problem_cache`).
   * :class:`VectorisedMLProblem` (more poses): cost, gradient and Gauss–Newton Hessian
     evaluated in numpy (:class:`NormResidualCost`) and handed to IPOPT as callbacks
     (:class:`optcal.solvers.nlp.CallbackNLP`), built per solve in milliseconds whatever n
     (10⁶ poses in about a second).
3. :class:`MaximumLikelihood` — the estimator: starting point from an algebraic fit
   (``convex`` by default, eq. 18-30, :func:`convex_start`), weights ``1/σ_r,k²`` when per-pose
   noise is known (re-propagated until they settle, :func:`weights_settled`), optional robust
   loss (Huber, Cauchy) and bounds on named parameters (for example a known scale range),
   covariance from the Fisher information.

The cost (:class:`NormResidualCost`), the start (:func:`convex_start`), the cost scale
(:func:`scaled_cost`) and the settling of the weights take a leading axis of units, so that
:mod:`optcal.families.accel.batched` solves many calibrations by the same rules.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, InputError
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish, pose_weights, propagated_weights
from optcal.core.constraints import PHYSICAL_NAMES, ParameterConstraints, physical_of_theta
from optcal.core.model import unpack_theta, theta_from
from optcal.core.norm_residual import NormResidualKernel, NormResidualPoint, casadi_norm_residual, norm_residuals
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, problem_cache
from optcal.core.fit_result import SolverInfo
from optcal.solvers.convergence import SOLVER_FAILURES, Remedy, plugin_iterations, solver_record
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS, CallbackNLP, NumpyObjective, cost_scale, nlp_solver
from optcal.solvers.registry import SolverChoice, choose_conic_solver, choose_nlp_solver, takes_callbacks
from optcal.families.accel.result import CalibrationResult

LOSSES = ("squared", "huber", "cauchy")
#: Default loss scales (in standard deviations): 95 % efficiency at the Gaussian.
DEFAULT_LOSS_SCALE = {"squared": 1.0, "huber": 1.345, "cauchy": 2.385}
#: What to change when IPOPT stops early or fails (the ML problems of this module and of ``exact``).
IPOPT_REMEDY = Remedy(
    stopped_early="raise the iteration limit (ipopt_options={'ipopt.max_iter': 1000}) or start from another fit (init=...)",
    failed='check ipopt_options, or use method="convex"',
)
#: The same advice for a solver other than IPOPT (named with ``solver=``).
SOLVER_REMEDY = Remedy(
    stopped_early="raise the iteration limit (solver_options={'max_iter': 1000}) or use another solver (solver=...)",
    failed="check solver_options, or use another solver (solver=...)",
)


def robust_loss(z: Any, loss: str, delta: Any) -> Any:
    """ρ(z) for a standardised residual z: z², Huber or Cauchy (scale ``delta``)."""
    import casadi as ca

    if loss == "squared":
        return z**2
    if loss == "huber":
        az = ca.fabs(z)
        return ca.if_else(az <= delta, z**2, 2 * delta * az - delta**2)
    if loss == "cauchy":
        return delta**2 * ca.log1p((z / delta) ** 2)
    raise InputError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")


def robust_loss_terms(z: NDArray, loss: str, delta: float) -> tuple[NDArray, NDArray, NDArray]:
    """ρ(z), ρ'(z) and the IRLS weight ρ'(z)/z of a standardised residual, in numpy.

    The IRLS weight (2 for the squared loss) is the Gauss–Newton curvature of ρ: it gives the
    positive semi-definite Hessian approximation ``Σ ρ'(z_k)/z_k · w_k ∇r_k ∇r_kᵀ`` used for
    large problems (exact in the limit of zero residuals for the squared loss).
    """
    if loss == "squared":
        return z * z, 2.0 * z, np.full_like(z, 2.0)
    if loss == "huber":
        az = np.abs(z)
        inside = az <= delta
        rho = np.where(inside, z * z, 2.0 * delta * az - delta * delta)
        drho = np.where(inside, 2.0 * z, 2.0 * delta * np.sign(z))
        return rho, drho, np.where(inside, 2.0, 2.0 * delta / np.maximum(az, 1e-300))
    if loss == "cauchy":
        q = 1.0 + (z / delta) ** 2
        return delta * delta * np.log(q), 2.0 * z / q, 2.0 / q
    raise InputError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")


class NormResidualCost:
    """The ML cost ``c Σ ρ(√w_k r_k(θ))`` with its gradient and Gauss–Newton Hessian, in numpy.

    Of one unit (``u`` (n, 3) normalised data, ``w`` (n,) weights, θ (9,)) or of a stack of K
    units with n poses each (``u`` (K, n, 3), ``w`` (K, n), ``scale`` (K,) or one number, ``x``
    the 9K stacked θ_j): ``Σ_j c_j Σ_k ρ(√w_jk r_jk(θ_j))``, separable, whose Hessian is
    block diagonal (:meth:`gauss_newton_hessian` returns the (K, 9, 9) blocks).

    The residuals and their Jacobian come from :class:`optcal.core.norm_residual.NormResidualKernel`
    (Lu 2017, eq. 13 and 15-16, column by column, T lower-triangular).  The kernel's evaluation
    at the last θ is kept: IPOPT asks for the cost, the gradient and the Hessian at the same
    point.  One instance serves one solve (it is never shared between threads).
    """

    def __init__(self, u: NDArray, w: NDArray, loss: str = "squared", delta: float = 1.0,
                 scale: float | NDArray = 1.0) -> None:
        self.u = np.asarray(u, dtype=float)
        self.kernel = NormResidualKernel(self.u)
        self.w = np.asarray(w, dtype=float)
        self.sqrt_w = np.sqrt(self.w)
        self.loss, self.delta = loss, float(delta)
        self.scale: float | NDArray = scale
        self.units = self.w.shape[:-1]  # () for one unit, (K,) for a stack
        self._x: NDArray | None = None
        self._point: NormResidualPoint | None = None
        self._J: NDArray | None = None

    @property
    def n(self) -> int:
        """Poses per unit."""
        return int(self.w.shape[-1])

    def _at(self, x: NDArray) -> NormResidualPoint:
        x = np.asarray(x, dtype=float).ravel()
        if self._point is None or self._x is None or not np.array_equal(x, self._x):
            self._x, self._point, self._J = x.copy(), self.kernel.at_theta(x.reshape(self.units + (9,))), None
        return self._point

    def residuals(self, x: NDArray) -> NDArray[np.float64]:
        """``r_k = ‖T(u_k − o)‖ − 1`` (Lu 2017, eq. 13), shape (..., n)."""
        return self._at(x).residuals

    def jacobian(self, x: NDArray) -> NDArray[np.float64]:
        """``∂r_k/∂θ``, shape (..., 9, n) (one row per parameter; Lu 2017, eq. 15-16)."""
        point = self._at(x)
        if self._J is None:
            self._J = point.jacobian()
        return self._J

    def normal_gain(self, x: NDArray) -> NDArray[np.float64]:
        """``‖Tᵀ ā_k‖`` in normalised units, shape (..., n) (see :func:`optcal.core.norm_residual.normal_gain`)."""
        return self._at(x).normal_gain()

    def unit_values(self, x: NDArray) -> NDArray[np.float64]:
        """``Σ_k ρ(√w_k r_k)`` of each unit, unscaled, shape (...)."""
        rho, _, _ = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        return np.sum(rho, axis=-1)

    def value(self, x: NDArray) -> float:
        return float(np.sum(self.scale * self.unit_values(x)))

    def gradient(self, x: NDArray) -> tuple[float, NDArray[np.float64]]:
        J = self.jacobian(x)
        rho, drho, _ = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        scale = np.asarray(self.scale)[..., None]
        g = scale * (J @ (drho * self.sqrt_w)[..., :, None])[..., 0]
        return float(np.sum(self.scale * np.sum(rho, axis=-1))), g.ravel()

    def gauss_newton_hessian(self, x: NDArray) -> NDArray[np.float64]:
        """``c Σ_k ρ'(z_k)/z_k · w_k ∇r_k ∇r_kᵀ`` (``2 c JᵀWJ`` for the squared loss), shape (..., 9, 9).

        The IRLS weight ``ρ'(z)/z`` (2 for the squared loss) is the Gauss–Newton curvature of ρ:
        a positive semi-definite approximation of the Hessian (exact in the limit of zero
        residuals for the squared loss).
        """
        J = self.jacobian(x)
        _, _, irls = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        Js = J * np.sqrt(irls * self.w)[..., None, :]
        return np.asarray(self.scale)[..., None, None] * (Js @ np.swapaxes(Js, -1, -2))

    def objective(self) -> NumpyObjective:
        """The functions IPOPT calls (:class:`optcal.solvers.nlp.CallbackNLP`)."""
        return NumpyObjective(self.value, self.gradient, lambda x, lam_f: self.gauss_newton_hessian(x) * lam_f)


def scaled_cost(u: NDArray, w: NDArray, theta0: NDArray, loss: str = "squared", delta: float = 1.0) -> NormResidualCost:
    """The cost of a solve from ``theta0``, scaled by :func:`optcal.solvers.nlp.cost_scale` (each unit by its own).

    ``s₀`` is the rms standardised residual at the start, ``√(Σ_k ρ(√w_k r_k)/n)``.
    """
    cost = NormResidualCost(u, w, loss, delta)
    cost.scale = cost_scale(cost.n, np.sqrt(cost.unit_values(theta0) / cost.n))
    return cost


def weights_settled(w: NDArray, w_used: NDArray | None, rtol: float) -> NDArray[np.bool_]:
    """Whether no weight changed by more than ``rtol`` (relative) since the last solve (per unit for a stack)."""
    if w_used is None:
        return np.zeros(np.shape(w)[:-1], dtype=bool)
    return np.asarray(np.max(np.abs(w / w_used - 1.0), axis=-1) <= rtol)


class _MLSolve(ABC):
    """What both forms of the ML problem share: one solve from a start, for data and weights."""

    loss: str

    def solve(
        self,
        theta0: NDArray,
        u: NDArray,
        w: NDArray,
        delta: float = 1.0,
        lbx: NDArray | None = None,
        ubx: NDArray | None = None,
        lbg: NDArray | None = None,
        ubg: NDArray | None = None,
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``theta0`` for normalised data ``u`` (n, 3) and weights ``w`` (n,); θ and the solver's statistics.

        ``lbg``, ``ubg`` bound the physical parameters the problem was built with (:class:`MLProblem`'s ``physical``).
        """
        cost = scaled_cost(u, w, theta0, self.loss, delta)
        args: dict[str, Any] = {"x0": theta0}
        for key, value in (("lbx", lbx), ("ubx", ubx), ("lbg", lbg), ("ubg", ubg)):
            if value is not None:
                args[key] = value
        return self._solve(cost, args)

    @abstractmethod
    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Run IPOPT on ``cost`` with the start and bounds in ``args``."""


def ml_nlp(n: int, loss: str = "squared", physical: tuple[str, ...] = ()) -> dict[str, Any]:
    """The NLP ``min_θ c Σ_k ρ(√w_k r_k(θ))`` (Lu 2017, eq. 13-14) for n poses as a CasADi SX dictionary.

    ``x`` is θ in normalised coordinates; ``p`` stacks the normalised measurements (column-major
    3×n), the weights (scaled to mean one), the robust loss's threshold δ and the cost scale c;
    ``g``, when ``physical`` names parameters of :data:`optcal.core.constraints.PHYSICAL_NAMES`,
    holds their values at θ (scale factors in normalised units, ``S' = S/s``; angles in degrees).
    """
    import casadi as ca

    r = casadi_norm_residual()
    x = ca.SX.sym("theta", 9)
    data = ca.SX.sym("a", 3, n)
    w = ca.SX.sym("w", 1, n)
    delta = ca.SX.sym("delta")
    scale = ca.SX.sym("scale")
    res = (r.map(n) if n > 1 else r)(x, data)  # 1 x n
    cost = scale * ca.sum2(robust_loss(res * ca.sqrt(w), loss, delta))
    nlp: dict[str, Any] = {"x": x, "p": ca.vertcat(ca.vec(data), ca.vec(w), delta, scale), "f": cost}
    if physical:
        values = physical_of_theta(x, _CASADI_MATH)
        nlp["g"] = ca.vertcat(*[values[PHYSICAL_NAMES.index(name)] for name in physical])
    return nlp


class MLProblem(_MLSolve):
    """The NLP ``min_θ c Σ ρ(√w_k r_k(θ))`` for n poses, data as parameters (built once).

    The cost is expanded into one CasADi SX graph with the exact Hessian (fastest
    derivatives for small and moderate n).  Building it takes about 0.4 ms per pose, so
    beyond :attr:`SX_LIMIT` poses :meth:`get` returns a :class:`VectorisedMLProblem` instead.
    ``c`` is the scale of :func:`optcal.solvers.nlp.cost_scale`, a parameter like the data; the
    IPOPT tuning is that of a scaled cost (:data:`optcal.solvers.nlp.SCALED_COST_IPOPT_OPTIONS`).
    """

    SX_LIMIT = 200

    def __init__(self, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None,
                 solver: SolverChoice | None = None, physical: tuple[str, ...] = ()) -> None:
        self.n, self.loss, self.physical = n, loss, tuple(physical)
        self.nlp = ml_nlp(n, loss, self.physical)
        self.solver = nlp_solver("ml_calibration", self.nlp, SCALED_COST_IPOPT_OPTIONS,
                                 solver=solver or "ipopt", solver_options=None if solver else ipopt_options,
                                 options_argument="ipopt_options" if solver is None or solver.name == "ipopt" else "solver_options")
        self._lock = threading.Lock()

    @classmethod
    def get(cls, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None,
            solver: SolverChoice | None = None, physical: tuple[str, ...] = ()) -> "MLProblem | VectorisedMLProblem":
        """The problem for n poses: the SX problem up to :attr:`SX_LIMIT` poses, built once and
        kept in :data:`ML_PROBLEMS`; beyond, a :class:`VectorisedMLProblem` (nothing to keep),
        unless physical parameters are constrained (their constraints are SX expressions) or the
        solver cannot take numpy callbacks (:func:`optcal.solvers.registry.takes_callbacks`)."""
        choice = solver or choose_nlp_solver(None, ipopt_options)
        if n > cls.SX_LIMIT and not physical and takes_callbacks(choice.name):
            return VectorisedMLProblem(loss, solver=choice)
        return ML_PROBLEMS.get(n, loss, choice, tuple(physical))

    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        # vec() is column-major, so p holds a_1, a_2, ... stacked
        p = np.concatenate([cost.u.ravel(), cost.w, [cost.delta, cost.scale]])
        with self._lock:  # the solver keeps the statistics of its last call
            return self.solver.solve(p=p, **args)


class VectorisedMLProblem(_MLSolve):
    """The same NLP for any n, still solved by IPOPT in CasADi, with numpy doing the sums.

    The cost, its gradient and the Gauss–Newton Hessian (IRLS curvature for the robust
    losses, :func:`robust_loss_terms`) of a :class:`NormResidualCost` are callbacks of a
    :class:`optcal.solvers.nlp.CallbackNLP` (the gradient as the cost's reverse derivative and
    as ``grad_f``, the Hessian as ``hess_lag``).  Nothing depends on n, and building the
    callbacks and the NLP takes a few milliseconds, so each :meth:`solve` builds its own:
    the object holds only the loss and the options, and any number of threads can solve with
    it at once.  One IPOPT iteration on 10⁶ poses costs a few dozen vector operations.
    """

    def __init__(self, loss: str = "squared", ipopt_options: dict[str, Any] | None = None,
                 solver: SolverChoice | None = None) -> None:
        self.loss = loss
        self.ipopt_options = dict(ipopt_options or {})
        self.choice = solver or choose_nlp_solver(None, self.ipopt_options)

    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        nlp = CallbackNLP("ml_calibration_vectorised", 9, hessian_block_size=9, tuning=SCALED_COST_IPOPT_OPTIONS,
                          solver=self.choice)
        return nlp.solve(cost.objective(), **args)


class _CasadiMath:
    """The functions :func:`optcal.core.constraints.physical_of_theta` needs, on CasADi symbols."""

    @staticmethod
    def sqrt(x: Any) -> Any:
        import casadi as ca

        return ca.sqrt(x)

    @staticmethod
    def asin(x: Any) -> Any:
        import casadi as ca

        return ca.asin(x)

    @staticmethod
    def cos(x: Any) -> Any:
        import casadi as ca

        return ca.cos(x)


_CASADI_MATH = _CasadiMath()

#: The SX problems of :class:`MLProblem`, keyed by (n, loss, solver choice, constrained physical parameters).
ML_PROBLEMS: ProblemCache[MLProblem] = problem_cache(
    lambda n, loss, choice, physical: MLProblem(n, loss, solver=choice, physical=physical), maxsize=32
)


def design_factor(u: NDArray) -> NDArray[np.float64]:
    """A factor R with ``RᵀR = DᵀD`` of the design matrix D of :func:`optcal.families.accel.ellipsoid.design_matrix`.

    The 10×10 triangular factor of D's QR decomposition (Lu 2017, eq. 23) up to
    :attr:`MLProblem.SX_LIMIT` poses; beyond, a factor of the Gram matrix ``DᵀD`` from its
    eigendecomposition (same singular vectors, 20x cheaper than QR for 10⁶ poses).  ``u`` is
    (n, 3) or a stack (K, n, 3).
    """
    from optcal.families.accel.ellipsoid import design_matrix

    D = design_matrix(u)
    if D.shape[-2] <= MLProblem.SX_LIMIT:
        return np.asarray(np.linalg.qr(D, mode="r"))
    lam, V = np.linalg.eigh(np.swapaxes(D, -1, -2) @ D)
    return np.sqrt(np.clip(lam, 0.0, None))[..., :, None] * np.swapaxes(V, -1, -2)


def convex_start(u: NDArray, eps: float, R: NDArray | None = None) -> NDArray[np.float64]:
    """The convex algebraic fit's θ in normalised coordinates where its constraint is inactive; NaN elsewhere.

    The quadric of ``min ‖Rη‖²`` s.t. ``tr A = 3`` (the KKT solution of
    :func:`optcal.families.accel.ellipsoid.kkt_polish`, R of :func:`design_factor`) *is* the
    convex fit's answer whenever the semidefinite constraint ``A ⪰ εI`` is inactive, i.e. its A
    clears ``2ε``; accepted when it is also a real ellipsoid (Lu 2017, eq. 19-21, 27-30).  ``u``
    is (n, 3) or a stack (K, n, 3); the result (9,) or (K, 9).
    """
    from optcal.families.accel.ellipsoid import kkt_polish, quadric_to_calibrations, unpack_quadric

    eta = kkt_polish(design_factor(u) if R is None else R)
    inactive = np.linalg.eigvalsh(unpack_quadric(eta)[0])[..., 0] >= 2 * eps
    T, o, _, _ = quadric_to_calibrations(eta)
    return np.where(inactive[..., None], theta_from(T, o), np.nan)


def _bounds_vectors(
    constraints: ParameterConstraints, scale_range: tuple[float, float] | None
) -> tuple[NDArray, NDArray] | None:
    """Bounds on θ (raw units) from the θ entries fixed or bounded and a scale-factor range."""
    theta_named = [n for n in (*constraints.fixed, *constraints.bounds) if n not in PHYSICAL_NAMES]
    if not theta_named and scale_range is None:
        return None
    lb = np.full(9, -np.inf)
    ub = np.full(9, np.inf)
    # a positive diagonal of T is part of the canonical form
    lb[[0, 2, 5]] = 0.0
    if scale_range is not None:
        lo, hi = map(float, scale_range)
        if not 0 < lo < hi:
            raise InputError("scale_range must be (low, high) with 0 < low < high, in raw units per g")
        for k in (0, 2, 5):  # diag(T) = 1/diag(C); diag(C) ≈ scale for small non-orthogonality
            lb[k], ub[k] = 1.0 / hi, 1.0 / lo
    user_lb, user_ub = constraints.theta_bounds()
    for k in range(9):
        if np.isfinite(user_lb[k]) or np.isfinite(user_ub[k]):
            lo, hi = user_lb[k], user_ub[k]
            lb[k], ub[k] = max(lb[k], lo), min(ub[k], hi)
            if lb[k] > ub[k]:
                raise InputError(f"empty bounds for θ entry {k + 1}: low {lo} > high {hi} (with the positive "
                                 "diagonal of T and scale_range)")
    return lb, ub


@dataclass(frozen=True)
class MLSetup:
    """The maximum-likelihood problem at its start (:meth:`MaximumLikelihood.setup`).

    ``u`` the normalised data, ``theta_n`` the start in normalised coordinates, the bounds on it
    (``lbx``, ``ubx``) and on the constrained ``physical`` parameters (``lbg``, ``ubg``, scale
    factors in normalised units), the robust loss's residual scale when no noise is given.
    """

    norm: Normaliser
    u: NDArray[np.float64]
    theta_n: NDArray[np.float64]
    init_method: str
    lbx: NDArray | None
    ubx: NDArray | None
    lbg: NDArray | None
    ubg: NDArray | None
    physical: tuple[str, ...]
    residual_scale: float | None


class MaximumLikelihood:
    """Maximum-likelihood calibration (Lu 2017, eq. 13-14) by IPOPT in CasADi.

    Parameters
    ----------
    init : {"convex", "svd"} or CalibrationResult
        Starting point: an algebraic ellipsoid fit (Lu 2017, section 2.2) or a given result.
    weighting : {"propagated", "paper"}
        Weights when per-pose noise is known (see :func:`optcal.families.accel.base.pose_weights`).
    loss : {"squared", "huber", "cauchy"}
        ``squared`` is maximum likelihood under Gaussian noise; the robust losses
        down-weight poses that do not fit (corrupt or non-static poses).
    loss_scale : float, optional
        Scale of the robust loss in standard deviations (1.345 Huber, 2.385 Cauchy).
    bounds : dict, optional
        ``{"T_xx": (low, high), "o_z": (low, high), "S_x": (low, high), "rho": (low, high), ...}``: θ
        entries and physical parameters (scale factors in raw units per g, angles in degrees; see
        :mod:`optcal.core.constraints`); ``±inf`` for a one-sided bound.
    fix : dict, optional
        ``{"o_x": value, "S_y": value, ...}``: parameters held at a known value (zero standard
        error; the covariance is computed on the free subspace).
    scale_range : (float, float), optional
        Known range of the scale factors (raw units per g), applied to the diagonal of T.
    reweight : int
        At most this many extra passes recomputing the propagated weights at the new
        estimate; the passes stop as soon as no weight changes by more than
        ``reweight_rtol`` (relative), i.e. when the weights are consistent with the estimate.
    reweight_rtol : float
        Relative weight change below which the weights count as settled.  A relative change
        ε of the weights moves θ by about ε standard errors, so 1e-3 is far below noise (and
        usually saves the third IPOPT pass).
    allow_degenerate : bool
        Proceed (with a warning) when the poses do not identify every parameter.
    ipopt_options : dict, optional
        Extra CasADi/IPOPT options (``{"ipopt.tol": 1e-9}``, on the scaled cost of
        :func:`optcal.solvers.nlp.cost_scale`); options IPOPT refuses are an :class:`InputError`.
    solver : str, optional
        The NLP solver by name (:data:`optcal.solvers.registry.NLP_SOLVERS`: ``"ipopt"``,
        ``"sqpmethod"``, ``"sqpmethod+osqp"``, ``"fatrop"``, ``"uno"``, ...); one that does not run
        here is an :class:`InputError` naming those that do.
    solver_options : dict, optional
        CasADi options of that solver (on top of its defaults and of ``ipopt_options``).
    conic_solver : str, optional
        The cvxpy solver of the convex start when its semidefinite constraint is active
        (:class:`~optcal.families.accel.ellipsoid.ConvexEllipsoidFit`'s ``solver``).
    keep_physical : bool
        Keep the refinement only inside the accelerometer's physical set around its start
        (:func:`optcal.families.accel.physical.physical_departure`); outside it the start is returned, with a note
        and ``extra["physical_set"]`` saying why.  Off when the user fixes or bounds a parameter or gives
        ``scale_range`` (the user's constraints are the set then).  Off by default: the magnetometer's refinement
        (:mod:`optcal.families.mag.refine`) judges the unguarded fit by its own set.
    """

    name = "mle"

    def __init__(
        self,
        init: Any = "convex",
        weighting: str = "propagated",
        loss: str = "squared",
        loss_scale: float | None = None,
        bounds: dict[str, tuple[float, float]] | None = None,
        scale_range: tuple[float, float] | None = None,
        reweight: int = 2,
        reweight_rtol: float = 1e-3,
        allow_degenerate: bool = False,
        ipopt_options: dict[str, Any] | None = None,
        solver: str | None = None,
        solver_options: dict[str, Any] | None = None,
        fix: dict[str, float] | None = None,
        conic_solver: str | None = None,
        keep_physical: bool = False,
    ) -> None:
        if loss not in LOSSES:
            raise InputError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")
        if not (isinstance(init, CalibrationResult) or init in ("convex", "svd")):
            raise InputError("init must be 'convex', 'svd' or a CalibrationResult")
        self.init = init
        self.weighting = weighting
        self.loss = loss
        self.loss_scale = DEFAULT_LOSS_SCALE[loss] if loss_scale is None else float(loss_scale)
        self.bounds = bounds
        self.scale_range = scale_range
        self.reweight = int(reweight)
        self.reweight_rtol = float(reweight_rtol)
        self.allow_degenerate = allow_degenerate
        self.ipopt_options = dict(ipopt_options or {})
        self.constraints = ParameterConstraints.of(fix, bounds)
        self.conic_solver = None if conic_solver is None else choose_conic_solver(conic_solver)
        self.keep_physical = bool(keep_physical)
        self.choice = choose_nlp_solver(solver, {**self.ipopt_options, **dict(solver_options or {})},
                                        constraints=bool(self.constraints.physical),
                                        problem="the maximum-likelihood fit with constrained physical parameters")

    def initial(self, poses: PoseTable) -> CalibrationResult:
        """The starting point (an algebraic fit), falling back to ``convex`` if ``svd`` fails."""
        from optcal.families.accel.ellipsoid import ConvexEllipsoidFit, SVDEllipsoidFit

        if isinstance(self.init, CalibrationResult):
            return self.init
        if self.init == "svd":
            try:
                return SVDEllipsoidFit(allow_degenerate=True).fit(poses)
            except FitError:
                pass
        return ConvexEllipsoidFit(solver=self.conic_solver or "CLARABEL", allow_degenerate=True).fit(poses)

    def initial_normalised(self, poses: PoseTable, norm: Normaliser, u: NDArray) -> tuple[NDArray[np.float64], str]:
        """The starting θ in normalised coordinates and the name of the fit that gave it.

        The same algebraic fits as :meth:`initial`, without assembling a result: ``svd`` from
        the triangular factor of the design matrix (:func:`design_factor`), ``convex`` from
        :func:`convex_start` whenever the semidefinite constraint is inactive (otherwise the
        cvxpy problem is solved).
        """
        from optcal.families.accel.ellipsoid import ConvexEllipsoidFit, quadric_to_calibration

        if isinstance(self.init, CalibrationResult):
            # θ of the result's calibration (a sixpos result's params are W and V, not θ)
            return norm.theta_to_normalised(self.init.calibration.lumped().theta), self.init.method
        R = design_factor(u)
        if self.init == "svd":
            try:
                T_n, o_n = quadric_to_calibration(np.linalg.svd(R)[2][-1])  # Lu 2017, eq. 24-30
                return theta_from(T_n, o_n), "svd"
            except FitError:
                pass
        convex = ConvexEllipsoidFit(solver=self.conic_solver or "CLARABEL", allow_degenerate=True)
        theta_n = convex_start(u, convex.eps, R)
        if np.all(np.isfinite(theta_n)):
            return theta_n, "convex"
        return norm.theta_to_normalised(convex.fit(poses).params[:9]), "convex"

    def weights(self, poses: PoseTable, norm: Normaliser, u: NDArray, theta_n: NDArray) -> NDArray[np.float64]:
        """:func:`~optcal.families.accel.base.pose_weights` at θ, the normal gain computed column-wise."""
        if poses.sigma is None or self.weighting != "propagated":
            T, o = unpack_theta(norm.theta_to_raw(theta_n))
            return pose_weights(poses, T, o, self.weighting)[0]
        gain = NormResidualCost(u, np.ones(poses.n)).normal_gain(theta_n) / norm.scale  # raw units
        return propagated_weights(poses.sigma, gain)

    def setup(self, poses: PoseTable) -> "MLSetup":
        """The problem at its start: normalised data, the starting θ, the bounds and the constrained physical parameters.

        Refuses (as :meth:`fit` does) a pose set that does not identify θ at the start.
        """
        poses.validate()
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        theta_n, init_method = self.initial_normalised(poses, norm, u)
        constraints = self.constraints
        if not constraints.fixed:  # a fixed parameter may be what makes the pose set determine θ: finish() judges
            check_pose_set(poses, norm.theta_to_raw(theta_n), self.weighting, self.allow_degenerate)
        raw_bounds = _bounds_vectors(constraints, self.scale_range)
        lbx = ubx = None
        if raw_bounds is not None:
            lo_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[0]), raw_bounds[0], 0.0))
            hi_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[1]), raw_bounds[1], 0.0))
            lbx = np.where(np.isfinite(raw_bounds[0]), lo_n, -np.inf)
            ubx = np.where(np.isfinite(raw_bounds[1]), hi_n, np.inf)
            theta_n = np.clip(theta_n, lbx, ubx)
        physical = constraints.physical
        lbg = ubg = None
        if physical:  # scale factors in normalised units (S' = S/s); angles in degrees
            units = np.array([1.0 / float(norm.scale) if name.startswith("S_") else 1.0 for name in physical])
            lbg = np.array([constraints.range_of(name)[0] for name in physical]) * units
            ubg = np.array([constraints.range_of(name)[1] for name in physical]) * units
        residual_scale = None
        if poses.sigma is None and self.loss != "squared":
            # no noise given: standardise by a robust scale of the starting point's residuals
            start_r = NormResidualCost(u, np.ones(poses.n)).residuals(theta_n)
            residual_scale = max(1.4826 * float(np.median(np.abs(start_r))), 1e-12)
        return MLSetup(norm, u, theta_n, init_method, lbx, ubx, lbg, ubg, physical, residual_scale)

    def pass_data(self, poses: PoseTable, setup: "MLSetup", theta_n: NDArray) -> tuple[NDArray, NDArray, float]:
        """The weights at ``theta_n``, the same scaled to mean one (what the NLP sees) and the robust loss's threshold."""
        w = self.weights(poses, setup.norm, setup.u, theta_n)
        w_n = w / np.mean(w, axis=-1, keepdims=True)  # scale-free weights: same optimum, better-scaled NLP
        # threshold of the robust loss on the residuals as weighted by w_n
        delta_n = self.loss_scale * (setup.residual_scale if setup.residual_scale else 1.0 / np.sqrt(np.mean(w)))
        return w, w_n, float(delta_n)

    def fit(self, poses: PoseTable) -> CalibrationResult:
        setup = self.setup(poses)
        norm, u, theta_n, init_method = setup.norm, setup.u, setup.theta_n, setup.init_method
        lbx, ubx, lbg, ubg, physical = setup.lbx, setup.ubx, setup.lbg, setup.ubg, setup.physical
        constraints = self.constraints
        residual_scale = setup.residual_scale
        problem = MLProblem.get(poses.n, self.loss, solver=self.choice, physical=physical)
        stats: dict[str, Any] = {}
        total_iter, total_time, passes = 0, 0.0, 0
        w_used: NDArray | None = None
        for _ in range(1 + max(self.reweight, 0)):
            w, w_n, delta_n = self.pass_data(poses, setup, theta_n)
            if weights_settled(w, w_used, self.reweight_rtol):
                break  # the weights are consistent with the estimate
            with Stopwatch() as sw:
                theta_n, stats = problem.solve(theta_n, u, w_n, delta_n, lbx, ubx, lbg, ubg)
            total_iter += plugin_iterations(stats)
            total_time += sw.seconds
            passes += 1
            w_used = w
        theta = norm.theta_to_raw(theta_n)
        raw_bounds = _bounds_vectors(constraints, self.scale_range)
        if raw_bounds is not None:  # the bounds hold exactly, also after the normalisation's rounding
            theta = np.clip(theta, *raw_bounds)
        notes: list[str] = []
        extra: dict[str, Any] = {"init": init_method, "loss": self.loss, "passes": passes}
        if self.loss != "squared":
            T, o = unpack_theta(theta)
            w, _ = pose_weights(poses, T, o, self.weighting)
            r = norm_residuals(T, o, poses.acc)
            z = r * np.sqrt(w) if residual_scale is None else r / residual_scale
            robust_w = 0.5 * robust_loss_terms(z, self.loss, self.loss_scale)[2]  # ψ(z)/(2z), 1 inside
            down = np.flatnonzero(robust_w < 0.5)
            extra["robust_weights"] = robust_w.tolist()
            extra["downweighted_rows"] = [int(r) for r in poses.rows[down]]
            if down.size:
                notes.append(
                    f"{down.size} pose(s) down-weighted below 0.5 by the {self.loss} loss "
                    f"({'poses' if poses.source == 'raw recording' else 'file rows'} "
                    f"{', '.join(str(int(r)) for r in poses.rows[down][:20])}{' ...' if down.size > 20 else ''})"
                )
        form = "SX, exact Hessian" if isinstance(problem, MLProblem) else "numpy callbacks, Gauss-Newton Hessian"
        extra["solver_options"] = self.choice.user_option_dict()
        solver = solver_record(stats, total_time, self.choice.label,
                               f"CasADi nlpsol {self.choice.plugin} ({form}), {self.loss} loss, {passes} pass(es)",
                               iterations=total_iter)
        method = self.name
        if self.keep_physical and not constraints and self.scale_range is None:
            theta, method, solver = self._kept_physical(theta, norm.theta_to_raw(setup.theta_n), init_method, solver,
                                                        notes, extra)
        return finish(
            method=method,
            poses=poses,
            theta=theta,
            solver=solver,
            weighting=self.weighting,
            allow_degenerate=self.allow_degenerate,
            notes=notes,
            extra=extra,
            remedy=IPOPT_REMEDY if self.choice.name == "ipopt" else SOLVER_REMEDY,
            constraints=constraints if constraints else None,
        )

    def _kept_physical(self, theta: NDArray, start: NDArray, init_method: str, solver: SolverInfo, notes: list[str],
                       extra: dict[str, Any]) -> tuple[NDArray, str, SolverInfo]:
        """θ, method and solver record to report: the refinement's where it stays in the physical set
        (:func:`optcal.families.accel.physical.physical_departure`), else the start's, with the note and
        ``extra["physical_set"]`` (appended to ``notes``, set in ``extra``) that say why.  A failed or non-finite
        solve is left to :func:`optcal.families.accel.base.finish` (it raises as before)."""
        from optcal.families.accel.physical import physical_departure

        if solver.status in SOLVER_FAILURES or not np.all(np.isfinite(theta)):
            return theta, self.name, solver
        departure = physical_departure(theta, start)
        if departure is None:
            return theta, self.name, solver
        extra["physical_set"] = {**departure.to_dict(), "kept": init_method, "refinement_status": solver.status}
        notes.append(
            f"MAXIMUM LIKELIHOOD NOT KEPT: the refinement left the physical set ({departure.reason}; {solver.name} "
            f"ended {solver.status!r}): the likelihood fell by growing the ellipsoid along a direction the poses do not "
            f"cover, so the {init_method} start is kept (--method {init_method} gives it directly; --bound "
            f"NAME=LOW:HIGH or --scale-range LOW HIGH sets the set yourself and keeps the refinement inside it)")
        kept = SolverInfo(f"the {init_method} start (the refinement left the physical set)", "start kept", True, 0,
                          solver.solve_time_s, f"refinement: {solver.name} {solver.status}, {solver.iterations} "
                          f"iterations; {solver.message}")
        return start, init_method, kept

