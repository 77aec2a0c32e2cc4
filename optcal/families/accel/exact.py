"""The exact maximum-likelihood problem of Lu 2017, eq. 8 (errors in variables) in CasADi/IPOPT.

Unknowns: the lumped matrix ``C`` (lower-triangular with positive diagonal, the identifiable
form), the bias ``o`` and one latent unit direction ``ā_k`` per pose::

    min  Σ_k ‖a_k − o − C ā_k‖² / σ_k²      s.t.  ‖ā_k‖² = 1          (Lu 2017, eq. 8)

Unlike eq. 13/14, which replaces the latent directions by the radial projection
``ξ_k/‖ξ_k‖`` (eq. 10-12, exact only for an orthogonal C), this is the true likelihood of the
measurement model and attains the Cramér–Rao bound of :mod:`optcal.core.identifiability`
asymptotically.  The NLP has ``9 + 3n`` variables and ``n`` equality constraints with a
sparse (block-diagonal plus border) KKT system, which IPOPT's sparse solver exploits.  It is
built once per n (kept in :data:`EXACT_PROBLEMS`), with the measurements and weights as parameters.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish
from optcal.families.accel.mle import IPOPT_REMEDY, MaximumLikelihood
from optcal.core.model import theta_from, unpack_theta
from optcal.core.norm_residual import casadi_lower_triangular
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, freeze_options, problem_cache
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import solver_record
from optcal.solvers.nlp import nlp_solver

#: IPOPT tuning of the errors-in-variables problem (on :data:`optcal.solvers.nlp.IPOPT_DEFAULTS`): its
#: cost is not scaled by :func:`optcal.solvers.nlp.cost_scale` (9 + 3n variables and n constraints),
#: so IPOPT's own scaled optimality error to 1e-10, and up to 500 iterations.
EXACT_IPOPT_TUNING: dict[str, Any] = {"ipopt.tol": 1e-10, "ipopt.max_iter": 500}


class ExactProblem:
    """The errors-in-variables NLP for n poses, data as parameters (built once, cached).

    The Hessian of the Lagrangian is handed to IPOPT assembled from per-pose 12×12 blocks
    (C, o and that pose's direction), so CasADi never has to discover its sparsity: colouring
    a Hessian whose 9 calibration rows are dense costs O(n²), about 35 s at 10⁴ poses, against
    a few seconds for this assembly.
    """

    def __init__(self, n: int, ipopt_options: dict[str, Any] | None = None) -> None:
        import casadi as ca

        nx = 9 + 3 * n
        x = ca.SX.sym("x", nx)  # lower-triangular C (6), o (3), latent unit directions (3n)
        p = ca.SX.sym("p", 4 * n)  # measurements (column-major 3×n), weights
        C, o = casadi_lower_triangular(x[:6]), x[6:9]
        d = ca.reshape(x[9:], 3, n)
        a = ca.reshape(p[: 3 * n], 3, n)
        w = p[3 * n:].T
        e = a - ca.repmat(o, 1, n) - ca.mtimes(C, d)  # Lu 2017, eq. 8 residuals
        cost = ca.sum2(w * ca.sum1(e * e))
        g = ca.sum1(d * d).T - 1.0  # ‖ā_k‖² = 1
        self.n = n
        self.solver = nlp_solver("exact_ml_calibration", {"x": x, "p": p, "f": cost, "g": g}, EXACT_IPOPT_TUNING,
                                 functions={"hess_lag": self._hessian(x, p, n)}, solver_options=ipopt_options)
        self._lock = threading.Lock()

    @staticmethod
    def _hessian(x: Any, p: Any, n: int) -> Any:
        """``∇²(λ_f f + Σ λ_k g_k)`` (upper triangle) from the per-pose blocks."""
        import casadi as ca

        z = ca.SX.sym("z", 12)  # c, o, d_k
        ak, wk, lf, lg = ca.SX.sym("a", 3), ca.SX.sym("w"), ca.SX.sym("lf"), ca.SX.sym("lg")
        ek = ak - z[6:9] - ca.mtimes(casadi_lower_triangular(z[:6]), z[9:12])
        block = ca.hessian(lf * wk * ca.dot(ek, ek) + lg * (ca.dot(z[9:12], z[9:12]) - 1.0), z)[0]
        blocks = ca.Function("pose_hessian", [z, ak, wk, lf, lg], [ca.densify(block)]).map(n, "serial")
        lam_f, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", n)
        z_all = ca.vertcat(ca.repmat(x[:9], 1, n), ca.reshape(x[9:], 3, n))
        H = ca.reshape(blocks(z_all, ca.reshape(p[: 3 * n], 3, n), p[3 * n:].T, lam_f, lam_g.T), 144, n)  # vec(H_k)
        H_sum = ca.sum2(H)
        # triplets of the upper triangle: the calibration block (summed over poses), then per
        # pose its column of couplings and its own 3×3 block; entry (i, j) of H_k is row 12j + i
        g_ij = [(i, j) for j in range(9) for i in range(j + 1)]
        local = [(i, 9 + j) for j in range(3) for i in range(9)] + [(9 + i, 9 + j) for j in range(3) for i in range(j + 1)]
        li, lj = (np.array(v) for v in zip(*local))
        shift = 3 * np.repeat(np.arange(n), len(local))  # pose k's direction starts at 9 + 3k
        rows = np.concatenate([[i for i, _ in g_ij], np.tile(li, n) + np.where(np.tile(li, n) >= 9, shift, 0)])
        cols = np.concatenate([[j for _, j in g_ij], np.tile(lj, n) + shift])
        flat = np.tile(12 * lj + li, n) + 48 * shift  # positions in vec([H_1 … H_n]): 144 per pose
        values = ca.vertcat(H_sum[[12 * j + i for i, j in g_ij]], ca.vec(H)[flat.tolist()])
        nx = 9 + 3 * n
        H_triu = ca.SX.triplet(rows.tolist(), cols.tolist(), values, nx, nx)
        return ca.Function("hess_lag", [x, p, lam_f, lam_g], [H_triu],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])

    @classmethod
    def get(cls, n: int, ipopt_options: dict[str, Any] | None = None) -> "ExactProblem":
        """The problem for n poses, built on first use and kept in :data:`EXACT_PROBLEMS`."""
        return EXACT_PROBLEMS.get(n, freeze_options(ipopt_options))

    def solve(self, x0: NDArray, acc: NDArray, weights: NDArray, lbx: NDArray) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Solve from ``x0`` (C, o, directions) for normalised measurements (n, 3) and weights (n,)."""
        with self._lock:  # the solver keeps the statistics of its last call
            return self.solver.solve(x0=x0, p=np.concatenate([acc.ravel(), weights]), lbg=0.0, ubg=0.0, lbx=lbx)


#: The errors-in-variables problems, keyed by (n, frozen IPOPT options).
EXACT_PROBLEMS: ProblemCache[ExactProblem] = problem_cache(lambda n, options: ExactProblem(n, dict(options)), maxsize=16)


class ExactMaximumLikelihood:
    """Exact (errors-in-variables) maximum likelihood, Lu 2017 eq. 8.

    Parameters
    ----------
    init : {"mle", "convex", "svd"}
        Starting point; ``mle`` (the eq. 14 solution) by default, whose radial projections
        ``ξ_k/‖ξ_k‖`` start the latent directions.
    allow_degenerate : bool
        Proceed (with a warning) when the poses do not identify every parameter.
    ipopt_options : dict, optional
        Extra CasADi/IPOPT options; options IPOPT refuses are an :class:`~optcal.errors.InputError`.
    """

    name = "exact"

    def __init__(self, init: str = "mle", allow_degenerate: bool = False, ipopt_options: dict[str, Any] | None = None) -> None:
        if init not in ("mle", "convex", "svd"):
            raise InputError("init must be 'mle', 'convex' or 'svd'")
        self.init = init
        self.allow_degenerate = allow_degenerate
        self.ipopt_options = dict(ipopt_options or {})

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        if self.init == "mle":
            start = MaximumLikelihood(allow_degenerate=self.allow_degenerate).fit(poses)  # refuses as exact would
        else:
            start = MaximumLikelihood(init=self.init, allow_degenerate=True).initial(poses)
            check_pose_set(poses, start.calibration.lumped().theta, allow_degenerate=self.allow_degenerate)
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        T_n = start.T * norm.scale
        o_n = (start.o - norm.centre) / norm.scale
        C_n = np.linalg.inv(T_n)
        xi = (u - o_n) @ T_n.T
        d0 = xi / np.linalg.norm(xi, axis=1, keepdims=True)  # Lu 2017, eq. 10
        x0 = np.concatenate([theta_from(C_n, o_n), d0.ravel()])  # C packed like T in θ
        w = np.ones(poses.n) if poses.sigma is None else 1.0 / poses.sigma**2
        w = w / np.mean(w)
        lbx = np.full(x0.size, -np.inf)
        lbx[[0, 2, 5]] = 1e-9  # positive diagonal of C: the canonical identifiable form
        problem = ExactProblem.get(poses.n, self.ipopt_options)
        with Stopwatch() as sw:
            x, stats = problem.solve(x0, u, w, lbx)
        C, o_fit = unpack_theta(x[:9])
        theta = norm.theta_to_raw(theta_from(np.linalg.inv(C), o_fit))
        solver = solver_record(stats, sw.seconds, "IPOPT", f"errors-in-variables NLP, {x.size} variables")
        directions = x[9:].reshape(poses.n, 3)
        return finish(
            method=self.name,
            poses=poses,
            theta=theta,
            solver=solver,
            allow_degenerate=self.allow_degenerate,
            remedy=IPOPT_REMEDY,
            extra={"init": start.method, "latent_directions": directions.tolist()},
        )
