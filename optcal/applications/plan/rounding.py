"""From relaxed weights to K poses: apportionment, exchange, refinement on the sphere.

1. Efficient apportionment (Pukelsheim & Rieder 1992) turns the weights into pose counts.
2. An exchange pass (Fedorov's exchange, here exhaustive over the candidates) replaces one
   pose at a time by the candidate that improves the criterion most, until no swap helps.
3. For free orientations (or a cap) the poses then leave the grid: a local refinement of all
   K directions at once, solved by IPOPT in CasADi with ``‖d_k‖ = 1`` (and ``d_k·axis ≥ cos α``
   in a cap) as constraints; the criterion and its gradient come from numpy
   (:func:`optcal.applications.plan.information.criterion_gradient` with the information vectors'
   derivative by central differences).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.plan.candidates import Cap
from optcal.applications.plan.information import Criterion, criterion_gradient, criterion_value, criterion_values, information
from optcal.solvers.convergence import plugin_status
from optcal.solvers.nlp import CallbackNLP, NumpyObjective

#: Step of the central differences of the information vectors (unit directions).
DIFF_STEP: float = 1e-6
#: IPOPT tuning of the refinement (on :data:`optcal.solvers.nlp.IPOPT_DEFAULTS`): the criterion's
#: Hessian is not computed (limited-memory quasi-Newton), a local improvement of the rounded design
#: is all that is asked (tolerance 1e-9, at most 60 iterations) and the barrier parameter follows
#: IPOPT's own monotone rule.
REFINE_IPOPT_TUNING: dict[str, Any] = {
    "ipopt.hessian_approximation": "limited-memory",
    "ipopt.mu_strategy": "monotone",
    "ipopt.tol": 1e-9,
    "ipopt.acceptable_tol": 1e-7,
    "ipopt.acceptable_iter": 3,
    "ipopt.max_iter": 60,
}


def apportion(weights: NDArray, n_poses: int) -> NDArray[np.int64]:
    """Candidate index of each of ``n_poses`` poses by efficient apportionment of ``weights``.

    Only the support (weights above 10⁻⁴ of the largest) takes part; when it has more points
    than poses, the heaviest ``n_poses`` get one pose each.
    """
    support = np.flatnonzero(weights > 1e-4 * weights.max())
    support = support[np.argsort(-weights[support])]
    if len(support) >= n_poses:
        return support[:n_poses]
    w = weights[support] / weights[support].sum()
    counts = np.ceil((n_poses - len(support) / 2.0) * w).astype(int)
    while counts.sum() < n_poses:
        counts[np.argmin(counts / w)] += 1
    while counts.sum() > n_poses:
        counts[np.argmax((counts - 1) / w)] -= 1
    return np.repeat(support, counts)


def exchange(H: NDArray, design: NDArray, criterion: Criterion, base: NDArray | None = None,
             max_sweeps: int = 50) -> NDArray[np.int64]:
    """Improve a design (candidate indices) by single swaps until none helps."""
    design = np.array(design, dtype=np.int64)
    p = H.shape[1]
    M0 = np.zeros((p, p)) if base is None else base
    outer = np.einsum("ni,nj->nij", H, H)
    M = information(H[design], base=M0)
    value = criterion_value(M, criterion)
    for _ in range(max_sweeps):
        improved = False
        for k in range(len(design)):
            trial = _swap_values(M, value, H, outer, design[k], criterion)
            j = int(np.argmax(trial))
            if trial[j] > value + 1e-12 * max(1.0, abs(value)) or (not np.isfinite(value) and np.isfinite(trial[j])):
                M = M - outer[design[k]] + outer[j]
                design[k] = j
                value = float(trial[j])
                improved = True
        if not improved:
            break
    return design


def _swap_values(M: NDArray, value: float, H: NDArray, outer: NDArray, k: int, criterion: Criterion) -> NDArray:
    """Criterion of the design with pose ``k`` replaced by each candidate."""
    if criterion is Criterion.D and np.isfinite(value):
        # Fedorov's exchange: det(M − h_k h_kᵀ + h_j h_jᵀ)/det M
        # = (1 + d_j)(1 − d_k) + d_kj²  with d = hᵀ M⁻¹ h
        MinvH = np.linalg.solve(M, H.T)
        d_all = np.einsum("ij,ji->i", H, MinvH)
        ratio = (1.0 + d_all) * (1.0 - d_all[k]) + (H[k] @ MinvH) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(ratio > 0, value + np.log(np.where(ratio > 0, ratio, 1.0)), -np.inf)
    return criterion_values(M - outer[k] + outer, criterion)


def sequential(H: NDArray, n_poses: int, criterion: Criterion, base: NDArray | None = None) -> NDArray[np.int64]:
    """Greedy design: add the candidate with the largest improvement, one pose at a time.

    While the information is singular, a ridge of 10⁻⁹ of its scale keeps the gains finite, so
    the first poses fill the undetermined combinations.
    """
    p = H.shape[1]
    M = np.zeros((p, p)) if base is None else base.copy()
    outer = np.einsum("ni,nj->nij", H, H)
    ridge = 1e-9 * max(np.trace(M), np.mean(np.sum(H**2, axis=1))) * np.eye(p)
    design = []
    for _ in range(n_poses):
        j = int(np.argmax(criterion_values(M + ridge + outer, criterion)))
        design.append(j)
        M = M + outer[j]
    return np.array(design, dtype=np.int64)


def information_derivative(vectors: Callable[[NDArray], NDArray], directions: NDArray) -> NDArray[np.float64]:
    """``∂h_k/∂d_k`` by central differences, shape (K, p, 3)."""
    K = len(directions)
    steps = np.eye(3) * DIFF_STEP
    plus = vectors((directions[:, None, :] + steps[None]).reshape(-1, 3)).reshape(K, 3, -1)
    minus = vectors((directions[:, None, :] - steps[None]).reshape(-1, 3)).reshape(K, 3, -1)
    return np.swapaxes((plus - minus) / (2 * DIFF_STEP), 1, 2)


@dataclass(frozen=True)
class RefineProblem:
    """The refinement on the sphere as an NLP evaluated in numpy (:func:`refine_problem`).

    ``objective`` is ``−Φ(M)/|Φ(M₀)|`` with its gradient; ``constraints(x)`` the CasADi
    expressions ``‖d_k‖² − 1`` (= 0) and, with a cap, ``d_k · axis`` (≥ cos of its half-angle);
    ``lbg``, ``ubg`` their bounds; ``start_value`` the criterion at the start.
    """

    objective: NumpyObjective
    constraints: Callable[[Any], Any]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]
    start_value: float
    n: int


def refine_problem(vectors: Callable[[NDArray], NDArray], directions: NDArray, criterion: Criterion,
                   base: NDArray | None = None, cap: Cap | None = None) -> RefineProblem:
    """The NLP that moves all K directions on the sphere (in the cap) to a local optimum of the criterion."""
    import casadi as ca

    K = len(directions)
    p = vectors(directions[:1]).shape[1]
    M0 = np.zeros((p, p)) if base is None else base
    start_value = criterion_value(information(vectors(directions), base=M0), criterion)
    scale = max(abs(start_value), 1.0)

    def cost_and_gradient(x: NDArray) -> tuple[float, NDArray]:
        d = x.reshape(K, 3)
        H = vectors(d)
        M = information(H, base=M0)
        value = criterion_value(M, criterion)
        if not np.isfinite(value):
            return 1e6, np.zeros(3 * K)
        G = criterion_gradient(M, criterion)
        dH = information_derivative(vectors, d)  # (K, p, 3)
        grad = 2.0 * np.einsum("kp,pq,kqj->kj", H, G, dH)
        return -value / scale, -grad.ravel() / scale

    def constraints(x: Any) -> Any:
        D = ca.reshape(x, 3, K).T  # row k is d_k (CasADi reshapes column-major)
        g = [ca.sum2(D**2) - 1.0]
        if cap is not None:
            g.append(ca.mtimes(D, ca.DM(cap.axis)))
        return ca.vertcat(*g)

    lbg, ubg = [np.zeros(K)], [np.zeros(K)]
    if cap is not None:
        lbg.append(np.full(K, cap.cos_half_angle))
        ubg.append(np.full(K, np.inf))
    return RefineProblem(NumpyObjective(lambda x: cost_and_gradient(x)[0], cost_and_gradient), constraints,
                         np.concatenate(lbg), np.concatenate(ubg), float(start_value), 3 * K)


def refine(vectors: Callable[[NDArray], NDArray], directions: NDArray, criterion: Criterion,
           base: NDArray | None = None, cap: Cap | None = None,
           ipopt_options: dict[str, Any] | None = None, solver: str | None = None) -> tuple[NDArray[np.float64], str]:
    """Move all K directions on the sphere (in the cap) to a local optimum of the criterion (IPOPT).

    Returns the refined directions (the start when IPOPT does not improve on it) and IPOPT's
    return status.  ``ipopt_options`` override :data:`REFINE_IPOPT_TUNING`; options IPOPT refuses
    are an :class:`~optcal.errors.InputError`.  ``solver`` names another NLP solver of
    :data:`optcal.solvers.registry.NLP_SOLVERS` (``ipopt_options`` are then its options).
    """
    K = len(directions)
    p = vectors(directions[:1]).shape[1]
    M0 = np.zeros((p, p)) if base is None else base
    problem = refine_problem(vectors, directions, criterion, base, cap)
    nlp = CallbackNLP("plan_refine", problem.n, constraints=problem.constraints, tuning=REFINE_IPOPT_TUNING,
                      solver=solver or "ipopt", solver_options=ipopt_options)
    x, stats = nlp.solve(problem.objective, x0=directions.ravel(), lbg=problem.lbg, ubg=problem.ubg)
    status = plugin_status(stats)
    refined = x.reshape(K, 3)
    refined = refined / np.linalg.norm(refined, axis=1, keepdims=True)
    if cap is not None and not np.all(cap.contains(refined, slack=1e-7)):
        return directions, status
    value = criterion_value(information(vectors(refined), base=M0), criterion)
    return (refined, status) if value > problem.start_value else (directions, status)


__all__ = ["RefineProblem", "apportion", "exchange", "information_derivative", "refine", "refine_problem", "sequential"]
