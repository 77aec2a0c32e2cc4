"""Two bias steps searched together in a session of more than :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES`
kept poses: the first knock among each axis's best one-step places, the second among every place given it.

:mod:`~optcal.applications.diagnosis.step_pair` searches every pair of places and axes and adjusts the best pair's
p value by minP over all of them: ``n²`` sets in the observed scan and in each null draw (16 CPU s at 60 poses, 57
at 100).  Above :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` kept poses the search is *restricted*
and the minP adjustment is that of the restricted procedure, formed the same way on the observed residuals and on
every draw, so the adjusted p value stays a Monte Carlo p value of the statistic actually used (Westfall & Young's
single-step minP, of a data-dependent family):

1. the one-step score of every place ``k`` and axis ``a`` (the linearised likelihood ratio ``(uᵀe)²/(uᵀu)`` of the
   step column ``u`` with the fit's columns projected out, as :func:`~optcal.applications.diagnosis.bias_step.scan_step`
   scores it);
2. on each axis ``a₁`` its :data:`ANCHORS` best places ``P``;
3. for each such ``(a₁, P)`` and each axis ``a₂`` every place ``Q`` with at least
   :data:`~optcal.applications.diagnosis.effects.STEP_MIN_SIDE` kept poses between ``P`` and ``Q``: the pair's gain
   ``bᵀ(UᵀU)⁻¹b`` (one axis: the columns of ``(a₁, P)`` and ``(a₁, Q)``; two: ``(a₁, P)``, ``(a₂, P)`` and
   ``(a₂, Q)``, the model of :mod:`~optcal.applications.diagnosis.step_pair`) and its F p value with its own number
   of coefficients;
4. the statistic: the smallest p.

Costs ``axes² · ANCHORS · n`` sets per draw instead of ``axes² · n² / 2``.  Everything is formed from suffix sums in
time order (a step column is the bias column from a place on), so no ``n × n²`` column matrix is built: the
columns' Gram entries are ``Σ_{t ≥ max(k, l)} h_a h_b`` less their projections onto the fit's columns (under pose
noise correlated in time, the two-sided suffix sums of ``h_a R⁻¹ h_b``; the null model of
:func:`~optcal.applications.diagnosis.familywise.null_draws`, whitened).

**Draws and early stop.**  A Monte Carlo p value ``(1 + C)/(1 + L)`` (``C`` of ``L`` draws at least as extreme) is
valid at any ``L`` (Davison & Hinkley 1997, eq. 4.11); the pair is tested at its share of the step's level, so
``L`` is the number of draws that leaves :data:`EXCEEDANCES` draws below the level (about 8,800 at 0.00125, capped
at :data:`~optcal.applications.diagnosis.bias_step.DRAWS`).  The draws are made in blocks and stop as soon as the
exceedances settle the decision (``1 + C > level (1 + L)``: the pair is not significant whatever the rest show;
Besag & Clifford 1991's sequential p value, the decision the full run would take, ``(1 + C)/(1 + draws made)``
reported).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.bias_step import DRAWS, uses_minp_positions
from optcal.applications.diagnosis.effects import STEP_MIN_SIDE
from optcal.applications.diagnosis.familywise import NullDraws, null_draws, sequential_p
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.step_pair import PairScan, f_p, scan_pair, valid_splits, with_null

__all__ = ["ANCHORS", "EXCEEDANCES", "DENSE_POSES", "search_pair", "pair_adjusted_p", "PairGeometry"]

#: Places of each axis's best one-step scores a first knock is taken from.  The one-step score of a knock's own
#: place is lowered, not removed, by a second knock that hides it (mikoff imu0: each knock is still its axis's best
#: split); neighbouring places share all but one pose and score alike, so five cover the peak's width of a knock
#: and the next peak (a second knock's).  Costs five times one place per axis.
ANCHORS: int = 5
#: Null draws left below the pair's level by the number of draws made (``L ≈ (EXCEEDANCES + 1) / level``): the
#: Monte Carlo test's power against an exact test's at a true p of half the level is 0.97 (Poisson(5.5) ≤ 10).
EXCEEDANCES: int = 10
#: Elements of one block's (anchors × draws × places) arrays (memory: about 12 arrays of this many floats, 200 MB).
BLOCK_ELEMENTS: int = 2_000_000
#: Most poses correlated in time the pair is searched on: their whitening and the two-sided suffix sums are dense,
#: (axes + 2) n² floats (160 MB at 2,000 poses, the memory budget of the 2,000-pose diagnosis being 1.5 GB).
DENSE_POSES: int = 2000
#: Share of a set's information its columns must keep after the others' are projected out (as the full search's
#: Gram condition number below 1e8: a pair the fit already carries is not testable).
INFO_TOL: float = 1e-8


def _suffix(x: NDArray[np.float64], axis: int = 0) -> NDArray[np.float64]:
    """Suffix sums along ``axis``: entry ``k`` is the sum over ``k`` and every later entry."""
    return np.flip(np.cumsum(np.flip(x, axis=axis), axis=axis), axis=axis)


@dataclass(frozen=True)
class PairGeometry:
    """The step columns of every place and axis at a fit, as suffix sums in time order (module docstring).

    Attributes
    ----------
    splits : ndarray of int
        Places searched (poses before, time order: :func:`~optcal.applications.diagnosis.step_pair.valid_splits`).
    kept_before : ndarray of int
        Kept poses before each of :attr:`splits`.
    axes : list of int
    h : ndarray
        Each axis's bias column in time order, (axes, n) (zero on a pose the draws leave out).
    B : ndarray
        Each step column's projection on the fit's orthonormal columns, (axes, n, p).
    metric : ndarray or None
        ``WᵀW = R⁻¹`` in time order under correlated pose noise; ``None`` for independent poses.
    to_time : ndarray of int or None
        For independent poses, the time position of each row of the draws (the fit's kept poses).
    whiten : ndarray or None
        ``W`` with its columns in time order (correlated noise).
    left : ndarray or None
        Under correlated noise, ``Σ_{s ≥ P} h_a[s] M[s, t]`` for every axis, place ``P`` and pose ``t``.
    model : ndarray
        The fit's orthonormal columns in the draws' space.
    dof0 : int
        Residual degrees of freedom of the fit.
    """

    splits: NDArray[np.int_]
    kept_before: NDArray[np.int_]
    axes: list[int]
    h: NDArray[np.float64]
    B: NDArray[np.float64]
    metric: NDArray[np.float64] | None
    to_time: NDArray[np.int_] | None
    whiten: NDArray[np.float64] | None
    model: NDArray[np.float64]
    dof0: int
    left: NDArray[np.float64] | None = None

    @classmethod
    def at(cls, fitter: Fitter, fit: Fit, axes: list[int], system: NullDraws | None = None) -> "PairGeometry":
        """The geometry at ``fit`` (no step placed) for the steps of ``axes`` (``system``: ``null_draws(fitter, fit,
        0)`` when already made)."""
        system = null_draws(fitter, fit, 0) if system is None else system
        order = fitter.time_order
        n = fitter.n
        h = np.stack([system.J[order, 6 + a] for a in axes])
        if system.whiten is None:
            position = np.empty(n, dtype=int)
            position[order] = np.arange(n)
            to_time = position[np.flatnonzero(system.kept)]
            model_t = np.zeros((n, system.model.shape[1]))
            model_t[to_time] = system.model
            h = h * system.kept[order][None, :]
            metric, whiten = None, None
        else:
            whiten = system.whiten[:, order]
            model_t = whiten.T @ system.model
            metric = whiten.T @ whiten
            to_time = None
        B = _suffix(h[:, :, None] * model_t[None, :, :], axis=1)
        kept = fit.kept(n)[order]
        before = np.concatenate([[0], np.cumsum(kept)])[:n]
        splits = valid_splits(fitter, fit)
        left = None if metric is None else _suffix(h[:, :, None] * metric[None, :, :], axis=1)
        return cls(splits, before[splits], list(axes), h, B, metric, to_time, whiten, system.model,
                   fitter.n - fit.n_params, left)

    def scores(self, y: NDArray[np.float64]) -> NDArray[np.float64]:
        """``Uᵀy`` for every axis and place of :attr:`splits`, (axes, places, draws); ``y`` (rows of the draws,
        draws) with the fit's columns not yet projected out (they are here)."""
        if self.whiten is None:
            assert self.to_time is not None
            v = np.zeros((self.h.shape[1], y.shape[1]))
            v[self.to_time] = y
        else:
            v = self.whiten.T @ y
        coef = self.model.T @ y  # (p, draws)
        out = np.empty((len(self.axes), self.splits.size, y.shape[1]))
        for i in range(len(self.axes)):
            out[i] = _suffix(self.h[i][:, None] * v)[self.splits] - self.B[i][self.splits] @ coef
        return out

    def rows(self, i: int, places: NDArray[np.int_], j: int) -> NDArray[np.float64]:
        """Gram entries ``u(a_i, P)ᵀ u(a_j, Q)`` for each ``P`` of ``places`` (time order) and every ``Q`` of
        :attr:`splits`, (places, splits)."""
        Q = self.splits
        if self.metric is None:
            S = _suffix(self.h[i] * self.h[j])
            raw = S[np.maximum(places[:, None], Q[None, :])]
        else:
            assert self.left is not None
            raw = _suffix(self.left[i][places] * self.h[j][None, :], axis=1)[:, Q]
        return np.asarray(raw - self.B[i][places] @ self.B[j][Q].T)

    def family(self) -> int:
        """Sets of the search over *every* pair of places and axes (:func:`~optcal.applications.diagnosis.step_pair.column_sets`):
        ordered pairs of places :data:`~optcal.applications.diagnosis.effects.STEP_MIN_SIDE` kept poses apart, once
        per pair of axes and once per unordered pair on one axis; counted, never listed."""
        kb = np.sort(self.kept_before)
        near = np.searchsorted(kb, kb + STEP_MIN_SIDE, side="left") - np.searchsorted(kb, kb - STEP_MIN_SIDE, side="right")
        ordered = int(kb.size * kb.size - np.sum(near))  # (P, Q) with |kept before P − kept before Q| ≥ STEP_MIN_SIDE
        n_axes = len(self.axes)
        return ordered // 2 * n_axes + ordered * n_axes * (n_axes - 1)

    def cross(self, i: int, j: int) -> NDArray[np.float64]:
        """``u(a_i, k)ᵀ u(a_j, k)`` at every place ``k`` of :attr:`splits` before the fit's columns are projected
        out (``i = j``: ``cᵀc``)."""
        k = self.splits
        if self.metric is None:
            return _suffix(self.h[i] * self.h[j])[k]
        assert self.left is not None  # Σ_{t ≥ k} left[k, t] h[t]: the two-sided suffix sum's diagonal
        return np.asarray(np.sum(np.triu(self.left[i] * self.h[j][None, :]), axis=1)[k])

    def diagonal(self) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
        """Each step column's ``uᵀu`` (axes, places); whether it keeps :data:`INFO_TOL` of its ``cᵀc`` (the column
        before the fit's are projected out: a step the fit already carries is not testable); and ``u(a_i, k)ᵀ
        u(a_j, k)`` (axes, axes, places)."""
        k = self.splits
        n_axes = len(self.axes)
        cross = np.stack([np.stack([self.cross(i, j) - np.sum(self.B[i][k] * self.B[j][k], axis=1)
                                    for j in range(n_axes)]) for i in range(n_axes)])
        diag = np.stack([cross[i, i] for i in range(n_axes)])
        raw = np.stack([self.cross(i, i) for i in range(n_axes)])
        return diag, diag > INFO_TOL * np.maximum(raw, 1e-300), cross


def _three(a1: NDArray[np.float64], a2: NDArray[np.float64], a3: NDArray[np.float64], g11: NDArray[np.float64],
           g12: NDArray[np.float64], g22: NDArray[np.float64], g13: NDArray[np.float64], g23: NDArray[np.float64],
           g33: NDArray[np.float64], usable: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The gain ``bᵀG⁻¹b`` of three columns (scores ``a``, Gram entries ``g``; broadcast), by the Schur complement
    of the first two; ``-inf`` where ``usable`` is false or a column adds less than :data:`INFO_TOL` of its own
    information."""
    det = g11 * g22 - g12 ** 2
    good = usable & (det > INFO_TOL * g11 * g22)
    det = np.where(good, det, 1.0)
    w1 = (g22 * g13 - g12 * g23) / det
    w2 = (g11 * g23 - g12 * g13) / det
    den = g33 - (w1 * g13 + w2 * g23)
    good = good & (den > INFO_TOL * g33)
    gain = (g22 * a1 ** 2 - 2 * g12 * a1 * a2 + g11 * a2 ** 2) / det + (a3 - w1 * a1 - w2 * a2) ** 2 / \
        np.where(good, den, 1.0)
    return np.where(good, gain, -np.inf)


def _restricted(geo: PairGeometry, A: NDArray[np.float64], prepared: tuple[NDArray[np.float64], NDArray[np.bool_],
                NDArray[np.float64]], rss: NDArray[np.float64], best: bool = False
                ) -> tuple[NDArray[np.float64], tuple[int, int, int, int] | None]:
    """Each column of ``A``'s smallest p over the restricted procedure's sets (module docstring, steps 2-4) and,
    with ``best`` (one column: the observed residuals), the set ``(a₁, P, a₂, Q)`` that gives it.  ``prepared``:
    :meth:`PairGeometry.diagonal`."""
    diag, ok, cross = prepared
    n_axes, places, draws = A.shape
    single = np.where(ok[:, :, None], A ** 2 / np.where(ok, diag, 1.0)[:, :, None], -np.inf)
    K = min(ANCHORS, places)
    min_p = np.ones(draws)
    where: tuple[float, tuple[int, int, int, int]] | None = None
    far = np.abs(geo.kept_before[None, :] - geo.kept_before[:, None]) >= STEP_MIN_SIDE  # (P place, Q place)
    d = np.arange(draws)[None, :]
    ix = np.arange(K)[:, None]

    def keep(gain: NDArray[np.float64], q: int, set_of: Callable[[int, int], tuple[int, int, int, int]]) -> None:
        nonlocal min_p, where
        flat = gain.transpose(1, 0, 2).reshape(draws, -1)
        k = np.argmax(flat, axis=1)
        largest = flat[np.arange(draws), k]
        finite = np.isfinite(largest)
        p = np.where(finite, f_p(np.where(finite, largest, 0.0), rss, q, geo.dof0), 1.0)
        min_p = np.minimum(min_p, p)
        if best and finite[0] and (where is None or p[0] < where[0]):
            where = (float(p[0]), set_of(*divmod(int(k[0]), places)))

    for i in range(n_axes):
        top = np.argpartition(-single[i], K - 1, axis=0)[:K] if K < places else np.repeat(
            np.arange(places)[:, None], draws, axis=1)  # (K, draws): place indices of axis i's best scores
        P = geo.splits[top.ravel()]
        a1 = A[i][top, d][:, :, None]  # (K, draws, 1)
        g11 = diag[i][top][:, :, None]
        usable = np.isfinite(single[i][top, d])[:, :, None] & far[top]  # STEP_MIN_SIDE kept poses between P and Q
        own = geo.rows(i, P, i).reshape(K, draws, places)  # u(a_i, P)ᵀ u(a_i, Q)
        for j in range(n_axes):
            aq = np.moveaxis(A[j], 0, -1)[None, :, :]  # (1, draws, places): a_j's score at every Q
            if i == j:  # (a_i, P) and (a_i, Q): two offsets on one axis
                den = diag[j][None, None, :] - own ** 2 / g11
                good = usable & ok[j][None, None, :] & (den > INFO_TOL * diag[j][None, None, :])
                gain = np.where(good, a1 ** 2 / g11 + (aq - own / g11 * a1) ** 2 / np.where(good, den, 1.0), -np.inf)
                keep(gain, 2, lambda anchor, place: (geo.axes[i], int(P[anchor]), geo.axes[i], int(geo.splits[place])))
                continue
            row = geo.rows(i, P, j).reshape(K, draws, places)  # u(a_i, P)ᵀ u(a_j, Q)
            # the anchor first: (a_i, P), (a_j, P), (a_j, Q) for every Q
            other = geo.rows(j, P, j).reshape(K, draws, places)  # u(a_j, P)ᵀ u(a_j, Q)
            g12 = row[ix, d, top][:, :, None]
            g22 = diag[j][top][:, :, None]
            a2 = A[j][top, d][:, :, None]
            gain = _three(a1, a2, aq, g11, g12, g22, row, other, diag[j][None, None, :],
                          usable & ok[j][None, None, :] & ok[j][top][:, :, None])
            keep(gain, 3, lambda anchor, place: (geo.axes[i], int(P[anchor]), geo.axes[j], int(geo.splits[place])))
            # the anchor second: (a_j, R), (a_i, R), (a_i, P) for every R (the first knock on a_j, a_i's offset at R)
            ar_j, ar_i = aq, np.moveaxis(A[i], 0, -1)[None, :, :]
            gain = _three(ar_j, ar_i, a1, diag[j][None, None, :], cross[j, i][None, None, :], diag[i][None, None, :],
                          row, own, g11, usable & ok[j][None, None, :] & ok[i][None, None, :])
            keep(gain, 3, lambda anchor, place: (geo.axes[j], int(geo.splits[place]), geo.axes[i], int(P[anchor])))
    return min_p, (None if where is None else where[1])


def _block(geo: PairGeometry, draws: int) -> int:
    """Draws per block: :data:`BLOCK_ELEMENTS` over anchors × places."""
    return max(1, BLOCK_ELEMENTS // max(ANCHORS * geo.splits.size, 1))


def search_pair(fitter: Fitter, fit: Fit, axes: list[int], note: Callable[[str], None] | None = None
                ) -> PairScan | None:
    """The best pair of bias steps from ``fit`` (no step placed): every pair
    (:func:`~optcal.applications.diagnosis.step_pair.scan_pair`) in a session of at most
    :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` kept poses, the restricted procedure (module
    docstring) in a larger one; ``None`` when no pair can be placed (or, with a ``note``, when poses correlated in
    time are more than :data:`DENSE_POSES`)."""
    if uses_minp_positions(fitter, fit):
        return scan_pair(fitter, fit, axes)
    if fitter.n - fit.n_params - 3 <= 0 or not axes:
        return None
    if fitter.correlation is not None and fitter.n > DENSE_POSES:
        if note is not None:
            note(f"two bias steps together not searched: {fitter.n} poses correlated in time need dense {fitter.n}² "
                 f"matrices (at most {DENSE_POSES} poses); the one-step search keeps its level share")
        return None
    system = null_draws(fitter, fit, 0)
    geo = PairGeometry.at(fitter, fit, axes, system)
    if geo.splits.size < 2:
        return None
    e = system.residuals(fitter, fit)
    y = e[:, None]
    resid = e - system.model @ (system.model.T @ e)
    p, where = _restricted(geo, geo.scores(y), geo.diagonal(), np.array([float(resid @ resid)]), best=True)
    if where is None:
        return None
    a1, P, a2, Q = where
    sets = len(axes) * min(ANCHORS, geo.splits.size) * (2 * len(axes) - 1) * geo.splits.size
    return PairScan(a1, P, a2, Q, float(p[0]), sets, np.zeros(0))


def pair_adjusted_p(fitter: Fitter, fit: Fit, scan: PairScan, axes: list[int], p_exact: float, level: float,
                    seed: int = 0) -> float:
    """``p_exact`` (the best pair's exact F test) adjusted for the search that found it (the minP over the pairs):
    over every pair (:func:`~optcal.applications.diagnosis.step_pair.with_null`,
    :data:`~optcal.applications.diagnosis.bias_step.DRAWS` draws) in a session of at most
    :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` kept poses; over the restricted procedure's sets in
    a larger one, its draws stopped once they settle the test at ``level`` (module docstring), none drawn when
    Bonferroni over every pair already passes ``level`` (``P(min p ≤ x) ≤ sets · x`` for every pair's smallest p, and
    the restricted procedure's is never below it: its exact minP p is at most Bonferroni's)."""
    if uses_minp_positions(fitter, fit):
        return with_null(fitter, fit, scan, axes, null_draws(fitter, fit, DRAWS, seed)).adjusted(p_exact)
    system = null_draws(fitter, fit, 0)
    geo = PairGeometry.at(fitter, fit, axes, system)
    bonferroni = min(1.0, p_exact * geo.family())
    if bonferroni <= level:  # the restricted minP p is never above Bonferroni's over every pair: no draw needed
        return bonferroni
    prepared = geo.diagonal()
    total = min(DRAWS, max(int(math.ceil((EXCEEDANCES + 1) / max(level, 1e-12))), 1))

    def smallest(z: NDArray[np.float64], rss0: NDArray[np.float64]) -> NDArray[np.float64]:
        return _restricted(geo, geo.scores(z), prepared, rss0)[0]

    # stopped once not significant whatever the remaining draws show (Besag & Clifford)
    return sequential_p(system, smallest, [p_exact], level, total, _block(geo, total), seed)[0]
