"""The dip channel of the magnetometer's diagnosis (:mod:`optcal.applications.magnetic.diagnosis`, 2): the angle
between the calibrated field and gravity at the still samples, its residual per sample and per block (less its misfit
with the gravity direction), and its noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.magnetic.band import BLOCK
from optcal.applications.magnetic.orientation import BLOCKS_PER_TERM, DIP_ORIENTATION_DEGREE, biweight_fit, direction_basis
from optcal.data.rest_tests import unit_rows
from optcal.families.mag.dip import MAX_DIP_SAMPLES, fit_dip, per_sample_dip

#: A block's dip mean is used when at least this share of its samples are still: its white noise is then at most
#: √2 times a full block's, so one scatter describes every block used (fewer still samples: a block of motion, whose
#: measured vertical is tilted by the hand's acceleration, is left out of the dip channel, and counted).
DIP_BLOCK_SHARE: float = 0.5


@dataclass(frozen=True)
class DipChannel:
    """The dip residual's noise (module docstring, 2: the dip channel).

    Attributes
    ----------
    n_still : int
        Samples where the accelerometer shows the sensor near rest.
    sigma_sample : float
        White noise of a still sample's dip, degrees (first differences of consecutive still samples, robust).
    sigma_block : float
        Noise of a block's mean dip, degrees (the usable blocks' robust scatter).
    blocks_used, blocks : int
        Blocks with at least :data:`DIP_BLOCK_SHARE` of their samples still, of all blocks.
    dip_deg, dip_se_deg : float
        The plain calibration's dip and its standard error by batch means of the still samples' dips
        (:func:`batch_means_se`).
    rate_bound : float or None
        The gyroscope's rate bound of near rest, rad/s (:func:`optcal.families.mag.dip.rest_gate`); ``None`` without
        a gyroscope in rad/s or deg/s.
    n_turning : int
        Samples with ``|a|`` near g left out because the sensor turned faster.
    near_rest : str
        How near rest was decided (printed).
    """

    n_still: int
    sigma_sample: float
    sigma_block: float
    blocks_used: int
    blocks: int
    dip_deg: float
    dip_se_deg: float
    rate_bound: float | None = None
    n_turning: int = 0
    near_rest: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"still_samples": self.n_still, "sigma_sample_deg": self.sigma_sample,
                "sigma_block_deg": self.sigma_block, "blocks_used": self.blocks_used, "blocks": self.blocks,
                "dip_deg": self.dip_deg, "dip_se_deg": self.dip_se_deg, "rate_bound_rad_s": self.rate_bound,
                "turning_samples": self.n_turning, "near_rest": self.near_rest}


def _dip_fit(a: NDArray[np.float64], rows: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
             o: NDArray[np.float64], R0: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], float]:
    """``R`` and ``sin δ`` on the still samples ``rows`` (at most :data:`MAX_DIP_SAMPLES`, evenly spaced) of the
    field calibrated by ``T``, ``o`` (:func:`optcal.families.mag.dip.fit_dip`)."""
    index = np.flatnonzero(rows)
    index = index[:: max(1, index.size // MAX_DIP_SAMPLES)]
    R, sin_dip, _ = fit_dip(a[index], unit_rows((m[index] - o) @ T.T), R0=R0)
    return R, sin_dip


def _dip_residuals(a: NDArray[np.float64], still: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
                   o: NDArray[np.float64], R: NDArray[np.float64], sin_dip: float) -> NDArray[np.float64]:
    """``δ_k − δ`` in degrees at the still samples, NaN elsewhere (module docstring, 2)."""
    d = per_sample_dip(a, unit_rows((m - o) @ T.T) @ R.T) - math.degrees(math.asin(sin_dip))
    return np.where(still, d, np.nan)


def _masked_blocks(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Blocks' means of the finite values of ``d``; NaN where fewer than :data:`DIP_BLOCK_SHARE` of a block's are."""
    k = d.size // BLOCK
    ok = np.isfinite(d[: k * BLOCK]).reshape(k, BLOCK)
    count = ok.sum(axis=1)
    sums = np.where(ok, d[: k * BLOCK].reshape(k, BLOCK), 0.0).sum(axis=1)
    return np.where(count >= DIP_BLOCK_SHARE * BLOCK, sums / np.maximum(count, 1), np.nan)


def _dip_noise(d: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[float, float, int]:
    """The still samples' white σ (first differences of the dip residuals ``d``, robust), a usable block mean's σ (the
    robust scatter of the block means ``b``, :func:`dip_block_means`) and the usable blocks (as :func:`_noise`)."""
    values = d[np.isfinite(d)]
    diff = np.diff(values)
    white = float(1.4826 * np.median(np.abs(diff - np.median(diff))) / math.sqrt(2.0)) if diff.size else 0.0
    b = b[np.isfinite(b)]
    block = float(1.4826 * np.median(np.abs(b - np.median(b)))) if b.size else white
    return white, max(block, white / math.sqrt(BLOCK)), int(b.size)


def dip_block_means(d: NDArray[np.float64], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """The blocks' mean dip residuals (:func:`_masked_blocks` of ``d``, NaN where not usable) less their misfit with
    the gravity direction ``a`` (unit rows): the raw accelerometer's own scale, bias and misalignment tilt the
    measured vertical by an amount that depends on its direction, a polynomial in ``a`` (as
    :func:`orientation_misfit`, biweight on the usable blocks); a disturbance over a minority is not absorbed."""
    b = _masked_blocks(d)
    ok = np.isfinite(b)
    still = np.isfinite(d)
    X = np.where(still[:, None], direction_basis(np.where(still[:, None], a, 0.0), DIP_ORIENTATION_DEGREE), 0.0)
    if np.count_nonzero(ok) <= BLOCKS_PER_TERM * X.shape[1]:
        return b  # under two usable blocks per term of the polynomial: the misfit is not determined
    k = b.size
    counts = np.maximum(still[: k * BLOCK].reshape(k, BLOCK).sum(axis=1), 1)
    Xb = X[: k * BLOCK].reshape(k, BLOCK, -1).sum(axis=1) / counts[:, None]
    out = np.full(k, np.nan)
    out[ok] = b[ok] - Xb[ok] @ biweight_fit(Xb[ok], b[ok])
    return out
