"""A selection step's per-candidate level from the joint null distribution of its tests (Westfall & Young 1993, minP).

A step tests ``m`` candidate terms at once, and names the best that passes.  Bonferroni (each at ``α/m``) keeps the
step's family-wise false-finding rate at most ``α`` whatever the candidates' dependence, and is conservative
when they are dependent.  In a small session they are strongly so:

* every candidate's F test divides by a residual sum that all of them share but for their own columns (a session
  of 14 poses leaves 4 residual degrees of freedom after a term: a low residual sum makes *every* candidate look
  significant together);
* their columns correlate (a temperature bias and a temperature scale on one axis, a drift's orders 1-3 nested,
  a temperature rising monotonically through the session and time).

The minP procedure tests each candidate at the level ``c`` at which the *smallest* of the step's p values falls
below ``c`` with probability ``α`` when no candidate is true: the step's family-wise level is then ``α`` (to the
Monte Carlo's precision, :data:`DRAWS`), with more power than ``α/m``.  The null distribution is the linearised
model at the current fit: the weighted pose residuals are ``σ z`` with ``z`` standard normal, the current model's
columns projected out, and each candidate's statistic formed as
:meth:`~optcal.applications.diagnosis.fitting.Fitter.f_test` forms it, on the route
:meth:`~optcal.applications.diagnosis.fitting.Fitter.test_scale2` takes (the residuals' scale, an F test with each
candidate's own degrees of freedom: the p values do not depend on σ).

Used only where the tests keep fewer than :data:`~optcal.applications.diagnosis.fitting.MIN_DOF` residual degrees
of freedom (a small session): there the shared residual sum makes Bonferroni most conservative (14 Xsens rests:
the level is 0.0019 against Bonferroni's 0.0011 over 18 candidates), and the simulation
is of a few dozen poses.  Larger sessions keep Bonferroni (their residual sums are nearly constant, their
candidates nearly independent, and the 2,000-pose diagnosis keeps its speed); so do poses whose noise is
correlated in time (:func:`uses_minp`).  The bias step's position search draws from the same null model, under a
correlation in time whitened (:func:`whitening`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.fitting import MIN_DOF, Fit, Fitter, mean_shift_columns
from optcal.applications.diagnosis.problem import BETA_INDEX

#: Draws of the null simulation.  The level is the ``α`` quantile of the smallest p: at α = 0.02, 80 draws lie
#: below it, so the family-wise level it gives is within α ± 0.0022 (binomial, one standard error): an eighth of
#: the level itself.
DRAWS: int = 4000
#: Singular values of a candidate's columns, after the current model's are projected out, below this share of
#: the largest carry no information (``√IDENTIFIABLE_TOL``: the same share of information as
#: :meth:`~optcal.applications.diagnosis.fitting.Fitter.identifiable`, which such a candidate fails).
RANK_TOL: float = 1e-3


def candidate_columns(fit: Fit, effect: str, axis: int, order: int) -> list[int]:
    """Columns of the full parameter vector a candidate adds to ``fit``: orders 1..``order`` of a new term, or
    the orders above ``fit``'s of a term ``fit`` already has."""
    first = fit.terms[(effect, axis)] + 1 if (effect, axis) in fit.terms else 1
    return [9 + BETA_INDEX[(effect, axis, p)] for p in range(first, order + 1)]


def orthonormal(A: NDArray[np.float64], tol: float = 1e-10) -> NDArray[np.float64]:
    """An orthonormal basis of the column space of ``A`` (singular values below ``tol`` of the largest dropped)."""
    if A.shape[1] == 0:
        return A
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, s > tol * max(float(s.max(initial=0.0)), 1e-300)]


@dataclass(frozen=True)
class NullDraws:
    """Draws of the linearised null model at a fit (:func:`null_draws`).

    Attributes
    ----------
    kept : ndarray of bool
        The poses the draws stand for: the fit's kept poses (its outliers out); every pose under correlated noise
        (each outlier a mean-shift column of :attr:`model`, as the generalised fit carries it).
    J : ndarray
        The full weighted Jacobian at the fit, every pose, not whitened (each candidate's columns are taken from it
        and passed through :meth:`columns`).
    model : ndarray
        An orthonormal basis of the fit's free columns on :attr:`kept` (whitened under correlated noise).
    z : ndarray
        Standard normal weighted residuals, (:attr:`kept` poses, draws): σ z with σ = 1 (whitened: ``W e``).
    rss0 : ndarray
        The null model's residual sum of each draw (``z`` with ``model`` projected out), σ² = 1.
    whiten : ndarray or None
        ``W`` with ``WᵀW = R⁻¹`` (:func:`whitening`) under correlated pose noise, ``None`` for independent poses.
    """

    kept: NDArray[np.bool_]
    J: NDArray[np.float64]
    model: NDArray[np.float64]
    z: NDArray[np.float64]
    rss0: NDArray[np.float64]
    whiten: NDArray[np.float64] | None = None

    def columns(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """Columns ``X`` of every pose (rows of :attr:`J`'s form) as the draws see them: whitened, then the rows of
        :attr:`kept`."""
        return (X if self.whiten is None else self.whiten @ X)[self.kept]

    def draw(self, rng: np.random.Generator, count: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``count`` more draws of this null model: standard normal weighted residuals ``z`` (rows of :attr:`model`,
        ``count``) and their residual sums with :attr:`model` projected out (σ² = 1), as :attr:`z` and :attr:`rss0`
        are drawn (draws made in blocks, :func:`sequential_p`)."""
        z = rng.standard_normal((self.model.shape[0], count))
        return z, np.sum((z - self.model @ (self.model.T @ z)) ** 2, axis=0)

    def residuals(self, fitter: Fitter, fit: Fit) -> NDArray[np.float64]:
        """``fit``'s weighted residuals as :attr:`z` stands for them (the observed counterpart of a draw)."""
        if self.whiten is None:
            return (np.sqrt(fitter.weights(fit)) * fit.residuals)[self.kept]
        return self.whiten @ (np.sqrt(fitter.w) * fit.residuals)


def whitening(fitter: Fitter) -> NDArray[np.float64] | None:
    """``W`` with ``WᵀW = R⁻¹`` (upper triangular, the transposed Cholesky factor of ``R⁻¹``), ``R`` the correlation
    of the poses' weighted residuals the diagnosis measured (:mod:`~optcal.applications.diagnosis.correlation`);
    ``None`` for independent poses (no correlation used, or ``ρ₀ = 0``: ``R = I``).

    The null model under correlated noise: the weighted residuals are ``σ R^½ z``, ``z`` standard normal, ``R`` as
    estimated (REML) taken as known, as the generalised least-squares fit and its F tests take it.  ``W e`` is then
    ``σ z``: the generalised fit of ``e`` is the ordinary one of ``W e`` on ``W G``, and every statistic of the
    independent case holds for the whitened residuals and columns.  Dense (``n × n``): used where the minP
    simulation is (:data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` poses).
    """
    op = fitter.correlation
    if op is None or op.covariance is None:
        return None
    inverse = op.solve(np.eye(fitter.n))
    return np.asarray(np.linalg.cholesky((inverse + inverse.T) / 2).T)


def null_draws(fitter: Fitter, fit: Fit, draws: int, seed: int = 0) -> NullDraws:
    """``draws`` draws of the linearised null model at ``fit``: the weighted residuals of the kept poses ``σ z``
    with ``z`` standard normal (Lu 2017, eq. 14's weights make them so), the fit's own columns projected out
    (the selection's minP level, :func:`minp_level`, and the bias step's adjusted p,
    :func:`~optcal.applications.diagnosis.bias_step.adjusted_p`).  Under correlated pose noise the same in the
    whitened space (:func:`whitening`): every pose, the fit's outliers as its mean-shift columns."""
    W = whitening(fitter)
    if W is None:
        kept = fit.kept(fitter.n)
        G, J = fitter.jacobians(fit, fitter.weights(fit))
        model = orthonormal(G[kept])
    else:
        kept = np.ones(fitter.n, dtype=bool)
        G, J = fitter.jacobians(fit, fitter.w)
        model = orthonormal(W @ np.column_stack([G, mean_shift_columns(fitter.n, fit.outliers)]))
    system = NullDraws(kept, J, model, np.zeros((model.shape[0], 0)), np.zeros(0), W)
    z, rss0 = system.draw(np.random.default_rng(seed), draws)  # the null model's residual sum, σ² = 1
    return replace(system, z=z, rss0=rss0)


def uses_minp(fitter: Fitter, fit: Fit) -> bool:
    """Whether a step from ``fit`` takes its level from :func:`minp_level`: its tests keep fewer than
    :data:`MIN_DOF` residual degrees of freedom, and the poses are independent."""
    return fitter.correlation is None and fitter.n - fit.n_params - 1 < MIN_DOF


def minp_level(fitter: Fitter, fit: Fit, candidates: list[tuple[str, int, int]], alpha: float,
               seed: int = 0) -> float | None:
    """The per-candidate level at which a step from ``fit`` over ``candidates`` has family-wise level ``alpha``.

    Parameters
    ----------
    fitter : Fitter
    fit : Fit
        The current model (the null hypothesis: no candidate is true).
    candidates : list of (str, int, int)
        ``(effect, axis, order)`` of the step's term candidates; those with no information left after ``fit``
        take no part (they are not tested).
    alpha : float
        The step's family-wise level.
    seed : int
        Seed of the null simulation (the level is reproducible).

    Returns
    -------
    float or None
        The ``alpha`` quantile of the smallest p value of the step's route (module docstring); ``None`` when no
        candidate can be tested.
    """
    null = null_draws(fitter, fit, DRAWS, seed)
    model, z, rss0 = null.model, null.z, null.rss0
    bases: list[NDArray[np.float64]] = []
    added: list[int] = []
    for effect, axis, order in candidates:
        columns = candidate_columns(fit, effect, axis, order)
        J = null.columns(null.J[:, columns])
        projected = J - model @ (model.T @ J)
        basis = orthonormal(projected / max(float(np.linalg.norm(J)), 1e-300), RANK_TOL)
        if basis.shape[1]:
            bases.append(basis)
            added.append(len(columns))
    if not bases:
        return None
    gain = np.stack([np.sum((b.T @ z) ** 2, axis=0) for b in bases])  # each candidate's fall in it, (K, DRAWS)
    dof0 = fitter.n - fit.n_params
    # candidates adding the same number of coefficients share their test's distribution, whose p value falls as the
    # gain rises: each such group's smallest p is that of its largest gain (one tail probability per group and draw)
    sizes = np.asarray(added)
    p = np.ones(DRAWS)
    for q in np.unique(sizes):
        dof = dof0 - int(q)
        if dof <= 0:  # no room left to test such a candidate: p = 1
            continue
        largest = gain[sizes == q].max(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):  # the F test of Fitter.f_test (Fitter.test_scale2)
            p = np.minimum(p, sps.f.sf(largest / q / ((rss0 - largest) / dof), q, dof))
    smallest = np.sort(p)
    return float(smallest[int(np.floor(alpha * DRAWS))])  # P(min p < level) ≤ α


def sequential_p(system: NullDraws,
                 smallest_p: Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]],
                 observed: list[float], level: float, total: int, block: int, seed: int = 0) -> list[float]:
    """Monte Carlo p values ``(1 + C)/(1 + L)`` of each of ``observed`` against the smallest p of a search in draws
    of ``system`` (``smallest_p(z, rss0)``: one value per draw; ``C`` of the ``L`` draws made at most the observed).

    Valid at any ``L`` (Davison & Hinkley 1997, eq. 4.11).  At most ``total`` draws, made in blocks of ``block``
    (:meth:`NullDraws.draw`), stopped as soon as the smallest of ``observed`` is settled not significant at
    ``level`` (``1 + C > level (1 + total)``: whatever the remaining draws show; Besag & Clifford 1991's sequential
    p value, ``(1 + C)/(1 + draws made)``); every larger observed value is then settled too."""
    rng = np.random.default_rng(seed)
    least = observed.index(min(observed))
    exceed = np.zeros(len(observed), dtype=int)
    made = 0
    while made < total:
        z, rss0 = system.draw(rng, min(block, total - made))
        p = smallest_p(z, rss0)
        exceed += np.array([int(np.sum(p <= x)) for x in observed])
        made += z.shape[1]
        if 1 + int(exceed[least]) > level * (1 + total):
            break
    return [float((1 + c) / (1 + made)) for c in exceed]
