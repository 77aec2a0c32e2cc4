"""The paper's baseline: plain gradient descent on the ML cost (Lu 2017, eq. 14-17).

The parameter vector is ``x = [vec(T)ᵀ, oᵀ]ᵀ`` with the full 3×3 T (row-major vec, as in
the paper), the cost ``f(x) = Σ_k w_k (‖T u_k‖ − 1)²`` with ``u_k = a_k − o`` (eq. 14), its
gradient (eq. 15-16, with ``c_T = 1 − ‖T u_k‖⁻¹``)::

    ∇_T f = Σ_k 2 w_k c_T (T u_k) u_kᵀ          ∇_o f = −Σ_k 2 w_k c_T Tᵀ T u_k

and the iteration ``x_k = x_{k−1} − μ ∇f`` (eq. 17), stopped when ``‖x_k − x_{k−1}‖ ≤ ε``.
It runs on the same normalised data and weights as :mod:`optcal.families.accel.mle`, so the
two minimise the same cost and can be compared iteration for iteration.  With
``step="auto"`` the step is ``μ = 1/L``, ``L`` the largest eigenvalue of the Gauss–Newton
Hessian at the starting point (a fixed step, as in the paper, chosen so that it converges).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish, pose_weights
from optcal.core.model import canonicalise, theta_from
from optcal.core.norm_residual import NormResidualKernel
from optcal.core.poses import PoseTable
from optcal.core.fit_result import SolverInfo
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import Remedy


def cost_and_gradient(x: NDArray, u: NDArray | NormResidualKernel, w: NDArray) -> tuple[float, NDArray[np.float64]]:
    """f(x) (Lu 2017, eq. 14) and its gradient (eq. 15-16) for x = [vec(T), o].

    ``∇f = Σ_k 2 w_k r_k ∂r_k/∂x`` with ``r_k ∂r_k/∂T = c_T (T u_k) u_kᵀ`` (eq. 15) and
    ``r_k ∂r_k/∂o = −c_T Tᵀ T u_k`` (eq. 16); ``u`` may be the kernel of the data already built.
    """
    kernel = u if isinstance(u, NormResidualKernel) else NormResidualKernel(u)
    point = kernel.at_full(x)
    r = point.residuals
    return float(np.sum(w * r * r)), point.jacobian_full_dot(2.0 * w * r)  # Lu 2017, eqs. 15-16


@np.errstate(over="ignore", invalid="ignore")  # a divergence is reported in the status
def descend(
    x: NDArray, u: NDArray, w: NDArray, mu: float, tol: float, max_iter: int, target: float | None = None
) -> tuple[NDArray[np.float64], float, int, str]:
    """Iterate ``x_k = x_{k−1} − μ ∇f`` (Lu 2017, eq. 17) on normalised data.

    Stops when ``‖x_k − x_{k−1}‖ ≤ tol``, or when ``f ≤ target`` if a target is given.

    Returns
    -------
    x, f, iterations, status
        ``status`` is ``"converged"``, ``"diverged"`` or ``"max_iter reached"``.
    """
    it = 0
    kernel = NormResidualKernel(u)
    f, g = cost_and_gradient(x, kernel, w)
    while it < max_iter:
        step = mu * g
        x = x - step  # Lu 2017, eq. 17
        it += 1
        f, g = cost_and_gradient(x, kernel, w)
        if not np.isfinite(f):
            return x, f, it, "diverged"
        if np.linalg.norm(step) <= tol or (target is not None and f <= target):
            return x, f, it, "converged"
    return x, f, it, "max_iter reached"


class GradientDescent:
    """Plain gradient descent with a fixed step (Lu 2017, eq. 17): the baseline.

    Parameters
    ----------
    step : float or "auto"
        The step μ (in the normalised coordinates); ``auto`` = 1/L (module docstring).
    tol : float
        ε of the stopping rule ``‖x_k − x_{k−1}‖ ≤ ε``.
    max_iter : int
        Iteration limit (reported as not converged when reached).
    target_cost : float, optional
        Also stop as soon as the cost is at or below this value (for speed comparisons
        "to the same cost").
    init : {"svd", "convex"} or CalibrationResult
        Starting point: an algebraic fit (eq. 18-30) or a given result.
    allow_degenerate : bool
        Proceed (with a warning) when the poses do not identify every parameter.
    """

    name = "gd"

    def __init__(
        self,
        step: float | str = "auto",
        tol: float = 1e-10,
        max_iter: int = 1_000_000,
        target_cost: float | None = None,
        init: str | CalibrationResult = "svd",
        weighting: str = "propagated",
        allow_degenerate: bool = False,
    ) -> None:
        if step != "auto" and not (isinstance(step, (int, float)) and step > 0):
            raise InputError("step must be a positive number or 'auto'")
        self.step = step
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.target_cost = target_cost
        self.init = init
        self.weighting = weighting
        self.allow_degenerate = allow_degenerate

    def fit(self, poses: PoseTable) -> CalibrationResult:
        from optcal.families.accel.mle import MaximumLikelihood

        poses.validate()
        start = MaximumLikelihood(init=self.init, allow_degenerate=True).initial(poses)
        check_pose_set(poses, start.calibration.lumped().theta, self.weighting, self.allow_degenerate)
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        w, _ = pose_weights(poses, start.T, start.o, self.weighting)
        w_n = w / np.mean(w)
        T0 = start.T * norm.scale
        o0 = (start.o - norm.centre) / norm.scale
        x = np.concatenate([T0.ravel(), o0])
        mu = self.auto_step(x, u, w_n) if self.step == "auto" else float(self.step)
        target = None if self.target_cost is None else self.target_cost / np.mean(w)
        with Stopwatch() as sw:
            x, f, it, status = descend(x, u, w_n, mu, self.tol, self.max_iter, target)
        converged = status == "converged"
        finite = status != "diverged" and np.all(np.isfinite(x))
        theta = norm.theta_to_raw(theta_from(canonicalise(x[:9].reshape(3, 3)), x[9:12])) if finite else np.full(9, np.nan)
        solver = SolverInfo("gradient descent", status, converged, it, sw.seconds, f"step μ = {mu:.4g} (normalised)")
        return finish(
            method=self.name,
            poses=poses,
            theta=theta,
            solver=solver,
            weighting=self.weighting,
            allow_degenerate=self.allow_degenerate,
            remedy=Remedy(
                stopped_early="pass a larger max_iter or a looser tol",
                failed="pass step='auto' (μ = 1/L) or a smaller step",
            ),
            extra={"step": mu, "final_cost": f * np.mean(w), "init": start.method},
        )

    @staticmethod
    def auto_step(x: NDArray, u: NDArray, w: NDArray) -> float:
        """μ = 1/L with L the largest eigenvalue of the Gauss–Newton Hessian 2JᵀWJ at x."""
        J = NormResidualKernel(u).at_full(x).jacobian_full()  # (12, n)
        L = float(np.linalg.eigvalsh(2 * (J * w) @ J.T)[-1])
        return 1.0 / L


__all__ = ["GradientDescent", "cost_and_gradient", "descend"]
