"""Forward selection over the candidate effects, per axis, each fitted jointly with T and o.

A term is added when

* its likelihood-ratio test is significant: the F form (noise scale estimated from the
  residuals, so a wrong σ claim cannot manufacture findings), ``q`` = number of new
  coefficients, at level ``α/(2m)`` for ``m`` candidates in the step (Bonferroni: the
  family-wise false-finding rate of the first step is at most ``α/2``), or ``α/m`` in a step that cannot
  test outliers (a small session: :meth:`ForwardSelection.outliers_testable`); in a small session (tests with
  fewer than :data:`MIN_DOF` residual degrees of freedom) the level that keeps the same family-wise rate under
  the candidates' joint null distribution instead (Westfall–Young minP,
  :mod:`~optcal.applications.diagnosis.familywise`);
* it lowers the BIC (``n log(RSS/n) + p log n``);
* it lowers the held-out rms (k-fold).

Among the candidates passing the first two, the best BIC is tried first, except that among term candidates within
:data:`~optcal.applications.diagnosis.acceptance.BIC_TIE` of it the one with the fewest coefficients goes first
(:func:`~optcal.applications.diagnosis.acceptance.preference_order`; the acceptance of a step is
:mod:`~optcal.applications.diagnosis.acceptance`).  A term's polynomial
order is raised (one coefficient at a time, same tests) where the data support it.  A time term that entered at a
higher order directly (:data:`~optcal.applications.diagnosis.acceptance.DIRECT_ORDERS`) is stepped down to the lowest order its higher coefficients do not
significantly improve on and that passes its own test (:mod:`~optcal.applications.diagnosis.drift_order`): a linear
drift is named as linear, not as the cubic that happened to fit a shade better (``s`` and ``s³`` correlate ≈ 0.9 over
a recording, so the cubic's first-order coefficient would carry only part of the trend), while a bias that rises and
falls keeps its order 2.  Outliers enter as mean-shift terms (:mod:`optcal.applications.diagnosis.outliers`).  When
nothing passes (or only drifts whose evidence is spread over their orders), terms (and a term with a knock) are
searched together (:mod:`~optcal.applications.diagnosis.term_pair`: two effects that mask each other); selection stops
when that passes nothing either.  After each accepted term every term, knock and outlier pose accepted before it is
tested again for removal given all the others (:meth:`ForwardSelection.backward_check`,
:mod:`~optcal.applications.diagnosis.backward`: the test it entered by, at the level it entered at, with ΔBIC and the
held-out check): a drift taken before two bias steps that explain the same rise is dropped, and so are knocks taken
before the drift they stood for.  The outlier poses set aside are then tested again under the final model with all its
effects (:meth:`ForwardSelection.recheck_outliers`, the backward check's rule): a pose still aside whose departure the
final model explains is returned to the fit when the held-out rms does not rise.

When temperature and time both explain a bias on the same axis (a sensor warming up), the
one with the better BIC enters first and the other is then tested *given* it; a
:class:`~optcal.applications.diagnosis.acceptance.TemperatureTimeDecision` says which was chosen, by how much, and whether the other
adds anything (and that the two cannot be told apart when the recording makes them collinear).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optcal.applications.diagnosis.acceptance import (
    HELDOUT_SE,
    BIC_TIE, DIRECT_ORDERS, Candidate, TemperatureTimeDecision, accept, outlier_candidate, prefer_terms_to_outliers,
    preference_order, restore_outliers, rivals, step_down_first,
)
from optcal.applications.diagnosis.backward import Dropped, backward_check, recheck_notes, recheck_outliers
from optcal.applications.diagnosis.bias_step import DRAWS as STEP_DRAWS, adjusted_p, scan_step, uses_minp_positions
from optcal.applications.diagnosis.effects import BIAS_STEP, MAX_ORDER, MAX_STEPS, SESSION_BIAS, describe_term
from optcal.applications.diagnosis.familywise import NullDraws, minp_level, null_draws, uses_minp
from optcal.applications.diagnosis.fitting import MIN_DOF, Fit, Fitter
from optcal.applications.diagnosis.outliers import detect_outliers
from optcal.applications.diagnosis.correlation import PoseCorrelation
from optcal.applications.diagnosis.noise_model import correlation_with_steps
from optcal.applications.diagnosis.step_pair import each_knock_needed, pair_correlation
from optcal.applications.diagnosis.pair_search import pair_adjusted_p, search_pair
from optcal.applications.diagnosis.term_pair import pair_count, search_term_pair
from optcal.applications.diagnosis.progress import Loop, plain_loop
from optcal.core.model import AXES

@dataclass
class Step:
    """One forward-selection step: every candidate tried, and the one accepted (``None``: stop)."""

    candidates: list[Candidate]
    accepted: Candidate | None
    #: Terms, knocks and outlier poses accepted in earlier steps and removed after this step's term entered
    #: (:meth:`ForwardSelection.backward_check`)
    dropped: list["Dropped"] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"accepted": self.accepted.term if self.accepted else None,
                               "candidates": [c.to_dict() for c in self.candidates]}
        if self.dropped:
            out["dropped"] = [d.to_dict() for d in self.dropped]
        return out


@dataclass
class SelectionResult:
    """The final fit, the steps that led to it, the temperature/time decisions, and the last step's level."""

    final: Fit
    steps: list[Step]
    decisions: list[TemperatureTimeDecision]
    last_level: float
    dropped: list[Dropped] = field(default_factory=list)
    #: The pose-noise correlation the selection ended under (re-estimated after each accepted bias step)
    correlation: PoseCorrelation | None = None


class ForwardSelection:
    """Forward selection (module docstring) over ``candidates`` ``[(effect, axis number)]``.

    Parameters
    ----------
    fitter : Fitter
    candidates : list of (str, int)
        The parametric candidates.
    with_outliers : bool
        Whether outlier poses are a candidate.
    alpha : float
        Family-wise false-finding level of a step (split in two when outliers are a candidate).
    note : callable
        Receives notes for the report (terms not identifiable from the poses).
    loop : callable, optional
        Wraps the loop over a step's candidates (a progress bar).
    drop_unneeded : bool
        Test the earlier terms for removal after each accepted term (:meth:`backward_check`).
    term_pairs : bool
        Search the best pair of first-order terms together when no one-term candidate of a step passes
        (:mod:`~optcal.applications.diagnosis.term_pair`).
    """

    def __init__(self, fitter: Fitter, candidates: list[tuple[str, int]], with_outliers: bool, alpha: float,
                 note: Callable[[str], None], loop: Loop = plain_loop, drop_unneeded: bool = True,
                 term_pairs: bool = True) -> None:
        self.fitter = fitter
        self.candidates = candidates
        self.with_outliers = with_outliers
        self.alpha = alpha
        #: A bias step is searched (a candidate axis of ``bias_step``): it is a departure of the poses after a point
        #: as an outlier is one pose's, and shares the departures' half of the level with the outliers
        self.with_step = any(e == BIAS_STEP for e, _ in candidates)
        self.alpha_terms = alpha / 2 if with_outliers or self.with_step else alpha
        both = with_outliers and self.with_step
        self.alpha_outliers = alpha / 4 if both else alpha / 2
        #: Family-wise level of the step search (over its axes and positions): half the departures' level
        self.alpha_step = alpha / 4 if both else alpha / 2
        self.note = note
        self.loop = loop
        self.drop_unneeded = drop_unneeded
        #: Search the best pair of first-order terms when no one-term candidate passes (:meth:`term_pair_candidate`)
        self.term_pairs = term_pairs
        #: Terms dropped by :meth:`backward_check`: not offered again
        self.dropped_keys: set[tuple[str, int]] = set()
        #: Outlier poses returned to the fit (:meth:`backward_check`, :meth:`recheck_outliers`): an outlier candidate
        #: setting one aside again is not accepted, so the selection cannot cycle
        self.returned: set[int] = set()
        #: The pose-noise correlation the fitter uses (set by the caller), re-estimated after each accepted bias step
        self.correlation: PoseCorrelation | None = None
        #: Standard errors of its paired held-out gain a candidate must show to enter (:func:`accept`; set by the caller)
        self.heldout_se: float = HELDOUT_SE

    def room(self, fit: Fit) -> bool:
        """Whether one more parameter leaves the fitter's :attr:`~Fitter.min_dof` residual degrees of freedom
        (:data:`MIN_DOF`, or one when the noise of the pose means was measured)."""
        return self.fitter.n - fit.n_params - 1 >= self.fitter.min_dof

    def outliers_testable(self, fit: Fit) -> bool:
        """Whether a step from ``fit`` tests outlier poses, and so spends :attr:`alpha_outliers` of its level.

        The outlier test estimates the noise with its suspects set aside: it keeps :data:`MIN_DOF` (a small
        session's real pose scatter, 2-2.5 times the rests' measured noise on IMU-TK's Xsens log, would otherwise
        make every pose off by that scatter an outlier).  A step that cannot test outliers gives the whole
        family-wise level :attr:`alpha` to its terms: the step's false-finding rate stays at most ``alpha``
        (Bonferroni over the terms alone), and a 14-pose session's terms are tested at twice the level they had
        when half of it was kept for a test that was never run.
        """
        return self.with_outliers and self.fitter.n - fit.n_params - 1 >= MIN_DOF

    def departures_testable(self, fit: Fit) -> bool:
        """Whether a step from ``fit`` tests departures of poses from the model (outliers, or a bias step): the terms
        then keep :attr:`alpha_terms`, otherwise the whole :attr:`alpha` (:meth:`outliers_testable`)."""
        return self.outliers_testable(fit) or bool(self.step_axes(fit))

    def term_candidates(self, fit: Fit) -> list[tuple[str, int, int]]:
        """New terms (order 1, or any order for :data:`DIRECT_ORDERS`) and the next order of every term in ``fit``.

        Only orders the regressor can carry and that leave the fitter's :attr:`~Fitter.min_dof` degrees of freedom.
        """
        least = self.fitter.min_dof
        if not self.room(fit):
            if self.candidates or self.with_outliers:
                why = ("with the noise of the pose means measured, a test keeps one to check that noise"
                       if least < MIN_DOF else "a test that estimates the noise from the residuals needs "
                       f"{MIN_DOF}; give poses with their σ measured from the samples to need only one")
                self.note(
                    f"{self.fitter.n} poses leave too few degrees of freedom to test another term after "
                    f"{fit.describe()} ({why}: at least {fit.n_params + 1 + least} poses)"
                )
            return []
        out = []
        sessions = self.fitter.reg.n_sessions
        for e, a in self.candidates:
            if e == BIAS_STEP and not self.fitter.steps_at:
                continue  # its position is searched (step_candidates); once placed, its other axes are plain terms
            if (e, a) not in fit.terms and (e, a) not in self.dropped_keys:
                top = MAX_ORDER[e] if e in DIRECT_ORDERS else 1
                orders = [sessions - 1] if e == SESSION_BIAS else range(1, top + 1)  # every session's offset at once
                out += [(e, a, order) for order in orders
                        if self.supports_order(e, order) and self.fitter.n - fit.n_params - order >= least]
        for (e, a), order in fit.terms.items():
            # a bias step's next "order" is the next step placed: a plain term only once that step is placed
            if e == BIAS_STEP and order >= len(self.fitter.steps_at):
                continue
            if e != SESSION_BIAS and order < MAX_ORDER[e] and self.supports_order(e, order + 1):
                out.append((e, a, order + 1))
        return out

    def supports_order(self, effect: str, order: int) -> bool:
        """Whether the regressor takes enough distinct values for a polynomial of ``order``."""
        if order == 1 or effect == SESSION_BIAS:
            return True
        values = self.fitter.reg.tau if effect.startswith("temperature") else self.fitter.reg.s
        return bool(np.unique(np.round(values, 6)).size >= order + 2)

    def run(self, baseline: Fit) -> SelectionResult:
        """Forward selection from ``baseline``."""
        fitter = self.fitter
        current = baseline
        steps: list[Step] = []
        rivalries: list[TemperatureTimeDecision] = []
        levels: dict[tuple[str, int], float] = {}  # each term in the model: the level it entered at
        step_levels: dict[int, float] = {}  # each knock placed (poses before it): the level it entered at
        for _ in range(4 * len(self.candidates) + 3):
            bic0 = fitter.bic(current)
            term_cands = self.term_candidates(current)
            outliers_tested = self.outliers_testable(current)
            steps_axes = self.step_axes(current)
            level = self.step_level(current, term_cands,
                                    self.alpha_terms if self.departures_testable(current) else self.alpha)
            # the step's axes (and the pair searched together) share its level (Bonferroni); its positions are paid
            # for in its p value (adjusted_p)
            single_level = self.single_step_level(current, steps_axes)
            pair_level = single_level if self.sets_searched(current, steps_axes) else None
            tried: list[Candidate] = self.step_candidates(current, steps_axes, single_level, bic0)
            if self.pair_searched(current, steps_axes) and not any(c.significant for c in tried):
                tried += self.pair_candidate(current, steps_axes, single_level, bic0)
            for effect, axis, order in self.loop(term_cands, f"selection step {len(steps) + 1}", len(term_cands)):
                if not fitter.identifiable(current, effect, axis, order):
                    self.note(f"{describe_term(effect, axis, order)} is not identifiable from these poses; not tested")
                    continue
                terms = dict(current.terms)
                terms[(effect, axis)] = order
                cand = fitter.fit(terms, current.outliers, current.x)
                p = fitter.f_test(current, cand)
                delta = fitter.bic(cand) - bic0
                tried.append(Candidate(describe_term(effect, axis, order), effect, AXES[axis], order, delta, p,
                                       level, bool(p < level and delta < 0), fit=cand))
            if outliers_tested:
                found = detect_outliers(fitter, current, self.alpha_outliers)
                if found is not None:
                    delta = fitter.bic(found.fit) - bic0
                    tried.append(Candidate(
                        f"outliers({len(found.poses)} poses)", "outliers", None, None, delta, found.p_value,
                        self.alpha_outliers, bool(delta < 0),
                        rows=[int(fitter.poses.rows[k]) for k in sorted(found.poses)], fit=found.fit,
                    ))
                    again = sorted(int(fitter.poses.rows[k]) for k in set(found.poses) & self.returned)
                    if again:  # a pose returned by the backward check is not set aside again: no cycling
                        tried[-1].significant = False
                        tried[-1].rejected_because = ("pose rows " + ", ".join(map(str, again)) +
                                                      " were returned to the fit by the backward check")
            kept = step_down_first(fitter, tried, current)
            set_aside = self.prefer_terms_to_outliers(current, tried, term_cands, pair_level, bic0, steps_axes)
            # only drifts kept at their order, their evidence spread, pass (before: nothing passed): sets compete
            spread = bool(kept) and all(id(c) in kept for c in tried if c.significant)
            if spread and pair_level is not None:
                tried += self.term_pair_candidate(current, term_cands, pair_level, bic0, tried, steps_axes)
            accepted = accept(fitter, tried, current, self.heldout_se)
            if accepted is None and pair_level is not None and not spread:  # nothing passed: terms searched together
                together = self.term_pair_candidate(current, term_cands, pair_level, bic0, tried, steps_axes)
                tried += together
                accepted = accept(fitter, together, current, self.heldout_se)
            if accepted is None and set_aside is not None:  # what explained the outliers did not enter: they compete
                restore_outliers(set_aside)
                accepted = accept(fitter, [set_aside], current, self.heldout_se)
            if accepted is not None:  # a directly entered drift was stepped down before the choice
                rivalries += rivals(accepted, tried)
            steps.append(Step(tried, accepted))
            if accepted is None or accepted.fit is None:
                break
            before, current = current, accepted.fit
            if accepted.effect == BIAS_STEP and self.correlation is not None:  # R without knocks it held as noise
                self.correlation = correlation_with_steps(fitter, current, self.alpha, self.correlation)
                fitter.correlation = self.correlation.operator
                current = fitter.fit(dict(current.terms), current.outliers, current.x)
            key = None if accepted.axis is None else (accepted.effect, AXES.index(accepted.axis))
            if key is not None and accepted.effect != SESSION_BIAS:
                # a raised order keeps the level its term entered at; a knock's axis, its share of the step's level
                # (positions paid), or the level of a plain term at a placed knock (an axis more it moved)
                levels.setdefault(key, accepted.threshold)
            for k2 in accepted.together or ():  # two terms entered together: each at the pair's level
                levels.setdefault(k2, accepted.threshold)
            for k in accepted.new_steps():  # each knock placed (two placed together: both): the level it entered at
                step_levels[k] = accepted.threshold
            if accepted.second_at is not None and accepted.fit is not None:  # the pair's first axis
                for k2 in accepted.fit.terms:
                    if k2[0] == BIAS_STEP:
                        levels.setdefault(k2, accepted.threshold)
            entered_outliers = accepted.fit.outliers - before.outliers if accepted.effect == "outliers" else frozenset()
            current, steps[-1].dropped = self.backward_check(current, levels, key, accepted.term, step_levels,
                                                             accepted.new_steps(), entered_outliers)
        current = self.recheck_outliers(current)
        alpha_terms = self.alpha_terms if self.departures_testable(current) else self.alpha
        level = self.step_level(current, self.term_candidates(current), alpha_terms) if self.room(current) else alpha_terms
        dropped = [d for s in steps for d in s.dropped]
        gone = {(d.effect, d.axis) for d in dropped}
        rivalries = [r for r in rivalries if (r.chosen, r.axis) not in gone or
                     (r.chosen, AXES.index(r.axis)) in current.terms]
        return SelectionResult(current, steps, self.explain(current, rivalries), level, dropped, self.correlation)

    def prefer_terms_to_outliers(self, current: Fit, tried: list[Candidate], term_cands: list[tuple[str, int, int]],
                                 pair_level: float | None, bic0: float, knock_axes: list[int]) -> Candidate | None:
        """The step's outlier candidate set aside when a candidate of the step explains its poses
        (:func:`~optcal.applications.diagnosis.acceptance.prefer_terms_to_outliers`), and returned (``None``: none).

        When no one term or knock does and the outlier candidate would be chosen (the first of the step's
        :func:`~optcal.applications.diagnosis.acceptance.preference_order`), the best set of terms searched together
        (:meth:`term_pair_candidate`, at the sets' own share ``pair_level`` of the step's departures level, every term
        needed given the others) is tried as the explanation: a nonlinearity on two axes moves the rests along both
        and neither term alone passes while the outlier poses carry their evidence.  The set enters the step's
        candidates when it explains the poses; otherwise it is listed as not significant, with why.
        """
        found = prefer_terms_to_outliers(self.fitter, tried, current, self.alpha_outliers)
        if found is not None or pair_level is None:
            return found
        outliers = outlier_candidate(tried)
        if outliers is None or preference_order([c for c in tried if c.significant])[0] is not outliers:
            return None
        together = self.term_pair_candidate(current, term_cands, pair_level, bic0, tried, knock_axes)
        if not together:
            return None
        found = prefer_terms_to_outliers(self.fitter, [outliers, *together], current, self.alpha_outliers)
        if found is None and together[0].significant:
            together[0].significant = False
            together[0].rejected_because = "searched as the outlier poses' explanation: some are still outliers under it"
        elif found is None:
            together[0].rejected_because = (together[0].rejected_because or "not significant at its level") + \
                "; searched as the outlier poses' explanation"
        tried += together
        return found

    def backward_check(self, current: Fit, levels: dict[tuple[str, int], float], entered: tuple[str, int] | None,
                       after: str, step_levels: dict[int, float] | None = None, entered_steps: tuple[int, ...] = (),
                       entered_outliers: frozenset[int] | None = None) -> tuple[Fit, list[Dropped]]:
        """``current`` with the terms, knocks and outlier poses accepted before ``entered`` that it made unneeded
        removed, one at a time (:func:`~optcal.applications.diagnosis.backward.backward_check`: each by the test it
        entered by, at the level it entered at, with ΔBIC and the held-out check).  ``step_levels``: each knock's
        entry level by the poses before it; ``entered_steps`` and ``entered_outliers``: what the step just accepted
        placed (``entered_outliers`` ``None``: outlier poses are not tested).  Nothing is removed with
        ``drop_unneeded`` off.

        After a knock is dropped, the pose-noise correlation in use (:attr:`correlation`) is estimated again
        under the model without it (:func:`~optcal.applications.diagnosis.noise_model.correlation_with_steps`,
        as after a knock is accepted): its column no longer among the REML's fixed effects, the departure it
        stood for is read by the terms that made it unneeded or as noise shared by neighbouring poses.
        """
        if not self.drop_unneeded:
            return current, []
        test_outliers = entered_outliers is not None and bool(current.outliers)
        final, dropped = backward_check(
            self.fitter, current, levels, {} if step_levels is None else step_levels, entered, after,
            self.dropped_keys, entered_steps, self.alpha_outliers if test_outliers else None,
            frozenset() if entered_outliers is None else entered_outliers)
        self.returned |= {k for k in current.outliers - final.outliers}
        if self.correlation is not None and any(d.effect == BIAS_STEP for d in dropped):
            self.correlation = correlation_with_steps(self.fitter, final, self.alpha, self.correlation)
            self.fitter.correlation = self.correlation.operator
            final = self.fitter.fit(dict(final.terms), final.outliers, final.x)
        return final, dropped

    def step_axes(self, current: Fit) -> list[int]:
        """The axes whose bias step is searched over its positions in a step from ``current``: every candidate axis
        while fewer than :data:`~optcal.applications.diagnosis.effects.MAX_STEPS` steps are in the model (each knock
        placed once; its other axes are then plain terms), when the step's coefficient leaves :data:`MIN_DOF`
        residual degrees of freedom, as the outlier test keeps (:meth:`outliers_testable`: the step is tested on the
        residuals' noise scale, and a small session's pose scatter would otherwise be named a step; its position is
        paid for in its p value, not in the test's degrees of freedom)."""
        if len(self.fitter.steps_at) >= MAX_STEPS or self.fitter.n - current.n_params - 1 < MIN_DOF:
            return []
        # a knock dropped as unneeded (backward.backward_check) is not searched again: the selection cannot cycle
        return [a for e, a in self.candidates if e == BIAS_STEP and (e, a) not in self.dropped_keys]

    def pair_searched(self, current: Fit, axes: list[int]) -> bool:
        """Whether a step from ``current`` searches two bias steps together (:mod:`~optcal.applications.diagnosis.step_pair`)
        when the one-step scan names nothing: no step placed yet, and its three coefficients leave :data:`MIN_DOF`
        residual degrees of freedom (as one step's coefficient must, :meth:`step_axes`); above
        :data:`~optcal.applications.diagnosis.bias_step.MINP_POSES` poses by :mod:`~optcal.applications.diagnosis.pair_search`."""
        return bool(axes) and not self.fitter.steps_at and self.fitter.n - current.n_params - 3 >= MIN_DOF

    def single_step_level(self, current: Fit, axes: list[int]) -> float:
        """The level of each axis's one-step test from ``current``: the step's family-wise level :attr:`alpha_step`
        shared (Bonferroni) by the axes searched and, where it is searched (:meth:`pair_searched`), the pair of
        steps searched together: one more share.  The pair is tried only when no single step is significant, but
        its share is set beforehand, so the step's false-finding rate stays at most :attr:`alpha_step` (3 axes:
        each one-step test at 0.00125 instead of 0.00167 at α = 0.02; the power this costs is in
        docs/diagnosis.md, "Two knocks searched together").  The terms searched together
        (:meth:`sets_searched`) are one more share (0.001 each with both)."""
        return self.alpha_step / max(len(axes) + int(self.pair_searched(current, axes))
                                     + int(self.sets_searched(current, axes)), 1)

    def pair_candidate(self, current: Fit, axes: list[int], level: float, bic0: float) -> list[Candidate]:
        """Two bias steps searched together (:func:`~optcal.applications.diagnosis.step_pair.scan_pair`), fitted
        exactly at the best pair, its F test adjusted for the pairs searched (minP), compared with ``level`` (its
        share of the step's level, :meth:`single_step_level`), and each knock needed given the other
        (:func:`~optcal.applications.diagnosis.step_pair.each_knock_needed`); its ΔBIC counts both places as parameters.  The simulation runs only when the
        exact p is below ``level`` (the adjusted p is never smaller) and both knocks are needed: its p value is the
        exact one otherwise (``rejected_because`` says why)."""
        fitter = self.fitter
        scan = search_pair(fitter, current, axes, self.note)
        if scan is None:
            return []
        terms = dict(current.terms)
        terms.update(scan.terms())
        placed = fitter.steps_at
        fitter.set_steps((scan.first_at, scan.second_at))
        try:
            cand = fitter.fit(terms, current.outliers, current.x)
        finally:
            fitter.set_steps(placed)
        p_exact = fitter.f_test(current, cand)
        delta = fitter.bic(cand) - bic0 + 2 * float(np.log(fitter.n))
        a1, a2 = AXES[scan.first_axis], AXES[scan.second_axis]
        name = f"{BIAS_STEP}({a1}, 2 steps together)" if a1 == a2 else f"{BIAS_STEP}({a1}+{a2}, 2 steps together)"
        out = Candidate(name, BIAS_STEP, a2, 2, delta, p_exact, level, False,
                        step_at=scan.first_at, second_at=scan.second_at, fit=cand)
        if p_exact >= level or delta >= 0:  # the adjusted p is never below the exact one: not significant either way
            return [out]
        # under correlated poses the pair's tests take R re-estimated with the pair in it (step_pair.pair_correlation)
        with pair_correlation(fitter, current, scan, self.alpha, p_exact) as under:
            out.correlation, out.p_value = under.note, under.p_exact
            if under.p_exact >= level:
                out.rejected_because = "not significant under the correlation re-estimated with the pair"
                return [out]
            # both conditions must hold; the cheaper one first (two one-step scans), the pairs' null only if it passes
            needed = each_knock_needed(fitter, under.current, scan)
            if needed >= level:
                out.rejected_because = (f"each knock is not needed given the other: the weaker one's test given the "
                                        f"other step, its position searched again, p = {needed:.2g} (a wander of the "
                                        "bias that rises and returns, not two knocks); the pairs' minP adjustment not run")
                return [out]
            out.p_value = pair_adjusted_p(fitter, under.current, scan, axes, under.p_exact, level)
        out.significant = out.p_value < level
        return [out]

    def step_candidates(self, current: Fit, axes: list[int], level: float, bic0: float) -> list[Candidate]:
        """The bias step of each axis at its best position (:func:`~optcal.applications.diagnosis.bias_step.scan_step`),
        fitted exactly there; after a step is placed, the next one at a position of its own (the placed steps'
        columns are among the fitted ones the scan projects out, their positions not searched again).

        Its p value is the exact likelihood-ratio test's (:meth:`Fitter.f_test`) adjusted for the positions searched
        (:func:`~optcal.applications.diagnosis.bias_step.adjusted_p`: minP in a small session, Bonferroni in a large
        one), compared with ``level`` (the step's family-wise level shared among its
        candidates).  Its ΔBIC counts the position as one more parameter (a change point is a fitted unknown).
        The next step of an axis the earlier steps did not move adds their offsets on it too (its "order" counts
        the steps placed, :data:`~optcal.applications.diagnosis.effects.MAX_STEPS`).
        """
        fitter = self.fitter
        out: list[Candidate] = []
        null: NullDraws | None = None  # the null model at ``current``, drawn once for every axis (the same draws)
        order = len(fitter.steps_at) + 1
        for axis in axes:
            scan = scan_step(fitter, current, axis)
            if scan is None:
                continue
            terms = dict(current.terms)
            terms[(BIAS_STEP, axis)] = order
            cand = fitter.fit(terms, current.outliers, current.x, fitter.step_data(scan.at))
            if null is None and uses_minp_positions(fitter, current):
                null = null_draws(fitter, current, STEP_DRAWS)
            p, _ = adjusted_p(fitter, current, scan, fitter.f_test(current, cand), null=null)
            delta = fitter.bic(cand) - bic0 + float(np.log(fitter.n))
            out.append(Candidate(describe_term(BIAS_STEP, axis, order), BIAS_STEP, AXES[axis], order, delta, p, level,
                                 bool(p < level and delta < 0), step_at=scan.at, fit=cand))
        return out

    def step_level(self, current: Fit, term_cands: list[tuple[str, int, int]], alpha_terms: float) -> float:
        """The level each term candidate of a step from ``current`` is tested at, the step's terms sharing the
        family-wise level ``alpha_terms``: Bonferroni's ``alpha_terms / m``, or in a small session the minP level
        of the candidates' joint null distribution (:mod:`~optcal.applications.diagnosis.familywise`), which keeps
        the same family-wise level with more power where the candidates are dependent."""
        bonferroni = alpha_terms / max(len(term_cands), 1)
        if not term_cands or not uses_minp(self.fitter, current):
            return bonferroni
        level = minp_level(self.fitter, current, term_cands, alpha_terms)
        return bonferroni if level is None else level

    def sets_searched(self, current: Fit, axes: list[int]) -> bool:
        """Whether a step from ``current`` searches terms together when no candidate passes
        (:mod:`~optcal.applications.diagnosis.term_pair`): with :attr:`term_pairs` on, a knock searched in the step
        (``axes``: the step's departures family, whose level the sets share) and a set to search."""
        return (self.term_pairs and bool(axes) and self.room(current)
                and pair_count(self.term_candidates(current), current, len(axes)) > 0)

    def term_pair_candidate(self, current: Fit, term_cands: list[tuple[str, int, int]], level: float,
                            bic0: float, tried: list[Candidate], knock_axes: list[int]) -> list[Candidate]:
        """The best set of new first-order terms, or a term and a knock, searched together
        (:func:`~optcal.applications.diagnosis.term_pair.search_term_pair`; the knock scanned given each term's fit
        among ``tried``), its p value Bonferroni's over the sets searched, significant when below ``level`` (its
        share of the step's departures level, :meth:`single_step_level`), each term needed given the others at that
        level, and its ΔBIC negative (a knock's place counted as a parameter)."""
        alone = {(c.effect, AXES.index(str(c.axis))): c.fit for c in tried
                 if c.order == 1 and c.fit is not None and c.together is None and c.step_at is None
                 and c.axis is not None and c.effect != "outliers"}
        found = search_term_pair(self.fitter, current, term_cands, level, alone, knock_axes)
        if found is None:
            return []
        name = " + ".join(describe_term(e, a, 1) for e, a in found.keys) + f", {len(found.keys)} terms together"
        knock = found.step_at is not None  # a term and a knock: the candidate places it (held-out fits, step levels)
        effect, axis = found.keys[-1] if knock else found.keys[0]
        delta = self.fitter.bic(found.fit) - bic0 + (float(np.log(self.fitter.n)) if knock else 0.0)
        out = Candidate(name + (f" (the knock after {found.step_at} poses)" if knock else ""), effect, AXES[axis],
                        len(self.fitter.steps_at) + 1 if knock else 1, delta, found.p_value, level, False,
                        step_at=found.step_at, together=found.keys, fit=found.fit)
        if found.p_value < level and delta < 0:
            out.significant = found.p_each < level
            if not out.significant:
                out.rejected_because = (f"not every term is needed given the others: the weakest one's F test given "
                                        f"the others, p = {found.p_each:.2g}")
        return [out]

    def recheck_outliers(self, final: Fit) -> Fit:
        """``final`` with its outlier poses tested again under its own terms, each returned whose departure they
        explain (:func:`~optcal.applications.diagnosis.backward.recheck_outliers`: the backward check's rule at the
        outliers' family-wise level :attr:`alpha_outliers`, held-out check included); the returned poses, and a pose
        not significant that the held-out check kept aside, in a note."""
        out, returned, kept = recheck_outliers(self.fitter, final, self.alpha_outliers)
        for text in recheck_notes(self.fitter, returned, kept, self.alpha_outliers):
            self.note(text)
        self.returned |= final.outliers - out.outliers
        return out

    def explain(self, final: Fit, rivalries: list[TemperatureTimeDecision]) -> list[TemperatureTimeDecision]:
        """Test the other explanation given the final model, and say what the data can tell apart."""
        fitter = self.fitter
        corr = fitter.reg.correlation()
        for r in rivalries:
            key = (r.other, AXES.index(r.axis))
            gap = r.delta_bic_other - r.delta_bic_chosen
            other = describe_term(r.other, key[1], r.other_order)
            chosen = describe_term(r.chosen, key[1], r.chosen_order)
            if key in final.terms:
                given = "both are in the final model: each explains something the other does not"
            else:
                terms = dict(final.terms)
                terms[key] = r.other_order
                r.p_other_given_chosen = fitter.f_test(final, fitter.fit(terms, final.outliers, final.x))
                given = (
                    f"with {chosen} in the model, {other} adds nothing significant (p = {r.p_other_given_chosen:.2g})"
                    if r.p_other_given_chosen >= (self.alpha_terms if r.level is None else r.level) else
                    f"even with {chosen} in the model, {other} still explains more (p = {r.p_other_given_chosen:.2g})"
                )
            r.temperature_time_correlation = corr
            corr_txt = f"temperature and time correlate (r = {corr:+.2f})" if corr is not None else ""
            if gap < 0:  # kept within the BIC tie as the term with fewer coefficients (preference_order)
                r.text = (
                    f"axis {r.axis}: temperature or time? both explain the change on their own ({corr_txt}); "
                    f"{other} fits a shade better (ΔBIC {r.delta_bic_other:+.1f} vs {r.delta_bic_chosen:+.1f}) with "
                    f"more coefficients, so the simpler {chosen} was kept (a difference under {BIC_TIE:g} is not strong "
                    f"evidence), and {given}; a temperature profile that does not follow time would separate them"
                )
            elif gap < BIC_TIE and corr is not None and abs(corr) > 0.9:
                r.text = (
                    f"axis {r.axis}: {chosen} and {other} cannot be told apart from this recording "
                    f"({corr_txt}; ΔBIC {r.delta_bic_chosen:+.1f} vs {r.delta_bic_other:+.1f}); {chosen} "
                    "was kept by a small margin: record a temperature profile that is not monotone in time to separate them"
                )
            else:
                r.text = (
                    f"axis {r.axis}: temperature or time? both explain the change on their own ({corr_txt}); "
                    f"{chosen} explains it better (ΔBIC {r.delta_bic_chosen:+.1f} vs {r.delta_bic_other:+.1f} "
                    f"for {other}), and {given}"
                )
        return rivalries
