"""Maximum-likelihood calibration as IPOPT nonlinear least squares in CasADi (Lu 2017, eq. 13-14).

Model, problem and solver are built in separate steps (as in CasADi's ``sysid.py`` example):

1. :func:`optcal.core.norm_residual.casadi_norm_residual` — the per-pose norm residual
   ``r_k = ‖T(a_k − o)‖ − 1`` (eq. 13) as a CasADi ``Function`` of θ and one measurement.
2. The NLP ``min_θ c Σ_k ρ(√w_k r_k)`` (eq. 14 for the squared loss ρ(z) = z²) over the nine
   identifiable parameters (T lower-triangular, o), with the measurements, weights, loss
   scale and cost scale ``c`` (:func:`cost_scale`) as data, in one of two forms, both solved by
   IPOPT through ``nlpsol``:

   * :class:`MLProblem` (up to :attr:`MLProblem.SX_LIMIT` poses): the cost mapped over n poses
     and expanded into one SX graph with the exact Hessian; built once per (n, loss, options)
     and kept in :data:`ML_PROBLEMS` (:func:`optcal.solvers.cache.problem_cache`).
   * :class:`VectorisedMLProblem` (more poses): cost, gradient and Gauss–Newton Hessian
     evaluated in numpy (:class:`NormResidualCost`) and handed to IPOPT as CasADi callbacks,
     built per solve in milliseconds whatever n (10⁶ poses in about a second).
3. :class:`MaximumLikelihood` — the estimator: starting point from an algebraic fit
   (``convex`` by default, eq. 18-30), weights ``1/σ_r,k²`` when per-pose noise is known
   (re-propagated until they settle), optional robust loss (Huber, Cauchy) and bounds on
   named parameters (for example a known scale range), covariance from the Fisher information.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, InputError, SolverError
from optcal.families.accel.base import Normaliser, Remedy, Stopwatch, check_pose_set, finish, pose_weights
from optcal.core.model import PARAM_NAMES, theta_from, unpack_theta
from optcal.core.norm_residual import NormResidualKernel, NormResidualPoint, casadi_norm_residual, norm_residuals
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, freeze_options, problem_cache
from optcal.core.fit_result import SolverInfo
from optcal.families.accel.result import CalibrationResult

LOSSES = ("squared", "huber", "cauchy")
#: Default loss scales (in standard deviations): 95 % efficiency at the Gaussian.
DEFAULT_LOSS_SCALE = {"squared": 1.0, "huber": 1.345, "cauchy": 2.385}
#: What to change when IPOPT stops early or fails (the ML problems of this module and of ``exact``).
IPOPT_REMEDY = Remedy(
    stopped_early="raise the iteration limit (ipopt_options={'ipopt.max_iter': 1000}) or start from another fit (init=...)",
    failed='check ipopt_options, or use method="convex"',
)
#: IPOPT options used unless overridden.
IPOPT_DEFAULTS: dict[str, Any] = {
    "ipopt.print_level": 0,
    "ipopt.sb": "yes",
    "print_time": False,
    "ipopt.tol": 1e-12,
    "ipopt.acceptable_tol": 1e-9,
    "ipopt.max_iter": 200,
    "ipopt.mu_strategy": "adaptive",
}


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

    The residuals and their Jacobian come from :class:`optcal.core.norm_residual.NormResidualKernel`
    (column by column, T lower-triangular).  The kernel's evaluation at the last θ is kept:
    IPOPT asks for the cost, the gradient and the Hessian at the same point.  One instance
    serves one solve (it is never shared between threads).
    """

    def __init__(self, u: NDArray, w: NDArray, loss: str = "squared", delta: float = 1.0, scale: float = 1.0) -> None:
        self.kernel = NormResidualKernel(u)
        self.w = np.asarray(w, dtype=float)
        self.sqrt_w = np.sqrt(self.w)
        self.loss, self.delta, self.scale = loss, float(delta), float(scale)
        self._x: NDArray | None = None
        self._point: NormResidualPoint | None = None
        self._J: NDArray | None = None

    def _at(self, x: NDArray) -> NormResidualPoint:
        x = np.asarray(x, dtype=float).ravel()
        if self._point is None or self._x is None or not np.array_equal(x, self._x):
            self._x, self._point, self._J = x.copy(), self.kernel.at_theta(x), None
        return self._point

    def residuals(self, x: NDArray) -> NDArray[np.float64]:
        """``r_k = ‖T(u_k − o)‖ − 1`` (Lu 2017, eq. 13)."""
        return self._at(x).residuals

    def jacobian(self, x: NDArray) -> NDArray[np.float64]:
        """``∂r_k/∂θ`` as a (9, n) array (one row per parameter; Lu 2017, eq. 15-16)."""
        point = self._at(x)
        if self._J is None:
            self._J = point.jacobian()
        return self._J

    def normal_gain(self, x: NDArray) -> NDArray[np.float64]:
        """``‖Tᵀ ā_k‖`` in normalised units (see :func:`optcal.core.norm_residual.normal_gain`)."""
        return self._at(x).normal_gain()

    def value(self, x: NDArray) -> float:
        rho, _, _ = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        return self.scale * float(np.sum(rho))

    def gradient(self, x: NDArray) -> tuple[float, NDArray[np.float64]]:
        J = self.jacobian(x)
        rho, drho, _ = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        return self.scale * float(np.sum(rho)), self.scale * (J @ (drho * self.sqrt_w))

    def gauss_newton_hessian(self, x: NDArray) -> NDArray[np.float64]:
        """``c Σ_k ρ'(z_k)/z_k · w_k ∇r_k ∇r_kᵀ`` (``2 c JᵀWJ`` for the squared loss)."""
        J = self.jacobian(x)
        _, _, irls = robust_loss_terms(self.sqrt_w * self.residuals(x), self.loss, self.delta)
        Js = J * np.sqrt(irls * self.w)
        return self.scale * (Js @ Js.T)


#: Floor of the residual scale in :func:`cost_scale` (normalised units, ≈ g): 10 ng per g, far
#: below the noise of any accelerometer and far above rounding (≈ 1e-16).
MIN_RESIDUAL_RMS: float = 1e-8


def cost_scale(n: int, start_rms: float) -> float:
    """Factor ``c = 1/(n s₀)`` applied to the cost Σ ρ (``s₀`` the rms standardised residual at the start).

    IPOPT stops on the absolute size of the gradient, while the cost can only resolve a
    decrease of about ``eps·f``: with the raw cost a tolerance is either too loose for small
    residuals or out of floating-point reach for large ones (IPOPT then backtracks for tens of
    iterations on a solution that is already exact).  With ``f ≈ n s²`` and a Hessian
    ``≈ 2n``·O(1), scaling by ``1/(n s₀)`` makes ``f·λ(H)`` of order one whatever n, noise or
    units, so one tolerance (:data:`ML_IPOPT_DEFAULTS`) sits just above the rounding floor and
    leaves the parameters within ~1e-7·√n standard errors of the exact optimum.  ``s₀`` is
    floored at :data:`MIN_RESIDUAL_RMS` so that noise-free data (residuals at rounding level)
    are not scaled up into a spurious gradient.
    """
    return 1.0 / (n * max(float(start_rms), MIN_RESIDUAL_RMS))


#: IPOPT options of the ML problems: :data:`IPOPT_DEFAULTS` with the tolerance on the scaled
#: cost of :func:`cost_scale`.  That scaling keeps the gradient at the start of order one, below
#: IPOPT's gradient-based scaling threshold (100), so that step is switched off (it would only
#: cost a gradient evaluation); the multipliers of the parameters are not needed.
ML_IPOPT_DEFAULTS: dict[str, Any] = {
    **IPOPT_DEFAULTS,
    "ipopt.tol": 1e-10,
    "ipopt.acceptable_tol": 1e-5,
    "ipopt.acceptable_iter": 3,
    "ipopt.nlp_scaling_method": "none",
    "calc_lam_p": False,
}


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
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``theta0`` for normalised data ``u`` (n, 3) and weights ``w`` (n,); θ and IPOPT's statistics."""
        cost = NormResidualCost(u, w, self.loss, delta)
        cost.scale = cost_scale(len(u), np.sqrt(cost.value(theta0) / len(u)))
        args: dict[str, Any] = {"x0": theta0}
        if lbx is not None:
            args["lbx"] = lbx
        if ubx is not None:
            args["ubx"] = ubx
        return self._solve(cost, args)

    @abstractmethod
    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Run IPOPT on ``cost`` with the start and bounds in ``args``."""


class MLProblem(_MLSolve):
    """The NLP ``min_θ c Σ ρ(√w_k r_k(θ))`` for n poses, data as parameters (built once).

    The cost is expanded into one CasADi SX graph with the exact Hessian (fastest
    derivatives for small and moderate n).  Building it takes about 0.4 ms per pose, so
    beyond :attr:`SX_LIMIT` poses :meth:`get` returns a :class:`VectorisedMLProblem` instead.
    ``c`` is the scale of :func:`cost_scale`, a parameter like the data.
    """

    SX_LIMIT = 200

    def __init__(self, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None) -> None:
        import casadi as ca

        self.n, self.loss = n, loss
        r = casadi_norm_residual()
        x = ca.SX.sym("theta", 9)
        data = ca.SX.sym("a", 3, n)
        w = ca.SX.sym("w", 1, n)
        delta = ca.SX.sym("delta")
        scale = ca.SX.sym("scale")
        res = (r.map(n) if n > 1 else r)(x, data)  # 1 x n
        cost = scale * ca.sum2(robust_loss(res * ca.sqrt(w), loss, delta))
        p = ca.vertcat(ca.vec(data), ca.vec(w), delta, scale)
        opts = {**ML_IPOPT_DEFAULTS, **(ipopt_options or {})}
        self.solver = ipopt_nlpsol("ml_calibration", {"x": x, "p": p, "f": cost}, opts)
        self._lock = threading.Lock()

    @classmethod
    def get(cls, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None) -> "MLProblem | VectorisedMLProblem":
        """The problem for n poses: the SX problem up to :attr:`SX_LIMIT` poses, built once and
        kept in :data:`ML_PROBLEMS`; beyond, a :class:`VectorisedMLProblem` (nothing to keep)."""
        if n > cls.SX_LIMIT:
            return VectorisedMLProblem(loss, ipopt_options)
        return ML_PROBLEMS.get(n, loss, freeze_options(ipopt_options))

    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        u = cost.kernel.data.T  # (n, 3): vec() is column-major, so p holds a_1, a_2, ... stacked
        p = np.concatenate([u.ravel(), cost.w, [cost.delta, cost.scale]])
        with self._lock:  # the solver keeps the statistics of its last call
            return run_nlpsol(self.solver, p=p, **args)


def numpy_callback(
    name: str,
    inputs: list[tuple[str, Any]],
    outputs: list[tuple[str, Any]],
    evaluate: Callable[[list], list],
    reverse: Callable[[str, list, list, dict], Any] | None = None,
    nonzeros: bool = False,
) -> Any:
    """A CasADi ``Callback`` evaluated in Python.

    ``inputs`` and ``outputs`` are ``(name, sparsity)`` pairs; ``evaluate`` maps the list of
    input values to the list of outputs; ``reverse(name, inames, onames, opts)``, if given,
    returns the Function of the first-order reverse derivative.  With ``nonzeros``, the
    values are exchanged through CasADi's buffers (``eval_buffer``) instead of ``DM`` s:
    ``evaluate`` receives each input's nonzeros as a float array (a view, valid during the
    call) and returns each output's nonzeros (arrays or floats, in the output sparsity's
    order), which are copied into CasADi's memory; no element-wise conversion, which for
    thousands of values costs more than the numpy work itself.
    """
    import casadi as ca

    class NumpyCallback(ca.Callback):
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self) -> int:
            return len(inputs)

        def get_n_out(self) -> int:
            return len(outputs)

        def get_name_in(self, i: int) -> str:
            return inputs[i][0]

        def get_name_out(self, i: int) -> str:
            return outputs[i][0]

        def get_sparsity_in(self, i: int) -> Any:
            return inputs[i][1]

        def get_sparsity_out(self, i: int) -> Any:
            return outputs[i][1]

        def eval(self, arg: list) -> list:
            return evaluate(arg)

        def has_eval_buffer(self) -> bool:
            return nonzeros

        def eval_buffer(self, arg: list, res: list) -> int:
            # an absent buffer: an input without nonzeros, or an output the caller does not need
            values = evaluate([np.empty(0) if a is None else np.frombuffer(a, dtype=np.float64) for a in arg])
            for buffer, value in zip(res, values):
                if buffer is not None:
                    np.frombuffer(buffer, dtype=np.float64)[:] = value
            return 0

        def has_reverse(self, nadj: int) -> bool:
            return reverse is not None and nadj == 1

        def get_reverse(self, nadj: int, fname: str, inames: list, onames: list, opts: dict) -> Any:
            assert reverse is not None
            return reverse(fname, inames, onames, opts)

    return NumpyCallback()


class VectorisedMLProblem(_MLSolve):
    """The same NLP for any n, still solved by IPOPT in CasADi, with numpy doing the sums.

    The cost, its gradient and the Gauss–Newton Hessian (IRLS curvature for the robust
    losses, :func:`robust_loss_terms`) of a :class:`NormResidualCost` are CasADi
    ``Callback`` s handed to ``nlpsol`` (the gradient as the cost's reverse derivative and
    as ``grad_f``, the Hessian as ``hess_lag``).  Nothing depends on n, and building the
    callbacks and the NLP takes a few milliseconds, so each :meth:`solve` builds its own,
    bound to that solve's data: the object holds only the loss and the options, and any
    number of threads can solve with it at once.  One IPOPT iteration on 10⁶ poses costs a
    few dozen vector operations.
    """

    def __init__(self, loss: str = "squared", ipopt_options: dict[str, Any] | None = None) -> None:
        self.loss = loss
        self.ipopt_options = dict(ipopt_options or {})

    def _solver(self, cost: NormResidualCost) -> tuple[Any, list[Any]]:
        """The NLP of ``cost`` and the callbacks it calls (kept alive by the caller during the solve)."""
        import casadi as ca

        dense9 = ca.Sparsity.dense(9, 1)
        scalar = ca.Sparsity.dense(1, 1)
        empty = ca.Sparsity(0, 1)

        def theta(arg: list) -> NDArray:
            return np.asarray(arg[0]).ravel()

        gradient = numpy_callback(
            "ml_grad_f", [("x", dense9), ("p", empty)], [("f", scalar), ("grad_f", dense9)],
            lambda arg: list(cost.gradient(theta(arg))),
        )

        def cost_reverse(name: str, inames: list, onames: list, opts: dict) -> Any:
            x, out, adj = ca.MX.sym("x", 9), ca.MX.sym("f", 1), ca.MX.sym("adj", 1)
            _, g = gradient(x, ca.MX(0, 1))
            return ca.Function(name, [x, out, adj], [adj * g], inames, onames, opts)

        value = numpy_callback(
            "ml_f", [("x", dense9)], [("f", scalar)], lambda arg: [cost.value(theta(arg))], reverse=cost_reverse
        )
        hessian = numpy_callback(
            "ml_hess_lag",
            [("x", dense9), ("p", empty), ("lam_f", scalar), ("lam_g", empty)],
            [("triu_hess_gamma_x_x", ca.Sparsity.upper(9))],
            lambda arg: [ca.triu(ca.DM(cost.gauss_newton_hessian(theta(arg)) * float(arg[2])))],
        )
        x = ca.MX.sym("theta", 9)
        opts = {**ML_IPOPT_DEFAULTS, "grad_f": gradient, "hess_lag": hessian, **self.ipopt_options}
        solver = ipopt_nlpsol("ml_calibration_vectorised", {"x": x, "f": value(x)}, opts)
        return solver, [gradient, value, hessian]

    def _solve(self, cost: NormResidualCost, args: dict[str, Any]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        solver, callbacks = self._solver(cost)
        result = run_nlpsol(solver, **args)
        del callbacks  # only now may the callbacks go
        return result


def ipopt_nlpsol(name: str, nlp: dict[str, Any], options: dict[str, Any]) -> Any:
    """``casadi.nlpsol(name, "ipopt", nlp, options)``; options CasADi or IPOPT refuse are an :class:`InputError`."""
    import casadi as ca

    try:
        return ca.nlpsol(name, "ipopt", nlp, options)
    except RuntimeError as exc:
        reason = str(exc).strip().splitlines()[-1].split(": ")[-1]  # CasADi's last line says why
        raise InputError(f"IPOPT refused the options ({reason}); check ipopt_options") from exc


def run_nlpsol(solver: Any, **args: Any) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Call a CasADi ``nlpsol`` and read its statistics; an exception inside the solver is a :class:`SolverError`."""
    try:
        sol = solver(**args)
    except RuntimeError as exc:
        reason = str(exc).strip().splitlines()[-1]
        raise SolverError(f"IPOPT raised an error in {solver.name()}: {reason}") from exc
    return np.asarray(sol["x"]).ravel(), solver.stats()


#: The SX problems of :class:`MLProblem`, keyed by (n, loss, frozen IPOPT options).
ML_PROBLEMS: ProblemCache[MLProblem] = problem_cache(
    lambda n, loss, options: MLProblem(n, loss, dict(options)), maxsize=32
)


def _bounds_vectors(
    bounds: dict[str, tuple[float, float]] | None, scale_range: tuple[float, float] | None
) -> tuple[NDArray, NDArray] | None:
    """Bounds on θ (raw units) from named bounds and a scale-factor range."""
    if not bounds and scale_range is None:
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
    for name, (lo, hi) in (bounds or {}).items():
        if name not in PARAM_NAMES:
            raise InputError(f"unknown parameter {name!r} in bounds; use one of {', '.join(PARAM_NAMES)}")
        k = PARAM_NAMES.index(name)
        lb[k], ub[k] = max(lb[k], float(lo)), min(ub[k], float(hi))
        if lb[k] > ub[k]:
            raise InputError(f"empty bounds for {name}: low {lo} > high {hi}")
    return lb, ub


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
        ``{"T_xx": (low, high), "o_z": (low, high), ...}`` in raw units.
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
        :func:`cost_scale`).
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
        return ConvexEllipsoidFit(allow_degenerate=True).fit(poses)

    def initial_normalised(self, poses: PoseTable, norm: Normaliser, u: NDArray) -> tuple[NDArray[np.float64], str]:
        """The starting θ in normalised coordinates and the name of the fit that gave it.

        The same algebraic fits as :meth:`initial`, without assembling a result: the
        quadric comes from the 10×10 triangular factor ``R`` of the design matrix (eq. 23),
        whose right singular vectors are those of the design matrix (``svd``), and whose
        equality-constrained least-squares solution (``tr A = 3``) *is* the convex fit's
        answer whenever the semidefinite constraint is inactive (checked here; otherwise the
        cvxpy problem is solved).
        """
        from optcal.families.accel.ellipsoid import ConvexEllipsoidFit, design_matrix, quadric_to_calibration, unpack_quadric

        if isinstance(self.init, CalibrationResult):
            # θ of the result's calibration (a sixpos result's params are W and V, not θ)
            return norm.theta_to_normalised(self.init.calibration.lumped().theta), self.init.method
        D = design_matrix(u)
        if poses.n <= MLProblem.SX_LIMIT:
            R = np.linalg.qr(D, mode="r")
        else:  # a factor of the Gram matrix: same singular vectors, 20x cheaper than QR for 10⁶ poses
            lam, V = np.linalg.eigh(D.T @ D)
            R = np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T
        if self.init == "svd":
            try:
                T_n, o_n = quadric_to_calibration(np.linalg.svd(R)[2][-1])  # Lu 2017, eq. 24-30
                return theta_from(T_n, o_n), "svd"
            except FitError:
                pass
        convex = ConvexEllipsoidFit(allow_degenerate=True)
        eta = ConvexEllipsoidFit._kkt_polish(R)
        if np.linalg.eigvalsh(unpack_quadric(eta)[0])[0] >= 2 * convex.eps:
            try:
                T_n, o_n = quadric_to_calibration(eta)
                return theta_from(T_n, o_n), "convex"
            except FitError:
                pass
        return norm.theta_to_normalised(convex.fit(poses).params[:9]), "convex"

    def weights(self, poses: PoseTable, norm: Normaliser, u: NDArray, theta_n: NDArray) -> NDArray[np.float64]:
        """:func:`~optcal.families.accel.base.pose_weights` at θ, the normal gain computed column-wise."""
        if poses.sigma is None or self.weighting != "propagated":
            T, o = unpack_theta(norm.theta_to_raw(theta_n))
            return pose_weights(poses, T, o, self.weighting)[0]
        gain = NormResidualCost(u, np.ones(poses.n)).normal_gain(theta_n) / norm.scale  # raw units
        return 1.0 / (poses.sigma * gain) ** 2

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        theta_n, init_method = self.initial_normalised(poses, norm, u)
        check_pose_set(poses, norm.theta_to_raw(theta_n), self.weighting, self.allow_degenerate)
        raw_bounds = _bounds_vectors(self.bounds, self.scale_range)
        lbx = ubx = None
        if raw_bounds is not None:
            lo_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[0]), raw_bounds[0], 0.0))
            hi_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[1]), raw_bounds[1], 0.0))
            lbx = np.where(np.isfinite(raw_bounds[0]), lo_n, -np.inf)
            ubx = np.where(np.isfinite(raw_bounds[1]), hi_n, np.inf)
            theta_n = np.clip(theta_n, lbx, ubx)
        problem = MLProblem.get(poses.n, self.loss, self.ipopt_options)
        total_iter, total_time, passes = 0, 0.0, 0
        stats: dict[str, Any] = {}
        residual_scale = None
        if poses.sigma is None and self.loss != "squared":
            # no noise given: standardise by a robust scale of the starting point's residuals
            start_r = NormResidualCost(u, np.ones(poses.n)).residuals(theta_n)
            residual_scale = max(1.4826 * float(np.median(np.abs(start_r))), 1e-12)
        w_used: NDArray | None = None
        for _ in range(1 + max(self.reweight, 0)):
            w = self.weights(poses, norm, u, theta_n)
            if w_used is not None and np.max(np.abs(w / w_used - 1.0)) <= self.reweight_rtol:
                break  # the weights are consistent with the estimate
            w_n = w / np.mean(w)  # scale-free weights: same optimum, better-scaled NLP
            # threshold of the robust loss on the residuals as weighted by w_n
            delta_n = self.loss_scale * (residual_scale if residual_scale else 1.0 / np.sqrt(np.mean(w)))
            with Stopwatch() as sw:
                theta_n, stats = problem.solve(theta_n, u, w_n, delta_n, lbx, ubx)
            total_iter += int(stats.get("iter_count", 0))
            total_time += sw.seconds
            passes += 1
            w_used = w
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False))
        theta = norm.theta_to_raw(theta_n)
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
        solver = SolverInfo(
            "IPOPT", status, success, total_iter, total_time,
            f"CasADi nlpsol ({form}), {self.loss} loss, {passes} pass(es)",
        )
        return finish(
            method=self.name,
            poses=poses,
            theta=theta,
            solver=solver,
            weighting=self.weighting,
            allow_degenerate=self.allow_degenerate,
            notes=notes,
            extra=extra,
            remedy=IPOPT_REMEDY,
        )

