"""The acceptance of a selection step: which of the candidates it tried enters the model.

:class:`~optcal.applications.diagnosis.selection.ForwardSelection` tries a step's candidates (each tested at the
step's level, with its ΔBIC); this module decides among them:

* a directly entered time term (:data:`DIRECT_ORDERS`) is stepped down to the lowest order its higher coefficients
  do not significantly improve on before the step compares it (:func:`step_down_first`, :func:`step_down`,
  :mod:`~optcal.applications.diagnosis.drift_order`);
* the outlier candidate is set aside when a significant term, set of terms or bias step explains every one of its
  poses (:func:`prefer_terms_to_outliers`);
* the significant candidates are tried in :func:`preference_order` (the best BIC first, the fewest coefficients
  first among terms within :data:`BIC_TIE` of it), and the first whose paired held-out gain exceeds
  :data:`HELDOUT_SE` of its standard errors enters (:func:`accept`, :func:`heldout_gain`);
* a temperature term and a time term that both explained a bias on the axis of the accepted one are recorded as
  rivals (:func:`rivals`, :class:`TemperatureTimeDecision`), tested again given the final model
  (:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.explain`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.drift_order import lower_order
from optcal.applications.diagnosis.effects import BIAS_STEP, describe_term
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.outliers import deleted_residual_p
from optcal.core.model import AXES
from optcal.core.stats import mean_and_se, rms

#: ΔBIC difference below which two competing explanations count as indistinguishable (Kass & Raftery).
BIC_TIE: float = 6.0
#: Effects whose higher polynomial orders may enter directly (not only after order 1): a bias that
#: rises and falls again in time (warm-up then cooling, bias instability at the scale of minutes)
#: has almost no linear part.  Every order counts as a candidate of the step (honest multiplicity).
DIRECT_ORDERS: frozenset[str] = frozenset({"bias_drift"})
#: Standard errors of its paired held-out gain (:func:`heldout_gain`) a candidate that passed its test and the BIC
#: must show to enter.  0: a positive gain, the held-out rms falling.  What a larger multiple would protect against,
#: a term that passed the step's F test at the family-wise level but carries to no held-out pose beyond their own
#: scatter, was not seen: on diag16's 22-rest mikoff nulls at 2σ every null term or outlier set named at 0 SE had a
#: held-out t above 1, so one SE named the same sessions.  What it costs was seen: a 14-rest session held out
#: 10-fold moves a term's gain onto the few poses that carry it, whose held-out fits lack them (the Xsens cut with
#: its z scale nonlinearity at the issue's 10 standard errors: held-out t 0.83).  The gain and its SE are stated
#: with every candidate judged; ``optcal diagnose --heldout-se K`` asks for K (docs/diagnosis.md, "The held-out
#: check, beyond its own noise").
HELDOUT_SE: float = 0.0
#: Span of a block of poses, in correlation times ``τ``, when the pose noise is correlated in time
#: (:func:`heldout_gain`): the means of two neighbouring blocks of an Ornstein–Uhlenbeck noise that span ``T = 2τ``
#: each share a correlation of ``(τ/T)²(1 − e^{−T/τ})² ≈ 0.19`` of the shared part ``ρ₀``, small enough that the
#: blocks' scatter measures the mean gain's standard error within about a tenth.
BLOCK_TAU: float = 2.0


def coefficient_count(c: "Candidate") -> int:
    """Coefficients a term candidate adds (its polynomial order; a session bias, one per session after the
    first; outliers, one per pose; a bias step searched over its positions, its size and its place: a change
    point is a fitted unknown)."""
    if c.together is not None:  # two first-order terms searched together
        return len(c.together)
    if c.second_at is not None and c.fit is not None:  # two steps searched together: their offsets and both places
        return sum(v for (e, _), v in c.fit.terms.items() if e == BIAS_STEP) + 2
    if c.step_at is not None:
        return 2
    if c.order is not None:
        return int(c.order)
    return len(c.rows) if c.rows is not None else 1


def preference_order(significant: list["Candidate"]) -> list["Candidate"]:
    """The order in which a step tries its significant candidates: the best BIC first, except that among the
    term candidates within :data:`BIC_TIE` of the best (evidence the data cannot call strong, Kass &
    Raftery 1995) the one with the fewest coefficients goes first, as the one-standard-error rule picks the
    simplest model the data do not reject.  A warm-up seen by a temperature channel is one temperature
    coefficient; a cubic in time mimics the same rise and fall with three, and wins on BIC only by fitting
    some noise as well (the Gauss–Markov family of the issue-13 study: 5 of 100 recordings at 3× the
    detection limit named a cubic drift instead of the planted temperature bias, ΔBIC 2 apart)."""
    if not significant:
        return []
    best = min(c.delta_bic for c in significant)
    tied = [c for c in significant if c.order is not None and c.delta_bic < best + BIC_TIE]
    first = sorted(tied, key=lambda c: (coefficient_count(c), c.delta_bic))
    taken = {id(c) for c in first}
    return first + sorted((c for c in significant if id(c) not in taken), key=lambda c: c.delta_bic)


@dataclass
class Candidate:
    """One candidate tried in a selection step.

    Attributes
    ----------
    term : str
        E.g. ``temperature_bias(z, order 2)`` or ``outliers(3 poses)``.
    effect : str
    axis : str or None
    order : int or None
    delta_bic : float
        BIC of the model with the candidate minus the current model's.
    p_value : float
        Likelihood-ratio (F) test, or the smallest Bonferroni p of the new outlier poses.
    threshold : float
        The level the p value is compared with.
    significant : bool
        Passed the test and the BIC (and, once tried, the held-out rms).
    rows : list of int or None
        For outliers, the poses' rows.
    stepped_down_from : int or None
        The order the term entered at, when its top coefficients were not significant and it was
        stepped down to :attr:`order`.
    heldout_rms_g_before, heldout_rms_g_after : float or None
        Held-out rms without and with the candidate (computed for the candidates that passed).
    heldout_gain_g2, heldout_se_g2, heldout_t, heldout_critical_t : float or None
        Its paired held-out gain (the mean over the kept poses of each pose's held-out squared residual without the
        candidate less with it, g²), the gain's standard error, their ratio, and the ratio it had to exceed
        (:func:`heldout_gain`, :func:`accept`).
    heldout_units : int or None
        The independent units the standard error was measured over: the kept poses, or the blocks of poses in
        time when the pose noise is correlated (:func:`heldout_gain`).
    rejected_because : str or None
    step_at : int or None
        For a bias step searched over its positions: the poses before the step in time order (its p value is
        then Bonferroni's over the positions searched, :mod:`~optcal.applications.diagnosis.bias_step`).
    second_at : int or None
        For two bias steps searched together (:mod:`~optcal.applications.diagnosis.step_pair`): the poses before the
        second step (:attr:`step_at` is the first's).
    correlation : str or None
        For two bias steps tested under correlated pose noise: the correlation re-estimated with them, in words
        (:func:`~optcal.applications.diagnosis.step_pair.pair_correlation`).
    together : tuple of (str, int) or None
        For two first-order terms searched together (:mod:`~optcal.applications.diagnosis.term_pair`): their
        ``(effect, axis)`` keys (:attr:`effect` and :attr:`axis` are the first's).
    """

    term: str
    effect: str
    axis: str | None
    order: int | None
    delta_bic: float
    p_value: float
    threshold: float
    significant: bool
    rows: list[int] | None = None
    heldout_rms_g_before: float | None = None
    heldout_rms_g_after: float | None = None
    heldout_gain_g2: float | None = None
    heldout_se_g2: float | None = None
    heldout_t: float | None = None
    heldout_critical_t: float | None = None
    heldout_units: int | None = None
    rejected_because: str | None = None
    stepped_down_from: int | None = None
    step_at: int | None = None
    second_at: int | None = None
    correlation: str | None = None
    together: tuple[tuple[str, int], ...] | None = None
    fit: Fit | None = field(default=None, repr=False, compare=False)

    def new_steps(self) -> tuple[int, ...]:
        """The bias steps the candidate places (poses before each, time order): none, one, or two together."""
        return tuple(k for k in (self.step_at, self.second_at) if k is not None)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "term": self.term, "effect": self.effect, "axis": self.axis, "order": self.order,
            "delta_bic": self.delta_bic, "p_value": self.p_value, "threshold": self.threshold,
            "significant": self.significant,
        }
        for key in ("rows", "heldout_rms_g_before", "heldout_rms_g_after", "heldout_gain_g2", "heldout_se_g2",
                    "heldout_t", "heldout_critical_t", "heldout_units", "rejected_because", "stepped_down_from",
                    "step_at", "second_at", "correlation"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        if self.together is not None:
            out["together"] = [describe_term(e, a, 1) for e, a in self.together]
        return out


@dataclass
class TemperatureTimeDecision:
    """Temperature or time: both explained a bias on one axis on their own; which was kept, and why."""

    axis: str
    chosen: str
    other: str
    delta_bic_chosen: float
    delta_bic_other: float
    temperature_time_correlation: float | None = None
    p_other_given_chosen: float | None = None
    text: str = ""
    #: Polynomial orders of the chosen term and of its rival (a rise and fall in time enters at order 2-3)
    chosen_order: int = 1
    other_order: int = 1
    #: The level the rivals were tested at in the step that chose (its term candidates' level: minP in a small
    #: session, Bonferroni otherwise); "adds nothing significant" is judged at it too
    level: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def heldout_blocks(fitter: Fitter) -> NDArray[np.intp]:
    """The independent unit of each pose for the held-out gain's standard error: the pose itself for independent
    pose noise; under the fitter's correlated pose noise (:mod:`~optcal.applications.diagnosis.correlation`),
    runs of consecutive poses in time spanning :data:`BLOCK_TAU` correlation times (a new run at each session)."""
    op = fitter.correlation
    if op is None or op.phi is None:
        return np.arange(fitter.n)
    # -log φ between consecutive poses is their gap in correlation times (∞ across sessions)
    gaps = -np.log(np.maximum(op.phi, 1e-300))
    block = np.empty(fitter.n, dtype=np.intp)
    current, span = 0, 0.0
    block[op.order[0]] = 0
    for i, gap in enumerate(gaps, start=1):
        span += float(gap)
        if span >= BLOCK_TAU or op.phi[i - 1] == 0.0:
            current, span = current + 1, 0.0
        block[op.order[i]] = current
    return block


def heldout_gain(fitter: Fitter, before: NDArray[np.float64], after: NDArray[np.float64],
                 mask: NDArray[np.bool_]) -> tuple[float, float, int]:
    """The paired held-out gain of a candidate, its standard error and the number of units it was measured over.

    Each kept pose's held-out squared residual without the candidate less with it (both k-fold, the pose's fold left
    out of the fit); the mean over the kept poses is the fall of the held-out mean square, so it is positive exactly
    when the held-out rms falls.  Its standard error is the poses' own scatter of the differences
    (:func:`~optcal.core.stats.mean_and_se`, paired: the pose's noise is in both and cancels from the difference's
    spread but for the candidate's correction).  Under correlated pose noise the units are the blocks of
    :func:`heldout_blocks`: each block's mean gain, weighted by its kept poses (the same mean)."""
    d = (before**2 - after**2)[mask]
    block = heldout_blocks(fitter)[mask]
    units, index, counts = np.unique(block, return_inverse=True, return_counts=True)
    if units.size == d.size:
        gain, se = mean_and_se(d)
    else:
        gain, se = mean_and_se(np.bincount(index, weights=d) / counts, counts)
    return gain, se, int(units.size)


def accept(fitter: Fitter, tried: list[Candidate], current: Fit, heldout_se: float = HELDOUT_SE) -> Candidate | None:
    """The first significant candidate of ``tried`` in :func:`preference_order` whose paired held-out gain
    (:func:`heldout_gain`) exceeds ``heldout_se`` of its standard errors (``fitter``'s steps left as its); the
    others tried are marked as rejected by it.  ``heldout_se = 0``: any fall of the held-out rms."""
    for c in preference_order([c for c in tried if c.significant]):
        assert c.fit is not None
        mask = c.fit.kept(fitter.n)
        before = fitter.heldout(current)
        c.heldout_rms_g_before = rms(before, mask)
        placed = fitter.steps_at
        if c.step_at is not None:
            fitter.set_steps((*placed, *c.new_steps()))  # the held-out fits of the step need its split
        after = fitter.heldout(c.fit)
        c.heldout_rms_g_after = rms(after, mask)
        gain, se, c.heldout_units = heldout_gain(fitter, before, after, mask)
        t = gain / se if se > 0 else (math.copysign(math.inf, gain) if gain != 0 else 0.0)
        c.heldout_gain_g2, c.heldout_se_g2, c.heldout_t, c.heldout_critical_t = gain, se, t, heldout_se
        if gain > 0 and t > heldout_se:
            return c
        if c.step_at is not None:
            fitter.set_steps(placed)
        c.significant = False
        c.rejected_because = (f"held-out gain {gain * 1e6:+.3g} ± {se * 1e6:.2g} mg² per pose (t {t:.2f}) not beyond "
                              f"{heldout_se:g} of its standard errors" if heldout_se > 0 else "held-out rms did not fall")
    return None


def explains_outliers(c: Candidate) -> bool:
    """Whether ``c`` is a candidate that can stand for a step's outlier poses: a significant term, set of terms or
    bias step with its fit (not the outlier candidate itself)."""
    return c.effect != "outliers" and c.significant and c.fit is not None


def outlier_candidate(tried: list[Candidate]) -> Candidate | None:
    """The step's significant outlier candidate, if any."""
    found = [c for c in tried if c.effect == "outliers" and c.significant and c.fit is not None]
    return found[0] if found else None


def still_outliers(fitter: Fitter, c: Candidate, poses: frozenset[int]) -> dict[int, float]:
    """The Bonferroni p of each of ``poses``' deleted residuals under ``c``'s model (its terms, and the bias steps it
    places), all of ``poses`` set aside together: the test that set them aside
    (:func:`~optcal.applications.diagnosis.outliers.deleted_residual_p`)."""
    assert c.fit is not None
    placed = fitter.steps_at
    if c.new_steps():
        fitter.set_steps((*placed, *c.new_steps()))  # the fit and its Jacobian hold the candidate's steps
    try:
        return deleted_residual_p(fitter, c.fit, poses, c.fit.x)
    finally:
        fitter.set_steps(placed)


def prefer_terms_to_outliers(fitter: Fitter, tried: list[Candidate], current: Fit,
                             alpha_outliers: float) -> Candidate | None:
    """Set the step's outlier candidate aside when one significant term, set of terms or bias step of the step
    explains every one of its poses; returns the outlier candidate so set aside (``None``: none).

    Physical model: a systematic effect moves each pose by its part along that pose's direction (the norm residual
    sees it as ``∂r/∂β`` of the pose), so the poses whose directions the effect moves most leave the fit most and the
    robust fit names them as several outliers.  On BIC the free offsets of those few poses can beat the one term
    (mgiurato's MPU-6050, 45 rests: seven outliers, six of them x-up or z-up rests, ΔBIC −92 against a scale
    nonlinearity on x and z; 20 Xsens rests, 1.5 mg step on y after rest 10: four outliers ΔBIC −70, the step −58).
    One physical effect explains what several unrelated corrupt rests would: when, with the candidate in the
    model, no new outlier pose is still an outlier (its deleted residual at the outliers' family-wise level
    ``alpha_outliers``, the test that set it aside, :func:`still_outliers`), the outlier candidate is not tried in
    this step.  The candidate must pass its own test at its own level (:attr:`Candidate.significant`, fitted on
    every pose, the outlier poses' departures included), and add fewer coefficients than the poses it stands for
    (:func:`coefficient_count`): ``q`` coefficients fit any ``q`` departures (with those poses set aside they are
    determined by nothing there and the deleted residuals' variance is the candidate's own uncertainty), so only
    ``m > q`` poses following the candidate's pattern are evidence for it, as one step for four rests is.  20 Xsens
    rests, one knocked by 1.7 mg: temperature_bias(z) + temperature_scale(z) together (p 0.00034 on every pose, 0.04
    with the knocked rest aside) left it at deleted-residual p 0.43; it stays an outlier, as does a cluster of
    corrupt rests that no candidate's fit of the whole session reaches.  Two rests a two-term set explains stay
    outliers too: two knocked rests and two nonlinearities are not told apart by those two rests.  The candidates are tried by ΔBIC, the best first; the first that
    explains the poses is named in the outlier candidate's ``rejected_because``.
    """
    found = outlier_candidate(tried)
    if found is None:
        return None
    assert found.fit is not None
    new = frozenset(found.fit.outliers - current.outliers)
    if not new:
        return None
    for c in sorted((c for c in tried if explains_outliers(c)), key=lambda c: c.delta_bic):
        if coefficient_count(c) >= len(new):  # as free as the poses' own offsets: it would fit any departures
            continue
        p_values = still_outliers(fitter, c, new)
        if min(p_values.values()) >= alpha_outliers:
            where = f" after {c.step_at} poses in time" if c.step_at is not None and c.together is None else ""
            found.significant = False
            found.rejected_because = (f"its poses are explained by {c.term}{where} (none is an outlier under it: "
                                      f"p ≥ {min(p_values.values()):.2g}, with {coefficient_count(c)} coefficients for "
                                      f"{len(new)} poses)")
            return found
    return None


def restore_outliers(found: Candidate) -> None:
    """Offer again an outlier candidate :func:`prefer_terms_to_outliers` set aside, when the candidate that explained
    its poses did not enter (its held-out rms did not fall): the poses' departures are then left to the outlier
    candidate's own tests (:func:`accept`)."""
    found.significant = True
    found.rejected_because = None


def step_down_first(fitter: Fitter, tried: list[Candidate], current: Fit) -> set[int]:
    """Step every significant directly entered time term down (:func:`step_down`) before the step compares them.

    A drift of order 2 or 3 wins the BIC on its fit of noise, then steps down to order 1 after it is chosen,
    where another candidate explained more (14 Xsens rests with a temperature bias planted on x: the y drift of
    order 2, ΔBIC −62, stepped down to the first-order y drift, ΔBIC −50, was named in place of the planted
    temperature_bias(x), ΔBIC −56).  A term that steps down to an order the step also tried leaves the choice
    to that candidate (its own ΔBIC, p and held-out test); otherwise it competes at the order it stepped to.
    Returns the ids of the terms kept at their order with their evidence spread (:func:`step_down`)."""
    spread: set[int] = set()
    for c in tried:
        if not c.significant or c.effect not in DIRECT_ORDERS or not c.order or c.order == 1 or c.fit is None:
            continue
        entered = c.order
        if step_down(fitter, c, current):
            spread.add(id(c))
        if c.order == entered:
            continue
        same = [o for o in tried if o is not c and o.effect == c.effect and o.axis == c.axis and o.order == c.order]
        c.significant = False
        c.rejected_because = (f"order {entered} stepped down to order {c.order}, its higher coefficients adding "
                              "nothing significant: tried as that order")
        if not same:  # the lower order was not a candidate of its own (not identifiable, no room): it competes
            c.significant, c.rejected_because = True, None
            c.delta_bic = fitter.bic(c.fit) - fitter.bic(current)
            c.p_value = fitter.f_test(current, c.fit)
    return spread


def step_down(fitter: Fitter, accepted: Candidate, current: Fit) -> bool:
    """Lower a directly entered time term to the lowest order its higher coefficients do not improve on and that
    passes its own test (:func:`~optcal.applications.diagnosis.drift_order.lower_order`, at the level the term
    entered at, the level raising the order from there would need in a later step); else it keeps its order.
    Returns whether it kept its order with its evidence spread (:class:`~optcal.applications.diagnosis.
    drift_order.StepDown`: no lower order passes its own test)."""
    if accepted.effect not in DIRECT_ORDERS or accepted.order is None or accepted.fit is None:
        return False
    key = (accepted.effect, AXES.index(str(accepted.axis)))
    if key in current.terms or accepted.order == 1:  # a raised order was tested on its own coefficient
        return False
    found = lower_order(fitter, current, accepted.fit, key, accepted.order, accepted.threshold)
    if found.fit is not None and found.order is not None:
        accepted.stepped_down_from = accepted.order
        accepted.fit, accepted.order = found.fit, found.order
        accepted.term = describe_term(accepted.effect, key[1], accepted.order)
    return found.spread


def rivals(accepted: Candidate, tried: list[Candidate]) -> list[TemperatureTimeDecision]:
    """Temperature vs time on the same axis: both significant in the step that chose one (each rival
    effect at its best order: a warm-up and cool-down is matched by a time polynomial of order 2-3).

    Significant at the level the step tested its terms at (each candidate's ``threshold``: the minP level in a
    small session, Bonferroni's ``α/m`` otherwise), not at the step's whole family-wise level; the rival given
    the chosen term is judged at the same level (:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.explain`)."""
    if accepted.effect not in ("temperature_bias", "temperature_scale", "bias_drift") or accepted.order is None:
        return []
    rivals = ("bias_drift",) if accepted.effect != "bias_drift" else ("temperature_bias", "temperature_scale")
    best: dict[str, Candidate] = {}
    for c in tried:
        if (c.effect in rivals and c.axis == accepted.axis and c.order is not None and c.p_value < c.threshold
                and (c.effect not in best or c.delta_bic < best[c.effect].delta_bic)):
            best[c.effect] = c
    return [
        TemperatureTimeDecision(str(accepted.axis), accepted.effect, c.effect, accepted.delta_bic, c.delta_bic,
                                chosen_order=int(accepted.order), other_order=int(c.order or 1),
                                level=c.threshold)
        for c in best.values()
    ]
