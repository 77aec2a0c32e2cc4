"""The band of the magnetometer's diagnosis (:mod:`optcal.applications.magnetic.diagnosis`, 1): the norm residual's
blocks, their noise measured (white, a block mean's, the colour) once the misfit that repeats with the field's
direction is taken out, and a correlated sequence's standard error by batch means.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optcal.families.mag.fit import batch_means_stderr

#: Samples per block of the band and the change-point search: long enough for a block mean to average the white
#: noise of a 10-100 Hz magnetometer, short enough to place a disturbance's ends within a fraction of a second.
BLOCK: int = 25
def _blocks(r: NDArray[np.float64]) -> NDArray[np.float64]:
    k = r.size // BLOCK
    return np.asarray(r[: k * BLOCK].reshape(k, BLOCK).mean(axis=1))


def _noise(r: NDArray[np.float64]) -> tuple[float, float, float]:
    """The samples' white σ (first differences, robust), a block mean's σ (the blocks' own scatter about their
    median, robust: a disturbance over a minority of the blocks does not widen it) and the colour (a block mean's
    variance over the white noise's ``σ²/BLOCK``), of residuals ``r`` less their orientation misfit."""
    d = np.diff(r)
    white = float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))
    b = _blocks(r)
    block = float(1.4826 * np.median(np.abs(b - np.median(b)))) if b.size else white
    block = max(block, white / math.sqrt(BLOCK))
    return white, block, block**2 / max(white**2 / BLOCK, 1e-300)


def batch_means_se(v: NDArray[np.float64]) -> float:
    """The standard error of the mean of the correlated sequence ``v`` (its finite values, in order) by batch means
    (:func:`optcal.families.mag.fit.batch_means_stderr` of the mean: a slow drift of the dip over a session widens
    it, however many samples measure it)."""
    v = v[np.isfinite(v)]
    if v.size < 2:
        return float("inf")
    return float(batch_means_stderr(np.ones((v.size, 1)), v - v.mean())[0])
