"""The extended fit as one CasADi/IPOPT problem: norm residuals with the model inverted inside.

Every term of :class:`~optcal.extended_model.ExtendedModel` is inverted in closed form per
axis (:func:`optcal.extended_model.invert_axis`), and the residual is Lu 2017's norm residual
of the recovered linear output, ``r = ‖T y(a)‖ − 1`` (eq. 13), weighted by
``1/(σ_k ‖Tᵀ ā_k‖)²``.  Why this and not the errors-in-variables problem with a latent
direction per pose (:mod:`optcal.estimators.exact`)?  Eliminating the latent unit direction
from eq. 8 leaves, to first order in the noise, exactly this weighted norm residual (the
distance of the measurement to the ellipsoid along its normal, :mod:`optcal.identifiability`);
the difference is of relative order σ² (≈1e-6 for mg noise), far below any effect worth
reporting.  The norm-residual problem has ``9 + P`` unknowns instead of ``9 + P + 3n``, so the
hundreds of re-solves of a bootstrap and a k-fold selection stay fast, and the held-out
residual of a pose (the model inverted at its own measurement) is the same formula.

:class:`ExtendedProblem` is built once per (n, loss) with *every* possible coefficient as a
variable and the data, weights, normalised temperature and time as parameters; an effect set
is chosen by fixing the unused coefficients to zero through the bounds (IPOPT then removes
them), so the bootstrap, the k-fold and the forward selection build nothing.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.diagnosis.regressors import Regressors
from optcal.extended_model import MAX_ORDER, PARAMETRIC, ExtendedModel, inverse_lower, invert_axis
from optcal.model import LumpedModel


def _beta_layout() -> dict[tuple[str, int, int], int]:
    index: dict[tuple[str, int, int], int] = {}
    for effect in PARAMETRIC:
        for axis in range(3):
            for order in range(1, MAX_ORDER[effect] + 1):
                index[(effect, axis, order)] = len(index)
    return index


#: (effect, axis number, order) → index of its coefficient in β (after the nine entries of θ).
BETA_INDEX: dict[tuple[str, int, int], int] = _beta_layout()
N_BETA: int = len(BETA_INDEX)
N_X: int = 9 + N_BETA


def extended_residual_function() -> Any:
    """``r(x, a, τ, s) = ‖T y(a)‖ − 1`` for one pose as a CasADi Function (normalised units).

    ``x = [θ (9), β (N_BETA)]``; the coefficients β multiply powers of the normalised
    temperature ``τ`` and time ``s`` (:class:`Regressors`), so each is a number in g (bias
    terms), a relative scale (temperature scale) or g/g² (nonlinearity).
    """
    import casadi as ca

    from optcal.norm_residual import casadi_lower_triangular as lower_triangular

    x = ca.SX.sym("x", N_X)
    a = ca.SX.sym("a", 3)
    tau = ca.SX.sym("tau")
    s = ca.SX.sym("s")
    T = lower_triangular(x[:6])
    L = [[x[0], 0, 0], [x[1], x[2], 0], [x[3], x[4], x[5]]]
    C = inverse_lower(L)
    S = [ca.sqrt(sum(C[i][j] ** 2 for j in range(i + 1))) for i in range(3)]
    beta = x[9:]
    y = []
    for i in range(3):
        b = lambda effect, p: beta[BETA_INDEX[(effect, i, p)]]  # noqa: E731
        bias = sum(b("temperature_bias", p) * tau**p for p in range(1, MAX_ORDER["temperature_bias"] + 1))
        bias += sum(b("bias_drift", p) * s**p for p in range(1, MAX_ORDER["bias_drift"] + 1))
        scale = sum(b("temperature_scale", p) * tau**p for p in range(1, MAX_ORDER["temperature_scale"] + 1))
        y.append(invert_axis(a[i] - x[6 + i], S[i], bias, scale, b("scale_nonlinearity", 1), ca.sqrt, ca.fmax))
    v = ca.mtimes(T, ca.vertcat(*y))
    return ca.Function("extended_norm_residual", [x, a, tau, s], [ca.norm_2(v) - 1.0])


@dataclass
class PoseData:
    """The data of an extended fit in normalised units (built once per data set).

    Attributes
    ----------
    u : ndarray, shape (n, 3)
        Normalised measurements ``(a − centre)/scale`` (:class:`optcal.estimators.base.Normaliser`).
    tau, s : ndarray, shape (n,)
        Normalised temperature and time.
    """

    u: NDArray[np.float64]
    tau: NDArray[np.float64]
    s: NDArray[np.float64]

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def parameters(self, w: NDArray, delta: float = 1.0) -> NDArray[np.float64]:
        """The parameter vector of :class:`ExtendedProblem` for weights ``w`` (passed as √w)."""
        return np.concatenate([self.u.ravel(), np.sqrt(w), self.tau, self.s, [delta]])


#: IPOPT options of :class:`ExtendedProblem`.  The norm residual ``‖v‖ − 1`` loses about
#: 1e-16 absolutely to cancellation, so near the optimum the cost is only known to ~1e-13
#: relatively and the gradient cannot be driven below ~√(curvature × that); the solve is
#: therefore accepted once the objective stops changing (relative change < 1e-12 for two
#: iterations) with the scaled optimality error below 1e-2 (which bounds the parameter error
#: at ~1e-10 of the parameters' size, far inside any standard error).
SOLVER_OPTIONS: dict[str, Any] = {
    "ipopt.tol": 1e-9,
    "ipopt.acceptable_tol": 1e-2,
    "ipopt.acceptable_obj_change_tol": 1e-12,
    "ipopt.acceptable_iter": 2,
    "ipopt.max_iter": 200,
    "calc_lam_p": False,
}


#: Built problems kept (least recently used dropped first): each holds a compiled IPOPT problem.
CACHE_SIZE: int = 16
_CACHE: "OrderedDict[tuple[int, str], ExtendedProblem]" = OrderedDict()
_CACHE_LOCK = threading.Lock()


class ExtendedProblem:
    """``min_x Σ_k ρ(√w_k r_k(x))`` over θ and every coefficient, data as parameters (built once).

    Unused coefficients are fixed at zero through the bounds (see :meth:`bounds`).  Also
    provides the residuals and their Jacobian as CasADi Functions (for held-out residuals and
    the Fisher information).
    """

    def __init__(self, n: int, loss: str = "squared") -> None:
        import casadi as ca

        from optcal.estimators.mle import IPOPT_DEFAULTS, robust_loss

        self.n, self.loss = n, loss
        r = extended_residual_function()
        # the squared loss is re-solved hundreds of times (bootstrap, k-fold): one expanded SX graph
        # (slower to build, ~4x faster to solve); the robust losses are solved a few times: MX map
        sym = ca.SX if loss == "squared" else ca.MX
        x = sym.sym("x", N_X)
        A = sym.sym("a", 3, n)
        sqrt_w = sym.sym("sqrt_w", 1, n)
        tau = sym.sym("tau", 1, n)
        s = sym.sym("s", 1, n)
        delta = sym.sym("delta")
        res = (r.map(n) if n > 1 else r)(x, A, tau, s)  # 1 x n
        cost = ca.sum2(robust_loss(res * sqrt_w, loss, delta))
        p = ca.vertcat(ca.vec(A), sqrt_w.T, tau.T, s.T, delta)
        opts = dict(IPOPT_DEFAULTS)
        opts.update(SOLVER_OPTIONS)
        self.solver = ca.nlpsol(f"extended_{loss}", "ipopt", {"x": x, "p": p, "f": cost}, opts)
        self.residuals = ca.Function("residuals", [x, p], [res.T])
        self.jacobian = ca.Function("jacobian", [x, p], [ca.jacobian(res.T, x)])

    @classmethod
    def get(cls, n: int, loss: str = "squared") -> "ExtendedProblem":
        """The problem for ``n`` poses and ``loss``, built once (a bounded, thread-safe cache)."""
        key = (n, loss)
        with _CACHE_LOCK:
            if key in _CACHE:
                _CACHE.move_to_end(key)
                return _CACHE[key]
        problem = cls(n, loss)
        with _CACHE_LOCK:
            _CACHE[key] = problem
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
        return problem

    @staticmethod
    def bounds(active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds fixing every inactive coefficient (``active`` over β) at zero."""
        lb = np.full(N_X, -np.inf)
        ub = np.full(N_X, np.inf)
        lb[9:][~active] = 0.0
        ub[9:][~active] = 0.0
        return lb, ub

    def solve(self, x0: NDArray, p: NDArray, active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``x0`` with parameters ``p`` and the coefficients ``active`` free."""
        lb, ub = self.bounds(active)
        x0 = np.clip(x0, lb, ub)
        sol = self.solver(x0=x0, p=p, lbx=lb, ubx=ub)
        return np.asarray(sol["x"]).ravel(), self.solver.stats()

    def residual_values(self, x: NDArray, p: NDArray) -> NDArray[np.float64]:
        return np.asarray(self.residuals(x, p)).ravel()

    def jacobian_values(self, x: NDArray, p: NDArray) -> NDArray[np.float64]:
        return np.asarray(self.jacobian(x, p))


def active_mask(terms: Mapping[tuple[str, int], int]) -> NDArray[np.bool_]:
    """β mask of the coefficients of ``{(effect, axis): order}`` (orders 1..order)."""
    mask = np.zeros(N_BETA, dtype=bool)
    for (effect, axis), order in terms.items():
        for p in range(1, order + 1):
            mask[BETA_INDEX[(effect, axis, p)]] = True
    return mask


def to_model(x: NDArray, centre: NDArray, scale: float, reg: Regressors) -> ExtendedModel:
    """The physical :class:`ExtendedModel` of a solution ``x`` in normalised units."""
    from optcal.model import canonicalise, unpack_theta

    T_n, o_n = unpack_theta(x[:9])
    T = canonicalise(T_n / scale)
    o = centre + scale * o_n
    coefficients = {}
    for effect in PARAMETRIC:
        c = np.zeros((3, MAX_ORDER[effect]))
        h = reg.half_span(effect)
        for i in range(3):
            for p in range(1, MAX_ORDER[effect] + 1):
                value = x[9 + BETA_INDEX[(effect, i, p)]]
                c[i, p - 1] = value / h**p if value != 0 else 0.0
        coefficients[effect] = c
    temp_ref = reg.temp_ref if np.isfinite(reg.temp_ref) else 25.0
    t_ref = reg.t_ref if np.isfinite(reg.t_ref) else 0.0
    return ExtendedModel(LumpedModel.from_T(T, o), coefficients, temp_ref, t_ref)
