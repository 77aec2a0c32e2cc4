"""The misfit of a fitted model with the direction: a polynomial in a unit direction, fitted robustly to block means.

What repeats wherever a sensor points the same way belongs to the model (a nonlinearity, a field not quite uniform over
the turns, a raw accelerometer's tilt of the vertical), not to a disturbance: the magnetometer's diagnosis
(:mod:`optcal.applications.magnetic.diagnosis`) takes it out of the norm and dip residuals before its search.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Blocks the robust fit needs per term of the polynomial: at two or fewer a block mean's noise is fitted, not the
#: misfit (the dip's block means use the same rule: :func:`optcal.applications.magnetic.dip_channel.dip_block_means`).
BLOCKS_PER_TERM: int = 2


#: Degree of the polynomial in the calibrated field's direction that carries the model's misfit with orientation (the
#: ellipsoid's own terms are degree 2; what is left of a real sensor's misfit, a nonlinearity or a field not quite
#: uniform over the turns, repeats wherever the sensor points the same way, and a disturbance does not).
ORIENTATION_DEGREE: int = 4


#: Degree of the polynomial in the gravity direction that carries the dip's misfit with orientation: a raw
#: accelerometer's linear errors (``â ↦ K â + b``: scale, misalignment, bias) tilt the measured vertical by terms of
#: degree up to 2 in ``â``; a higher degree would absorb a disturbance's bend over the few blocks that are still.
DIP_ORIENTATION_DEGREE: int = 2


def direction_basis(u: NDArray[np.float64], degree: int = ORIENTATION_DEGREE) -> NDArray[np.float64]:
    """Monomials ``x^a y^b z^c`` (``a + b + c ≤ degree``) of unit vectors ``u`` (n, 3)."""
    cols = [u[:, 0] ** a * u[:, 1] ** b * u[:, 2] ** c
            for a in range(degree + 1) for b in range(degree + 1 - a) for c in range(degree + 1 - a - b)]
    return np.column_stack(cols)


def biweight_fit(X: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
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


def n_terms(degree: int) -> int:
    """The monomials of :func:`direction_basis` of ``degree`` in three variables, ``C(degree + 3, 3)``."""
    return (degree + 1) * (degree + 2) * (degree + 3) // 6


def misfit_degree(n_blocks: int, highest: int = ORIENTATION_DEGREE) -> int:
    """The highest degree up to ``highest`` whose polynomial ``n_blocks`` block means determine: more than
    :data:`BLOCKS_PER_TERM` blocks per term (degree 4, 35 terms, needs 71 blocks: 1,775 samples in blocks of 25;
    a 534-sample log's 21 blocks fit degree 2, 10 terms); 0 (the mean) below that."""
    return max([0, *(d for d in range(highest + 1) if n_blocks > BLOCKS_PER_TERM * n_terms(d))])


def orientation_misfit(r: NDArray[np.float64], u: NDArray[np.float64], block: int,
                       degree: int | None = None) -> NDArray[np.float64]:
    """The part of the norm residuals ``r`` that depends on the direction ``u`` alone: a polynomial in ``u`` of
    ``degree`` (by default :func:`misfit_degree` of the blocks) fitted by Tukey's biweight on the means of blocks of
    ``block`` samples, so that a disturbance over a minority of the session, which does not repeat at the same
    orientation, is not absorbed.  With more terms than blocks the fit was underdetermined: on a 534-sample log
    (21 blocks, 35 terms) it subtracted a misfit of 61 % rms of the field and inflated the white noise tenfold."""
    k = r.size // block
    X = direction_basis(u, misfit_degree(k) if degree is None else degree)
    Xb = X[: k * block].reshape(k, block, -1).mean(axis=1)
    rb = r[: k * block].reshape(k, block).mean(axis=1)
    return np.asarray(X @ biweight_fit(Xb, rb))
