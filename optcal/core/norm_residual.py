"""Lu 2017's norm residual (eq. 13) and its derivatives: the one kernel every estimator uses.

For a measurement ``a_k`` and a calibration ``(T, o)``::

    u_k = a_k − o,   v_k = T u_k,   ā_k = v_k / ‖v_k‖
    r_k = ‖T (a_k − o)‖ − 1                                      (Lu 2017, eq. 13)
    ∂r_k/∂T_ij = ā_k,i u_k,j        ∂r_k/∂o = −Tᵀ ā_k           (Lu 2017, eq. 15-16)

``‖Tᵀ ā_k‖`` (= ‖∂r_k/∂o‖) is the gain from isotropic raw noise to the norm residual
(:func:`normal_gain`), used for the noise weights and the Fisher information.

Everything is evaluated on the measurements held as three contiguous rows
(:class:`NormResidualKernel`), for any 3×3 ``T``, in a handful of whole-array operations (fast
for ten poses and for a million).  The Jacobian comes in two orders: w.r.t. θ (the six lower-triangular entries of ``T``, then
``o``; every estimator, the Fisher information) and w.r.t. ``[vec(T) row-major, o]`` (the
paper's 12 parameters, its gradient-descent baseline).  :func:`casadi_norm_residual` is the
same residual as a CasADi expression for the IPOPT problems.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from optcal.core.model import TRIL_INDEX, unpack_theta

#: Rows and columns of the lower-triangular entries of ``T``, in the order of θ.
TRIL_ROWS: NDArray[np.intp] = np.array([i for i, _ in TRIL_INDEX])
TRIL_COLS: NDArray[np.intp] = np.array([j for _, j in TRIL_INDEX])


@dataclass(frozen=True)
class NormResidualPoint:
    """The norm residuals of every measurement at one ``(T, o)``, with what their derivatives need.

    Per-measurement quantities are stored one row per component, one column per measurement.
    For a stack of K measurement sets (:class:`NormResidualKernel` of (K, n, 3) measurements,
    each at its own ``(T, o)``) every shape below gains a leading axis K.

    Attributes
    ----------
    T : ndarray, shape (3, 3)
    o : ndarray, shape (3,)
    u : ndarray, shape (3, n)
        ``a_k − o``.
    direction : ndarray, shape (3, n)
        The unit calibrated vectors ``ā_k``.
    residuals : ndarray, shape (n,)
        ``r_k = ‖T(a_k − o)‖ − 1`` (Lu 2017, eq. 13).
    """

    T: NDArray[np.float64]
    o: NDArray[np.float64]
    u: NDArray[np.float64]
    direction: NDArray[np.float64]
    residuals: NDArray[np.float64]

    def bias_jacobian(self) -> NDArray[np.float64]:
        """``∂r_k/∂o = −Tᵀ ā_k`` (Lu 2017, eq. 16), shape (3, n)."""
        return -(np.swapaxes(self.T, -1, -2) @ self.direction)

    def jacobian(self) -> NDArray[np.float64]:
        """``∂r_k/∂θ`` (θ: lower-triangular ``T`` entries, then ``o``), shape (9, n).

        ``∂r_k/∂T_ij = ā_k,i u_k,j`` (Lu 2017, eq. 15) for ``(i, j)`` in :data:`TRIL_INDEX`.
        """
        return np.concatenate([self.direction[..., TRIL_ROWS, :] * self.u[..., TRIL_COLS, :], self.bias_jacobian()], axis=-2)

    def jacobian_full(self) -> NDArray[np.float64]:
        """``∂r_k/∂[vec(T) row-major, o]`` (the paper's 12 parameters; eq. 15-16), shape (12, n)."""
        dT = (self.direction[..., :, None, :] * self.u[..., None, :, :]).reshape(self.u.shape[:-2] + (9, -1))
        return np.concatenate([dT, self.bias_jacobian()], axis=-2)

    def jacobian_full_dot(self, c: NDArray[np.float64]) -> NDArray[np.float64]:
        """``jacobian_full() @ c`` for weights ``c`` (n,) of the residuals, without forming the (12, n) Jacobian:
        ``Σ_k c_k ā_k,i u_k,j = (ā c) uᵀ`` (eq. 15) and ``Σ_k c_k (−Tᵀ ā_k) = −Tᵀ (ā c)`` (eq. 16), shape (12,)
        (speed: the gradient-descent baseline takes it 10⁴-10⁵ times on up to 10⁵ poses)."""
        weighted = self.direction * c[..., None, :]
        dT = (weighted @ np.swapaxes(self.u, -1, -2)).reshape(self.u.shape[:-2] + (9,))
        do = -(np.swapaxes(self.T, -1, -2) @ weighted.sum(axis=-1)[..., None])[..., 0]
        return np.concatenate([dT, do], axis=-1)

    def normal_gain(self) -> NDArray[np.float64]:
        """``‖Tᵀ ā_k‖``: how isotropic raw noise propagates to ``r_k``, shape (n,)."""
        g = self.bias_jacobian()
        return np.sqrt(np.einsum("...ij,...ij->...j", g, g))


class NormResidualKernel:
    """The norm residual of fixed measurements, evaluated at any ``(T, o)``.

    Parameters
    ----------
    acc : array_like, shape (n, 3) or (K, n, 3)
        Measurements, in any units (``T`` maps them to g), or a stack of K sets of n
        measurements each, evaluated each at its own ``(T, o)`` (T (K, 3, 3), o (K, 3), θ
        (K, 9)).  Held transposed ((3, n) or (K, 3, n)), so that every operation runs along
        contiguous rows.
    """

    def __init__(self, acc: ArrayLike) -> None:
        acc = np.asarray(acc, dtype=float)
        acc = acc.reshape(-1, 3) if acc.ndim <= 2 else acc
        self.data = np.ascontiguousarray(np.swapaxes(acc, -1, -2))
        self.n = self.data.shape[-1]

    def at(self, T: ArrayLike, o: ArrayLike) -> NormResidualPoint:
        """Residuals and directions at ``(T, o)`` (Lu 2017, eq. 13)."""
        stack = self.data.shape[:-2]
        T = np.asarray(T, dtype=float).reshape(stack + (3, 3))
        o = np.asarray(o, dtype=float).reshape(stack + (3,))
        u = self.data - o[..., :, None]
        v = T @ u
        nv = np.sqrt(np.einsum("...ij,...ij->...j", v, v))
        return NormResidualPoint(T, o, u, v / nv[..., None, :], nv - 1.0)

    def at_theta(self, theta: ArrayLike) -> NormResidualPoint:
        """:meth:`at` for the parameter vector θ of :mod:`optcal.core.model` (θ (K, 9) for a stack)."""
        theta = np.asarray(theta, dtype=float)
        T, o = unpack_theta(theta.ravel()[:9] if theta.ndim <= 1 else theta[..., :9])
        return self.at(T, o)

    def at_full(self, x: ArrayLike) -> NormResidualPoint:
        """:meth:`at` for the paper's ``x = [vec(T) row-major, o]`` (12 numbers)."""
        x = np.asarray(x, dtype=float).ravel()
        return self.at(x[:9].reshape(3, 3), x[9:12])


def norm_residuals(T: ArrayLike, o: ArrayLike, acc: ArrayLike) -> NDArray[np.float64]:
    """``r_k = ‖T(a_k − o)‖ − 1`` (Lu 2017, eq. 13), shape (n,)."""
    return NormResidualKernel(acc).at(T, o).residuals


def norm_residual_jacobian(T: ArrayLike, o: ArrayLike, acc: ArrayLike) -> NDArray[np.float64]:
    """``∂r_k/∂θ`` (lower-triangular ``T`` entries, then ``o``; Lu 2017, eq. 15-16), shape (n, 9)."""
    return NormResidualKernel(acc).at(T, o).jacobian().T


def normal_gain(T: ArrayLike, o: ArrayLike, acc: ArrayLike) -> NDArray[np.float64]:
    """``‖Tᵀ ā_k‖``: how raw noise (per axis) propagates to the norm residual, shape (n,)."""
    return NormResidualKernel(acc).at(T, o).normal_gain()


def heldout_residuals(residuals: NDArray, jacobian: NDArray, weights: NDArray) -> NDArray[np.float64]:
    """Leave-one-out norm residuals ``r_k / (1 − h_kk)`` (the PRESS residuals).

    ``h_kk`` is the leverage of pose k, the diagonal of the hat matrix
    ``W½J (JᵀWJ)⁻¹ JᵀW½`` of the linearised fit: exact for a linear least-squares problem and
    first-order for the norm residual, it predicts each pose's residual under the fit made
    without it at the cost of one QR decomposition.  Columns are scaled first (the hat matrix
    does not depend on the parametrisation) and a rank-deficient J is handled by its range.
    """
    Js = jacobian * np.sqrt(weights)[:, None]
    Js = Js / np.maximum(np.linalg.norm(Js, axis=0), 1e-300)
    U, s, _ = np.linalg.svd(Js, full_matrices=False)
    U = U[:, s > s[0] * 1e-10]
    h = np.clip(np.sum(U * U, axis=1), 0.0, 1.0 - 1e-12)
    return residuals / (1.0 - h)


def casadi_lower_triangular(x: Any) -> Any:
    """CasADi 3×3 lower-triangular matrix from the first six entries of θ (order of :data:`TRIL_INDEX`)."""
    import casadi as ca

    z = ca.DM(0) if isinstance(x, ca.DM) else 0
    rows = [[z, z, z] for _ in range(3)]
    for k, (i, j) in enumerate(TRIL_INDEX):
        rows[i][j] = x[k]
    return ca.vertcat(*(ca.horzcat(*row) for row in rows))


def casadi_norm_residual() -> Any:
    """``r(θ, a) = ‖T(a − o)‖ − 1`` (Lu 2017, eq. 13) as a CasADi Function of θ (9) and one measurement (3)."""
    import casadi as ca

    x = ca.SX.sym("theta", 9)
    a = ca.SX.sym("a", 3)
    v = ca.mtimes(casadi_lower_triangular(x), a - x[6:9])
    return ca.Function("norm_residual", [x, a], [ca.norm_2(v) - 1.0])


__all__ = [
    "NormResidualKernel",
    "NormResidualPoint",
    "casadi_lower_triangular",
    "casadi_norm_residual",
    "heldout_residuals",
    "norm_residual_jacobian",
    "norm_residuals",
    "normal_gain",
]
