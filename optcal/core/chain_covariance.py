"""White noise plus a Markov chain of 3-vector states seen along each pose's direction, in linear time.

Two noise models of the diagnosis share one structure: the pose noise correlated in time
(:mod:`optcal.applications.diagnosis.correlation`, a Gauss–Markov process) and the bias that wanders as a
random walk (:mod:`optcal.families.accel.random_walk_bias`, a Wiener process).  Both give the
residuals ``r`` (one per pose) the covariance

``V = A + U (P ⊗ I₃) Uᵀ``,

with ``A = diag(a_k)`` the white part, ``U`` the ``n × 3m`` matrix whose row ``k`` holds the
3-vector ``u_k`` in the columns of the state ``s(k)`` pose ``k`` sees (a row of zeros for a pose
that sees none), and ``P`` the covariance of one axis of a first-order Markov chain of ``m``
states, ``x_0 ~ N(0, q_0)``, ``x_{i+1} = φ_i x_i + √q_{i+1} ε_i`` (``φ_i = 0`` restarts it).
Several poses may see the same state (poses recorded at the same time).

**Why linear time.**  ``P⁻¹`` of a Markov chain is tridiagonal (``1/q_i + φ_i²/q_{i+1}`` on the
diagonal, ``−φ_i/q_{i+1}`` beside it), so with the three axes of each state interleaved

``M = P⁻¹ ⊗ I₃ + Uᵀ A⁻¹ U``

is banded (bandwidth 3: ``Uᵀ A⁻¹ U`` is block diagonal, one 3 × 3 block per state).  By the
Woodbury identity and the determinant lemma (the Kalman filter's likelihood, written as one
banded factorisation),

``V⁻¹ = A⁻¹ − A⁻¹ U M⁻¹ Uᵀ A⁻¹``,   ``log det V = log det M + 3 Σ log q_i + Σ log a_k``,

and the states given the residuals (the Rauch–Tung–Striebel smoother's result) are

``E[x | r] = M⁻¹ Uᵀ A⁻¹ r``,   ``cov(x | r) = M⁻¹``,

the diagonal of ``M⁻¹`` from the banded factor by Takahashi's recursion.  A state no pose
sees (``u = 0``) is predicted from its neighbours in the chain: held-out poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import linalg

#: Bandwidth of ``M`` with the three axes of a state interleaved (the same axis of the next state).
BAND: int = 3


@dataclass(frozen=True)
class MarkovChain:
    """One axis of a first-order Markov chain of ``m`` states: ``x_{i+1} = φ_i x_i + √q_{i+1} ε_i``.

    Attributes
    ----------
    phi : ndarray, shape (m − 1,)
        ``φ_i`` between state ``i`` and ``i + 1`` (0 restarts the chain).
    q : ndarray, shape (m,)
        Innovation variance of each state (``q_0``: the first state's variance; after a restart,
        the restarted state's variance).  Positive.
    """

    phi: NDArray[np.float64]
    q: NDArray[np.float64]

    @property
    def size(self) -> int:
        return int(self.q.size)

    def precision(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``P⁻¹``: its diagonal (m,) and first off-diagonal (m − 1,)."""
        diag = 1.0 / self.q
        diag[:-1] += self.phi**2 / self.q[1:]
        return diag, -self.phi / self.q[1:]

    def logdet(self) -> float:
        """``log det P = Σ log q_i``."""
        return float(np.sum(np.log(self.q)))

    def covariance(self) -> NDArray[np.float64]:
        """``P`` as a dense matrix (for tests and small problems)."""
        diag, off = self.precision()
        return np.linalg.inv(np.diag(diag) + np.diag(off, 1) + np.diag(off, -1))  # type: ignore[return-value]  # numpy stubs type inv of float64 as floating[Any]

    def scaled(self, factor: float) -> "MarkovChain":
        """The chain of ``√factor · x`` (every variance times ``factor``)."""
        return MarkovChain(self.phi, self.q * factor)


class ChainCovariance:
    """``V = A + U (P ⊗ I₃) Uᵀ`` applied, inverted and factorised in O(n) (module docstring).

    Parameters
    ----------
    white : ndarray, shape (n,)
        ``a_k``, each pose's white variance (positive).
    loading : ndarray, shape (n, 3)
        ``u_k``, how pose ``k``'s residual sees its state.
    state : ndarray of int, shape (n,)
        The state each pose sees (``−1``: none; its row of ``U`` is zero).
    chain : MarkovChain or None
        The states' chain; ``None``: ``V = A``.
    """

    def __init__(self, white: NDArray, loading: NDArray, state: NDArray, chain: MarkovChain | None) -> None:
        self.white = np.asarray(white, dtype=float)
        self.loading = np.asarray(loading, dtype=float)
        self.state = np.asarray(state, dtype=np.intp)
        self.chain = chain
        self.n = self.white.size
        self._seen = self.state >= 0
        self.factor: NDArray[np.float64] | None = None
        if chain is None or chain.size == 0:
            self.chain = None
            self._one_to_one = True
            self.logdet = float(np.sum(np.log(self.white)))
            return
        m = chain.size
        seen_states = self.state[self._seen]
        #: every state seen by at most one pose (the usual case): scatter without accumulating
        self._one_to_one = bool(seen_states.size == 0 or np.bincount(seen_states, minlength=m).max() <= 1)
        diag, off = chain.precision()
        # Uᵀ A⁻¹ U: one 3 × 3 block per state (a sum over the poses that see it)
        u = self.loading[self._seen]
        w = 1.0 / self.white[self._seen]
        blocks = np.zeros((m, 3, 3))
        outer = w[:, None, None] * u[:, :, None] * u[:, None, :]
        if self._one_to_one:
            blocks[seen_states] = outer
        else:
            np.add.at(blocks, seen_states, outer)
        ab = np.zeros((BAND + 1, 3 * m))  # upper banded storage: ab[BAND + i − j, j] = M[i, j]
        ab[BAND] = np.repeat(diag, 3) + blocks[:, [0, 1, 2], [0, 1, 2]].ravel()
        ab[BAND - 1, 1:] = np.stack([blocks[:, 0, 1], blocks[:, 1, 2], np.zeros(m)], axis=1).ravel()[:-1]
        ab[BAND - 2, 2:] = np.stack([blocks[:, 0, 2], np.zeros(m), np.zeros(m)], axis=1).ravel()[:-2]
        ab[BAND - 3, 3:] = np.repeat(off, 3)
        self.factor = linalg.cholesky_banded(ab, lower=False, check_finite=False)
        self.logdet = (2.0 * float(np.sum(np.log(self.factor[BAND]))) + 3.0 * chain.logdet()
                       + float(np.sum(np.log(self.white))))

    # -- pieces -----------------------------------------------------------------------------
    def _Ut(self, Y: NDArray) -> NDArray[np.float64]:
        """``Uᵀ Y`` for ``Y`` of shape (n, c): shape (3m, c)."""
        assert self.chain is not None
        out = np.zeros((self.chain.size, 3, Y.shape[1]))
        seen = self._seen
        part = self.loading[seen][:, :, None] * Y[seen][:, None, :]
        if self._one_to_one:
            out[self.state[seen]] = part
        else:
            np.add.at(out, self.state[seen], part)
        return out.reshape(3 * self.chain.size, Y.shape[1])

    def _U(self, Z: NDArray) -> NDArray[np.float64]:
        """``U Z`` for ``Z`` of shape (3m, c): shape (n, c)."""
        assert self.chain is not None
        Z3 = Z.reshape(self.chain.size, 3, Z.shape[1])
        out = np.zeros((self.n, Z.shape[1]))
        seen = self._seen
        out[seen] = np.einsum("ka,kac->kc", self.loading[seen], Z3[self.state[seen]])
        return out

    def _solve_M(self, Y: NDArray) -> NDArray[np.float64]:
        return linalg.cho_solve_banded((self.factor, False), Y, check_finite=False)

    # -- what the models need -------------------------------------------------------------------
    def solve(self, X: NDArray) -> NDArray[np.float64]:
        """``V⁻¹ X`` (a vector of length n or an (n, c) matrix)."""
        X = np.asarray(X, dtype=float)
        vector = X.ndim == 1
        Y = (X[:, None] if vector else X) / self.white[:, None]
        if self.chain is not None:
            Y = Y - self._U(self._solve_M(self._Ut(Y))) / self.white[:, None]
        return Y[:, 0] if vector else Y

    def state_mean(self, r: NDArray) -> NDArray[np.float64]:
        """``E[x | r] = M⁻¹ Uᵀ A⁻¹ r``: the smoothed states, shape (m, 3)."""
        if self.chain is None:
            return np.zeros((0, 3))
        return self._solve_M(self._Ut((np.asarray(r, dtype=float) / self.white)[:, None]))[:, 0].reshape(-1, 3)

    def state_variance(self) -> NDArray[np.float64]:
        """The diagonal of ``cov(x | r) = M⁻¹``, shape (m, 3) (:func:`block_inverse_diagonal`)."""
        if self.chain is None or self.factor is None:
            return np.zeros((0, 3))
        return block_inverse_diagonal(self.factor).reshape(-1, 3)

    def dense(self) -> NDArray[np.float64]:
        """``V`` as a dense matrix (for tests)."""
        V = np.diag(self.white)
        if self.chain is not None:
            P = self.chain.covariance()
            U = np.zeros((self.n, self.chain.size))
            for axis in range(3):
                U[:] = 0.0
                U[self._seen, self.state[self._seen]] = self.loading[self._seen, axis]
                V += U @ P @ U.T
        return V


def block_inverse_diagonal(factor: NDArray[np.float64]) -> NDArray[np.float64]:
    """Diagonal of ``M⁻¹`` for ``M = RᵀR``, ``R`` upper triangular with bandwidth 3 (LAPACK upper storage).

    ``M`` is block tridiagonal in 3 × 3 blocks (a state's three axes), so ``R`` has diagonal blocks
    ``D_s`` and blocks ``E_s`` beside them, and ``Σ = M⁻¹`` follows from the last state up by
    Takahashi, Fagan & Chin's (1973) recursion: ``Σ_s = D_s⁻¹ D_s⁻ᵀ + G_s Σ_{s+1} G_sᵀ`` with
    ``G_s = D_s⁻¹ E_s`` (from ``R Σ = R⁻ᵀ``, lower triangular).  O(m).
    """
    N = factor.shape[1]
    m = N // 3
    i, j = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    base = 3 * np.arange(m)[:, None, None]
    upper = j >= i
    D = np.where(upper, factor[np.clip(BAND + i - j, 0, BAND)[None], base + j], 0.0)  # R[3s+i, 3s+j]
    D_inv = np.linalg.inv(D)
    out = np.empty((m, 3))
    S = D_inv[-1] @ D_inv[-1].T
    out[-1] = np.diag(S)
    if m > 1:
        lower = j <= i  # R[3s+i, 3(s+1)+j] is inside the band when 3 + j − i ≤ 3
        E = np.where(lower, factor[np.clip(i - j, 0, BAND)[None], base[:-1] + 3 + j], 0.0)
        G = D_inv[:-1] @ E
        A = D_inv[:-1] @ np.swapaxes(D_inv[:-1], 1, 2)
        for s in range(m - 2, -1, -1):
            S = A[s] + G[s] @ S @ G[s].T
            out[s] = S[[0, 1, 2], [0, 1, 2]]
    return out.ravel()


__all__ = ["BAND", "ChainCovariance", "MarkovChain", "block_inverse_diagonal"]
