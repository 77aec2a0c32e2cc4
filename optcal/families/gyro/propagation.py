"""Gravity carried across a move by the corrected gyro (Tedaldi 2014, eq. 13-14).

A world-fixed vector seen from the body obeys ``u̇ = −ω × u``.  Over one integration step of
length ``dt_k`` with the trapezoid mean rate ``ω̄_k = T_g (ḡ_k − b_g − G_g f_k)`` the body
turns by ``E_k = exp([θ_k]×)``, ``θ_k = ω̄_k dt_k`` (exponential map, Rodrigues' formula), so
the rotation accumulated over a move is ``Φ = E_1 E_2 ⋯ E_n`` and the gravity direction it
predicts at the next pose is ``Φᵀ u_i`` (Tedaldi 2014, eq. 14, their Ψ with an exponential
map instead of quaternion Runge–Kutta).  The residual of move ``i`` is
``Φᵀ u_i − u_{i+1}`` (Tedaldi 2014, eq. 13, imu_tk's ``MultiPosGyroResidual``).

:class:`GravityPredictor` evaluates this for every move of a recording at once, in numpy,
with the analytic sensitivity ``∂(Φᵀu₀)/∂T_g``: with the prefix products
``P_k = E_1 ⋯ E_k`` and the right Jacobian ``J_r(−θ) = I + c₂[θ]× + c₃[θ]×²`` of each step,

    ∂(Φᵀu₀)/∂θ_k = Φᵀ [u₀]× P_{k−1} J_r(−θ_k),    ∂θ_k/∂T_ij = e_i q_kj,

(``q_k = w_k dt_k`` the bias-free raw rotation of the step, ``T_g`` row-major), because
``∂(E_kᵀ v)/∂θ_k = E_kᵀ [v]× J_r(−θ_k)`` and ``P [Pᵀu₀]× = [u₀]× P`` for a rotation ``P``.
The rotations of all steps come from one vectorised Rodrigues formula
(:func:`optcal.core.rotations.exponential_map_with_right_jacobian`); only the prefix
products are a loop, over the steps of the longest move with the moves side by side.  It
serves both the fit (:mod:`optcal.families.gyro.estimator`, residuals and Jacobian in one pass) and
the convention-free figure of merit, :func:`angles_deg` between predicted and measured
directions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optcal.core.rotations import exponential_map, exponential_map_with_right_jacobian, skew


class GravityPredictor:
    """Gravity directions carried across every move of a recording layout, with ``∂/∂T_g``.

    Made once per layout (the index arrays of the moves); the rates, step lengths and start
    directions are arguments of :meth:`evaluate`.

    Parameters
    ----------
    first_step : ndarray of bool, shape (N,)
        First integration step of each move (the steps of a move are contiguous).
    last_step : ndarray of int, shape (m,)
        Last step of each move.
    """

    def __init__(self, first_step: NDArray[np.bool_], last_step: NDArray[np.int64]) -> None:
        n = int(first_step.size)
        m = int(np.asarray(last_step).size)
        self.n_steps, self.n_moves = n, m
        self.starts = np.flatnonzero(first_step)
        lengths = np.asarray(last_step) - self.starts + 1
        self.length = int(lengths.max())
        #: position of each step inside its move and the move it belongs to
        self.position = np.arange(n) - np.repeat(self.starts, lengths)
        self.move = np.repeat(np.arange(m), lengths)

    @classmethod
    def of_starts(cls, starts: NDArray[np.intp], n_steps: int) -> GravityPredictor:
        """The layout of moves whose steps begin at ``starts`` (m,) among ``n_steps`` contiguous steps."""
        first = np.zeros(n_steps, dtype=bool)
        first[starts] = True
        return cls(first, np.r_[np.asarray(starts)[1:], n_steps] - 1)

    def _prefixes(self, theta: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each move's orientation after each of its steps, ``P_k = E_1 ⋯ E_k`` (L + 1, m, 3, 3; ``P_0 = I``, the
        identity after a move's end), for the steps' rotation vectors ``theta`` (N, 3), and each step's right
        Jacobian ``J_r(−θ_k)`` (N, 3, 3).  Tedaldi 2014, eq. 13-14: the orientation composed step by step."""
        L, m = self.length, self.n_moves
        E_steps, Jr_steps = exponential_map_with_right_jacobian(theta)
        E = np.broadcast_to(np.eye(3), (L, m, 3, 3)).copy()  # the identity after a move's end
        E[self.position, self.move] = E_steps
        prefix = np.empty((L + 1, m, 3, 3))
        prefix[0] = np.eye(3)
        for s in range(L):
            np.matmul(prefix[s], E[s], out=prefix[s + 1])
        return prefix, Jr_steps

    def evaluate(self, T: NDArray, w: NDArray, dt: NDArray, u0: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Predicted directions (m, 3), their Jacobian w.r.t. row-major ``T`` (m, 3, 9) and ``Φ`` (m, 3, 3).

        ``w`` (N, 3) are bias-free raw rates, ``dt`` (N,) step lengths, ``u0`` (m, 3) start directions.
        """
        L, m = self.length, self.n_moves
        at = (self.position, self.move)  # each step's slot when the moves are laid side by side, (L, m)
        q = np.asarray(w, float) * np.asarray(dt, float)[:, None]
        prefix, Jr_steps = self._prefixes(q @ np.asarray(T, float).T)
        P = prefix[L]
        u0 = np.asarray(u0, float)
        v = np.einsum("mji,mj->mi", P, u0)  # Φᵀ u₀
        # C[(a, i), j] = Σ_k (P_{k−1} J_r(−θ_k))[a, i] q_kj over the steps of each move (zero in the padding)
        B = np.zeros((L, m, 9))
        B[at] = np.matmul(prefix[at], Jr_steps).reshape(-1, 9)
        q_side = np.zeros((L, m, 3))
        q_side[at] = q
        C = np.matmul(B.transpose(1, 2, 0), q_side.transpose(1, 0, 2))  # (m, 9, 3)
        S = np.einsum("mji,mjk,mkl->mil", P, skew(u0), C.reshape(m, 3, 9))
        return v, S, P

    def step_sensitivities(self, theta: NDArray, u0: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Predicted directions ``v = Φᵀ u₀`` (m, 3) for the steps' rotation vectors ``theta`` (N, 3), and each
        step's ``∂v/∂θ_k = Φᵀ [u₀]× P_{k−1} J_r(−θ_k)`` (N, 3, 3): chained with any parameter's ``∂θ_k/∂x`` and
        summed over a move's steps, that parameter's Jacobian (:meth:`evaluate` chains it with ``T``'s)."""
        prefix, Jr_steps = self._prefixes(np.asarray(theta, float))
        P = prefix[self.length]
        u0 = np.asarray(u0, float)
        v = np.einsum("mji,mj->mi", P, u0)
        A = np.einsum("kji,kjl->kil", P[self.move], skew(u0)[self.move])  # Φᵀ[u₀]× per step
        return v, np.matmul(np.matmul(A, prefix[self.position, self.move]), Jr_steps)

    def directions(self, theta: NDArray, u0: NDArray) -> NDArray[np.float64]:
        """Predicted directions ``Φᵀ u₀`` (m, 3) for the steps' rotation vectors ``theta`` (N, 3), without a
        Jacobian: the steps composed pairwise in order (associative), ⌈log₂ L⌉ array products."""
        E = np.broadcast_to(np.eye(3), (self.length, self.n_moves, 3, 3)).copy()
        E[self.position, self.move] = exponential_map(np.asarray(theta, float))
        while E.shape[0] > 1:
            if E.shape[0] % 2:
                E = np.concatenate([E, np.broadcast_to(np.eye(3), (1, self.n_moves, 3, 3))])
            E = np.matmul(E[0::2], E[1::2])
        return np.asarray(np.einsum("mji,mj->mi", E[0], np.asarray(u0, float)))

    def __call__(self, omega: NDArray, dt: NDArray, u0: NDArray) -> NDArray[np.float64]:
        """Predicted directions (m, 3) for corrected rates ``omega`` (N, 3) rad/s (:meth:`directions`)."""
        return self.directions(np.asarray(omega, float) * np.asarray(dt, float)[:, None], u0)


def unit_rows(x: NDArray) -> NDArray[np.float64]:
    """Rows of ``x`` scaled to unit length."""
    x = np.asarray(x, dtype=float)
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def angles_deg(predicted: NDArray, measured: NDArray) -> NDArray[np.float64]:
    """Angle between corresponding rows of two direction arrays, degrees."""
    p, q = unit_rows(predicted), unit_rows(measured)
    cross = np.linalg.norm(np.cross(p, q), axis=1)
    return np.degrees(np.arctan2(cross, np.sum(p * q, axis=1)))
