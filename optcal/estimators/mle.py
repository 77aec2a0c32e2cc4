"""Maximum-likelihood calibration as IPOPT nonlinear least squares in CasADi (Lu 2017, eq. 13-14).

Model, problem and solver are built in separate steps (as in CasADi's ``sysid.py`` example):

1. :func:`residual_function` — the per-pose norm residual ``r_k = ‖T(a_k − o)‖ − 1``
   (eq. 13) as a CasADi ``Function`` of θ and one measurement, with exact derivatives.
2. :class:`MLProblem` — the cost ``Σ_k ρ(√w_k r_k)`` (eq. 14 for the squared loss ρ(z) = z²)
   mapped over n poses, with the measurements, weights and loss scale as *parameters*;
   only the nine identifiable parameters are free (T lower-triangular, o).  Built once per
   (n, loss) and cached, then re-solved with new data: a Monte Carlo study builds nothing.
3. :class:`MaximumLikelihood` — the estimator: starting point from an algebraic fit
   (``convex`` by default, eq. 18-30), weights ``1/σ_r,k²`` when per-pose noise is known,
   optional robust loss (Huber, Cauchy) and bounds on named parameters (for example a known
   scale range), covariance from the Fisher information.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, InputError
from optcal.estimators.base import Normaliser, Stopwatch, finish, pose_weights
from optcal.model import PARAM_NAMES, unpack_theta
from optcal.poses import PoseTable
from optcal.result import CalibrationResult, SolverInfo

LOSSES = ("squared", "huber", "cauchy")
#: Default loss scales (in standard deviations): 95 % efficiency at the Gaussian.
DEFAULT_LOSS_SCALE = {"squared": 1.0, "huber": 1.345, "cauchy": 2.385}
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


def lower_triangular(x: Any) -> Any:
    """CasADi 3×3 lower-triangular matrix from the first six entries of θ."""
    import casadi as ca

    z = ca.DM(0) if isinstance(x, ca.DM) else 0
    return ca.vertcat(
        ca.horzcat(x[0], z, z),
        ca.horzcat(x[1], x[2], z),
        ca.horzcat(x[3], x[4], x[5]),
    )


def residual_function() -> Any:
    """``r(θ, a) = ‖T(a − o)‖ − 1`` (Lu 2017, eq. 13) as a CasADi Function."""
    import casadi as ca

    x = ca.SX.sym("theta", 9)
    a = ca.SX.sym("a", 3)
    v = ca.mtimes(lower_triangular(x), a - x[6:9])
    return ca.Function("norm_residual", [x, a], [ca.norm_2(v) - 1.0])


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


class MLProblem:
    """The NLP ``min_θ Σ ρ(√w_k r_k(θ))`` for n poses, data as parameters (built once).

    Up to :attr:`SX_LIMIT` poses the cost is expanded into one CasADi SX graph (fastest
    derivatives).  Beyond it, the per-pose residual is mapped over the poses (MX, evaluated
    on both cores) and, for the squared loss, IPOPT receives the Gauss–Newton Hessian
    ``2 Jᵀ W J`` through ``hess_lag`` (exact at a zero-residual optimum, and the standard choice
    for nonlinear least squares), which keeps each iteration linear in n with a small constant.
    """

    SX_LIMIT = 20_000
    _cache: dict[tuple[int, str, tuple[tuple[str, Any], ...]], "MLProblem"] = {}

    def __init__(self, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None) -> None:
        import casadi as ca

        self.n, self.loss = n, loss
        r = residual_function()
        opts = dict(IPOPT_DEFAULTS)
        large = n > self.SX_LIMIT
        sym = ca.MX if large else ca.SX
        x = sym.sym("theta", 9)
        data = sym.sym("a", 3, n)
        w = sym.sym("w", 1, n)
        delta = sym.sym("delta")
        mapped = (r.map(n, "thread", 2) if large else r.map(n)) if n > 1 else r
        res = mapped(x, data)  # 1 x n
        cost = ca.sum2(robust_loss(res * ca.sqrt(w), loss, delta))
        p = ca.vertcat(ca.vec(data), ca.vec(w), delta)
        if large and loss == "squared":
            lam_f = ca.MX.sym("lam_f")
            lam_g = ca.MX.sym("lam_g", 0, 1)
            J = ca.jacobian(res, x)  # n x 9, forward mode through the map
            H = 2 * lam_f * ca.mtimes(J.T, J * ca.repmat(w.T, 1, 9))
            opts["hess_lag"] = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [ca.triu(H)],
                                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        opts.update(ipopt_options or {})
        self.solver = ca.nlpsol("ml_calibration", "ipopt", {"x": x, "p": p, "f": cost}, opts)

    @classmethod
    def get(cls, n: int, loss: str = "squared", ipopt_options: dict[str, Any] | None = None) -> "MLProblem":
        key = (n, loss, tuple(sorted((ipopt_options or {}).items())))
        if key not in cls._cache:
            if len(cls._cache) > 32:
                cls._cache.clear()
            cls._cache[key] = cls(n, loss, ipopt_options)
        return cls._cache[key]

    def solve(
        self,
        theta0: NDArray,
        u: NDArray,
        w: NDArray,
        delta: float = 1.0,
        lbx: NDArray | None = None,
        ubx: NDArray | None = None,
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``theta0`` for normalised data ``u`` (n, 3) and weights ``w`` (n,)."""
        p = np.concatenate([u.ravel(), w, [delta]])  # vec() is column-major: a_k stacked
        args: dict[str, Any] = {"x0": theta0, "p": p}
        if lbx is not None:
            args["lbx"] = lbx
        if ubx is not None:
            args["ubx"] = ubx
        sol = self.solver(**args)
        return np.asarray(sol["x"]).ravel(), self.solver.stats()


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
        Weights when per-pose noise is known (see :func:`optcal.estimators.base.pose_weights`).
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
        Passes recomputing the propagated weights at the new estimate.
    allow_degenerate : bool
        Proceed (with a warning) when the poses do not identify every parameter.
    ipopt_options : dict, optional
        Extra CasADi/IPOPT options (``{"ipopt.tol": 1e-10}``).
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
        allow_degenerate: bool = False,
        ipopt_options: dict[str, Any] | None = None,
    ) -> None:
        if loss not in LOSSES:
            raise InputError(f"unknown loss {loss!r}; use one of {', '.join(LOSSES)}")
        self.init = init
        self.weighting = weighting
        self.loss = loss
        self.loss_scale = DEFAULT_LOSS_SCALE[loss] if loss_scale is None else float(loss_scale)
        self.bounds = bounds
        self.scale_range = scale_range
        self.reweight = int(reweight)
        self.allow_degenerate = allow_degenerate
        self.ipopt_options = dict(ipopt_options or {})

    def initial(self, poses: PoseTable) -> CalibrationResult:
        """The starting point (an algebraic fit), falling back to ``convex`` if ``svd`` fails."""
        from optcal.estimators.ellipsoid import ConvexEllipsoidFit, SVDEllipsoidFit

        if isinstance(self.init, CalibrationResult):
            return self.init
        if self.init == "svd":
            try:
                return SVDEllipsoidFit(allow_degenerate=True).fit(poses)
            except FitError:
                pass
        elif self.init != "convex":
            raise InputError("init must be 'convex', 'svd' or a CalibrationResult")
        return ConvexEllipsoidFit(allow_degenerate=True).fit(poses)

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        start = self.initial(poses)
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        theta_n = norm.theta_to_normalised(start.params[:9])
        raw_bounds = _bounds_vectors(self.bounds, self.scale_range)
        lbx = ubx = None
        if raw_bounds is not None:
            lo_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[0]), raw_bounds[0], 0.0))
            hi_n = norm.theta_to_normalised(np.where(np.isfinite(raw_bounds[1]), raw_bounds[1], 0.0))
            lbx = np.where(np.isfinite(raw_bounds[0]), lo_n, -np.inf)
            ubx = np.where(np.isfinite(raw_bounds[1]), hi_n, np.inf)
            theta_n = np.clip(theta_n, lbx, ubx)
        problem = MLProblem.get(poses.n, self.loss, self.ipopt_options)
        total_iter, total_time = 0, 0.0
        stats: dict[str, Any] = {}
        passes = 1 + (self.reweight if poses.sigma is not None and self.weighting == "propagated" else 0)
        residual_scale = None
        if poses.sigma is None and self.loss != "squared":
            # no noise given: standardise by a robust scale of the starting point's residuals
            residual_scale = max(1.4826 * float(np.median(np.abs(start.residuals))), 1e-12)
        for _ in range(passes):
            T, o = unpack_theta(norm.theta_to_raw(theta_n))
            w, _known = pose_weights(poses, T, o, self.weighting)
            w_n = w / np.mean(w)  # scale-free weights: same optimum, better-scaled NLP
            # threshold of the robust loss on the residuals as weighted by w_n
            delta_n = self.loss_scale * (residual_scale if residual_scale else 1.0 / np.sqrt(np.mean(w)))
            with Stopwatch() as sw:
                new, stats = problem.solve(theta_n, u, w_n, delta_n, lbx, ubx)
            total_iter += int(stats.get("iter_count", 0))
            total_time += sw.seconds
            step = float(np.max(np.abs(new - theta_n)))
            theta_n = new
            if step < 1e-12:
                break
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False))
        theta = norm.theta_to_raw(theta_n)
        notes = [] if success else [f"IPOPT did not report success: {status}"]
        extra: dict[str, Any] = {"init": start.method, "loss": self.loss}
        if self.loss != "squared":
            T, o = unpack_theta(theta)
            w, _ = pose_weights(poses, T, o, self.weighting)
            from optcal.identifiability import norm_residuals

            r = norm_residuals(T, o, poses.acc)
            z = r * np.sqrt(w) if residual_scale is None else r / residual_scale
            robust_w = _irls_weight(z, self.loss, self.loss_scale)
            down = np.flatnonzero(robust_w < 0.5)
            extra["robust_weights"] = robust_w.tolist()
            extra["downweighted_rows"] = [int(r) for r in poses.rows[down]]
            if down.size:
                notes.append(
                    f"{down.size} pose(s) down-weighted below 0.5 by the {self.loss} loss "
                    f"(rows {', '.join(str(int(r)) for r in poses.rows[down][:20])}{' ...' if down.size > 20 else ''})"
                )
        solver = SolverInfo("IPOPT", status, success, total_iter, total_time, f"CasADi nlpsol, {self.loss} loss")
        return finish(
            method=self.name,
            poses=poses,
            theta=theta,
            solver=solver,
            weighting=self.weighting,
            allow_degenerate=self.allow_degenerate,
            notes=notes,
            extra=extra,
        )


def _irls_weight(z: NDArray, loss: str, delta: float) -> NDArray[np.float64]:
    """IRLS weight ψ(z)/(2z) of a robust loss for standardised residuals ``z``."""
    az = np.abs(z)
    if loss == "huber":
        return np.where(az <= delta, 1.0, delta / np.maximum(az, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + (z / delta) ** 2)
    return np.ones_like(z)
