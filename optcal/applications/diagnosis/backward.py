"""The backward check: what forward selection accepted earlier, tested again for removal after each accepted term.

Forward selection tests a term against the model of its step, so a term taken early can be explained entirely by
terms that enter later: two knocks on one axis make a staircase that a first-order drift fits best until the steps
are placed; a knock at the middle of a drift is the drift's best two-level summary; a rest set aside before a drift
entered is on the fit with it.  After each accepted term (:meth:`~optcal.applications.diagnosis.selection.
ForwardSelection.run`) every earlier one is tested for removal given all the others, each by the test it entered by,
at the level it entered at, with ΔBIC (:func:`removals`):

* **a polynomial term** (drift, temperature, ...): the likelihood-ratio (F) test of all its coefficients;
* **one axis's offset at a knock that moved several axes** (a step whose place another axis's offset also holds):
  the F test of that offset, the place fixed by the others (as the axis entered: a plain term at a placed step);
* **a knock** (a step with one offset left: a single knock, either knock of two, one of two knocks placed together,
  :mod:`~optcal.applications.diagnosis.step_pair`): the exact F test of its offset at its place given every other
  term and the other knock, adjusted for the positions searched
  (:func:`~optcal.applications.diagnosis.bias_step.adjusted_p`: minP or Bonferroni, the null at the model without
  it, the other knock placed), the test each knock of a pair passed given the other
  (:func:`~optcal.applications.diagnosis.step_pair.each_knock_needed`) and a single knock's entry test; its ΔBIC
  counts its position as a parameter.  A knock on several axes loses its offsets one at a time (the offset test
  above) until one is left, then is tested as a knock;
* **an outlier pose** set aside in an earlier step: its deleted residual under the current model with the other
  poses aside, Bonferroni over the poses (:func:`~optcal.applications.diagnosis.outliers.deleted_residual_p`, the
  test that set it aside) at the outliers' family-wise level; its ΔBIC counts its mean shift as a parameter.

The least significant candidate that fails its test or its ΔBIC is removed when the held-out rms without it is not
larger than with it (:meth:`~optcal.applications.diagnosis.fitting.Fitter.heldout`, over the poses both models keep:
the simpler model must predict the left-out poses at least as well); the others are then tested again under the
smaller model.  A removed term or knock is not offered again (its key in ``dropped_keys``), so the selection
cannot cycle; a returned pose may be set aside again only by a later outlier test that finds it significant.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from optcal.applications.diagnosis.bias_step import adjusted_p, scan_step
from optcal.applications.diagnosis.effects import BIAS_STEP, describe_term
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.outliers import deleted_residual_p
from optcal.core.model import AXES
from optcal.core.stats import rms

__all__ = ["Dropped", "Removal", "removals", "backward_check", "recheck_outliers", "recheck_notes", "step_offsets"]

#: The effect name of an outlier pose returned to the fit (as the selection names the outlier candidate).
OUTLIERS: str = "outliers"


@dataclass(frozen=True)
class Dropped:
    """A term, knock or outlier pose accepted in an earlier step and removed once a later term made it unneeded
    (:func:`backward_check`).

    Attributes
    ----------
    term : str
        What was removed as it was in the model, e.g. ``bias_drift(y)``, ``bias_step(x) after 11 poses``,
        ``outlier pose row 14 (returned to the fit)``.
    effect : str
        The effect (``outliers`` for a pose returned to the fit).
    axis : str or None
        The axis (``None`` for an outlier pose).
    order : int
        Its order in the model (a bias step: the steps its axis carried; an outlier pose: 1).
    p_value : float
        The test it entered by, given every other term of the model.
    level : float
        The level it entered at (its step's level, multiplicity adjustment included).
    delta_bic : float
        BIC of the model with it minus the model without it.
    heldout_rms_g_with, heldout_rms_g_without : float
        Held-out rms with and without it (the removal is kept only when the latter is not larger).
    after : str
        The term whose entry it was tested after.
    reason : str
    poses_before : int or None
        A knock removed: the poses before it in time order.
    rows : tuple of int or None
        An outlier pose returned: its row in the pose table.
    """

    term: str
    effect: str
    axis: str | None
    order: int
    p_value: float
    level: float
    delta_bic: float
    heldout_rms_g_with: float
    heldout_rms_g_without: float
    after: str
    reason: str
    poses_before: int | None = None
    rows: tuple[int, ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if k not in ("poses_before", "rows")}
        if self.poses_before is not None:
            out["poses_before"] = self.poses_before
        if self.rows is not None:
            out["rows"] = list(self.rows)
        return out


@dataclass(frozen=True)
class Removal:
    """One candidate removal that failed its test or its ΔBIC (:func:`removals`).

    Attributes
    ----------
    term : str
    effect : str
    axis : int or None
    order : int
        Its order in the model before the removal.
    p_value, level, delta_bic : float
        As :class:`Dropped`'s.
    without : Fit
        The model without it.
    steps : tuple of int
        The steps placed in the model without it (:attr:`~optcal.applications.diagnosis.fitting.Fitter.steps_at`).
    kind : str
        ``term``, ``offset``, ``knock`` or ``outlier``.
    poses_before : int or None
    pose : int or None
        An outlier pose's index.
    """

    term: str
    effect: str
    axis: int | None
    order: int
    p_value: float
    level: float
    delta_bic: float
    without: Fit = field(repr=False)
    steps: tuple[int, ...]
    kind: str
    poses_before: int | None = None
    pose: int | None = None

    @property
    def failed_test(self) -> bool:
        """Whether it failed its test (else only its ΔBIC)."""
        return self.p_value >= self.level


def step_offsets(terms: dict[tuple[str, int], int], j: int) -> list[int]:
    """The axes carrying an offset at the ``j``-th step placed: a ``bias_step`` term of "order" ``k`` carries offsets
    at the first ``k`` steps (:data:`~optcal.applications.diagnosis.effects.MAX_STEPS`)."""
    return sorted(a for (e, a), k in terms.items() if e == BIAS_STEP and k > j)


def without_step(terms: dict[tuple[str, int], int], j: int) -> dict[tuple[str, int], int]:
    """``terms`` without the ``j``-th step's offsets: each axis that carried it keeps its offsets at the others."""
    out: dict[tuple[str, int], int] = {}
    for (e, a), k in terms.items():
        k2 = k - 1 if e == BIAS_STEP and k > j else k
        if k2 > 0:
            out[(e, a)] = k2
    return out


def _fails(r: Removal) -> bool:
    return r.p_value >= r.level or r.delta_bic >= 0


def removals(fitter: Fitter, current: Fit, levels: dict[tuple[str, int], float], step_levels: dict[int, float],
             entered: tuple[str, int] | None, entered_steps: tuple[int, ...], outliers_level: float | None,
             entered_outliers: frozenset[int]) -> list[Removal]:
    """Every earlier term, knock offset, knock and outlier pose of ``current`` that fails the test it entered by or
    its ΔBIC given all the others (module docstring).

    ``levels``: each polynomial term's and each knock axis's entry level; ``step_levels``: each knock's (by the poses
    before it; a knock absent from it takes its axis's level in ``levels``); ``entered``, ``entered_steps`` and
    ``entered_outliers``: what the step just accepted placed (not tested); ``outliers_level``: the outliers'
    family-wise level (``None``: outlier poses are not tested).
    """
    bic = fitter.bic(current)
    placed = fitter.steps_at
    out: list[Removal] = []
    for key, order in current.terms.items():
        if key == entered or key not in levels or key[0] == BIAS_STEP:
            continue
        without = fitter.fit({k: v for k, v in current.terms.items() if k != key}, current.outliers, current.x)
        out.append(Removal(describe_term(key[0], key[1], order), key[0], key[1], order, fitter.f_test(without, current),
                           levels[key], bic - fitter.bic(without), without, placed, "term"))
    for j, at in enumerate(placed):
        axes = step_offsets(current.terms, j)
        if at in entered_steps or not axes:
            continue
        if len(axes) > 1:  # a knock on several axes: each offset whose removal the terms can say (its axis's last)
            for a in axes:
                key = (BIAS_STEP, a)
                if current.terms[key] != j + 1 or key == entered or key not in levels:
                    continue
                terms = {k: v for k, v in current.terms.items() if k != key}
                if current.terms[key] > 1:
                    terms[key] = current.terms[key] - 1
                without = fitter.fit(terms, current.outliers, current.x)
                out.append(Removal(f"{BIAS_STEP}({AXES[a]})'s offset at the knock after {at} poses", BIAS_STEP, a,
                                   current.terms[key], fitter.f_test(without, current), levels[key],
                                   bic - fitter.bic(without), without, placed, "offset", poses_before=at))
            continue
        a = axes[0]
        level = step_levels.get(at, levels.get((BIAS_STEP, a)))
        if level is None:
            continue
        out.append(_knock(fitter, current, j, a, level, bic))
    if outliers_level is not None:
        returned = _outlier(fitter, current, outliers_level, entered_outliers, bic)
        if returned is not None:
            out.append(returned)
    return [r for r in out if _fails(r)]


def _knock(fitter: Fitter, current: Fit, j: int, axis: int, level: float, bic: float) -> Removal:
    """The ``j``-th knock (one offset, on ``axis``) re-tested by its entry test given the rest (module docstring)."""
    placed = fitter.steps_at
    rest = placed[:j] + placed[j + 1:]
    fitter.set_steps(rest)
    try:
        without = fitter.fit(without_step(current.terms, j), current.outliers, current.x)
        p_exact = fitter.f_test(without, current)
        scan = scan_step(fitter, without, axis)  # the positions its entry test paid for, the other knock placed
        p = 1.0 if scan is None else adjusted_p(fitter, without, scan, p_exact)[0]
    finally:
        fitter.set_steps(placed)
    delta = bic + float(np.log(fitter.n)) - fitter.bic(without)  # its position a parameter too
    return Removal(f"{BIAS_STEP}({AXES[axis]}) after {placed[j]} poses", BIAS_STEP, axis,
                   int(current.terms[(BIAS_STEP, axis)]), p, level, delta, without, rest, "knock",
                   poses_before=placed[j])


def _outlier(fitter: Fitter, current: Fit, level: float, entered: frozenset[int], bic: float) -> Removal | None:
    """The least significant outlier pose set aside before this step, tested under ``current`` (module docstring)."""
    earlier = current.outliers - entered
    if not earlier:
        return None
    without_all = replace(current, outliers=frozenset())
    p_values = deleted_residual_p(fitter, without_all, current.outliers, current.x, current)
    k = max(earlier, key=lambda i: (p_values[i], i))
    back = fitter.fit(current.terms, current.outliers - {k}, current.x)
    return Removal(f"outlier pose row {int(fitter.poses.rows[k])} (returned to the fit)", OUTLIERS, None, 1,
                   p_values[k], level,
                   bic - fitter.bic(back), back, fitter.steps_at, "outlier", pose=k)


def _held_out_rms(fitter: Fitter, current: Fit, r: Removal) -> tuple[float, float]:
    """The held-out rms with and without ``r`` over the poses the model without it keeps (a returned pose's own
    held-out residual included); the fitter's steps are left as the model without it's."""
    mask = r.without.kept(fitter.n)
    with_rms = rms(fitter.heldout(current), mask)
    fitter.set_steps(r.steps)
    return with_rms, rms(fitter.heldout(r.without), mask)


def _held_out_passes(fitter: Fitter, current: Fit, failing: list[Removal]) -> tuple[Removal, float, float] | None:
    """The removal to make among ``failing``, with the held-out rms with and without it; ``None``: none.

    The least significant term or knock is tried first, then the least significant outlier pose (one queue each: a
    pose's return does not wait on a term the held-out check keeps, nor the reverse); each is made only when the
    held-out rms over the poses the model without it keeps (a returned pose's own held-out residual included) is
    not larger than with it.  The fitter's steps are left as the chosen removal's.
    """
    placed = fitter.steps_at
    for kind in (lambda f: f.kind != "outlier", lambda f: f.kind == "outlier"):
        queue = [f for f in failing if kind(f)]
        if not queue:
            continue
        r = max(queue, key=lambda f: (f.p_value, f.term))
        with_rms, without_rms = _held_out_rms(fitter, current, r)
        if without_rms <= with_rms:
            return r, with_rms, without_rms
        fitter.set_steps(placed)
    return None


def backward_check(fitter: Fitter, current: Fit, levels: dict[tuple[str, int], float], step_levels: dict[int, float],
                   entered: tuple[str, int] | None, after: str, dropped_keys: set[tuple[str, int]],
                   entered_steps: tuple[int, ...] = (), outliers_level: float | None = None,
                   entered_outliers: frozenset[int] = frozenset()) -> tuple[Fit, list[Dropped]]:
    """``current`` with the terms, knocks and outlier poses accepted before ``entered`` that it made unneeded
    removed, one at a time (module docstring); the fitter's steps are left as the returned model's.

    ``levels`` and ``step_levels`` lose the entries of what is removed; ``dropped_keys`` gains each removed term's and
    knock's key (not offered again).
    """
    out: list[Dropped] = []
    while True:
        failing = removals(fitter, current, levels, step_levels, entered, entered_steps, outliers_level,
                           entered_outliers)
        if not failing:
            return current, out
        chosen = _held_out_passes(fitter, current, failing)
        if chosen is None:
            return current, out
        r, with_rms, without_rms = chosen
        given = f"given {after} and the model's other terms"
        what = "its deleted residual is" if r.kind == "outlier" else "it is"
        why = (f"{given} {what} not significant (p = {r.p_value:.2g} ≥ {r.level:.2g}, the level it entered at)"
               if r.failed_test else f"{given} it no longer lowers the BIC (ΔBIC {r.delta_bic:+.1f})")
        rows = None if r.pose is None else (int(fitter.poses.rows[r.pose]),)
        out.append(Dropped(r.term, r.effect, None if r.axis is None else AXES[r.axis], r.order, float(r.p_value),
                           r.level, float(r.delta_bic), with_rms, without_rms, after,
                           f"{why}; held-out rms {with_rms * 1e3:.3g} → {without_rms * 1e3:.3g} mg without it",
                           r.poses_before, rows))
        if r.axis is not None:
            key = (r.effect, r.axis)
            if key not in r.without.terms:
                levels.pop(key, None)
            dropped_keys.add(key)  # not offered again, nor its axis's knock searched again: no cycling
        if r.poses_before is not None and r.kind == "knock":
            step_levels.pop(r.poses_before, None)
        current = r.without


def recheck_outliers(fitter: Fitter, final: Fit, level: float,
                     after: str = "the final model") -> tuple[Fit, list[Dropped], tuple[Removal, float, float] | None]:
    """``final`` with its outlier poses tested again under its own terms, each returned whose departure they explain;
    the poses returned, and the pose the held-out check kept aside with the held-out rms with and without it
    (``None``: none).

    An outlier is accepted in the step it passes, against the model of that step; a later effect (a drift,
    a temperature term) can explain its departure: a rest 2.6 σ from a fit without the drift is on the fit
    with it.  Every pose still aside under ``final`` (those the last accepted step set aside, which no later term
    re-tested, and those the backward check kept aside) is tested by the backward check's rule for a pose, written
    once (:func:`backward_check` with no term to test): its deleted residual with the others aside, Bonferroni over
    the poses (the test that set it aside, :func:`~optcal.applications.diagnosis.outliers.deleted_residual_p`) at the
    outliers' family-wise level ``level``, and ΔBIC; the least significant failing pose is returned when the
    held-out rms over the poses kept without it (its own held-out residual included) is not larger than with it,
    then the others are tested again (a returned pose changes their noise scale).  One rule for both checks: a
    pose the backward check kept aside after a term entered is not returned once selection stops by a laxer one.
    """
    out, returned = backward_check(fitter, final, {}, {}, None, after, set(), (), level, frozenset())
    failing = [r for r in removals(fitter, out, {}, {}, None, (), level, frozenset()) if r.kind == "outlier"]
    if not failing:
        return out, returned, None
    placed = fitter.steps_at
    r = max(failing, key=lambda f: (f.p_value, f.term))
    with_rms, without_rms = _held_out_rms(fitter, out, r)
    fitter.set_steps(placed)
    return out, returned, (r, with_rms, without_rms)


def recheck_notes(fitter: Fitter, returned: list[Dropped], kept: tuple[Removal, float, float] | None,
                  level: float) -> list[str]:
    """The report's notes on :func:`recheck_outliers`: the poses returned with their p and held-out rms, and the pose
    whose departure is not significant that the held-out check kept aside."""
    out = []
    if returned:
        rows = ", ".join(f"{d.rows[0]} (p = {d.p_value:.2g}, held-out rms {d.heldout_rms_g_with * 1e3:.4g} → "
                         f"{d.heldout_rms_g_without * 1e3:.4g} mg)" for d in returned if d.rows)
        out.append(f"outlier poses returned to the fit: under the final model with its effects their departure is not "
                   f"significant at the family-wise level {level:g}: pose rows {rows}")
    if kept is not None:
        r, with_rms, without_rms = kept
        out.append(f"outlier pose row {int(fitter.poses.rows[r.pose or 0])} stays aside: under the final model its "
                   f"departure is not significant (p = {r.p_value:.2g}, level {r.level:g}, ΔBIC {r.delta_bic:+.1f}), but "
                   f"the held-out rms would rise with it back ({with_rms * 1e3:.4g} → {without_rms * 1e3:.4g} mg), the "
                   "rule the backward check returns a pose by")
    return out
