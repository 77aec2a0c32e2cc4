"""White noise plus a Markov chain seen along each pose's direction: the O(n) operator against dense algebra."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.chain_covariance import ChainCovariance, MarkovChain, block_inverse_diagonal


def _dense_loading(op: ChainCovariance) -> np.ndarray:
    """``U`` (n × 3m, a state's axes interleaved) written out."""
    assert op.chain is not None
    U = np.zeros((op.n, 3 * op.chain.size))
    for k in np.flatnonzero(op.state >= 0):
        U[k, 3 * op.state[k]:3 * op.state[k] + 3] = op.loading[k]
    return U


def _random_operator(seed: int, n: int = 40, m: int = 25) -> ChainCovariance:
    """Poses sharing states, poses seeing none, states nobody sees and chain restarts."""
    rng = np.random.default_rng(seed)
    phi = np.where(rng.random(m - 1) < 0.2, 0.0, rng.uniform(0.0, 1.0, m - 1))
    chain = MarkovChain(phi, rng.uniform(0.1, 2.0, m))
    return ChainCovariance(rng.uniform(0.2, 2.0, n), rng.standard_normal((n, 3)), rng.integers(-1, m, n), chain)


def test_ornstein_uhlenbeck_and_wiener_chains_have_their_known_covariances():
    t = np.array([0.0, 0.5, 2.0, 2.1, 7.0])
    tau = 1.7
    phi = np.exp(-np.diff(t) / tau)
    ou = MarkovChain(phi, np.concatenate([[1.0], 1 - phi**2]))
    assert np.allclose(ou.covariance(), np.exp(-np.abs(t[:, None] - t[None, :]) / tau), rtol=0, atol=1e-12)
    wiener = MarkovChain(np.ones(4), np.diff(t, prepend=-1.0))  # starts 1 s before the first time
    assert np.allclose(wiener.covariance(), np.minimum(t[:, None], t[None, :]) + 1.0, rtol=0, atol=1e-12)
    assert ou.logdet() == pytest.approx(np.linalg.slogdet(ou.covariance())[1], abs=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_solve_logdet_and_smoother_equal_the_dense_algebra(seed: int):
    op = _random_operator(seed)
    rng = np.random.default_rng(100 + seed)
    V = op.dense()
    X = rng.standard_normal((op.n, 5))
    assert np.max(np.abs(op.solve(X) - np.linalg.solve(V, X))) < 1e-10
    assert np.max(np.abs(op.solve(X[:, 0]) - np.linalg.solve(V, X[:, 0]))) < 1e-10
    assert op.logdet == pytest.approx(np.linalg.slogdet(V)[1], abs=1e-10)
    # the states given the residuals: E[x|r] = P Uᵀ V⁻¹ r, cov = P − P Uᵀ V⁻¹ U P (every axis)
    U = _dense_loading(op)
    P = np.kron(op.chain.covariance(), np.eye(3))
    r = rng.standard_normal(op.n)
    mean = P @ U.T @ np.linalg.solve(V, r)
    cov = P - P @ U.T @ np.linalg.solve(V, U @ P)
    assert np.max(np.abs(op.state_mean(r).ravel() - mean)) < 1e-10
    assert np.max(np.abs(op.state_variance().ravel() - np.diag(cov))) < 1e-10


def test_block_inverse_diagonal_is_the_inverse_s_diagonal():
    rng = np.random.default_rng(3)
    N = 30
    A = rng.standard_normal((N, N))
    band = np.abs(np.arange(N)[:, None] - np.arange(N)[None, :]) <= 3
    M = np.where(band, A + A.T, 0.0) + 12 * np.eye(N)
    from scipy import linalg

    ab = np.zeros((4, N))
    for d in range(4):
        ab[3 - d, d:] = np.diag(M, d)
    factor = linalg.cholesky_banded(ab, lower=False)
    assert np.max(np.abs(block_inverse_diagonal(factor) - np.diag(np.linalg.inv(M)))) < 1e-12


def test_without_a_chain_it_is_the_white_noise():
    w = np.array([1.0, 2.0, 4.0])
    op = ChainCovariance(w, np.ones((3, 3)), np.zeros(3, dtype=int), None)
    assert np.array_equal(op.solve(np.ones(3)), 1 / w) and op.logdet == pytest.approx(np.log(8.0))
    assert op.state_mean(np.ones(3)).shape == (0, 3)
