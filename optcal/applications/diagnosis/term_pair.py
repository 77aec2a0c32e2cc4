"""Two terms searched together: two effects that hide each other from the one-term tests.

Each candidate term of a selection step is tested against a model that lacks every other effect, by an F test whose
noise scale is that model's residual scale (:meth:`~optcal.applications.diagnosis.fitting.Fitter.f_test`).  When a
recording holds two effects of similar size, each test counts the other effect's unexplained departure as noise: the
scale grows with the other effect, the statistic stops growing with either, and neither passes (the masking of
forward selection).  mikoff's MPU-9150 unit 0, 22 hand-held rests: a drift of 8 mg over the log on x alone is named
at p 5e-6, on y alone at 2e-7; on both together the best single term has p 0.0011 (y) and 0.020 (x) against a level
of 0.00083, and 12 mg on both gives 0.00087, no better: the statistic is a ratio of the two effects' sizes.  A warm-up
drifts every axis at once; a drift and a scale nonlinearity, or a drift and a knock, are as common.

When nothing is accepted in a step, sets of new first-order terms are searched together (:func:`term_sets`: every
pair of the step's new term candidates, one effect on all three axes, and each term with a knock of each searched
axis, the knock's position scanned given the term).  Each set is scored by the linearised likelihood ratio (its
columns with the current fit's projected out, the gain ``eᵀPe`` of Lu 2017, eq. 14's weighted norm residuals ``e``;
the F p value with its own number of coefficients); the :data:`TRIED` best are fitted exactly and tested by the F
test of all their coefficients (its scale the set's own residuals, which the other effect no longer inflates).

**Its level.**  The sets are one more share of the step's departures level, beside each axis's one-knock search and
the two knocks searched together
(:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.single_step_level`), set before the data are
seen, so the step's false-finding rate stays at most its family-wise level.  The set's p value is Bonferroni's over
everything searched (the term sets, and the (term, knock axis) pairs times the knock's positions); where that does not
pass in a session of at most :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` kept poses, the search's own
minP (:func:`search_smallest_p`: the distribution of the smallest p over every set and position in draws of the
linearised null model at the current fit, :func:`~optcal.applications.diagnosis.familywise.null_draws`), its draws
stopped once they settle the test at the level (:func:`search_minp`, as the two knocks' restricted search stops).
Bonferroni pays for every set as if each were as likely as the best to reach the smallest p; the sets share columns (a
term is in several sets, a knock's neighbouring positions share all but one pose), so the minP p is smaller: mikoff
imu0, an 8 mg x drift and a 4.5 mg y knock after rest 11, exact p 2.0e-6, Bonferroni (35 kinds of set, a knock's
share split over its 17 positions) 0.0012, minP 0.00037 against 0.001.

**Every term needed given the others**: the set stands for several effects only if each term's test given the others
passes at the set's level (a knock: its entry test given the term), so a strong term with a spare one is not named as
two effects.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from itertools import combinations

import numpy as np
from numpy.typing import NDArray
from scipy import stats as sps

from optcal.applications.diagnosis.bias_step import DRAWS, StepScan, adjusted_p, scan_step, uses_minp_positions
from optcal.applications.diagnosis.effects import BIAS_STEP, SESSION_BIAS
from optcal.applications.diagnosis.familywise import NullDraws, null_draws, orthonormal, sequential_p
from optcal.applications.diagnosis.fitting import MIN_DOF, Fit, Fitter
from optcal.applications.diagnosis.pair_search import BLOCK_ELEMENTS
from optcal.applications.diagnosis.problem import BETA_INDEX

__all__ = ["TermPair", "pair_keys", "term_sets", "pair_count", "search_term_pair"]

#: Sets fitted exactly, the best by the linearised test first: the linearisation at a fit without them can rank
#: sets of nearly equal gain in another order than their exact fits; the Bonferroni p is valid for any set chosen
#: (it bounds every set's test at once), and so is the search's minP (it is the distribution of the smallest p over
#: every set), so trying three costs no level, only three fits of the model.
TRIED: int = 3


@dataclass(frozen=True)
class TermPair:
    """The best set of new first-order terms searched together (:func:`term_sets`) and its tests.

    Attributes
    ----------
    keys : tuple of (str, int)
        The terms' ``(effect, axis)``.
    fit : Fit
        The exact fit of the current model with both terms.
    p_exact : float
        The F test of both coefficients against the current model.
    p_value : float
        :attr:`p_exact` adjusted for the search (:attr:`adjusted`): times :attr:`pairs` (and a knock's positions),
        at most 1; or the search's minP p where it is computed (:func:`search_smallest_p`), at most that.
    pairs : int
        The kinds of set searched (the Bonferroni factor).
    p_each : float
        The largest of the terms' F tests, each given the others (every one needed: below the level).
    step_at : int or None
        For a term with a knock: the poses before the knock in time order (its axis is the second key's).
    adjusted : str
        How :attr:`p_value` was adjusted for the search: ``"Bonferroni"`` or ``"minP"``.
    """

    keys: tuple[tuple[str, int], ...]
    fit: Fit
    p_exact: float
    p_value: float
    pairs: int
    p_each: float
    step_at: int | None = None
    adjusted: str = "Bonferroni"


def pair_keys(term_cands: list[tuple[str, int, int]], current: Fit) -> list[tuple[str, int]]:
    """The term keys a pair is formed from: the step's new candidates at order 1 (not a raised order of a term in
    the model, not a knock's plain offset nor the sessions' offsets, which are placed by their own searches)."""
    keys = [(e, a) for e, a, order in term_cands
            if order == 1 and (e, a) not in current.terms and e not in (BIAS_STEP, SESSION_BIAS)]
    return list(dict.fromkeys(keys))


def term_sets(keys: list[tuple[str, int]]) -> list[tuple[tuple[str, int], ...]]:
    """The sets of terms searched together: every pair of ``keys``, and one effect on all of its offered axes where
    it has three (a warm-up drifts every axis at once: one physical effect, whose third axis would otherwise mask
    the other two as the pair's second term masks the first)."""
    sets: list[tuple[tuple[str, int], ...]] = list(combinations(keys, 2))
    for effect in dict.fromkeys(e for e, _ in keys):
        same = tuple(k for k in keys if k[0] == effect)
        if len(same) >= 3:
            sets.append(same)
    return sets


def pair_count(term_cands: list[tuple[str, int, int]], current: Fit, knock_axes: int = 0) -> int:
    """How many kinds of set a step from ``current`` would search together: the :func:`term_sets` of
    :func:`pair_keys`, and each key with each of ``knock_axes`` axes' knock (0: none; not counting the knocks'
    positions, which :func:`search_term_pair` counts once it has scanned them)."""
    keys = pair_keys(term_cands, current)
    return len(term_sets(keys)) + len(keys) * knock_axes


def search_term_pair(fitter: Fitter, current: Fit, term_cands: list[tuple[str, int, int]], level: float,
                     single_fits: Mapping[tuple[str, int], Fit] | None = None,
                     knock_axes: Sequence[int] = ()) -> TermPair | None:
    """The set of :func:`term_sets`, or a term of :func:`pair_keys` with a knock of ``knock_axes`` at its best
    position given that term, whose columns explain most of ``current``'s residuals (linearised, each set's F p value
    with its own number of coefficients), fitted exactly and tested (module docstring): the first of the :data:`TRIED`
    best whose p (Bonferroni's, else the search's minP, module docstring) is below ``level`` with each term needed,
    else the one of the smallest p.
    ``single_fits``: the step's fits of ``current`` with each key alone (a knock is scanned given them,
    :func:`~optcal.applications.diagnosis.bias_step.scan_step`).  ``None`` when nothing can be searched."""
    keys = pair_keys(term_cands, current)
    sets = term_sets(keys)
    room = fitter.n - current.n_params - fitter.min_dof
    if room < 2 or not keys:
        return None
    dof = fitter.n - current.n_params
    scored: list[tuple[float, tuple[tuple[str, int], ...], StepScan | None]] = []
    if len(keys) >= 2:
        w = fitter.weights(current)
        G, J = fitter.jacobians(current, w)
        e = np.sqrt(w) * current.residuals
        # the candidates' columns with the fitted parameters' projected out (Lu 2017, eq. 14's linearisation)
        cols = np.column_stack([J[:, 9 + BETA_INDEX[(eff, a, 1)]] for eff, a in keys])
        coef, *_ = np.linalg.lstsq(G, cols, rcond=None)
        H = cols - G @ coef
        for terms in sets:
            if len(terms) > room:
                continue
            Hs = H[:, [keys.index(k) for k in terms]]
            gram = Hs.T @ Hs
            if np.linalg.cond(gram) > 1e12:  # columns the fitted model leaves collinear: no information as a set
                continue
            r = Hs.T @ e
            scored.append((linear_p(current.rss, float(r @ np.linalg.solve(gram, r)), len(terms), dof), terms, None))
    combos = 0
    if knock_axes and fitter.n - current.n_params - 2 >= MIN_DOF:  # a knock keeps MIN_DOF, as the step search does
        for key, fit in (single_fits or {}).items():
            if key not in keys:
                continue
            for axis in knock_axes:
                scan = scan_step(fitter, fit, axis)
                if scan is None:
                    continue
                combos += 1
                kept = int((fitter.weights(fit) > 0).sum())
                s2 = fit.rss / max(kept - fit.n_params + len(fit.outliers), 1)  # scan_step's unit of its statistic
                gain = current.rss - fit.rss + scan.statistic * s2
                scored.append((linear_p(current.rss, gain, 2, dof), (key, (BIAS_STEP, axis)), scan))
    count = len(sets) + combos  # Bonferroni over the term sets and the (term, knock axis) pairs searched
    scored.sort(key=lambda item: item[0])
    minp: list[Callable[[list[float]], list[float]]] = []  # the search's minP, set up once (only if needed)
    out: TermPair | None = None
    for _, terms, scan in scored[:TRIED]:
        found = (exact(fitter, current, terms, count) if scan is None else
                 exact_knock(fitter, current, terms[0], scan, (single_fits or {})[terms[0]], count))
        # Bonferroni passes not: the search's own minP, never above it and never below the exact p, for a set it can
        # make pass (its exact p and each term given the others below the level)
        if (found.p_value >= level and max(found.p_exact, found.p_each) < level
                and uses_minp_positions(fitter, current)):
            if not minp:
                minp.append(search_minp(fitter, current, keys, scored, level))
            found = replace(found, p_value=min(found.p_value, minp[0]([found.p_exact])[0]), adjusted="minP")
        if max(found.p_value, found.p_each) < level:
            return found
        if out is None or found.p_value < out.p_value:
            out = found
    return out


def search_minp(fitter: Fitter, current: Fit, keys: list[tuple[str, int]],
                scored: list[tuple[float, tuple[tuple[str, int], ...], StepScan | None]], level: float
                ) -> Callable[[list[float]], list[float]]:
    """The search's minP adjusted p values of exact p values (:func:`search_smallest_p` over every set ``scored``):
    :data:`~optcal.applications.diagnosis.bias_step.DRAWS` draws, as the one-knock minP takes (a draw costs the sets'
    columns times the poses, a few hundred by 22 on mikoff: 40,000 draws in well under a second; about 40 of them
    below a level of 0.001, so an adjusted p there is known to about ±16 %, where the pairs' 11,000 would leave it
    ±30 % and the decision near the level to the seed), stopped once they settle the test at ``level``
    (:func:`~optcal.applications.diagnosis.familywise.sequential_p`); blocks of
    :data:`~optcal.applications.diagnosis.pair_search.BLOCK_ELEMENTS` over the sets' columns."""
    system = null_draws(fitter, current, 0)
    smallest = search_smallest_p(fitter, current, keys, [terms for _, terms, scan in scored if scan is None],
                                 [(terms[0], scan) for _, terms, scan in scored if scan is not None], system)
    columns = sum(scan.positions + 1 for _, _, scan in scored if scan is not None) + sum(
        len(terms) for _, terms, scan in scored if scan is None)
    block = max(1, BLOCK_ELEMENTS // max(columns, 1))
    return lambda observed: sequential_p(system, smallest, observed, level, DRAWS, block)


def linear_p(rss: float, gain: float, q: int, dof: int) -> float:
    """The F test's p value of ``q`` columns that lower the residual sum ``rss`` by ``gain`` (linearised)."""
    if dof - q <= 0:
        return 1.0
    gain = min(max(gain, 0.0), rss * (1 - 1e-12))
    return float(sps.f.sf(gain / q / ((rss - gain) / (dof - q)), q, dof - q))


def exact(fitter: Fitter, current: Fit, terms: tuple[tuple[str, int], ...], sets: int) -> TermPair:
    """The exact fit and tests of the set ``terms`` added to ``current``, its p value Bonferroni's over ``sets``."""
    full = dict(current.terms)
    full.update({k: 1 for k in terms})
    fit = fitter.fit(full, current.outliers, current.x)
    p_exact = fitter.f_test(current, fit)
    each = []
    for key in terms:
        less = dict(full)
        del less[key]
        each.append(fitter.f_test(fitter.fit(less, current.outliers, current.x), fit))
    return TermPair(terms, fit, p_exact, min(1.0, p_exact * sets), sets, max(each))


def exact_knock(fitter: Fitter, current: Fit, key: tuple[str, int], scan: StepScan, alone: Fit,
                sets: int) -> TermPair:
    """The exact fit and tests of the term ``key`` and a knock of ``scan.axis`` at ``scan.at`` added to ``current``
    (the knock's offset as :meth:`~optcal.applications.diagnosis.selection.ForwardSelection.step_candidates` adds it).

    Its p value: the exact F test of both times the positions searched and ``sets`` (Bonferroni; the search's minP,
    :func:`search_smallest_p`, where that does not pass).  The term needed given the knock (its F test), the knock
    given the term (its entry test: :func:`~optcal.applications.diagnosis.bias_step.adjusted_p` at the term's fit)."""
    full = dict(current.terms)
    full[key] = 1
    full[(BIAS_STEP, scan.axis)] = len(fitter.steps_at) + 1
    data = fitter.step_data(scan.at)
    fit = fitter.fit(full, current.outliers, current.x, data)
    p_exact = fitter.f_test(current, fit)
    less = dict(full)
    del less[key]
    p_term = fitter.f_test(fitter.fit(less, current.outliers, current.x, data), fit)
    p_knock, _ = adjusted_p(fitter, alone, scan, fitter.f_test(alone, fit))
    return TermPair((key, (BIAS_STEP, scan.axis)), fit, p_exact, min(1.0, p_exact * scan.positions * sets), sets,
                    max(p_term, p_knock), scan.at)


def search_smallest_p(fitter: Fitter, current: Fit, keys: list[tuple[str, int]],
                      sets: list[tuple[tuple[str, int], ...]], knocks: list[tuple[tuple[str, int], StepScan]],
                      system: NullDraws) -> Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]:
    """The smallest p value of the whole search in draws of the null model at ``current`` (``system``,
    :func:`~optcal.applications.diagnosis.familywise.null_draws`: no term of ``keys`` and no knock in the model):
    over the term ``sets`` scored and, for each ``(term, knock scan)`` of ``knocks``, over the term with a knock at
    each of the scan's positions.  Westfall & Young's single-step minP of the search (the family of
    :func:`search_term_pair`), its draws' statistic formed as the search scores a set: the set's columns with the
    fit's projected out, the fall of the residual sum in them, the F test with the set's own number of coefficients
    (as :meth:`~optcal.applications.diagnosis.fitting.Fitter.f_test` forms it on the residuals' scale).  A draw's
    smallest p over sets of ``q`` coefficients is that of their largest fall (one tail probability per ``q``)."""
    n = fitter.n
    dof0 = n - current.n_params
    cols = system.columns(system.J[:, [9 + BETA_INDEX[(e, a, 1)] for e, a in keys]])
    cols = cols - system.model @ (system.model.T @ cols)  # Lu 2017, eq. 14's linearisation, as the search's
    bases = [(len(terms), orthonormal(cols[:, [keys.index(k) for k in terms]])) for terms in sets]
    knock_bases = []
    for key, scan in knocks:
        term = cols[:, [keys.index(key)]]
        unit = term / max(float(np.linalg.norm(term)), 1e-300)
        h = system.J[:, 6 + scan.axis]
        steps = system.columns(np.stack([np.where(np.isin(np.arange(n), fitter.time_order[k:]), h, 0.0)
                                         for k in scan.splits], axis=1))
        steps = steps - system.model @ (system.model.T @ steps)
        steps = steps - unit @ (unit.T @ steps)  # each position's knock column given the term's
        knock_bases.append((unit, steps / np.maximum(np.linalg.norm(steps, axis=0), 1e-300)))

    def smallest(z: NDArray[np.float64], rss0: NDArray[np.float64]) -> NDArray[np.float64]:
        largest: dict[int, NDArray[np.float64]] = {}
        for q, basis in bases:
            gain = np.sum((basis.T @ z) ** 2, axis=0)
            largest[q] = np.maximum(largest.get(q, gain), gain)
        for unit, steps in knock_bases:  # the term's fall and the best position's knock given it
            gain = (unit.T @ z)[0] ** 2 + np.max((steps.T @ z) ** 2, axis=0)
            largest[2] = np.maximum(largest.get(2, gain), gain)
        p = np.ones(z.shape[1])
        for q, gain in largest.items():
            if dof0 - q <= 0:
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                p = np.minimum(p, sps.f.sf(gain / q / ((rss0 - gain) / (dof0 - q)), q, dof0 - q))
        return p

    return smallest
