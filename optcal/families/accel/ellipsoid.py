"""Algebraic ellipsoid fits: the paper's SVD fit and the same fit as a constrained convex problem.

Both fit the quadric ``aᵀ A a + bᵀ a + c = 0`` through the poses (Lu 2017, eq. 18) by
minimising the algebraic residuals ``J η`` (eq. 22-24).  With ``A`` symmetric, ``J``'s rows
are ``[x², y², z², 2xy, 2xz, 2yz, x, y, z, 1]`` (the paper's Kronecker form ``a ⊗ a`` would
leave the antisymmetric part of A free).  The scale ``α`` follows from eq. 19-21 (eq. 27),
``o = −½ A⁻¹ b`` (eq. 20) and ``T`` from ``A = Tᵀ T`` (eq. 29-30; optcal takes the
lower-triangular factor, eq. 30's symmetric square root differs from it by a rotation).

* :class:`SVDEllipsoidFit`: η is the right singular vector of ``J`` for the smallest singular
  value (``‖η‖ = 1`` excludes the zero solution).  Nothing forces ``A ≻ 0``: with poses
  covering only a cap of the sphere, or with much noise, the answer can be a hyperboloid,
  and then there is no calibration to return.
* :class:`ConvexEllipsoidFit`: ``min ‖J η‖²`` subject to ``A ⪰ ε I`` (semidefinite constraint,
  so the answer is always an ellipsoid) and ``tr A = 3`` (a linear normalisation that
  excludes the zero solution), solved by cvxpy with Clarabel by default.  The problem is
  built once and re-solved with the data as a parameter: ``‖J η‖² = ‖R η‖²`` with ``R``
  the 10×10 triangular factor of ``J``, so the problem size does not depend on the number of
  poses.  When the semidefinite constraint is inactive at the solution, the equality-
  constrained least-squares problem it then solves is re-solved exactly by its KKT system
  ("polish"), which gives the interior-point answer to machine precision.
"""

from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.errors import FitError, SolverError
from optcal.families.accel.base import Normaliser, Stopwatch, check_pose_set, finish
from optcal.core.model import canonical_T, theta_from
from optcal.core.poses import PoseTable
from optcal.solvers.cache import FrozenOptions, ProblemCache, freeze_options, problem_cache
from optcal.core.fit_result import SolverInfo
from optcal.families.accel.result import CalibrationResult
from optcal.solvers.convergence import Remedy


def design_matrix(u: NDArray) -> NDArray[np.float64]:
    """Rows ``[x², y², z², 2xy, 2xz, 2yz, x, y, z, 1]`` (Lu 2017, eq. 23, A symmetric); ``u`` (..., n, 3)."""
    x, y, z = u[..., 0], u[..., 1], u[..., 2]
    return np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, x, y, z, np.ones_like(x)], axis=-1)


def unpack_quadric(eta: NDArray) -> tuple[NDArray, NDArray, Any]:
    """η → (A, b, c) for η ordered as in :func:`design_matrix`; η (10,) or a stack (..., 10)."""
    eta = np.asarray(eta, dtype=float)
    a11, a22, a33, a12, a13, a23 = (eta[..., i] for i in range(6))
    A = np.stack([np.stack([a11, a12, a13], -1), np.stack([a12, a22, a23], -1), np.stack([a13, a23, a33], -1)], -2)
    c = eta[..., 9]
    return A, eta[..., 6:9], float(c) if c.ndim == 0 else c


def kkt_polish(R: NDArray) -> NDArray[np.float64]:
    """Exact solution of ``min ‖R η‖²`` s.t. ``tr A = 3`` from its KKT system; ``R`` (..., m, 10).

    The KKT matrix ``[[2RᵀR, g], [gᵀ, 0]]`` (g selects the trace) is solved by least squares,
    which also gives an answer (the smallest) when it is singular (a degenerate pose set).
    """
    R = np.asarray(R, dtype=float)
    K = np.zeros(R.shape[:-2] + (11, 11))
    K[..., :10, :10] = 2 * (np.swapaxes(R, -1, -2) @ R)
    K[..., :3, 10] = K[..., 10, :3] = 1.0  # g: the trace of A
    rhs = np.zeros(11)
    rhs[10] = 3.0
    systems = K.reshape(-1, 11, 11)
    eta = np.empty((len(systems), 10))
    for k, system in enumerate(systems):  # numpy's least squares takes one system at a time
        eta[k] = np.linalg.lstsq(system, rhs, rcond=None)[0][:10]
    return eta.reshape(R.shape[:-2] + (10,))


#: What a fitted quadric is (:func:`quadric_to_calibrations`): a real ellipsoid, a hyperboloid
#: (A indefinite) or an ellipsoid without real points.
ELLIPSOID, HYPERBOLOID, IMAGINARY = 0, 1, 2


def quadric_to_calibrations(eta: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Scale each quadric to ``‖T(a − o)‖ = 1`` (Lu 2017, eq. 19-21, 27-30); η (10,) or a stack (..., 10).

    Returns
    -------
    T : ndarray, shape (..., 3, 3)
        Lower-triangular, positive diagonal; NaN where the quadric is not a real ellipsoid.
    o : ndarray, shape (..., 3)
        NaN where the quadric is not a real ellipsoid.
    kind : ndarray of int, shape (...)
        :data:`ELLIPSOID`, :data:`HYPERBOLOID` or :data:`IMAGINARY`.
    eigenvalues : ndarray, shape (..., 3)
        Of the quadric's A, ascending.
    """
    A_s, b, c = unpack_quadric(eta)
    eigenvalues = np.linalg.eigvalsh(A_s)
    kind = np.where(eigenvalues[..., 0] * eigenvalues[..., -1] <= 0, HYPERBOLOID, ELLIPSOID)
    A_s = np.where((kind == ELLIPSOID)[..., None, None], A_s, np.eye(3))
    A_inv_b = np.linalg.solve(A_s, b[..., None])[..., 0]
    o = -0.5 * A_inv_b  # Lu 2017, eq. 20
    alpha = 1.0 / (0.25 * (b[..., None, :] @ A_inv_b[..., :, None])[..., 0, 0] - c)  # eq. 27
    A = alpha[..., None, None] * A_s  # eq. 28
    kind = np.where((kind == ELLIPSOID) & ~(np.linalg.eigvalsh(A)[..., 0] > 0), IMAGINARY, kind)
    real = kind == ELLIPSOID
    T = canonical_T(np.where(real[..., None, None], A, np.eye(3)))  # eq. 29-30, lower-triangular
    return np.where(real[..., None, None], T, np.nan), np.where(real[..., None], o, np.nan), kind, eigenvalues


def quadric_to_calibration(eta: NDArray) -> tuple[NDArray, NDArray]:
    """Scale the quadric to ``‖T(a − o)‖ = 1`` and return (T, o) (Lu 2017, eq. 19-21, 27-30).

    Raises
    ------
    FitError
        When the quadric is not a real ellipsoid.
    """
    T, o, kind, eig = quadric_to_calibrations(eta)
    if kind == HYPERBOLOID:
        raise FitError(
            f"the algebraic fit is not an ellipsoid (eigenvalues of A: {', '.join(f'{e:.3g}' for e in eig)}: "
            "a hyperboloid); this happens when the poses cover only part of the sphere or the noise is "
            "large; use method=\"convex\", which constrains A to be positive definite"
        )
    if kind == IMAGINARY:
        raise FitError("the algebraic fit is an imaginary ellipsoid (no real points); check the data")
    return T, o


class SVDEllipsoidFit:
    """Lu 2017's algebraic ellipsoid fit by singular value decomposition (eq. 18-30).

    Parameters
    ----------
    allow_degenerate : bool
        Return a result (with a warning note) for pose sets that do not identify every parameter.
    """

    name = "svd"

    def __init__(self, allow_degenerate: bool = False) -> None:
        self.allow_degenerate = allow_degenerate

    def fit(self, poses: PoseTable) -> CalibrationResult:
        poses.validate()
        norm = Normaliser.of(poses.acc)
        with Stopwatch() as sw:
            J = design_matrix(norm.forward(poses.acc))
            _, s, vt = np.linalg.svd(J, full_matrices=False)
            eta = vt[-1]  # right singular vector of the smallest singular value
            try:
                T_n, o_n = quadric_to_calibration(eta)
            except FitError:
                # Poses that leave a pencil of quadrics through them (e.g. two cones about one axis) give
                # an arbitrary member of it here, often a hyperboloid: name what the poses leave undetermined,
                # judged at the unit sphere of the normalised data, before blaming noise or coverage.
                sphere = norm.theta_to_raw(theta_from(np.eye(3), np.zeros(3)))
                check_pose_set(poses, sphere, allow_degenerate=self.allow_degenerate)
                raise
        solver = SolverInfo("numpy.linalg.svd", "solved", True, 0, sw.seconds, f"smallest singular value {s[-1]:.3g}")
        return finish(
            method=self.name,
            poses=poses,
            theta=norm.theta_to_raw(theta_from(T_n, o_n)),
            solver=solver,
            allow_degenerate=self.allow_degenerate,
        )


@dataclass(frozen=True)
class ConvexSolution:
    """What one solve of :class:`ConvexEllipsoidProblem` returned.

    Attributes
    ----------
    status : str
        cvxpy's status (``optimal``, ``optimal_inaccurate``, ...).
    eta : ndarray or None, shape (10,)
        The quadric, ordered as in :func:`design_matrix`.
    A : ndarray or None, shape (3, 3)
    iterations : int
    """

    status: str
    eta: NDArray[np.float64] | None
    A: NDArray[np.float64] | None
    iterations: int


class ConvexEllipsoidProblem:
    """``min ‖R η‖²`` s.t. ``A ⪰ εI``, ``tr A = 3`` in cvxpy, ``R`` a parameter.

    Built once per (ε, solver, solver options): cvxpy keeps the solver it set up on the first
    solve and re-uses it, settings included, so one problem serves one set of settings.
    Solving sets the parameter and reads the variables: one step, under the problem's lock.
    """

    def __init__(self, eps: float, solver: str, options: FrozenOptions) -> None:
        import cvxpy as cp

        A = cp.Variable((3, 3), symmetric=True)
        b = cp.Variable(3)
        c = cp.Variable()
        self._R = cp.Parameter((10, 10))
        self._A = A
        self._eta = cp.hstack([A[0, 0], A[1, 1], A[2, 2], A[0, 1], A[0, 2], A[1, 2], b, c])
        constraints = [A >> eps * np.eye(3), cp.trace(A) == 3.0]
        self._problem = cp.Problem(cp.Minimize(cp.sum_squares(self._R @ self._eta)), constraints)
        self.solver, self.options = solver, dict(options)
        self._lock = threading.Lock()

    def with_data(self, R: NDArray) -> tuple[Any, dict[str, Any]]:
        """The cvxpy problem with ``R`` set, and its variables ``eta`` (the quadric) and ``A`` (for a
        :class:`optcal.solvers.formulation.ConicFormulation`; not shared between threads)."""
        self._R.value = R
        return self._problem, {"eta": self._eta, "A": self._A}

    def solve(self, R: NDArray) -> ConvexSolution:
        """Solve for the triangular factor ``R`` (10×10) of the design matrix."""
        with self._lock:
            self._R.value = R
            with warnings.catch_warnings():  # optcal says it itself (ConvergenceWarning), with what to change
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                self._problem.solve(solver=self.solver, **self.options)
            eta, A = self._eta.value, self._A.value
            return ConvexSolution(
                status=str(self._problem.status),
                eta=None if eta is None else np.asarray(eta, dtype=float),
                A=None if A is None else np.asarray(A, dtype=float),
                iterations=int(self._problem.solver_stats.num_iters or 0),
            )


#: The convex problems, keyed by (ε, solver, frozen solver options).
CONVEX_PROBLEMS: ProblemCache[ConvexEllipsoidProblem] = problem_cache(ConvexEllipsoidProblem, maxsize=8)


#: Options each conic solver starts from (the user's ``solver_options`` go on top).  The cost
#: ‖Rη‖² of normalised data is about n σ² (1e-6 for a 5 mg sensor's hundred poses), so the
#: solvers' default absolute tolerances (1e-8 for Clarabel's duality gap, 1e-4 for SCS) are a
#: percent of it: where the semidefinite constraint is active (the KKT polish does not apply)
#: Clarabel stopped with min eig(A) at 1.047 ε instead of ε and its θ 7e-3 (normalised) from
#: SCS's on imucal's Ferraris session.  At 1e-12 (gap and feasibility) both agree to 2e-6 there
#: (a pose set that leaves o_z undetermined) and to 1e-14 on imu_tk's Xsens log.
CONIC_DEFAULTS: dict[str, dict[str, Any]] = {
    "SCS": {"eps_abs": 1e-10, "eps_rel": 1e-10, "max_iters": 200_000},
    "CLARABEL": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12},
}


class ConvexEllipsoidFit:
    """The algebraic ellipsoid fit as a semidefinite-constrained convex problem in cvxpy.

    Parameters
    ----------
    solver : str
        cvxpy solver name; ``"CLARABEL"`` by default.  Any installed solver that takes the
        semidefinite constraint (:func:`optcal.solvers.registry.available_conic_solvers`:
        CLARABEL, SCS, CVXOPT, MOSEK, ...); another is refused naming those.
    eps : float
        Lower bound on the eigenvalues of the normalised ``A`` (whose trace is 3).
    polish : bool
        Re-solve exactly by the KKT system when the semidefinite constraint is inactive.
    allow_degenerate : bool
        Return a result for pose sets that do not identify every parameter.
    solver_options : dict, optional
        Passed to ``problem.solve`` (on top of :data:`CONIC_DEFAULTS`).
    conic_solver : str, optional
        The same as ``solver`` (the spelling every estimator shares: ``optcal.calibrate(poses,
        method="convex", conic_solver="SCS")``); it wins when both are given.
    """

    name = "convex"

    def __init__(
        self,
        solver: str = "CLARABEL",
        eps: float = 1e-3,
        polish: bool = True,
        allow_degenerate: bool = False,
        solver_options: dict[str, Any] | None = None,
        conic_solver: str | None = None,
    ) -> None:
        from optcal.solvers.registry import choose_conic_solver

        self.solver = choose_conic_solver(conic_solver or solver)
        self.eps = float(eps)
        self.polish = polish
        self.allow_degenerate = allow_degenerate
        self.solver_options = {**CONIC_DEFAULTS.get(self.solver, {}), **dict(solver_options or {})}

    def fit(self, poses: PoseTable) -> CalibrationResult:
        import cvxpy as cp

        poses.validate()
        norm = Normaliser.of(poses.acc)
        J = design_matrix(norm.forward(poses.acc))
        R = np.zeros((10, 10))
        R_qr: NDArray[np.float64] = np.linalg.qr(J, mode="r")  # type: ignore[assignment]  # numpy stubs type R alone as QRResult
        R[: R_qr.shape[0]] = R_qr  # (min(n, 10), 10): pad for fewer than 10 poses
        notes: list[str] = []
        with Stopwatch() as sw:
            try:
                solution = CONVEX_PROBLEMS.get(self.eps, self.solver, freeze_options(self.solver_options)).solve(R)
            except cp.error.SolverError as exc:
                raise SolverError(f"the convex ellipsoid fit failed in {self.solver}: {exc}; try solver='SCS'") from exc
        status = solution.status
        if status not in cp.settings.SOLUTION_PRESENT or solution.eta is None or solution.A is None:
            # the problem is always feasible (A = I) and bounded below (by 0): any other end is the solver's
            raise SolverError(f"the convex ellipsoid fit ended with status {status!r} in {self.solver}; try solver='SCS'")
        eta_v = solution.eta
        iters = solution.iterations
        message = ""
        # to the solver's own precision (its gap is 1e-12): the digits below differ between two solves of the
        # same cached problem, and the result must not
        min_eig = float(f"{np.linalg.eigvalsh(solution.A)[0]:.9g}")
        active = min_eig < 2 * self.eps
        if active:
            notes.append(
                "the semidefinite constraint A ⪰ εI is active: the unconstrained algebraic fit is not an "
                "ellipsoid (poses on part of the sphere or large noise); the answer is the nearest ellipsoid"
            )
        elif self.polish:
            eta_v = kkt_polish(R)
            message = "polished by KKT solve (semidefinite constraint inactive)"
        try:
            T_n, o_n = quadric_to_calibration(eta_v)
        except FitError as exc:
            raise FitError(f"the convex fit returned a degenerate ellipsoid ({exc})") from exc
        solver = SolverInfo(self.solver, status, status == cp.OPTIMAL, iters, sw.seconds, message)
        return finish(
            method=self.name,
            poses=poses,
            theta=norm.theta_to_raw(theta_from(T_n, o_n)),
            solver=solver,
            allow_degenerate=self.allow_degenerate,
            notes=notes,
            extra={"min_eigenvalue_normalised_A": min_eig, "psd_constraint_active": active},
            remedy=Remedy(stopped_early="raise the solver's iteration limit (solver_options) or try solver='SCS'",
                          failed="try solver='SCS'"),
        )
