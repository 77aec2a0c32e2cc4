"""Lu 2017, eq. 8 by variable projection: the nine calibration parameters of the profile likelihood.

The errors-in-variables likelihood (Lu 2017, eq. 8)::

    min_{θ, ā_1..ā_n}  Σ_k w_k ‖a_k − o − C ā_k‖²    s.t. ‖ā_k‖ = 1,   C = T⁻¹

separates over poses once θ = (T, o) is fixed: pose k's latent direction is the closest point of
the ellipsoid to ``a_k`` (:func:`optcal.families.accel.ellipsoid_projection.closest_points`, one
secular equation each, vectorised).  Eliminating them leaves the profile cost of nine variables::

    f(θ) = Σ_k w_k ρ_k(θ)²,      ρ_k = signed distance of a_k to the ellipsoid of θ

whose minimiser is the θ of eq. 8 (variable projection, Golub & Pereyra 1973).  By the envelope
theorem the derivative of ``ρ_k`` is that of ``n̂_kᵀ(a_k − o − C d_k)`` with the closest direction
``d_k`` and the unit normal ``n̂_k`` held fixed::

    ∂ρ_k/∂o = −n̂_k,      ∂ρ_k/∂T_ij = (Cᵀ n̂_k)_i (C d_k)_j        (dC = −C dT C)

so Levenberg–Marquardt on the n scalar residuals ``√w_k ρ_k`` with this n × 9 Jacobian costs one
projection and one 9 × 9 system per iteration.  ``JᵀWJ`` is the information of θ with the directions
eliminated (each pose's 3 × 3 noise projected on the ellipsoid's normal), the Fisher information of
:mod:`optcal.core.identifiability` evaluated at the fitted closest points.

The covariance reported is the inverse of the profile cost's exact Hessian (the observed
information of θ, :func:`profile_hessian`), which is the Schur complement of the full
``9 + 3n``-variable NLP's reduced Hessian of the Lagrangian on its directions' block: computed pose
by pose in closed form (the cost is bilinear in C and the directions) and mapped from C to T.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.core.model import TRIL_INDEX, unpack_theta
from optcal.families.accel.ellipsoid_projection import ClosestPoints, closest_points

#: Levenberg–Marquardt stops when the Gauss–Newton step moves θ by less than this many standard
#: errors (``δᵀ JᵀWJ δ / σ̂² ≤ STEP_TOL_SE²``): far below any statistical meaning, and about where the
#: cost's rounding (1e-16 of n terms) stops resolving a change.
STEP_TOL_SE = 1e-7
#: A step smaller than this in every component of θ (the data normalised, θ of order 1) is rounding:
#: converged whatever the noise (noise-free data leave no σ̂ to measure the step in).
STEP_TOL_ABS = 1e-12
#: Iterations at most.  From the norm-residual ML's answer the profile cost's minimum is a few
#: Gauss–Newton steps away (its residuals are O(σ), so Gauss–Newton converges fast).
MAX_ITER = 100
#: Marquardt's damping: start, factor on a rejected and on an accepted step.
DAMPING_START, DAMPING_UP, DAMPING_DOWN = 1e-6, 10.0, 0.1
#: Poses per block when summing the per-pose Hessian blocks (bounds the (block, 9, 3) temporaries).
HESSIAN_BLOCK = 1 << 16

_TI = np.array([i for i, _ in TRIL_INDEX])
_TJ = np.array([j for _, j in TRIL_INDEX])


@dataclass(frozen=True)
class ProfileFit:
    """The minimiser of the profile cost (:func:`fit_profile`).

    Attributes
    ----------
    theta : ndarray, shape (9,)
        θ = (T lower-triangular, o) in the coordinates of the data given.
    cost : float
        ``Σ w_k ρ_k²`` at θ.
    iterations : int
        Levenberg–Marquardt iterations (accepted and rejected steps).
    projection_iterations : int
        Newton iterations of the slowest secular equation, summed over the projections.
    converged : bool
        Whether the last Gauss–Newton step was below :data:`STEP_TOL_SE` standard errors.
    status : str
        ``"converged"``, ``"max_iter"`` or ``"stalled"`` (no damping gives a decrease).
    points : ClosestPoints
        The closest points at θ.
    """

    theta: NDArray[np.float64]
    cost: float
    iterations: int
    projection_iterations: int
    converged: bool
    status: str
    points: ClosestPoints


def residual_jacobian(T: NDArray, cp: ClosestPoints) -> NDArray[np.float64]:
    """``∂ρ_k/∂θ`` (n, 9) at the closest points ``cp`` of θ (envelope theorem; module docstring)."""
    C = np.linalg.inv(T)
    g = cp.normal @ C  # Cᵀ n̂, one row per pose
    h = cp.d @ C.T  # C d
    return np.concatenate([g[:, _TI] * h[:, _TJ], -cp.normal], axis=1)


def fit_profile(theta0: NDArray, a: NDArray, w: NDArray, sigma_known: bool) -> ProfileFit:
    """Minimise ``Σ w_k ρ_k(θ)²`` from ``theta0`` by Levenberg–Marquardt (data ``a`` (n, 3), weights ``w``).

    ``sigma_known``: whether ``w`` are absolute (``1/σ_k²``), for the stopping rule in standard
    errors; otherwise σ̂² = cost/(n − 9) scales it.
    """
    theta = np.asarray(theta0, dtype=float).copy()
    n = a.shape[0]
    sw = np.sqrt(w)

    def evaluate(th: NDArray) -> tuple[ClosestPoints, float]:
        T, o = unpack_theta(th)
        cp = closest_points(np.linalg.inv(T), o, a)
        return cp, float(np.sum(w * cp.distance**2))

    cp, cost = evaluate(theta)
    proj_it = cp.iterations
    damping = DAMPING_START
    status = "max_iter"
    it = 0
    while it < MAX_ITER:
        it += 1
        T, _ = unpack_theta(theta)
        J = residual_jacobian(T, cp) * sw[:, None]
        res = cp.distance * sw
        F = J.T @ J
        grad = J.T @ res
        scale = 1.0 if sigma_known else max(cost / max(n - 9, 1), np.finfo(float).tiny)
        while True:
            A = F + damping * np.diag(np.diag(F))
            try:
                step = -np.linalg.solve(A, grad)
            except np.linalg.LinAlgError:
                step = np.full(9, np.nan)
            if np.all(np.isfinite(step)) and np.max(np.abs(step)) <= STEP_TOL_ABS * max(1.0, float(np.max(np.abs(theta)))):
                return ProfileFit(theta, cost, it, proj_it, True, "converged", cp)
            if np.all(np.isfinite(step)):
                T_new, _ = unpack_theta(theta + step)
                if np.all(np.diag(T_new) > 0):
                    cp_new, cost_new = evaluate(theta + step)
                    proj_it += cp_new.iterations
                    if cost_new <= cost:
                        break
            damping *= DAMPING_UP
            if damping > 1e12:
                return ProfileFit(theta, cost, it, proj_it, False, "stalled", cp)
        decrement = float(step @ F @ step) / scale  # (step in standard errors)²
        theta, cp, cost = theta + step, cp_new, cost_new
        damping = max(damping * DAMPING_DOWN, 1e-12)
        if decrement <= STEP_TOL_SE**2:
            status = "converged"
            break
    return ProfileFit(theta, cost, it, proj_it, status == "converged", status, cp)


def curvature_sum(T: NDArray, cp: ClosestPoints) -> NDArray[np.float64]:
    """``κ₁ + κ₂`` of the ellipsoid ``‖T(x − o)‖ = 1`` at each closest point (positive: convex).

    The divergence of the unit normal of the level set of ``F(x) = ‖T(x − o)‖²``:
    ``(tr ∇²F − n̂ᵀ∇²F n̂)/‖∇F‖`` with ``∇F = 2Tᵀd``, ``∇²F = 2TᵀT`` (2/R for a sphere of radius R).
    """
    return (np.sum(T**2) - np.sum((cp.normal @ T.T) ** 2, axis=1)) / np.linalg.norm(cp.d @ T, axis=1)


def fit_corrected_score(theta0: NDArray, a: NDArray, sigma2: NDArray | None) -> ProfileFit:
    """Solve the curvature-corrected score equation ``Σ_k w_k (ρ_k − ½σ_k²(κ₁+κ₂)_k) ∂ρ_k/∂θ = 0`` by Gauss–Newton.

    Why: eq. 8 has one latent direction per pose, so its ML is not consistent at a fixed noise
    level (Neyman & Scott 1948): a measurement's distance to the true ellipsoid is, to second
    order, ``ε_n + ½ε_tᵀKε_t`` (ε_n, ε_t its normal and tangential noise, K the shape operator),
    whose mean ``½σ²(κ₁+κ₂)`` — not zero — shifts the ML's ellipsoid outwards by O(σ²) however
    many poses there are.  Subtracting that mean from each residual makes the estimating equation
    unbiased to O(σ⁴) (the Jacobian's first-order dependence on the noise is tangential, uncorrelated
    with ε_n), at the ML's first-order efficiency.

    ``sigma2`` (n,): the poses' noise variances in the units of ``a``, weights ``1/σ_k²``.  ``None``:
    one unknown variance, estimated from the residuals (``σ̂² = Σρ²/(n − 9)``) as the iteration goes.
    Started from the ML (:func:`fit_profile`), the correction is a shift of O(σ²): two or three steps.
    """
    theta = np.asarray(theta0, dtype=float).copy()
    n = a.shape[0]
    proj_it = 0
    status = "max_iter"
    it = 0
    cp: ClosestPoints | None = None
    cost = float("nan")
    for it in range(1, MAX_ITER + 1):  # noqa: B007
        T, o = unpack_theta(theta)
        cp = closest_points(np.linalg.inv(T), o, a)
        proj_it += cp.iterations
        s2 = (np.full(n, max(float(np.sum(cp.distance**2)) / max(n - 9, 1), np.finfo(float).tiny))
              if sigma2 is None else sigma2)
        w = 1.0 / s2
        res = cp.distance - 0.5 * s2 * curvature_sum(T, cp)
        cost = float(np.sum(w * res**2))
        J = residual_jacobian(T, cp)
        F = J.T @ (J * w[:, None])
        try:
            step = -np.linalg.solve(F, J.T @ (w * res))
        except np.linalg.LinAlgError:
            return ProfileFit(theta, cost, it, proj_it, False, "singular", cp)
        theta = theta + step
        if (float(step @ F @ step) <= STEP_TOL_SE**2
                or np.max(np.abs(step)) <= STEP_TOL_ABS * max(1.0, float(np.max(np.abs(theta))))):
            status = "converged"
            break
    T, o = unpack_theta(theta)
    cp = closest_points(np.linalg.inv(T), o, a)
    return ProfileFit(theta, cost, it, proj_it + cp.iterations, status == "converged", status, cp)


def tangent_bases(d: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two orthonormal vectors (n, 3) each spanning the tangent plane of the unit sphere at each ``d``."""
    e = np.zeros_like(d)
    e[np.arange(d.shape[0]), np.argmin(np.abs(d), axis=1)] = 1.0  # the axis least aligned with d
    z1 = np.cross(d, e)
    z1 /= np.linalg.norm(z1, axis=1, keepdims=True)
    return z1, np.cross(d, z1)


def profile_hessian(theta: NDArray, a: NDArray, w: NDArray, cp: ClosestPoints | None = None) -> NDArray[np.float64]:
    """The exact Hessian ``∇²f`` of the profile cost ``f(θ) = Σ w_k ρ_k²`` at a stationary θ (9 × 9).

    Per pose, in the variables ``p = (vec_tril C, o)`` and ``d`` of the full NLP, the Lagrangian
    ``ℓ = w‖r‖² + ν(‖d‖² − 1)``, ``r = a − o − C d``, ``ν = wλ``, has the blocks (``J_p = ∂r/∂p``:
    ``∂r/∂C_ij = −e_i d_j``, ``∂r/∂o = −I``; r is linear in p)::

        H_pp = 2w J_pᵀJ_p,   H_pd = −2w (J_pᵀC + [r_i δ_jl]_(ij),l),   H_dd = 2w CᵀC + 2ν I

    Eliminating the direction on the tangent plane of its sphere (orthonormal basis Z, 3 × 2) gives
    the pose's share of the profile Hessian ``H_pp − K M⁻¹ Kᵀ`` with ``K = H_pd Z`` and
    ``M = ZᵀH_dd Z = 2w (CZ)ᵀ(CZ) + 2ν I`` — the Schur complement of the full NLP's reduced Hessian.
    With ``M = LLᵀ`` (2 × 2 Cholesky, in closed form) ``K M⁻¹ Kᵀ = YYᵀ``, ``Y = K L⁻ᵀ``, so the sum
    over poses is two products of (n × 9) matrices.  At a stationary point the gradient vanishes, so
    the Hessian in θ = (T, o) is ``Gᵀ H G`` with ``G = ∂p/∂θ`` (``dC = −C dT C``).
    """
    T, o = unpack_theta(theta)
    C = np.linalg.inv(T)
    if cp is None:
        cp = closest_points(C, o, a)
    n = a.shape[0]
    H = np.zeros((9, 9))
    for start in range(0, n, HESSIAN_BLOCK):
        sl = slice(start, min(start + HESSIAN_BLOCK, n))
        d, r, wk, nu = cp.d[sl], cp.r[sl], w[sl], w[sl] * cp.lam[sl]
        # H_pp summed: Σ w d dᵀ in the (i,j),(i,l) entries, Σ w d in the C–o entries, Σ w in the o block
        wd = d * wk[:, None]
        Sdd, Sd, Sw = wd.T @ d, wd.sum(axis=0), float(wk.sum())
        Hpp = np.zeros((9, 9))
        for k, (i, j) in enumerate(TRIL_INDEX):
            for m_, (i2, l) in enumerate(TRIL_INDEX):
                if i2 == i:
                    Hpp[k, m_] = Sdd[j, l]
            Hpp[k, 6 + i] = Hpp[6 + i, k] = Sd[j]
        Hpp[6:, 6:] = Sw * np.eye(3)
        H += 2.0 * Hpp
        z1, z2 = tangent_bases(d)
        cz1, cz2 = z1 @ C.T, z2 @ C.T
        # K = H_pd Z, column by column: K_(ij) = 2w (d_j (CZ)_i − r_i Z_j), K_(o_b) = 2w (CZ)_b
        K1 = 2.0 * wk[:, None] * np.concatenate([d[:, _TJ] * cz1[:, _TI] - r[:, _TI] * z1[:, _TJ], cz1], axis=1)
        K2 = 2.0 * wk[:, None] * np.concatenate([d[:, _TJ] * cz2[:, _TI] - r[:, _TI] * z2[:, _TJ], cz2], axis=1)
        m11 = 2.0 * (wk * np.sum(cz1 * cz1, axis=1) + nu)
        m21 = 2.0 * wk * np.sum(cz1 * cz2, axis=1)
        m22 = 2.0 * (wk * np.sum(cz2 * cz2, axis=1) + nu)
        l11 = np.sqrt(m11)
        l21 = m21 / l11
        l22 = np.sqrt(m22 - l21**2)
        Y1 = K1 / l11[:, None]
        Y2 = (K2 - l21[:, None] * Y1) / l22[:, None]
        H -= Y1.T @ Y1 + Y2.T @ Y2
    # p = (vec_tril C, o) → θ = (vec_tril T, o): dC = −C dT C
    G = np.eye(9)
    for k, (i, j) in enumerate(TRIL_INDEX):
        for m_, (p_, q_) in enumerate(TRIL_INDEX):
            G[k, m_] = -C[i, p_] * C[q_, j]
    return G.T @ H @ G


__all__ = ["DAMPING_DOWN", "DAMPING_START", "DAMPING_UP", "HESSIAN_BLOCK", "MAX_ITER", "STEP_TOL_ABS", "STEP_TOL_SE", "ProfileFit",
           "curvature_sum", "fit_corrected_score", "fit_profile", "profile_hessian", "residual_jacobian",
           "tangent_bases"]
