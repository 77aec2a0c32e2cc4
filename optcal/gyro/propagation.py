"""Gravity carried across a move by the corrected gyro, in CasADi (Tedaldi 2014, eq. 13-14).

A world-fixed vector seen from the body obeys ``u̇ = −ω × u``.  Over one integration step of
length ``dt_k`` with the trapezoid mean rate ``ω̄_k = T_g (ḡ_k − b_g − G_g f_k)`` the body
turns by ``exp([ω̄_k dt_k]×)`` (exponential map, Rodrigues' formula), so the rotation
accumulated over a move is ``Φ = Π_k exp([ω̄_k dt_k]×)`` and the gravity direction it
predicts at the next pose is ``Φᵀ u_i`` (Tedaldi 2014, eq. 14, their Ψ with an exponential
map instead of quaternion Runge–Kutta).  The residual of move ``i`` is
``Φᵀ u_i − u_{i+1}`` (Tedaldi 2014, eq. 13, imu_tk's ``MultiPosGyroResidual``).

:class:`GravityPredictor` builds this once per recording layout (number of steps of each
move): the step, with the forward sensitivity ``∂u/∂T_g`` carried along, is one CasADi SX
function (:func:`rotation_step`), mapped over the moves side by side and accumulated over
the steps by ``mapaccum``, with the rates, step lengths and gravity directions as inputs.
It serves both the fit (:mod:`optcal.gyro.estimator`, residuals and Jacobian in one pass)
and the convention-free figure of merit, :func:`angles_deg` between predicted and measured
directions.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Below this squared rotation angle (rad²) the Rodrigues coefficients use their Taylor series.
SMALL_ANGLE_SQ: float = 1e-8


@lru_cache(maxsize=1)
def rotation_step() -> Any:
    """CasADi SX step ``(z, θ, q, u₀, first) → z'`` of the gravity direction and its sensitivity.

    ``z = (v, S, Φ)``: the direction ``v`` (3) carried so far, ``S = ∂v/∂T_g`` (3×9,
    column-major, ``T_g`` row-major) and the accumulated rotation ``Φ`` (3×3, column-major).
    ``θ = T_g q`` is the step's rotation vector and ``q = w dt`` its bias-free raw part, so
    ``∂θ_i/∂T_ij = q_j``.  On the first step of a move the state restarts from ``(u₀, 0, I)``.
    ``v' = Eᵀ v`` with ``E = exp([θ]×)`` (Rodrigues), ``S' = Eᵀ S + ∂(Eᵀ v)/∂θ · ∂θ/∂T``,
    ``Φ' = Φ E``.
    """
    import casadi as ca

    z = ca.SX.sym("z", 3 + 27 + 9)
    th = ca.SX.sym("theta", 3)
    q = ca.SX.sym("q", 3)
    u0 = ca.SX.sym("u0", 3)
    first = ca.SX.sym("first")
    a2 = ca.dot(th, th)
    small = a2 < SMALL_ANGLE_SQ
    a2_safe = ca.if_else(small, 1.0, a2)
    a = ca.sqrt(a2_safe)
    c1 = ca.if_else(small, 1 - a2 / 6 + a2**2 / 120, ca.sin(a) / a)
    c2 = ca.if_else(small, 0.5 - a2 / 24 + a2**2 / 720, (1 - ca.cos(a)) / a2_safe)
    c3 = ca.if_else(small, 1.0 / 6 - a2 / 120 + a2**2 / 5040, (a - ca.sin(a)) / (a2_safe * a))
    K = ca.skew(th)
    K2 = K @ K
    E = ca.SX.eye(3) + c1 * K + c2 * K2
    keep = 1 - first
    v = first * u0 + keep * z[0:3]
    S = keep * ca.reshape(z[3:30], 3, 9)
    P = first * ca.SX.eye(3) + keep * ca.reshape(z[30:39], 3, 3)
    v_next = E.T @ v
    # ∂(exp(−[θ]×) v)/∂θ = exp(−[θ]×) [v]× J_r(−θ),  J_r(−θ) = I + c2 [θ]× + c3 [θ]×²
    dv_dth = E.T @ ca.skew(v) @ (ca.SX.eye(3) + c2 * K + c3 * K2)
    # ∂θ/∂T (3×9, T row-major): row i holds q in the columns 3i..3i+2
    dth_dT = ca.SX.zeros(3, 9)
    for i in range(3):
        for j in range(3):
            dth_dT[i, 3 * i + j] = q[j]
    S_next = E.T @ S + dv_dth @ dth_dT
    return ca.Function("rotation_step", [z, th, q, u0, first], [ca.vertcat(v_next, ca.vec(S_next), ca.vec(P @ E))])


class GravityPredictor:
    """Gravity directions carried across every move of a recording layout, with ``∂/∂T_g``.

    Built once per layout; the rates, step lengths and start directions are inputs.

    Parameters
    ----------
    first_step : ndarray of bool, shape (N,)
        First integration step of each move.
    last_step : ndarray of int, shape (m,)
        Last step of each move.

    Attributes
    ----------
    function : casadi.Function
        ``(theta (3, L·m), q (3, L·m), u0 (3, m)) → (v (3, m), S (27, m), Phi (9, m))``:
        per move the predicted direction, its derivative w.r.t. the row-major ``T_g`` and the
        accumulated rotation (column-major), from the rotation vectors ``θ = ω dt`` of the
        steps of all moves side by side (the step mapped over the ``m`` moves, accumulated
        over the ``L ≥`` steps of the longest move by ``mapaccum``, as ``b`` blocks of ``a``).
    """

    def __init__(self, first_step: NDArray[np.bool_], last_step: NDArray[np.int64]) -> None:
        import casadi as ca

        n = int(first_step.size)
        m = int(last_step.size)
        self.n_steps, self.n_moves = n, m
        starts = np.flatnonzero(first_step)
        lengths = np.asarray(last_step) - starts + 1
        # L = a·b steps, accumulated as b blocks of a steps (two short mapaccum graphs instead
        # of one with L nodes: building costs ~2√L nodes)
        a = int(np.ceil(np.sqrt(lengths.max())))
        b = int(np.ceil(lengths.max() / a))
        L = a * b
        self.length = L
        # steps of all moves side by side: slot (step s, move i) at column s·m + i; moves shorter
        # than L are padded at the end with zero rotations (the identity)
        slot = (np.arange(n) - np.repeat(starts, lengths)) * m + np.repeat(np.arange(m), lengths)
        self.slot = slot
        first = np.zeros((1, L * m))
        first[0, :m] = 1.0
        self.first = first
        theta, q, u0 = ca.MX.sym("theta", 3, L * m), ca.MX.sym("q", 3, L * m), ca.MX.sym("u0", 3, m)
        inner = rotation_step().map(m).mapaccum("block_steps", a)
        z = ca.MX.sym("z", 39, m)
        args = [ca.MX.sym(name, rows, a * m) for name, rows in (("theta", 3), ("q", 3), ("u0", 3), ("first", 1))]
        block = ca.Function("block", [z, *args], [inner(z, *args)[:, (a - 1) * m:]])
        states = block.mapaccum("move_blocks", b)(ca.DM.zeros(39, m), theta, q, ca.repmat(u0, 1, L), ca.DM(first))
        ends = states[:, (b - 1) * m:]
        self.function = ca.Function("predict_gravity", [theta, q, u0], [ends[0:3, :], ends[3:30, :], ends[30:39, :]],
                                    ["theta", "q", "u0"], ["v", "S", "Phi"])

    def evaluate(self, T: NDArray, w: NDArray, dt: NDArray, u0: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Predicted directions (m, 3), their Jacobian w.r.t. row-major ``T`` (m, 3, 9) and ``Φ`` (m, 3, 3).

        ``w`` (N, 3) are bias-free raw rates, ``dt`` (N,) step lengths, ``u0`` (m, 3) start directions.
        """
        q = np.zeros((self.length * self.n_moves, 3))
        q[self.slot] = np.asarray(w, float) * np.asarray(dt, float)[:, None]
        theta = q @ np.asarray(T, float).T
        v, S, P = self.function(theta.T, q.T, np.asarray(u0, float).T)
        m = self.n_moves
        return (np.asarray(v).T, np.asarray(S).T.reshape(m, 9, 3).transpose(0, 2, 1),
                np.asarray(P).T.reshape(m, 3, 3).transpose(0, 2, 1))

    def __call__(self, omega: NDArray, dt: NDArray, u0: NDArray) -> NDArray[np.float64]:
        """Predicted directions (m, 3) for corrected rates ``omega`` (N, 3) rad/s."""
        return self.evaluate(np.eye(3), omega, dt, u0)[0]


def unit_rows(x: NDArray) -> NDArray[np.float64]:
    """Rows of ``x`` scaled to unit length."""
    x = np.asarray(x, dtype=float)
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def angles_deg(predicted: NDArray, measured: NDArray) -> NDArray[np.float64]:
    """Angle between corresponding rows of two direction arrays, degrees."""
    p, q = unit_rows(predicted), unit_rows(measured)
    cross = np.linalg.norm(np.cross(p, q), axis=1)
    return np.degrees(np.arctan2(cross, np.sum(p * q, axis=1)))


def rms(x: NDArray) -> float:
    """Root mean square of ``x``."""
    return float(np.sqrt(np.mean(np.square(x))))
