"""The gyroscope diagnosis's held-out units: the folds of moves, each move and rest predicted by the model refitted
without its fold, and the paired gain, Student's t and the moves' response by which a finding must hold on them
(step 2 of :mod:`~optcal.applications.diagnosis.gyro_diagnosis`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.gyro_problem import GyroData, GyroParams, Noise, evaluate, gauss_newton, move_angles
from optcal.core.stats import mean_and_se

#: Fewest moves the held-out folds and the time offset's t test need (two per fold and a scatter of several).
MIN_DIAGNOSIS_MOVES: int = 8


def interleaved_folds(m: int, k: int) -> list[NDArray[np.bool_]]:
    """Held-out moves of each fold (interleaved: every ``k``-th move, so each fold spans the session)."""
    return [np.arange(m) % k == j for j in range(k)]


@dataclass(frozen=True)
class HeldOut:
    """Each move's squared gravity-prediction angle (degrees²) and each move's and rest's squared residual over its
    noise, every one under the model refitted without its fold."""

    angles2: NDArray[np.float64]
    #: Each move's residual (m, 3) over its noise, under the model refitted without its fold.
    move_residuals: NDArray[np.float64]
    rests: NDArray[np.float64]

    @property
    def moves(self) -> NDArray[np.float64]:
        """Each move's squared residual over its noise."""
        return np.asarray(np.sum(self.move_residuals ** 2, axis=1))

    @property
    def rms_deg(self) -> float:
        return float(np.sqrt(np.mean(self.angles2)))


def heldout(data: GyroData, noise: Noise, p: GyroParams, folds: list[NDArray[np.bool_]],
            rest_folds: list[NDArray[np.bool_]]) -> HeldOut:
    """:class:`HeldOut` of ``p`` (k-fold: the moves and rests of each fold predicted by the model fitted to the
    others, one Gauss–Newton step from ``p``)."""
    angles2 = np.zeros(data.n_moves)
    residuals = np.zeros((data.n_moves, 3))
    rests = np.zeros(data.rest_raw.shape[0])
    for test, test_rests in zip(folds, rest_folds):
        refit = gauss_newton(data, noise, p, iterations=1, train=~test, train_rests=~test_rests)
        e = evaluate(data, noise, refit, jac=False)
        angles2[test] = move_angles(data, refit, test) ** 2
        residuals[test] = e.moves[test]
        rests[test_rests] = np.sum(e.rests[test_rests] ** 2, axis=1)
    return HeldOut(angles2, residuals, rests)


def moves_response(before: HeldOut, after: HeldOut) -> tuple[float, float]:
    """How much of the change a term makes to the held-out moves' gravity prediction their misfit without it held:
    ``β = −Σ r·Δ / Σ |Δ|²`` (``r`` a held-out move's residual without the term, ``Δ`` the change the term makes to
    it), 1 when the moves carried the effect the term removes, 0 when they carried none of it (the term then adds
    ``Δ`` as an error), and its standard error (:func:`~optcal.core.stats.mean_and_se` of the moves' own ratios,
    weighted by ``|Δ|²``).  Linear in the moves' noise, where the paired gain of their angles is second order in a
    small ``Δ``: a term the rests fix well and the moves see faintly is judged by it."""
    delta = after.move_residuals - before.move_residuals
    x = np.sum(delta * delta, axis=1)
    keep = x > 0
    if np.count_nonzero(keep) < 2:
        return float("nan"), float("nan")
    y = -np.sum(before.move_residuals * delta, axis=1)
    beta, se = mean_and_se(y[keep] / x[keep], x[keep])
    return float(beta), float(se)


def heldout_gain_t(before: HeldOut, after: HeldOut) -> float:
    """Student's t of the held-out moves' and rests' paired improvement (each kind over its mean before, so that
    moves and rests weigh alike): a term that only fits the fitted units' noise improves some held-out ones and
    worsens others, its t near zero; a real effect's improvement holds unit after unit."""
    return _paired_t(np.concatenate([(before.moves - after.moves) / max(float(np.mean(before.moves)), 1e-300),
                                     (before.rests - after.rests) / max(float(np.mean(before.rests)), 1e-300)]))


def _paired_t(d: NDArray[np.float64]) -> float:
    """Student's t of the mean of paired differences ``d`` (improvements: positive when the term helps)."""
    return paired_gain(d)[2]


def paired_gain(d: NDArray[np.float64]) -> tuple[float, float, float]:
    """The mean of the paired held-out improvements ``d`` (one per held-out unit, positive when the finding helps),
    its standard error from their own scatter (:func:`~optcal.core.stats.mean_and_se`) and Student's t (infinite
    for a gain without scatter, 0 for none)."""
    gain, se = mean_and_se(d)
    t = gain / se if se > 0 else (math.inf if gain > 0 else 0.0)
    return gain, se, float(t)
