"""The held-out comparison of the magnetometer's diagnosis (:mod:`optcal.applications.magnetic.diagnosis`, 4): the
samples split into alternate stretches of blocks, each half's model predicting the other's norm residual and dip
residual, and the gain's standard error by batch means.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.magnetic.band import BLOCK, batch_means_se
from optcal.applications.magnetic.dip_channel import _dip_fit, _dip_residuals
from optcal.core.norm_residual import norm_residuals
from optcal.families.mag.dip import MIN_STILL
from optcal.families.mag.fit import MagSettings, fit_form
from optcal.families.mag.samples import MagSamples

#: Blocks per held-out half: alternate stretches of this many blocks fit and test each other (a disturbance and a
#: slow turn span several blocks, so both halves see each).
HELD_OUT_BLOCKS: int = 4


def _halves(n: int) -> NDArray[np.bool_]:
    """Alternate stretches of :data:`HELD_OUT_BLOCKS` blocks: True in one half."""
    return np.asarray((np.arange(n) // (BLOCK * HELD_OUT_BLOCKS)) % 2 == 0)


def _fit(samples: MagSamples, keep: NDArray[np.bool_], form: str, settings: MagSettings) -> Any:
    sub = MagSamples(samples.m[keep], samples.units, path=samples.path)
    return fit_form(sub, form, settings)


def _heldout(samples: MagSamples, keep: NDArray[np.bool_], form: str, s: MagSettings, halves: NDArray[np.bool_],
             test_keep: NDArray[np.bool_], shift: Any = None) -> NDArray[np.float64]:
    """The norm residual of each half's samples in ``test_keep`` under the model fitted to the other half's samples
    in ``keep`` (``shift(m)``: the column terms' offsets removed first), in sample order; NaN elsewhere."""
    m = samples.m if shift is None else shift(samples.m)
    sub = MagSamples(m, samples.units, path=samples.path)
    out = np.full(samples.n, np.nan)
    for train in (halves, ~halves):
        fit = _fit(sub, train & keep, form, s)
        out[~train & test_keep] = norm_residuals(fit.T, fit.o, m[~train & test_keep])
    return out


def _heldout_dip(a: NDArray[np.float64], still: NDArray[np.bool_], m: NDArray[np.float64], T: NDArray[np.float64],
                 o: NDArray[np.float64], keep: NDArray[np.bool_], halves: NDArray[np.bool_],
                 test_keep: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The dip residual (degrees) of each half's still samples in ``test_keep`` under ``R``, ``δ`` fitted on the
    other half's still samples in ``keep`` (the field calibrated by ``T``, ``o``), in sample order; NaN elsewhere."""
    out = np.full(m.shape[0], np.nan)
    for train in (halves, ~halves):
        rows, test = still & keep & train, still & test_keep & ~train
        if np.count_nonzero(rows) < MIN_STILL or not test.any():
            continue
        R, sin_dip = _dip_fit(a, rows, m, T, o)
        out[test] = _dip_residuals(a, test, m, T, o, R, sin_dip)[test]
    return out


def _rms(e: NDArray[np.float64]) -> float:
    """The rms of the finite held-out errors ``e`` (NaN: none)."""
    return float(np.sqrt(np.nanmean(e**2))) if np.isfinite(e).any() else float("nan")


def heldout_gain(before: NDArray[np.float64], after: NDArray[np.float64]) -> tuple[float, float]:
    """The held-out mean square error's decrease from ``before`` to ``after`` (the same samples in order, NaN: not
    held out) and its standard error by batch means of the paired differences (:func:`batch_means_se`): coloured
    errors, a slow turn through a misfit, count once per correlation length, not once per sample."""
    d = before**2 - after**2
    d = d[np.isfinite(d)]
    return (float(np.mean(d)), batch_means_se(d)) if d.size else (0.0, float("inf"))
