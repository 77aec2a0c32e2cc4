"""A statistic of a calibration's fit against the band its model predicts for it.

The band comes from a distribution (χ² with the fit's degrees of freedom,
:func:`optcal.applications.quality.evidence.chi_square_check`) or from simulations of the fitted model
(:mod:`optcal.applications.quality.simulation_band`, and the diagnosis's simulation check,
:func:`optcal.applications.quality.evidence.simulation_check`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BandCheck:
    """A statistic of the fit against the band the model predicts for it.

    Attributes
    ----------
    statistic : str
        What is compared, in words.
    measured, low, high : float
        The measured value and the band (``low``, ``high``); NaN when no band exists.
    source : str
        Where the band comes from (the χ² distribution, or N simulations).
    meaningful : bool
        False when the band cannot test anything (no per-pose noise given: χ² is matched by construction).
    percentile : float
        Where the measured value lies in a simulated distribution, % (NaN for a distribution's band).
    median : float
        The median of the simulated distribution (NaN for a distribution's band).
    unit : str
        ``"g"`` for a statistic in g (shown in mg), ``""`` for a number without unit.
    """

    statistic: str
    measured: float
    low: float
    high: float
    source: str
    meaningful: bool = True
    percentile: float = float("nan")
    median: float = float("nan")
    unit: str = ""

    @property
    def position(self) -> str:
        """``"inside"``, ``"above"`` or ``"below"`` the band (``"untested"`` when not meaningful)."""
        if not self.meaningful or not np.isfinite(self.low):
            return "untested"
        return "above" if self.measured > self.high else "below" if self.measured < self.low else "inside"
