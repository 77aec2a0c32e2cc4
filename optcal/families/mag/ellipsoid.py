"""The ellipsoid of a magnetometer's calibration in numpy: its forms, the symmetric ``T``, the Jacobian of the norm
residual, the sphere's fit and a form's maximum-likelihood fit by Levenberg–Marquardt.

The model ``‖T(m − o)‖ = 1`` (Lu 2017, eq. 6, 13, the local field in place of gravity); the forms and how one
is chosen are in :mod:`optcal.families.mag.fit`, the held-out comparison that uses these fits in
:mod:`optcal.families.mag.heldout`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: The reduced forms, richest last, with their parameter counts.
FORMS: dict[str, int] = {"offsets": 4, "diagonal": 6, "full": 9}
#: Each form's free parameters mapped onto the symmetric ``T``'s six entries (:data:`SYMMETRIC_ENTRIES`).
FORM_BASIS: dict[str, NDArray[np.float64]] = {
    "offsets": np.array([[1.0], [0.0], [0.0], [1.0], [0.0], [1.0]]),  # T = s I: a sphere
    "diagonal": np.eye(6)[:, [0, 3, 5]],
    "full": np.eye(6),
}


def symmetric_T(T: NDArray) -> NDArray[np.float64]:
    """The symmetric positive definite ``(TᵀT)^½``: the same ‖T u‖ for every u, no rotation."""
    w, V = np.linalg.eigh(T.T @ T)
    S: NDArray[np.float64] = (V * np.sqrt(w)) @ V.T
    return 0.5 * (S + S.T)


#: The six entries of a symmetric ``T`` (upper triangle) and their names.
SYMMETRIC_ENTRIES: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
SYMMETRIC_NAMES: tuple[str, ...] = ("T_xx", "T_xy", "T_xz", "T_yy", "T_yz", "T_zz")


def norm_residual_jacobian(m: NDArray[np.float64], T: NDArray[np.float64], o: NDArray[np.float64]
                           ) -> NDArray[np.float64]:
    """Jacobian of ``|T(m − o)| − 1`` with respect to the symmetric ``T``'s six entries
    (:data:`SYMMETRIC_ENTRIES`) and ``o`` (Lu 2017, eq. 13 differentiated)."""
    d = m - o
    v = np.einsum("kj,ij->ki", d, T)  # T d per row (numpy's matmul of (n, 3) by (3, 3) is several times slower)
    e = v / np.sqrt(np.einsum("ki,ki->k", v, v))[:, None]
    J = np.empty((m.shape[0], 9))
    for c, (i, j) in enumerate(SYMMETRIC_ENTRIES):  # ∂|T d|/∂T_ij = e_i d_j + e_j d_i (i ≠ j), e_i d_i
        np.multiply(e[:, i], d[:, j], out=J[:, c])
        if i != j:
            J[:, c] += e[:, j] * d[:, i]
    J[:, 6:] = -np.einsum("kj,ji->ki", e, T)
    return J


def sphere_fit(m: NDArray) -> tuple[NDArray, float, NDArray]:
    """Offsets-only fit: ``‖m − o‖ = r`` (m in any dimension: a circle in a plane) by linear least squares, refined by Gauss–Newton; o, r, cov of (o, r)."""
    J = np.column_stack([2 * m, np.ones(len(m))])
    sol = np.linalg.lstsq(J, np.sum(m * m, axis=1), rcond=None)[0]
    o = sol[:-1]
    r = float(np.sqrt(max(sol[-1] + o @ o, 1e-300)))
    for _ in range(20):  # Gauss-Newton on the geometric residuals ‖m − o‖ − r
        d = m - o
        n = np.linalg.norm(d, axis=1)
        res = n - r
        G = np.column_stack([-d / n[:, None], -np.ones(len(m))])
        step = np.linalg.solve(G.T @ G, -(G.T @ res))  # normal equations: 4×4, linear in the samples
        o, r = o + step[:-1], r + float(step[-1])
        if np.linalg.norm(step) < 1e-10 * r:  # far below any standard error of a field's offset
            break
    d = m - o
    n = np.linalg.norm(d, axis=1)
    G = np.column_stack([-d / n[:, None], -np.ones(len(m))])
    res = n - r
    dof = max(len(m) - 4, 1)
    cov = np.linalg.pinv(G.T @ G) * float(res @ res) / dof
    return o, r, cov



def fit_symmetric(m: NDArray[np.float64], basis: NDArray[np.float64], sphere: tuple[NDArray[np.float64], float],
                   iterations: int = 30) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``T`` (symmetric, its entries ``basis @ θ``) and ``o`` minimising Σ (‖T(m − o)‖ − 1)², by
    Levenberg–Marquardt from ``sphere`` (o, r), the sphere's fit of the same samples (Lu 2017, eq. 13; the Jacobian of
    :func:`norm_residual_jacobian`).  Starting from the samples' own sphere, a direction the samples do not
    determine stays at the sphere's value instead of at a fit that saw other samples."""
    o, r = sphere
    theta = np.linalg.lstsq(basis, np.array([1 / r, 0, 0, 1 / r, 0, 1 / r]), rcond=None)[0]

    def unpack(th: NDArray[np.float64]) -> NDArray[np.float64]:
        e = basis @ th
        return np.array([[e[0], e[1], e[2]], [e[1], e[3], e[4]], [e[2], e[4], e[5]]])

    def residual(T: NDArray[np.float64], oo: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.einsum("kj,ij->ki", m - oo, T)
        return np.asarray(np.sqrt(np.einsum("ki,ki->k", v, v)) - 1.0)

    T = unpack(theta)
    res = residual(T, o)
    cost = float(res @ res)
    lam = 1e-6  # Marquardt's damping, relative to JᵀJ's diagonal; grown tenfold on a step that does not descend
    for _ in range(iterations):
        J = norm_residual_jacobian(m, T, o)
        J = np.column_stack([J[:, :6] @ basis, J[:, 6:]])
        A, g = J.T @ J, J.T @ res
        improved = False
        while lam < 1e6:
            try:
                step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-300), -g)
            except np.linalg.LinAlgError:  # a direction the samples do not see at all: damp it more
                lam *= 10.0
                continue
            T_new, o_new = unpack(theta + step[:-3]), o + step[-3:]
            res_new = residual(T_new, o_new)
            cost_new = float(res_new @ res_new)
            if cost_new <= cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
        done = cost - cost_new <= 1e-7 * cost  # settled: far below the forms' held-out differences (1e-3 of the cost and more)
        theta, T, o, res, cost, lam = theta + step[:-3], T_new, o_new, res_new, cost_new, max(lam / 10.0, 1e-9)
        if done:
            break
    return T, o
