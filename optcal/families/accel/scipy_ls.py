"""The ML cost (Lu 2017, eq. 14) solved by scipy's ``least_squares``: a reference for the solver study.

Same normalised data, starting point, propagated weights and reweighting rule as
:class:`~optcal.families.accel.mle.MaximumLikelihood`; the residuals ``√w_k r_k(θ)`` and their
analytic Jacobian come from the same column-wise numpy evaluator
(:class:`~optcal.families.accel.mle.NormResidualCost`), so that a comparison with IPOPT measures
the solvers and not the model code.  ``method="lm"`` is MINPACK's Levenberg–Marquardt,
``method="trf"`` scipy's trust-region reflective algorithm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, least_squares

from optcal.errors import InputError
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish
from optcal.families.accel.mle import MaximumLikelihood, NormResidualCost
from optcal.core.poses import PoseTable
from optcal.core.fit_result import SolverInfo
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import Remedy

METHODS = ("lm", "trf")


def solve_least_squares(
    theta0: NDArray, u: NDArray, w: NDArray, method: str = "lm", tol: float = 1e-10
) -> tuple[NDArray[np.float64], OptimizeResult]:
    """Minimise ``Σ w_k r_k(θ)²`` from ``theta0`` for normalised data ``u`` with scipy.

    ``tol`` is used for ``xtol``, ``ftol`` and ``gtol`` alike.
    """
    if method not in METHODS:
        raise InputError(f"unknown least_squares method {method!r}; use one of {', '.join(METHODS)}")
    cost = NormResidualCost(u, w)

    def residuals(theta: NDArray) -> NDArray[np.float64]:
        return cost.sqrt_w * cost.residuals(theta)

    def jacobian(theta: NDArray) -> NDArray[np.float64]:
        return (cost.jacobian(theta) * cost.sqrt_w).T

    res = least_squares(residuals, theta0, jac=jacobian, method=method, xtol=tol, ftol=tol, gtol=tol)
    return np.asarray(res.x, dtype=float), res


class ScipyLeastSquares:
    """Maximum-likelihood calibration (Lu 2017, eq. 14) with ``scipy.optimize.least_squares``.

    Parameters
    ----------
    method : {"lm", "trf"}
        Levenberg–Marquardt (MINPACK) or trust-region reflective.
    tol : float
        ``xtol = ftol = gtol``.
    init, weighting, reweight, reweight_rtol, allow_degenerate
        As for :class:`~optcal.families.accel.mle.MaximumLikelihood`.
    """

    name = "scipy"

    def __init__(
        self,
        method: str = "lm",
        tol: float = 1e-10,
        init: Any = "convex",
        weighting: str = "propagated",
        reweight: int = 2,
        reweight_rtol: float = 1e-3,
        allow_degenerate: bool = False,
    ) -> None:
        if method not in METHODS:
            raise InputError(f"unknown least_squares method {method!r}; use one of {', '.join(METHODS)}")
        self.method = method
        self.tol = float(tol)
        self.allow_degenerate = allow_degenerate
        self.weighting = weighting
        self._ml = MaximumLikelihood(init=init, weighting=weighting, reweight=reweight, reweight_rtol=reweight_rtol)

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        theta_n, init_method = self._ml.initial_normalised(poses, norm, u)
        check_pose_set(poses, norm.theta_to_raw(theta_n), self._ml.weighting, self.allow_degenerate)
        total_time, nfev, passes = 0.0, 0, 0
        res: OptimizeResult | None = None
        w_used: NDArray | None = None
        for _ in range(1 + max(self._ml.reweight, 0)):
            w = self._ml.weights(poses, norm, u, theta_n)
            if w_used is not None and np.max(np.abs(w / w_used - 1.0)) <= self._ml.reweight_rtol:
                break
            with Stopwatch() as sw:
                theta_n, res = solve_least_squares(theta_n, u, w / np.mean(w), self.method, self.tol)
            total_time += sw.seconds
            nfev += int(res.nfev)
            passes += 1
            w_used = w
        assert res is not None
        success = bool(res.success)
        solver = SolverInfo(
            f"scipy least_squares ({self.method})", str(res.message), success, nfev, total_time,
            f"{passes} pass(es); iterations counted as residual evaluations",
        )
        return finish(
            method=f"scipy-{self.method}",
            poses=poses,
            theta=norm.theta_to_raw(theta_n),
            solver=solver,
            weighting=self.weighting,
            allow_degenerate=self.allow_degenerate,
            remedy=Remedy(stopped_early="loosen tol or use the other method ('lm' or 'trf')",
                          failed="use the other method ('lm' or 'trf')"),
            extra={"init": init_method, "passes": passes},
        )
