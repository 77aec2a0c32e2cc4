"""Two bias steps searched together: two knocks that hide each other from the one-step scan.

Two knocks in one small session (mikoff's MPU-9150 unit 0, 22 rests: 4 mg on x after rest 7 and 3 mg on y after
rest 15) are each the best split of their axis, yet neither one-step test is significant: each counts the other
knock's departure as noise (p 0.013-0.33 against 0.0017).  Fitted together they explain both departures and the
residual scale falls to the poses' own noise.

The pair is placed as the selection places two steps (:data:`~optcal.applications.diagnosis.effects.MAX_STEPS`:
"order" k of ``bias_step`` is the k-th step's offset): a step of axis ``a₁`` after position ``P`` and a step of axis
``a₂`` after ``Q``.  On one axis that is two coefficients; on two axes the second axis also carries an offset at the
first position (three coefficients, the model the sequential search would fit; the spare coefficient costs a little
power and no level).  Every pair of positions with at least
:data:`~optcal.applications.diagnosis.effects.STEP_MIN_SIDE` kept poses before, between and after, every ordered
pair of axes, is scored by the linearised likelihood ratio (the steps' columns with the current fit's projected out,
the gain ``eᵀP e`` of Lu 2017, eq. 14's weighted norm residuals ``e``; each set's F p value with its own number of
coefficients); the best is fitted exactly and tested by :meth:`~optcal.applications.diagnosis.fitting.Fitter.f_test`.

The search over the pairs is paid for as the one-step scan pays for its positions
(:func:`~optcal.applications.diagnosis.bias_step.adjusted_p`): Westfall & Young's single-step minP over the pairs,
the share of :data:`~optcal.applications.diagnosis.bias_step.DRAWS` draws of the linearised null model (no step;
:func:`~optcal.applications.diagnosis.familywise.null_draws`) whose smallest p over every pair is at most the
observed one.  Every pair is searched so only where the one-step scan's minP simulation runs
(:func:`~optcal.applications.diagnosis.bias_step.uses_minp_positions`: at most
:data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` kept poses; its cost grows as ``n²``); a larger session
takes the restricted search of :mod:`~optcal.applications.diagnosis.pair_search` (the first knock among each
axis's best one-step places), its minP formed by that same procedure.  Under pose noise correlated in time (:mod:`~optcal.applications.diagnosis.correlation`)
the null model is the generalised fit's: the weighted residuals ``σ R^½ z`` with ``R`` as measured, so the scan and
the draws are formed on the whitened residuals and columns (:func:`~optcal.applications.diagnosis.familywise.whitening`),
where the generalised F test is the ordinary one (mikoff's raw log read as ``optcal diagnose`` reads it, its still
parts' noise making the poses correlated: two knocks of 8 and 5 mg named, none before).

**The correlation the pair is tested under** (:func:`pair_correlation`).  ``R`` is estimated from the baseline fit,
before any step is in the model, so two knocks not yet modelled look like noise that neighbouring poses share
(mikoff imu0's raw log with x 6 + y 4 mg knocks: ρ₀ at its bound 0.95, τ 14 s; unplanted ρ₀ 0.2, τ 0.7 s), and
the pair is then tested against a noise that already holds it.  Once the best pair's exact F test passes under
that ``R`` (the cheap gate, unchanged), ``R`` is estimated again by the same REML, within the same bounds
(:func:`~optcal.applications.diagnosis.noise_model.pose_correlation`), with the pair's step columns among its
fixed effects, as the smooth candidates already are there; the pair's exact F test, each knock given the other
(:func:`each_knock_needed`) and the minP over the pairs (:func:`with_null`) are then all formed under it.  **Null
model of that test:** no step; the weighted residuals ``σ R₂^½ z``, ``z`` standard normal, ``R₂`` the re-estimated
correlation taken as known (as the generalised fit takes the baseline's); the minP draws are those of that model,
every pair searched in each.  ``R₂`` depends on the pair chosen from the data, so the level is measured, not
assumed: correlated null sessions (ρ₀ 0.9 / τ 1 gap, ρ₀ 0.95 / τ 2 gaps) and the unplanted recordings
(docs/diagnosis.md, "Two knocks searched together").  The pair is named only if both the gate under the baseline
``R`` and the tests under ``R₂`` pass: the extra condition only removes rejections.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.bias_step import adjusted_p, scan_step
from optcal.applications.diagnosis.effects import BIAS_STEP, STEP_MIN_SIDE
from optcal.applications.diagnosis.familywise import NullDraws, null_draws
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.noise_model import pose_correlation

__all__ = ["PairScan", "PairRetest", "scan_pair", "with_null", "each_knock_needed", "pair_correlation"]

#: Sets of columns whose null gains are formed at once (memory: sets × 3 × draws floats, 60 MB at 40,000 draws).
CHUNK: int = 64


@dataclass(frozen=True)
class PairScan:
    """The best pair of bias steps and its position-adjusted p value.

    Attributes
    ----------
    first_axis, second_axis : int
        The axis of the step placed first (at :attr:`first_at`) and of the one placed second (at :attr:`second_at`;
        on another axis it carries an offset at :attr:`first_at` too).
    first_at, second_at : int
        Poses before each step in time order (:attr:`~optcal.applications.diagnosis.fitting.Fitter.time_order`).
    p_linear : float
        The linearised test's p value at the best pair (F with the pair's coefficients).
    pairs : int
        Sets of steps searched (positions and axes).
    null_min_p : ndarray
        The smallest p over every set searched in each null draw (the minP adjustment, :meth:`adjusted`).
    """

    first_axis: int
    first_at: int
    second_axis: int
    second_at: int
    p_linear: float
    pairs: int
    null_min_p: NDArray[np.float64]

    @property
    def coefficients(self) -> int:
        """Step offsets the pair adds (two on one axis; three on two)."""
        return 2 if self.first_axis == self.second_axis else 3

    def terms(self) -> dict[tuple[str, int], int]:
        """The pair's ``bias_step`` terms (each axis's "order": the steps whose offsets it carries)."""
        if self.first_axis == self.second_axis:
            return {("bias_step", self.first_axis): 2}
        return {("bias_step", self.first_axis): 1, ("bias_step", self.second_axis): 2}

    def adjusted(self, p_exact: float) -> float:
        """``p_exact`` (the exact fit's F test) adjusted for the pairs searched: ``(1 + #{draws: min p ≤ p_exact}) /
        (1 + draws)``."""
        return float((1 + np.sum(self.null_min_p <= p_exact)) / (1 + self.null_min_p.size))


def valid_splits(fitter: Fitter, fit: Fit) -> NDArray[np.int_]:
    """Splits (poses before, time order) with :data:`STEP_MIN_SIDE` kept poses on each side, the first after kept."""
    kept = fit.kept(fitter.n)[fitter.time_order]
    before = np.concatenate([[0], np.cumsum(kept)])[: fitter.n]
    total = int(kept.sum())
    valid = (before >= STEP_MIN_SIDE) & (total - before >= STEP_MIN_SIDE) & kept
    valid[0] = False
    return np.flatnonzero(valid)


def column_sets(splits: NDArray[np.int_], kept_before: NDArray[np.int_], axes: list[int]
                ) -> tuple[list[tuple[int, int, int, int]], dict[tuple[int, int], int]]:
    """Every pair ``(a₁, P, a₂, Q)`` searched and the column index of each ``(axis, split)`` (module docstring)."""
    index = {(a, int(k)): i for i, (a, k) in enumerate((a, k) for a in axes for k in splits)}
    sets = []
    for P in splits:
        for Q in splits:
            if abs(int(kept_before[Q]) - int(kept_before[P])) < STEP_MIN_SIDE:
                continue  # fewer than STEP_MIN_SIDE kept poses between the two knocks
            for a1 in axes:
                for a2 in axes:
                    if a1 == a2 and Q < P:
                        continue  # one axis: the same two columns in either order
                    sets.append((a1, int(P), a2, int(Q)))
    return sets, index


def _sets(fitter: Fitter, fit: Fit, axes: list[int], null: NullDraws) -> tuple[
        list[tuple[int, int, int, int]], dict[tuple[int, int], int], NDArray[np.float64]]:
    """The pairs searched, each ``(axis, split)``'s column index, the columns (per unit bias, weighted, as ``null``'s
    draws see them: the kept poses, whitened under correlated noise)."""
    splits = valid_splits(fitter, fit)
    kept_before = np.concatenate([[0], np.cumsum(fit.kept(fitter.n)[fitter.time_order])])[: fitter.n]
    sets, index = column_sets(splits, kept_before, axes)
    position = np.empty(fitter.n, dtype=int)
    position[fitter.time_order] = np.arange(fitter.n)
    columns = (null.columns(np.stack([np.where(position >= k, null.J[:, 6 + a], 0.0) for (a, k) in index], axis=1))
               if index else np.zeros((int(null.kept.sum()), 0)))
    return sets, index, columns


def _inverses(gram: NDArray[np.float64], idx: NDArray[np.int_]) -> NDArray[np.float64]:
    """Each set's inverse Gram matrix; zeros for a set whose columns the fit already carries (not testable)."""
    sub = gram[idx[:, :, None], idx[:, None, :]]
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.linalg.cond(sub)
    ok = np.isfinite(cond) & (cond < 1e8)  # information left in every direction of the set (as the scan's den > 0)
    inverse = np.zeros_like(sub)
    if np.any(ok):
        inverse[ok] = np.linalg.inv(sub[ok])
    return inverse


def f_p(gain: NDArray[np.float64], rss: NDArray[np.float64] | float, q: int, dof0: int) -> NDArray[np.float64]:
    """The F test's p value of a set of ``q`` step offsets whose gain is ``gain`` (as :meth:`Fitter.f_test`)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(sps.f.sf(gain / q / ((rss - gain) / (dof0 - q)), q, dof0 - q))


def scan_pair(fitter: Fitter, fit: Fit, axes: list[int]) -> PairScan | None:
    """The best pair of bias steps on ``axes`` from ``fit`` (no step placed), by the linearised test (module docstring).

    ``None`` when no pair can be placed or no residual degree of freedom is left for three coefficients.  Its
    :attr:`PairScan.null_min_p` is empty until :func:`with_null` fills it (only a pair whose exact p is below the
    level needs the simulation: the adjusted p is never below the unadjusted one).
    """
    dof0 = fitter.n - fit.n_params
    if dof0 - 3 <= 0 or not axes:
        return None
    system = null_draws(fitter, fit, 0)  # the fit's columns and residuals as the null draws see them (no draw)
    sets, index, columns = _sets(fitter, fit, axes, system)
    if not sets:
        return None
    model = system.model
    U = columns - model @ (model.T @ columns)  # the current fit's columns projected out
    gram = U.T @ U
    e = system.residuals(fitter, fit)
    observed = U.T @ e
    rss = float(e @ e)
    best: tuple[float, tuple[int, int, int, int]] | None = None
    for q, chosen, idx in _groups(sets, index):
        inverse = _inverses(gram, idx)
        gains = np.einsum("bij,bi,bj->b", inverse, observed[idx], observed[idx])
        p = f_p(gains, rss, q, dof0)
        k = int(np.argmin(p))
        if best is None or p[k] < best[0]:
            best = (float(p[k]), chosen[k])
    assert best is not None
    a1, P, a2, Q = best[1]
    return PairScan(a1, P, a2, Q, best[0], len(sets), np.zeros(0))


def _groups(sets: list[tuple[int, int, int, int]], index: dict[tuple[int, int], int]
            ) -> list[tuple[int, list[tuple[int, int, int, int]], NDArray[np.int_]]]:
    """The sets by their number of coefficients: ``(q, sets, column indices)``."""
    out = []
    for q in (2, 3):
        chosen = [s for s in sets if (s[0] == s[2]) == (q == 2)]
        if chosen:
            out.append((q, chosen, np.array([[index[(a1, P)], index[(a2, Q)]] if q == 2 else
                                              [index[(a1, P)], index[(a2, P)], index[(a2, Q)]]
                                              for a1, P, a2, Q in chosen])))
    return out


def with_null(fitter: Fitter, fit: Fit, scan: PairScan, axes: list[int], null: NullDraws) -> PairScan:
    """``scan`` with the smallest p over every pair searched in each of ``null``'s draws (the minP adjustment).

    ``null``: draws of the linearised null model at ``fit`` (:func:`~optcal.applications.diagnosis.familywise.null_draws`),
    each set's statistic formed as the observed one is (its columns with ``fit``'s projected out, its F p value).
    """
    dof0 = fitter.n - fit.n_params
    sets, index, columns = _sets(fitter, fit, axes, null)
    U = columns - null.model @ (null.model.T @ columns)
    gram = U.T @ U
    A = U.T @ null.z  # (columns, draws)
    min_p = np.ones(null.z.shape[1])
    for q, chosen, idx in _groups(sets, index):
        inverse = _inverses(gram, idx)
        largest = np.zeros(null.z.shape[1])  # each draw's largest gain among the sets of q coefficients
        for start in range(0, len(chosen), CHUNK):
            block = A[idx[start:start + CHUNK]]  # (sets, q, draws)
            largest = np.maximum(largest, np.einsum("bij,bid,bjd->bd", inverse[start:start + CHUNK], block, block)
                                 .max(axis=0))
        # sets of the same q share their test's distribution, whose p falls as the gain rises (familywise.minp_level)
        min_p = np.minimum(min_p, f_p(largest, null.rss0, q, dof0))
    return PairScan(scan.first_axis, scan.first_at, scan.second_axis, scan.second_at, scan.p_linear, scan.pairs, min_p)


def each_knock_needed(fitter: Fitter, current: Fit, scan: PairScan) -> float:
    """The larger of the two knocks' p values, each tested given the other as the one-step search tests a second
    step (binary segmentation's second stage): the other knock placed, this knock's axis scanned again over its
    positions (:func:`~optcal.applications.diagnosis.bias_step.scan_step`) and its exact F test adjusted for them
    (:func:`~optcal.applications.diagnosis.bias_step.adjusted_p`).

    Two knocks that hide each other are each strongly needed given the other (mikoff imu0, 22 rests, 4 mg on x
    after rest 7 and 3 mg on y after 15: p 0.00087 and 2.5e-5).  Two steps that only trace a bias rising and
    returning are not: on the unplanted Xsens log (38 rests) the best pair, z up after rest 11 and down after 29
    with y after 11 (exact p 2e-7, minP-adjusted over the pairs 0.00022), has its y knock at p 0.16 given the z
    one.  Requiring both only shrinks
    the joint test's rejections, so the step's family-wise level holds.
    """
    placed = fitter.steps_at
    first = ({(BIAS_STEP, scan.first_axis): 1} if scan.first_axis == scan.second_axis else
             {(BIAS_STEP, scan.first_axis): 1, (BIAS_STEP, scan.second_axis): 1})
    worst = 0.0
    try:
        for terms, at, axis in ((first, scan.first_at, scan.second_axis),
                                ({(BIAS_STEP, scan.second_axis): 1}, scan.second_at, scan.first_axis)):
            fitter.set_steps((at,))
            given = fitter.fit({**current.terms, **terms}, current.outliers, current.x)
            other = scan_step(fitter, given, axis)
            if other is None:
                return 1.0
            both = {**given.terms, (BIAS_STEP, axis): 2}
            fit = fitter.fit(both, given.outliers, given.x, fitter.step_data(other.at))
            p, _ = adjusted_p(fitter, given, other, fitter.f_test(given, fit))
            worst = max(worst, p)
    finally:
        fitter.set_steps(placed)
    return worst


@dataclass(frozen=True)
class PairRetest:
    """The pair tested under the correlation re-estimated with it (:func:`pair_correlation`).

    Attributes
    ----------
    current : Fit
        The model without the pair, fitted under the re-estimated correlation (the null of the pair's tests).
    p_exact : float
        The pair's exact F test under it.
    note : str or None
        The correlation used, in words (``None`` for independent poses: nothing re-estimated).
    """

    current: Fit
    p_exact: float
    note: str | None


@contextmanager
def pair_correlation(fitter: Fitter, current: Fit, scan: PairScan, alpha: float,
                     p_exact: float) -> Iterator[PairRetest]:
    """The fitter's pose-noise correlation re-estimated with ``scan``'s pair among the REML fixed effects, for the
    pair's tests inside the ``with`` block (module docstring); the baseline's restored on leaving it.

    With independent poses (no correlation used) nothing changes: ``current`` and ``p_exact`` are yielded as given.
    The same REML and bounds as the baseline's (:func:`~optcal.applications.diagnosis.noise_model.pose_correlation`,
    its smooth trends among the fixed effects where the poses leave room); used whatever its own test says, as the
    baseline's was (``ρ₀ = 0``: the poses independent under the pair).
    """
    operator = fitter.correlation
    if operator is None:
        yield PairRetest(current, p_exact, None)
        return
    placed = fitter.steps_at
    terms = {**current.terms, **scan.terms()}
    try:
        fitter.set_steps((scan.first_at, scan.second_at))
        cand = fitter.fit(terms, current.outliers, current.x)
        again = pose_correlation(fitter, cand, alpha, use="on")
        fitter.correlation = again.operator
        cand = fitter.fit(terms, current.outliers, cand.x)
        fitter.set_steps(placed)
        null = fitter.fit(dict(current.terms), current.outliers, current.x)
        p = fitter.f_test(null, cand)
        note = (f"pose-noise correlation re-estimated with the pair among its fixed effects: rho0 {again.rho0:.2g}, "
                f"tau {again.tau_s:.3g} s (baseline rho0 {operator.rho0:.2g}, tau {operator.tau_s:.3g} s); the pair's "
                f"exact p under it {p:.2g} (under the baseline's {p_exact:.2g})")
        yield PairRetest(null, p, note)
    finally:
        fitter.correlation = operator
        fitter.set_steps(placed)
