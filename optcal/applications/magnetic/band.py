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
#: Degree of the polynomial in the calibrated field's direction that carries the model's misfit with orientation (the
#: ellipsoid's own terms are degree 2; what is left of a real sensor's misfit, a nonlinearity or a field not quite
#: uniform over the turns, repeats wherever the sensor points the same way, and a disturbance does not).
ORIENTATION_DEGREE: int = 4


def _blocks(r: NDArray[np.float64]) -> NDArray[np.float64]:
    k = r.size // BLOCK
    return np.asarray(r[: k * BLOCK].reshape(k, BLOCK).mean(axis=1))


def _direction_basis(u: NDArray[np.float64], degree: int = ORIENTATION_DEGREE) -> NDArray[np.float64]:
    """Monomials ``x^a y^b z^c`` (``a + b + c ≤ degree``) of unit vectors ``u`` (n, 3)."""
    cols = [u[:, 0] ** a * u[:, 1] ** b * u[:, 2] ** c
            for a in range(degree + 1) for b in range(degree + 1 - a) for c in range(degree + 1 - a - b)]
    return np.column_stack(cols)


def _biweight_fit(X: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Coefficients of ``y ≈ X c`` by Tukey's biweight (4.685 robust σ, six reweightings)."""
    w = np.ones(y.size)
    coef: NDArray[np.float64] = np.zeros(X.shape[1])
    for _ in range(6):
        sw = np.sqrt(w)
        coef = np.asarray(np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0], dtype=np.float64)
        e = y - X @ coef
        scale = max(1.4826 * float(np.median(np.abs(e))), 1e-300)
        z = e / (4.685 * scale)
        w = np.where(np.abs(z) < 1.0, (1.0 - z * z) ** 2, 0.0)
    return np.asarray(coef)


def orientation_misfit(r: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
    """The part of the norm residuals ``r`` that depends on the direction ``u`` alone (module docstring, 2): a
    polynomial in ``u`` fitted by Tukey's biweight on the blocks' means, so that a disturbance over a minority of
    the session, which does not repeat at the same orientation, is not absorbed."""
    X = _direction_basis(u)
    k = r.size // BLOCK
    Xb = X[: k * BLOCK].reshape(k, BLOCK, -1).mean(axis=1)
    return np.asarray(X @ _biweight_fit(Xb, _blocks(r)))


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
