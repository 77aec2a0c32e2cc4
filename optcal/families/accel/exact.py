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

Two formulations of the same problem (``formulation=``):

* ``"profile"`` (the default): variable projection (:mod:`optcal.families.accel.exact_profile`) —
  each pose's direction is the closest point of the ellipsoid to its measurement, a secular equation
  solved for all poses at once (:mod:`optcal.families.accel.ellipsoid_projection`), and
  Levenberg–Marquardt runs on the nine calibration parameters with the envelope theorem's Jacobian.
  Linear in n: 10⁵ poses in a fraction of a second where the full NLP takes about a minute.
* ``"full"``: the ``9 + 3n``-variable NLP above, in IPOPT (chosen by default when ``ipopt_options`` are
  given, the only formulation they apply to).

Both report the covariance of θ as the inverse of the profile likelihood's Hessian — the observed
information with the directions eliminated, the Schur complement of the full NLP's reduced Hessian
(:func:`optcal.families.accel.exact_profile.profile_hessian`).

Eq. 8's ML is not consistent at a fixed noise level (one latent direction per pose: Neyman & Scott
1948): its ellipsoid sits O(σ²) outside the true one however many poses there are, about 2.5
standard errors of the scale factors at 10⁶ poses and 5 mg.  ``curvature_correction=True`` solves
the score equation with each residual's second-order mean removed instead
(:func:`optcal.families.accel.exact_profile.fit_corrected_score`), unbiased to O(σ⁴).
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import InputError
from optcal.core.fit_result import SolverInfo
from optcal.core.identifiability import pseudo_inverse
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish
from optcal.families.accel.exact_profile import (ProfileFit, fit_corrected_score, fit_profile, profile_hessian,
                                                 residual_jacobian)
from optcal.families.accel.mle import IPOPT_REMEDY, MaximumLikelihood
from optcal.core.model import theta_from, unpack_theta
from optcal.core.norm_residual import casadi_lower_triangular
from optcal.core.poses import PoseTable
from optcal.solvers.cache import ProblemCache, freeze_options, problem_cache
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import Remedy, solver_record
from optcal.solvers.nlp import nlp_solver

#: IPOPT tuning of the errors-in-variables problem (on :data:`optcal.solvers.nlp.IPOPT_DEFAULTS`): its
#: cost is not scaled by :func:`optcal.solvers.nlp.cost_scale` (9 + 3n variables and n constraints),
#: so IPOPT's own scaled optimality error to 1e-10, and up to 500 iterations.
EXACT_IPOPT_TUNING: dict[str, Any] = {"ipopt.tol": 1e-10, "ipopt.max_iter": 500}


#: Formulations of eq. 8 (module docstring).
FORMULATIONS = ("profile", "full")
#: What to change when the profile formulation stops early or fails.
PROFILE_REMEDY = Remedy(
    stopped_early="start from another fit (init=...) or solve the full NLP (formulation='full')",
    failed="solve the full NLP (formulation='full') or use method='mle'",
)


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
        ``ξ_k/‖ξ_k‖`` start the latent directions of the full NLP.
    allow_degenerate : bool
        Proceed (with a warning) when the poses do not identify every parameter.
    ipopt_options : dict, optional
        Extra CasADi/IPOPT options of the full NLP; options IPOPT refuses are an
        :class:`~optcal.errors.InputError`.
    formulation : {"profile", "full"}, optional
        Variable projection in 9 variables, or the ``9 + 3n``-variable NLP in IPOPT (module
        docstring); by default ``profile``, or ``full`` when ``ipopt_options`` are given.
    curvature_correction : bool
        Solve the curvature-corrected score equation instead of eq. 8 (consistent at a fixed noise
        level; module docstring).  Profile formulation only.
    """

    name = "exact"

    def __init__(self, init: str = "mle", allow_degenerate: bool = False, ipopt_options: dict[str, Any] | None = None,
                 formulation: str | None = None, curvature_correction: bool = False) -> None:
        if init not in ("mle", "convex", "svd"):
            raise InputError("init must be 'mle', 'convex' or 'svd'")
        if formulation is None:
            formulation = "full" if ipopt_options else "profile"
        if formulation not in FORMULATIONS:
            raise InputError(f"formulation must be one of {', '.join(map(repr, FORMULATIONS))}, not {formulation!r}")
        if curvature_correction and formulation != "profile":
            raise InputError("curvature_correction=True needs formulation='profile'")
        if ipopt_options and formulation != "full":
            raise InputError("ipopt_options apply to the full NLP only: pass formulation='full' (or leave it out)")
        self.init = init
        self.allow_degenerate = allow_degenerate
        self.ipopt_options = dict(ipopt_options or {})
        self.formulation = formulation
        self.curvature_correction = curvature_correction

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        if self.init == "mle":
            start = MaximumLikelihood(allow_degenerate=self.allow_degenerate).fit(poses)  # refuses as exact would
        else:
            start = MaximumLikelihood(init=self.init, allow_degenerate=True).initial(poses)
            check_pose_set(poses, start.calibration.lumped().theta, allow_degenerate=self.allow_degenerate)
        norm = Normaliser.of(poses.acc)
        u = norm.forward(poses.acc)
        theta0_n = norm.theta_to_normalised(theta_from(start.T, start.o))
        known = poses.sigma is not None
        # absolute weights 1/σ_k² in normalised units when the noise is given (the covariance needs them)
        w = np.ones(poses.n) if poses.sigma is None else (norm.scale / poses.sigma) ** 2
        if self.formulation == "profile":
            restart = ""
            with Stopwatch() as sw:
                pf = fit_profile(theta0_n, u, w, known)
                if not pf.converged:  # a start far from the optimum (e.g. an mle that stopped early): the algebraic fits
                    for alt in ("convex", "svd"):
                        if alt == self.init:
                            continue
                        other = MaximumLikelihood(init=alt, allow_degenerate=True).initial(poses)
                        candidate = fit_profile(norm.theta_to_normalised(theta_from(other.T, other.o)), u, w, known)
                        if candidate.converged:
                            pf, restart = candidate, f"; restarted from the {alt} fit ({self.init} start did not converge)"
                            break
                if self.curvature_correction:
                    pf = fit_corrected_score(pf.theta, u, None if not known else 1.0 / w)
            theta_n, directions = pf.theta, pf.points.d
            solver = SolverInfo(
                name="Levenberg-Marquardt" if not self.curvature_correction else "Gauss-Newton",
                status=pf.status, success=pf.converged, iterations=pf.iterations, solve_time_s=sw.seconds,
                message=(f"{'curvature-corrected score of' if self.curvature_correction else 'profile likelihood of'} "
                         f"eq. 8 in 9 variables (variable projection; {poses.n} closest points by their secular "
                         f"equations, {pf.projection_iterations} Newton steps{restart})"),
            )
            remedy = PROFILE_REMEDY
        else:
            theta_n, directions, solver = self._full(poses, u, theta0_n, w)
            pf = None
            remedy = IPOPT_REMEDY
        theta = norm.theta_to_raw(theta_n)
        result = finish(
            method=self.name,
            poses=poses,
            theta=theta,
            solver=solver,
            allow_degenerate=self.allow_degenerate,
            remedy=remedy,
            extra={"init": start.method, "formulation": self.formulation,
                   "curvature_correction": self.curvature_correction, "latent_directions": directions},
        )
        result.covariance = self._covariance(theta_n, u, w, known, norm, pf)
        return result

    def _full(self, poses: PoseTable, u: NDArray, theta0_n: NDArray, w: NDArray) -> tuple[NDArray, NDArray, SolverInfo]:
        """The 9 + 3n-variable NLP in IPOPT from θ₀ (normalised) and its radial projections."""
        T_n, o_n = unpack_theta(theta0_n)
        xi = (u - o_n) @ T_n.T
        d0 = xi / np.linalg.norm(xi, axis=1, keepdims=True)  # Lu 2017, eq. 10
        x0 = np.concatenate([theta_from(np.linalg.inv(T_n), o_n), d0.ravel()])  # C packed like T in θ
        lbx = np.full(x0.size, -np.inf)
        lbx[[0, 2, 5]] = 1e-9  # positive diagonal of C: the canonical identifiable form
        problem = ExactProblem.get(poses.n, self.ipopt_options)
        with Stopwatch() as sw:
            x, stats = problem.solve(x0, u, w / np.mean(w), lbx)
        C, o_fit = unpack_theta(x[:9])
        solver = solver_record(stats, sw.seconds, "IPOPT", f"errors-in-variables NLP, {x.size} variables")
        return theta_from(np.linalg.inv(C), o_fit), x[9:].reshape(poses.n, 3), solver

    def _covariance(self, theta_n: NDArray, u: NDArray, w: NDArray, known: bool, norm: Normaliser,
                    pf: ProfileFit | None) -> NDArray[np.float64]:
        """Covariance of θ (raw units): the inverse observed information ``½∇²f`` of the profile cost.

        For the curvature-corrected score, the information ``JᵀWJ`` of the signed distances (its
        first-order covariance).  Scaled by the reduced chi-square ``Σwρ²/(n − 9)`` when the noise
        is not given.
        """
        points = None if pf is None else pf.points
        if self.curvature_correction and pf is not None:
            T_n, _ = unpack_theta(theta_n)
            J = residual_jacobian(T_n, pf.points)
            information = J.T @ (J * w[:, None])
        else:
            information = 0.5 * profile_hessian(theta_n, u, w, points)
        cov_n, _, _ = pseudo_inverse(information)
        if not known:
            if points is None:
                from optcal.families.accel.ellipsoid_projection import closest_points

                T_n, o_n = unpack_theta(theta_n)
                points = closest_points(np.linalg.inv(T_n), o_n, u)
            cov_n = cov_n * float(np.sum(w * points.distance**2)) / max(u.shape[0] - 9, 1)
        D = norm.jacobian()
        return D @ cov_n @ D
