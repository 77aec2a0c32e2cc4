"""The convex relaxation of pose planning and its certificate.

Choosing K poses from candidate directions ``d_i`` is relaxed to choosing weights ``w`` on the
simplex (the approximate design of Kiefer)::

    maximise  f(M(w)),   M(w) = M₀ + K Σ_i w_i h_i h_iᵀ,   w ≥ 0,  Σ w = 1

with ``f = log det`` (D), ``−tr M⁻¹`` (A, written as the matrix-fractional function
``tr(Iᵀ M⁻¹ I)``, a Schur-complement LMI) or ``λ_min`` (E) and ``M₀`` the information of
poses already taken.  Each is a conic program (solved by Clarabel, SCS as the fallback).

Certificate.  ``f`` is concave, so for any design ξ of K poses anywhere in the feasible set
(on the grid or not) ``f(M(ξ)) ≤ f(M) + ⟨∇f(M), M(ξ) − M⟩ ≤ f(M) + K max_d φ(d) − ⟨∇f(M), M − M₀⟩``
with the sensitivity ``φ(d) = h(d)ᵀ ∇f(M) h(d)`` (for E, ``∇f = v vᵀ`` with ``v`` the weakest
direction, a supergradient).  Maximising φ over the whole feasible set, not only the grid,
makes this bound hold for refined poses too (Kiefer–Wolfowitz equivalence: the bound equals
``f(M)`` exactly when ``M`` is optimal over the set).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.errors import SolverError
from optcal.applications.plan.candidates import CandidateSet, fibonacci_sphere
from optcal.applications.plan.information import Criterion, criterion_gradient, criterion_value

#: Grid over which the sensitivity φ is maximised for the bound (before local refinement).
SENSITIVITY_GRID: int = 20000


@dataclass(frozen=True)
class Relaxation:
    """Solution of the relaxation.

    Attributes
    ----------
    weights : ndarray, shape (n,)
        Weight of each candidate direction (sums to 1).
    information : ndarray, shape (p, p)
        ``M(w)`` (including the poses already taken).
    value : float
        ``f(M(w))``: no K-pose design on the grid does better.
    bound : float
        The certificate (module docstring): no K-pose design in the feasible set does better.
    solver : str
        The conic solver that solved it.
    """

    weights: NDArray[np.float64]
    information: NDArray[np.float64]
    value: float
    bound: float
    solver: str

    @property
    def support(self) -> NDArray[np.int64]:
        """Candidates with a weight above 10⁻⁴ of the largest, heaviest first."""
        idx = np.flatnonzero(self.weights > 1e-4 * self.weights.max())
        return idx[np.argsort(-self.weights[idx])]


def solve_relaxation(H: NDArray, n_poses: int, criterion: Criterion, base: NDArray | None = None) -> tuple[NDArray, str]:
    """Weights of the relaxed design over the candidates with information vectors ``H`` (n, p)."""
    import cvxpy as cp

    n, p = H.shape
    M0 = np.zeros((p, p)) if base is None else base
    # Whitening by the uniform design's information M_u (congruence M' = S M Sᵀ, S = M_u^(−1/2))
    # keeps each criterion exact and the conic problem well conditioned when the feasible set
    # is narrow: log det M' = log det M + const, tr M⁻¹ = tr(Sᵀ M'⁻¹ S), M ⪰ tI ⟺ M' ⪰ t S Sᵀ.
    evals, evecs = np.linalg.eigh(M0 + n_poses * (H.T @ H) / n)
    S = (evecs / np.sqrt(np.clip(evals, evals[-1] * 1e-15, None))) @ evecs.T
    Hw, M0w = H @ S, S @ M0 @ S
    # vec(h_i h_iᵀ) as columns: M(w) is affine in w
    outer = np.einsum("ni,nj->ijn", Hw, Hw).reshape(p * p, n)
    w = cp.Variable(n, nonneg=True)
    M = cp.reshape(outer @ w, (p, p), order="C") * n_poses + M0w
    M = (M + M.T) / 2
    constraints = [cp.sum(w) == 1]
    objective: cp.Maximize | cp.Minimize
    if criterion is Criterion.D:
        objective = cp.Maximize(cp.log_det(M))
    elif criterion is Criterion.A:
        objective = cp.Minimize(cp.matrix_frac(S, M))
    else:
        t = cp.Variable()
        objective = cp.Maximize(t)
        constraints.append(M - t * (S @ S) >> 0)
    problem = cp.Problem(objective, constraints)
    failures = []
    for solver in ("CLARABEL", "SCS"):
        try:
            problem.solve(solver=solver)
        except cp.error.SolverError as exc:
            failures.append(f"{solver}: {exc}")
            continue
        if problem.status in ("optimal", "optimal_inaccurate") and w.value is not None:
            weights = np.clip(np.asarray(w.value, float), 0.0, None)
            return weights / weights.sum(), solver.lower()
        failures.append(f"{solver}: {problem.status}")
    raise SolverError("the relaxation of the pose plan was not solved (" + "; ".join(failures) + ")")


def maximise_on_set(function: Callable[[NDArray], NDArray], candidates: CandidateSet,
                    grid: int = SENSITIVITY_GRID, polish: int = 4) -> float:
    """Maximum of ``function`` (directions (n, 3) → values (n,)) over the feasible set.

    A fixed list is searched exhaustively; a continuous set (sphere or cap) on a dense grid and
    its candidates, then the ``polish`` best points by Nelder–Mead on the tangent plane.
    """
    if not candidates.continuous:
        return float(np.max(function(candidates.directions)))
    from scipy.optimize import minimize

    dense = fibonacci_sphere(grid)
    if candidates.cap is not None:
        dense = dense[candidates.cap.contains(dense)]
    points = np.vstack([dense, candidates.directions])
    values = function(points)
    best = float(np.max(values))
    for start in points[np.argsort(-values)[:polish]]:
        e1 = np.linalg.svd(start[None, :])[2][1]
        e2 = np.cross(start, e1)

        def negative(ab: NDArray, start: NDArray = start, e1: NDArray = e1, e2: NDArray = e2) -> float:
            d = start + ab[0] * e1 + ab[1] * e2
            d = d / np.linalg.norm(d)
            if candidates.cap is not None and not candidates.cap.contains(d[None, :])[0]:
                return -best
            return -float(function(d[None, :])[0])

        res = minimize(negative, np.zeros(2), method="Nelder-Mead",
                       options={"xatol": 1e-7, "fatol": 1e-12, "initial_simplex": [[0, 0], [0.02, 0], [0, 0.02]]})
        best = max(best, -float(res.fun))
    return best


def _weakest_subspace_weight(M: NDArray, H: NDArray, rtol: float = 1e-3) -> NDArray[np.float64]:
    """``Z = V W Vᵀ`` for the E bound: ``V`` spans the eigenvectors of λ_min (within ``rtol``), and
    ``W ⪰ 0``, ``tr W = 1`` minimises the largest sensitivity over the candidates.

    At an E-optimal design the smallest eigenvalue is usually multiple, and a single
    eigenvector (a valid but loose supergradient) overstates the bound.
    """
    import cvxpy as cp

    evals, evecs = np.linalg.eigh(0.5 * (M + M.T))
    V = evecs[:, evals <= evals[0] + rtol * max(abs(evals[0]), 1e-300)]
    m = V.shape[1]
    if m == 1:
        return np.outer(V[:, 0], V[:, 0])
    P = H @ V
    W = cp.Variable((m, m), PSD=True)
    t = cp.Variable()
    problem = cp.Problem(cp.Minimize(t), [cp.trace(W) == 1, cp.sum(cp.multiply(P @ W, P), axis=1) <= t])
    for solver in ("CLARABEL", "SCS"):
        try:
            problem.solve(solver=solver)
        except cp.error.SolverError:
            continue
        if W.value is not None:
            Wv = 0.5 * (W.value + W.value.T)
            e, U = np.linalg.eigh(Wv)
            Wv = (U * np.clip(e, 0, None)) @ U.T
            Wv /= np.trace(Wv)
            return V @ Wv @ V.T
    return np.outer(V[:, 0], V[:, 0])


def relax(H: NDArray, n_poses: int, criterion: Criterion, candidates: CandidateSet,
          vectors: Callable[[NDArray], NDArray], base: NDArray | None = None) -> Relaxation:
    """Solve the relaxation and certify it (module docstring).

    ``vectors`` maps directions to information vectors (:meth:`Prior.information_vectors`).
    """
    p = H.shape[1]
    M0 = np.zeros((p, p)) if base is None else base
    weights, solver = solve_relaxation(H, n_poses, criterion, M0)
    M = M0 + n_poses * (H.T @ (H * weights[:, None]))
    value = criterion_value(M, criterion)
    G = criterion_gradient(M, criterion) if criterion is not Criterion.E else _weakest_subspace_weight(M, H)

    def sensitivity(d: NDArray) -> NDArray:
        h = vectors(d)
        return np.einsum("ni,ij,nj->n", h, G, h)

    top = maximise_on_set(sensitivity, candidates)
    if criterion is Criterion.E:
        # λ_min(M(ξ)) ≤ ⟨Z, M(ξ)⟩ = ⟨Z, M₀⟩ + K E_ξ[hᵀ Z h] for every Z ⪰ 0 with tr Z = 1
        bound = float(np.sum(G * M0)) + n_poses * top
    else:
        bound = value + n_poses * top - float(np.sum(G * (M - M0)))
    return Relaxation(weights, M, value, max(bound, value), solver)


__all__ = ["Relaxation", "maximise_on_set", "relax", "solve_relaxation"]
