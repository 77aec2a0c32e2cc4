"""The magnetometer's forms compared on directions left out of their fit: cross-validation over direction cells
(:func:`heldout_forms`); the rule that chooses a form from it is
:func:`optcal.families.mag.heldout_rule.richest_within_se`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.stats import mean_and_se
from optcal.families.mag.coverage import COVERAGE_DIRECTIONS, COVERAGE_NAMES
from optcal.families.mag.ellipsoid import FORM_BASIS, FORMS, fit_symmetric, sphere_fit

#: The held-out comparison of the forms (:func:`heldout_forms`) is made on at most this many samples, evenly
#: spaced in time: a cell of the 26 then keeps about 200 samples (its mean square known to about a tenth of
#: itself under white noise, far less than the cells differ), and the 26 × 3 refits stay under a second.
#: Measured on the peers' files: 5,000 against 20,000 samples moved the held-out rms by at most 2 % of itself
#: and no form's paired gain by more than 0.1 of its standard error.
HELDOUT_SAMPLES: int = 5_000
#: Fewest direction cells the held-out comparison needs: the standard error of a paired difference from k
#: cells is itself uncertain by about 1/√(2(k − 1)), 41 % at 4; with fewer, the forms are chosen by how well
#: their parameters are determined alone (:data:`optcal.families.mag.fit.RELEVANT_SHARE`).
MIN_HELDOUT_CELLS: int = 4


@dataclass(frozen=True)
class HeldOut:
    """The forms' errors on direction cells left out of their fit (:func:`heldout_forms`).

    Attributes
    ----------
    cells : ndarray of int, shape (C,)
        The coverage directions (indices into :data:`COVERAGE_NAMES`) holding samples: each a fold.
    counts : ndarray of int, shape (C,)
        Samples per cell.
    mse : dict of str to ndarray, shape (C,)
        Per form, the mean square of ``‖T(m − o)‖ − 1`` over each cell's samples, ``T`` and ``o`` fitted
        without that cell.
    n_samples : int
        Samples compared (at most :data:`HELDOUT_SAMPLES`).
    """

    cells: NDArray[np.int64]
    counts: NDArray[np.int64]
    mse: dict[str, NDArray[np.float64]]
    n_samples: int

    def rms(self, form: str) -> float:
        """The held-out rms of ``‖T(m − o)‖ − 1`` of ``form`` over all the cells' samples."""
        return float(np.sqrt(np.sum(self.counts * self.mse[form]) / np.sum(self.counts)))

    def summary(self) -> dict[str, Any]:
        """The evidence for the JSON: the cells left out, the samples, each form's held-out rms and each richer
        form's mean-square gain over the simplest with its standard error."""
        forms = list(self.mse)
        return {"cells": [COVERAGE_NAMES[c] for c in self.cells], "n_samples": self.n_samples,
                "rms": {f: self.rms(f) for f in forms}, "fit": "maximum likelihood, squared loss",
                "gain_over_" + forms[0]: {f: dict(zip(("gain", "se"), self.gain(forms[0], f))) for f in forms[1:]}}

    def gain(self, simpler: str, richer: str) -> tuple[float, float]:
        """The paired difference of the held-out mean squares, ``simpler`` less ``richer``, and its standard
        error with the cells as the independent units (their samples correlated within, the weights the
        cells' shares of the samples)."""
        return mean_and_se(self.mse[simpler] - self.mse[richer], self.counts)


def heldout_forms(m: NDArray[np.float64], forms: tuple[str, ...]) -> HeldOut:
    """Each form's error on the directions it did not see: cross-validation over direction cells.

    The model: a calibration is used in the directions the sensor will see, so a form is worth its
    parameters when it predicts ``‖T(m − o)‖ = 1`` in a direction left out of its fit, not only in the
    samples it fitted.  The samples (at most :data:`HELDOUT_SAMPLES`, evenly spaced in time) are put in
    the cell of their nearest coverage direction (:data:`COVERAGE_DIRECTIONS`, caps of about 35°), their
    direction taken from the sphere fitted to them all (determined whenever any form is);
    each cell in turn is left out, every form fitted on the rest (:func:`optcal.families.mag.ellipsoid.fit_symmetric`: maximum
    likelihood under white norm noise, the estimator's model) and its mean square residual measured
    on the cell.  A form that extrapolates badly into directions the others do not determine loses
    there, which is what the parameters' standard errors alone stand for.
    """
    stride = max(1, -(-len(m) // HELDOUT_SAMPLES))
    mm = np.ascontiguousarray(m[::stride])
    try:
        u = mm - sphere_fit(mm)[0]
    except np.linalg.LinAlgError:  # no sphere through them all (not a field): the cells about their mean
        u = mm - mm.mean(axis=0)
    cell = np.argmax(u @ COVERAGE_DIRECTIONS.T / np.linalg.norm(u, axis=1, keepdims=True), axis=1)
    cells, counts = np.unique(cell, return_counts=True)
    mse: dict[str, NDArray[np.float64]] = {f: np.empty(len(cells)) for f in forms}
    for i, c in enumerate(cells):
        out = cell == c
        try:
            o_s, r_s, _ = sphere_fit(mm[~out])
        except np.linalg.LinAlgError:  # the rest hold no sphere (not a field): no form predicts the cell
            for f in forms:
                mse[f][i] = np.inf
            continue
        for f in forms:
            if (~out).sum() <= FORMS[f]:
                mse[f][i] = np.inf
                continue
            T, o = fit_symmetric(mm[~out], FORM_BASIS[f], (o_s, r_s))
            v = (mm[out] - o) @ T.T
            mse[f][i] = float(np.mean((np.linalg.norm(v, axis=1) - 1.0) ** 2))
    return HeldOut(cells.astype(np.int64), counts.astype(np.int64), mse, len(mm))
