"""Where a bias step would be: the split of the poses in time that a step of one axis's bias explains best.

A knock between two rests (a shock, a re-seated connector or mount) moves the accelerometer's zero offset and it
stays moved: every pose after the knock carries the same extra bias ``δ`` on the axes it moved (a session bias of
two segments, :data:`~optcal.applications.diagnosis.effects.SESSION_BIAS`, whose split is unknown).  The split is
chosen by the likelihood ratio of the step over the positions with at least
:data:`~optcal.applications.diagnosis.effects.STEP_MIN_SIDE` kept poses on each side.  The scan is linearised at
the current fit (the step's column projected off the fitted parameters' columns, the score statistic
``(g⊥ᵀe)²/(g⊥ᵀg⊥)``, the likelihood ratio to first order; Lu 2017, eq. 14's weighted norm residuals ``e``), through
suffix sums in time order, so every position costs O(p²) and a 2,000-pose session one pass; only the best position
is then fitted exactly and tested (:class:`~optcal.applications.diagnosis.selection.ForwardSelection`).

The search over positions is paid for by the distribution of the *best* position's p value when there is no step
(:func:`adjusted_p`): in a session of at most :data:`MINP_POSES` kept poses, Westfall & Young's single-step minP
adjusted p value, the share of :data:`DRAWS` null draws of the linearised model (as
:mod:`~optcal.applications.diagnosis.familywise` draws them, for the F test the step's tests take; under pose noise
correlated in time, of the whitened generalised model) whose smallest p
over the positions is at most the observed one; in a larger session Bonferroni over the positions (the exact test's
p times their number), which bounds the false-step rate whatever the dependence and costs little power where a
session has hundreds of poses.  Neighbouring splits' statistics are strongly dependent (they share all but one
pose), so the minP p is several times smaller than Bonferroni's on a 20-rest session (mikoff's MPU-9150, 22 rests,
a 2 mg step: 0.0027 by Bonferroni over 16 positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from scipy import stats as sps

from optcal.applications.diagnosis.effects import STEP_MIN_SIDE
from optcal.applications.diagnosis.familywise import NullDraws, null_draws
from optcal.applications.diagnosis.fitting import Fit, Fitter

__all__ = ["StepScan", "scan_step", "adjusted_p", "MINP_POSES", "DRAWS"]

#: Largest session (kept poses) whose step p value is adjusted by the minP simulation; above it, Bonferroni over the
#: positions.  The simulation costs poses × positions × :data:`DRAWS` (60 poses: 1.4e8, a fraction of a second);
#: a session of hundreds of poses detects a step of a fraction of its pose noise either way.
MINP_POSES: int = 60
#: Null draws of the minP simulation.  A step is tested at the step's family-wise level shared among its candidates
#: (about α/15 = 0.0013 at α = 0.02 on 15 candidates; 0.0005 with outliers tested): 40,000 draws put about 20 below
#: such a level, so the adjusted p value there is known to about ±22 % of itself (binomial, one standard error).
DRAWS: int = 40_000


@dataclass(frozen=True)
class StepScan:
    """The best split of one axis's bias step.

    Attributes
    ----------
    axis : int
    at : int
        Poses before the step in time order (the step comes after the first ``at`` poses of
        :attr:`~optcal.applications.diagnosis.fitting.Fitter.time_order`).
    statistic : float
        The linearised likelihood-ratio statistic at that split (in units of the fit's noise scale²).
    positions : int
        Distinct splits searched (the Bonferroni factor of the step's p value).
    splits : tuple of int
        The splits searched (poses before each in time order).
    information : tuple of float
        The step coefficient's information at each split of :attr:`splits` (its column's weighted sum of squares
        after the fit's columns are projected out, per unit of the bias column): its standard error at a split is
        proportional to ``1/√information`` (:func:`~optcal.applications.diagnosis.limits.step_limit`).
    """

    axis: int
    at: int
    statistic: float
    positions: int
    splits: tuple[int, ...] = ()
    information: tuple[float, ...] = ()


def scan_step(fitter: Fitter, fit: Fit, axis: int) -> StepScan | None:
    """The split of the poses in time where a step of axis ``axis``'s bias explains the most of ``fit``'s residuals.

    ``None`` when fewer than two sides of :data:`~optcal.applications.diagnosis.effects.STEP_MIN_SIDE` kept poses
    exist.  The splits of the steps already placed (:attr:`Fitter.steps_at`) are not searched.  Only the splits between kept poses count (a split next to an outlier pose is the same split as the one
    beside it).
    """
    order = fitter.time_order
    w = fitter.weights(fit)
    G, J = fitter.jacobians(fit, w)
    # the step's column is S_axis times the bias column (both per unit bias): the scale does not change the statistic
    h = J[order, 6 + axis]
    e = (np.sqrt(w) * fit.residuals)[order]
    Go = G[order]
    kept = (w > 0)[order]
    n = fitter.n
    # suffix sums: entry k is the sum over the poses order[k:], those after a step placed after the first k
    ge = np.cumsum((h * e)[::-1])[::-1]
    gg = np.cumsum((h * h)[::-1])[::-1]
    Gg = np.cumsum((Go * h[:, None])[::-1], axis=0)[::-1]
    before = np.concatenate([[0], np.cumsum(kept)])[:n]  # kept poses before split k
    total = int(kept.sum())
    valid = (before >= STEP_MIN_SIDE) & (total - before >= STEP_MIN_SIDE) & kept  # the first pose after is kept
    valid[0] = False
    valid[list(fitter.steps_at)] = False  # a step placed is not placed again (the next one is a knock of its own)
    if not np.any(valid):
        return None
    info = G.T @ G
    values, vectors = np.linalg.eigh(info)
    keep = values > 1e-12 * max(float(values.max()), 1e-300)
    inverse = (vectors[:, keep] / values[keep]) @ vectors[:, keep].T
    Ge = G.T @ (np.sqrt(w) * fit.residuals)
    ks = np.flatnonzero(valid)
    proj = Gg[ks] @ inverse
    num = ge[ks] - proj @ Ge
    den = gg[ks] - np.einsum("ij,ij->i", proj, Gg[ks])
    # a split whose step the fitted parameters already carry (no information left) cannot be tested
    ok = den > 1e-9 * np.maximum(gg[ks], 1e-300)
    if not np.any(ok):
        return None
    stat = np.where(ok, num**2 / np.where(ok, den, 1.0), -np.inf)
    best = int(np.argmax(stat))
    s2 = fit.rss / max(total - fit.n_params + len(fit.outliers), 1)
    return StepScan(axis, int(ks[best]), float(stat[best]) / max(s2, 1e-300), int(ok.sum()),
                    tuple(int(k) for k in ks[ok]), tuple(float(d) for d in den[ok]))


def null_largest(fitter: Fitter, fit: Fit, scan: StepScan, seed: int = 0,
                 null: NullDraws | None = None) -> NDArray[np.float64] | None:
    """The largest F statistic over ``scan``'s positions in each of :data:`DRAWS` draws of the linearised null model
    at ``fit`` (:func:`~optcal.applications.diagnosis.familywise.null_draws`: no step; ``null``: those draws, made
    once for several axes), each position's statistic formed as :meth:`Fitter.f_test` forms it; ``None`` when no
    residual degree of freedom is left for it."""
    dof = fitter.n - fit.n_params - 1
    if dof <= 0:
        return None
    null = null_draws(fitter, fit, DRAWS, seed) if null is None else null
    h = null.J[:, 6 + scan.axis]
    columns = null.columns(np.stack([np.where(np.isin(np.arange(fitter.n), fitter.time_order[k:]), h, 0.0)
                                     for k in scan.splits], axis=1))
    projected = columns - null.model @ (null.model.T @ columns)
    unit = projected / np.maximum(np.linalg.norm(projected, axis=0), 1e-300)
    gain = (unit.T @ null.z) ** 2  # each position's fall in it, (positions, DRAWS)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(np.max(gain / ((null.rss0[None, :] - gain) / dof), axis=0))


def uses_minp_positions(fitter: Fitter, fit: Fit) -> bool:
    """Whether a step's p value from ``fit`` is adjusted by the minP simulation (at most :data:`MINP_POSES` kept
    poses), not by Bonferroni over the positions.  Poses whose noise is correlated in time take it too, drawn
    under the correlation the diagnosis measured (:func:`~optcal.applications.diagnosis.familywise.whitening`)."""
    return int(fit.kept(fitter.n).sum()) <= MINP_POSES


def adjusted_p(fitter: Fitter, fit: Fit, scan: StepScan, p_single: float, seed: int = 0,
               null: NullDraws | None = None) -> tuple[float, str]:
    """The p value of the best position's step test ``p_single`` adjusted for the search over the positions.

    Returns the adjusted p value and how it was adjusted (``"minP"`` or ``"Bonferroni"``; module docstring).
    The minP null is the linearised model at ``fit`` (the poses' weighted residuals ``σ z``, ``fit``'s columns
    projected out); each position's statistic is formed as :meth:`Fitter.f_test` forms it on the route
    :meth:`Fitter.test_scale2` takes (the F test on the residuals' scale).  The adjusted p is ``(1 + #{draws: min_k p_k ≤ p_single}) / (1 + DRAWS)``.
    ``null``: the null draws at ``fit`` made once for several axes (:func:`null_largest`).
    """
    bonferroni = min(1.0, p_single * scan.positions)
    if not uses_minp_positions(fitter, fit):
        return bonferroni, "Bonferroni"
    largest = null_largest(fitter, fit, scan, seed, null)
    if largest is None:
        return bonferroni, "Bonferroni"
    # every position's test has one degree of freedom and the same residual ones, so its p value falls as its
    # statistic rises: a draw's smallest p is at most p_single exactly when its largest statistic reaches the
    # statistic whose p is p_single (one quantile, not a tail probability per position and draw)
    critical = float(sps.f.isf(p_single, 1, fitter.n - fit.n_params - 1))
    return float((1 + np.sum(largest >= critical)) / (1 + DRAWS)), "minP"
