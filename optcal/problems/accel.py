"""The accelerometer's problems as formulations: the convex ellipsoid fit, the norm-residual ML, the exact ML."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import PARAM_NAMES, theta_from, unpack_theta
from optcal.core.poses import PoseTable
from optcal.families.accel.base import Normaliser
from optcal.families.accel.ellipsoid import CONIC_DEFAULTS, ConvexEllipsoidProblem, design_matrix
from optcal.families.accel.mle import MaximumLikelihood, ml_nlp, scaled_cost
from optcal.solvers.formulation import ConicFormulation, Formulation
from optcal.solvers.nlp import SCALED_COST_IPOPT_OPTIONS

#: How the accelerometer's NLPs are scaled (every builder of this module).
NORMALISED = ("data normalised u = (a − m)/s (m the mean pose, s the rms distance to it); θ' in those coordinates "
              "(T = T'/s, o = m + s o': theta_of() maps back)")


def convex_fit(poses: PoseTable, eps: float = 1e-3) -> ConicFormulation:
    """The convex algebraic ellipsoid fit (Lu 2017, eq. 18-23) as a cvxpy problem.

    ``min ‖R η‖²`` s.t. ``A ⪰ εI``, ``tr A = 3``, with η the quadric ``(A, b, c)`` of the
    normalised data and R the triangular factor of its design matrix (eq. 23).  Solve with any
    installed cvxpy solver that takes the semidefinite constraint (``.solve("SCS")``).

    Parameters
    ----------
    poses : PoseTable
        The static poses (raw units).
    eps : float
        The smallest eigenvalue ε allowed to ``A`` (normalised units), which keeps the fit an ellipsoid.

    Returns
    -------
    ConicFormulation
        The cvxpy problem with its variables, equation and scaling.
    """
    poses.validate()
    norm = Normaliser.of(poses.acc)
    D = design_matrix(norm.forward(poses.acc))
    R = np.zeros((10, 10))
    R_qr = np.asarray(np.linalg.qr(D, mode="r"))
    R[: R_qr.shape[0]] = R_qr
    problem, variables = ConvexEllipsoidProblem(eps, "CLARABEL", ()).with_data(R)
    return ConicFormulation(
        name="convex ellipsoid fit",
        equation=f"min ‖R η‖² s.t. A ⪰ {eps:g} I, tr A = 3 (Lu 2017, eq. 18-23; η = (A_xx, A_yy, A_zz, A_xy, A_xz, "
                 "A_yz, b, c) of the quadric uᵀAu + bᵀu + c = 0)",
        scaling=NORMALISED + "; tr A = 3 fixes the quadric's scale",
        problem=problem,
        variables=variables,
        solver_defaults=dict(CONIC_DEFAULTS),
    )


def theta_of(poses: PoseTable, x: NDArray) -> NDArray[np.float64]:
    """θ in raw units from the first nine entries of a formulation's solution (normalised θ').

    Parameters
    ----------
    poses : PoseTable
        The poses the formulation was built from (their normalisation is undone).
    x : ndarray
        The formulation's solution; its first nine entries are the normalised θ'.

    Returns
    -------
    ndarray, shape (9,)
        θ in the poses' raw units (the convention of :mod:`optcal.core.model`).
    """
    return Normaliser.of(poses.acc).theta_to_raw(np.asarray(x, dtype=float)[:9])


def norm_residual_ml(poses: PoseTable, **settings: Any) -> Formulation:
    """The norm-residual maximum-likelihood problem (Lu 2017, eq. 13-14) at its start.

    ``min_θ' c Σ_k ρ(√w_k r_k(θ'))``, ``r_k = ‖T'(u_k − o')‖ − 1``, with ρ the loss (squared,
    Huber, Cauchy), the weights of the first pass (propagated noise, scaled to mean one), the
    cost scale c of :func:`optcal.solvers.nlp.cost_scale`, the user's bounds on θ entries and
    constraints on physical parameters.  ``settings`` are those of
    :class:`~optcal.families.accel.mle.MaximumLikelihood` (``loss``, ``fix``, ``bounds``, ...);
    its :meth:`~optcal.families.accel.mle.MaximumLikelihood.fit` solves this problem, reweights
    and solves again until the weights settle.
    """
    ml = MaximumLikelihood(**settings)
    setup = ml.setup(poses)
    _, w_n, delta_n = ml.pass_data(poses, setup, setup.theta_n)
    cost = scaled_cost(setup.u, w_n, setup.theta_n, ml.loss, delta_n)
    nlp = ml_nlp(poses.n, ml.loss, setup.physical)
    values: dict[str, Any] = {"x0": setup.theta_n, "p": np.concatenate([setup.u.ravel(), w_n, [delta_n, cost.scale]])}
    for key in ("lbx", "ubx", "lbg", "ubg"):
        if getattr(setup, key) is not None:
            values[key] = np.asarray(getattr(setup, key), dtype=float)
    constraints = [f"{name} within its bounds" + (" (scale factor in normalised units S' = S/s)" if name.startswith("S_") else
                                                   " (degrees)") for name in setup.physical]
    return Formulation(
        name="norm-residual ML",
        equation=f"min_θ' c Σ_k ρ(√w_k r_k(θ')), r_k = ‖T'(u_k − o')‖ − 1, ρ = {ml.loss} loss (Lu 2017, eq. 13-14)",
        variables=[f"{name}'" for name in PARAM_NAMES],
        parameters={"a": f"normalised measurements u_k, 3×{poses.n} column-major",
                    "w": f"weights of the first pass, mean one ({ml.weighting})",
                    "delta": "robust loss threshold (weighted residual units)", "scale": "cost scale c = 1/(n s₀)"},
        scaling=NORMALISED + f"; cost scaled by c = {cost.scale:.4g} so one tolerance serves any n, noise, units",
        nlp_dict=nlp,
        values=values,
        constraints=constraints,
        tuning=dict(SCALED_COST_IPOPT_OPTIONS),
        structure=("norm-residual ML", poses.n, ml.loss, setup.physical),
    )


def exact_ml(poses: PoseTable, start: NDArray | None = None) -> Formulation:
    """The exact errors-in-variables ML problem (Lu 2017, eq. 8), pose by pose: 9 + 3n variables, n constraints.

    ``min Σ_k w_k ‖u_k − o' − C' ā_k‖²`` s.t. ``‖ā_k‖² = 1``, C' lower-triangular with a positive
    diagonal (the identifiable form), from ``start`` (θ in raw units; the norm-residual ML's
    answer by default) with the latent directions at their radial projections (eq. 10).

    Parameters
    ----------
    poses : PoseTable
        The static poses (raw units).
    start : ndarray, optional
        θ in raw units to start from; by default the norm-residual ML's answer.

    Returns
    -------
    Formulation
        The 9 + 3n NLP with its variables, constraints and scaling.
    """
    import casadi as ca

    from optcal.core.norm_residual import casadi_lower_triangular

    poses.validate()
    n = poses.n
    if start is None:
        start = MaximumLikelihood(allow_degenerate=True).fit(poses).params
    norm = Normaliser.of(poses.acc)
    u = norm.forward(poses.acc)
    T_n, o_n = unpack_theta(norm.theta_to_normalised(np.asarray(start, dtype=float)))
    xi = (u - o_n) @ T_n.T
    d0 = xi / np.linalg.norm(xi, axis=1, keepdims=True)  # Lu 2017, eq. 10
    x0 = np.concatenate([theta_from(np.linalg.inv(T_n), o_n), d0.ravel()])
    w = np.ones(n) if poses.sigma is None else 1.0 / poses.sigma**2
    w = w / np.mean(w)
    x = ca.SX.sym("x", 9 + 3 * n)
    p = ca.SX.sym("p", 4 * n)
    C, o = casadi_lower_triangular(x[:6]), x[6:9]
    d = ca.reshape(x[9:], 3, n)
    a = ca.reshape(p[: 3 * n], 3, n)
    e = a - ca.repmat(o, 1, n) - ca.mtimes(C, d)  # Lu 2017, eq. 8
    nlp = {"x": x, "p": p, "f": ca.sum2(p[3 * n:].T * ca.sum1(e * e)), "g": ca.sum1(d * d).T - 1.0}
    lbx = np.full(x0.size, -np.inf)
    lbx[[0, 2, 5]] = 1e-9  # positive diagonal of C
    return Formulation(
        name="exact ML",
        equation="min Σ_k w_k ‖u_k − o' − C' ā_k‖² s.t. ‖ā_k‖² = 1 (Lu 2017, eq. 8; errors in variables)",
        variables=["C'_xx", "C'_yx", "C'_yy", "C'_zx", "C'_zy", "C'_zz", "o'_x", "o'_y", "o'_z", f"ā_k (3 per pose, {n} poses)"],
        parameters={"p": f"normalised measurements (3×{n} column-major), then the weights (mean one)"},
        scaling=NORMALISED + "; C' = T'⁻¹; weights 1/σ_k² scaled to mean one",
        nlp_dict=nlp,
        values={"x0": x0, "p": np.concatenate([u.ravel(), w]), "lbx": lbx, "lbg": np.zeros(n), "ubg": np.zeros(n)},
        constraints=[f"‖ā_k‖² = 1 for each of the {n} poses"],
        tuning={"ipopt.tol": 1e-10, "ipopt.max_iter": 500},
        structure=("exact ML", n),
    )


def exact_theta(poses: PoseTable, x: NDArray) -> NDArray[np.float64]:
    """θ in raw units from a solution of :func:`exact_ml` (``T' = C'⁻¹``).

    Parameters
    ----------
    poses : PoseTable
        The poses :func:`exact_ml` was built from.
    x : ndarray
        Its solution; the first nine entries are ``C'`` and ``o'``.

    Returns
    -------
    ndarray, shape (9,)
        θ in the poses' raw units.
    """
    C, o = unpack_theta(np.asarray(x, dtype=float)[:9])
    return Normaliser.of(poses.acc).theta_to_raw(theta_from(np.linalg.inv(C), o))


__all__ = ["convex_fit", "exact_ml", "exact_theta", "norm_residual_ml", "theta_of"]
