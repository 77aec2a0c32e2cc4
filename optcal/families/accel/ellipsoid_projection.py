"""The closest point of an ellipsoid to each of many points: one secular equation per point, vectorised.

The ellipsoid ``E = {o + C d : ‖d‖ = 1}`` (``C`` invertible) is the calibration's model of the
measurements (Lu 2017, eq. 3 with ``C = T⁻¹``).  For a measurement ``a`` and ``b = a − o`` the
latent direction of the errors-in-variables likelihood (Lu 2017, eq. 8) is::

    d* = argmin_{‖d‖ = 1} ‖b − C d‖²

Stationarity, ``Cᵀ(b − C d) = λ d``, gives ``d(λ) = (CᵀC + λI)⁻¹ Cᵀ b``; with the singular value
decomposition ``C = U diag(s) Vᵀ`` and ``β = Uᵀ b``, ``d(λ) = V p(λ)``, ``p_i = s_i β_i / (s_i² + λ)``,
and the constraint becomes the secular equation::

    φ(λ) = Σ_i s_i² β_i² / (s_i² + λ)²  = 1                  (one unknown per point)

The global minimiser is the root with ``CᵀC + λI ⪰ 0``, i.e. ``λ ≥ −s_min²`` (the trust-region
subproblem's characterisation, Moré & Sorensen 1983): there φ decreases from +∞ to 0, so the root
is unique.  It is found by Newton's method on ``g(λ) = φ(λ)^(−1/2) − 1``, which is increasing and
concave in λ (Moré & Sorensen 1983, the ``1/‖p(λ)‖`` form), so Newton's iterates started on the left
of the root climb to it monotonically; a start on the right (``λ = 0``, exact for a point on the
ellipsoid) is clamped to the lower bound ``s_min |β_min| − s_min²`` of the root, ``max_i (s_i |β_i| − (s_i² − s_min²))`` in μ, after its first step.
The shift ``μ = λ + s_min²`` is the working unknown, so that ``s_i² + λ = (s_i² − s_min²) + μ`` is
formed without cancellation.

The *hard case* (``β`` has no component along the ellipsoid's shortest axis and the point lies deep
inside, within that axis's evolute): ``λ = −s_min²`` and the missing norm of ``d`` goes along that axis
(either sign is a closest point; the positive one is returned).  Equal semi-axes need no special
treatment: a sphere's closest point is the radial projection, which the secular root gives.

At the closest point ``r = b − C d = λ C⁻ᵀ d`` is normal to the ellipsoid; ``λ > 0`` outside,
``λ < 0`` inside.  The signed distance ``ρ = n̂ᵀ r`` with the outward unit normal ``n̂ ∝ C⁻ᵀ d``
is the scalar residual of the profile likelihood (:mod:`optcal.families.accel.exact_profile`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Newton iterations at most on the secular equation.  Converged points leave the active set; a
#: start on the right of the root needs one step to the left, then the concave iteration converges
#: quadratically (5-6 steps to rounding for measurements within a few σ of the ellipsoid).
MAX_NEWTON = 60
#: A point's secular equation is solved when Newton's step changes μ by at most this fraction of
#: ``s_max²`` (the scale of the denominators ``s_i² + λ``): rounding level.
NEWTON_RTOL = 1e-15


#: Smallest denominator ``s_i² + λ`` used: its square is still a normal float, so a component
#: with ``s_i β_i = 0`` contributes exactly 0 where the denominator vanishes (the hard case).
_FLOOR = float(np.sqrt(np.finfo(float).tiny))


@dataclass(frozen=True)
class ClosestPoints:
    """The closest points of an ellipsoid to n points (:func:`closest_points`).

    Attributes
    ----------
    d : ndarray, shape (n, 3)
        Unit latent directions: the closest point of ``o + C d`` is ``x = o + C d``.
    r : ndarray, shape (n, 3)
        ``a − x``, normal to the ellipsoid at ``x``.
    normal : ndarray, shape (n, 3)
        Outward unit normal at ``x`` (along ``C⁻ᵀ d``).
    distance : ndarray, shape (n,)
        Signed distance ``n̂ᵀ r``: positive outside, negative inside.
    lam : ndarray, shape (n,)
        The Lagrange multiplier λ of ``‖d‖ = 1`` (``Cᵀ r = λ d``).
    iterations : int
        Newton iterations of the slowest point.
    hard : int
        Points in the hard case (λ = −s_min², a closest point not unique).
    """

    d: NDArray[np.float64]
    r: NDArray[np.float64]
    normal: NDArray[np.float64]
    distance: NDArray[np.float64]
    lam: NDArray[np.float64]
    iterations: int
    hard: int


def _secular_terms(q: NDArray, gap: NDArray, mu: NDArray) -> tuple[NDArray, NDArray]:
    """``φ`` and ``φ'`` at μ for ``q = (s β)²`` (n, 3), ``gap = s² − s_min²`` (3,)."""
    den = np.maximum(gap + mu[:, None], _FLOOR)  # a zero component contributes 0, even at den = 0
    with np.errstate(over="ignore"):
        t = q / (den * den)
        phi = t.sum(axis=1)
        dphi = -2.0 * (t / den).sum(axis=1)
    return phi, dphi


def closest_points(C: NDArray, o: NDArray, a: NDArray) -> ClosestPoints:
    """The closest point of the ellipsoid ``{o + C d : ‖d‖ = 1}`` to each row of ``a`` (n, 3).

    Euclidean distance: the noise of Lu 2017's model is isotropic per pose (``σ_k² I``), so each
    pose's weight scales its distance and does not change its closest point.
    """
    C = np.asarray(C, dtype=float)
    U, s, Vt = np.linalg.svd(C)  # C = U diag(s) Vᵀ, s descending
    beta = (np.asarray(a, dtype=float) - np.asarray(o, dtype=float)) @ U  # β = Uᵀ b, one row per point
    sb = s * beta
    q = sb**2
    s2 = s**2
    gap = s2 - s2[2]  # s_i² − s_min² ≥ 0
    n = beta.shape[0]
    # bounds of the root in μ = λ + s_min²: φ ≥ q_i/(gap_i + μ)² for each i, and φ ≤ Σq/μ²
    mu_lo = np.maximum(np.max(np.abs(sb) - gap, axis=1), 0.0)
    mu_hi = np.sqrt(q.sum(axis=1))
    mu = np.clip(np.full(n, s2[2]), mu_lo, mu_hi)  # λ = 0: exact on the ellipsoid
    active = np.arange(n)
    iterations = 0
    tol = NEWTON_RTOL * s2[0]
    for iterations in range(1, MAX_NEWTON + 1):  # noqa: B007
        m = mu[active]
        phi, dphi = _secular_terms(q[active], gap, m)
        with np.errstate(divide="ignore", invalid="ignore"):
            g = 1.0 / np.sqrt(phi) - 1.0
            dg = -0.5 * dphi / phi**1.5
            step = np.where(np.isfinite(g) & (dg > 0), -g / dg, 0.0)
        new = np.maximum(m + step, mu_lo[active])
        new = np.where(np.isfinite(new), new, m)
        mu[active] = new
        moving = np.abs(new - m) > tol * (1.0 + new / s2[0])
        active = active[moving]
        if active.size == 0:
            break
    # hard case: the root sits at μ = 0 with the shortest axis's component free
    den = gap + mu[:, None]
    p = sb / np.maximum(den, _FLOOR)
    shortfall = 1.0 - np.sum(p**2, axis=1)
    hard = (mu <= tol) & (shortfall > np.sqrt(np.finfo(float).eps))
    if np.any(hard):
        p[hard, 2] = np.sqrt(shortfall[hard])  # the free component along the shortest axis (either sign)
    p /= np.linalg.norm(p, axis=1, keepdims=True)  # rounding of the root to the unit sphere
    d = p @ Vt  # d = V p
    b = np.asarray(a, dtype=float) - np.asarray(o, dtype=float)
    r = b - d @ C.T
    m_dir = (p / s) @ U.T  # C⁻ᵀ d = U diag(1/s) p
    normal = m_dir / np.linalg.norm(m_dir, axis=1, keepdims=True)
    return ClosestPoints(d=d, r=r, normal=normal, distance=np.sum(normal * r, axis=1), lam=mu - s2[2],
                         iterations=iterations, hard=int(np.count_nonzero(hard)))


__all__ = ["MAX_NEWTON", "NEWTON_RTOL", "ClosestPoints", "closest_points"]
